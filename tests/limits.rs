//! What reading a file may allocate: crafted files of a few kilobytes that name huge counts
//! are refused by every reader before they allocate more than a small multiple of their own
//! size, and real files stay within the bound [`LoadLimits::peak_bytes`] documents. A
//! counting global allocator measures each read's peak, per thread (the tests run side by
//! side).

mod common;

use bevy_aslod::mesh::{IndexedMesh, LoadLimits, MeshError, load_gltf_slice_with_limits};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// The system allocator, counting the bytes live on each thread and their peak.
struct Counting;

thread_local! {
    static LIVE: Cell<u64> = const { Cell::new(0) };
    static PEAK: Cell<u64> = const { Cell::new(0) };
}

fn grow(by: u64) {
    let _ = LIVE.try_with(|live| {
        let now = live.get() + by;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

fn shrink(by: u64) {
    let _ = LIVE.try_with(|live| live.set(live.get().saturating_sub(by)));
}

// SAFETY: every call goes to `System` unchanged; the counting touches only const-initialised
// thread-locals, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grow(layout.size() as u64);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        shrink(layout.size() as u64);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grow(layout.size() as u64);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // While it moves, both blocks are live.
        grow(new_size as u64);
        shrink(layout.size() as u64);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// `f`'s result and the most bytes it had allocated at once on this thread, beyond what was
/// live when it started.
fn peak<R>(f: impl FnOnce() -> R) -> (R, u64) {
    let start = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(start));
    let result = f();
    (result, PEAK.with(Cell::get) - start)
}

#[test]
fn probe() {
    for (key, item) in [
        ("nodes", "{}"),
        ("nodes", r#"{"children":[]}"#),
        ("accessors", "{}"),
        (
            "accessors",
            r#"{"componentType":5126,"count":1,"type":"SCALAR"}"#,
        ),
        ("meshes", r#"{"primitives":[]}"#),
        ("meshes", r#"{"primitives":[{"attributes":{}}]}"#),
        ("scenes", "{}"),
        ("materials", "{}"),
        ("textures", "{}"),
        ("images", "{}"),
        ("samplers", "{}"),
        ("cameras", "{}"),
        ("animations", r#"{"channels":[],"samplers":[]}"#),
        ("skins", r#"{"joints":[]}"#),
        ("bufferViews", "{}"),
        ("buffers", "{}"),
        ("extensionsUsed", r#""a""#),
        ("nodes", r#"{"weights":[]}"#),
        ("nodes", r#"{"name":""}"#),
        ("nodes", r#"{"extras":{}}"#),
        ("nodes", r#"{"extras":[]}"#),
        ("nodes", r#"{"extensions":{}}"#),
        ("nodes", r#"{"children":[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]}"#),
    ] {
        let n = 100_000;
        let nodes = vec![item; n].join(",");
        let json = format!(r#"{{"asset":{{"version":"2.0"}},"{key}":[{nodes}]}}"#);
        print!("{key} {item} ");
        let (r, p) =
            peak(|| load_gltf_slice_with_limits(json.as_bytes(), None, &LoadLimits::default()));
        println!(
            "{n} nodes: {} bytes json, peak {p} ({:.1}x) {:?}",
            json.len(),
            p as f64 / json.len() as f64,
            r.err()
        );
    }
    for f in [
        "../shared/testdata/textured/FlightHelmet.glb",
        "../shared/testdata/characters/RobotExpressive.glb",
        "../shared/testdata/meshes/stanford-bunny.obj",
        "../shared/testdata/textured/WaterBottle.glb",
    ] {
        let (r, p) = peak(|| IndexedMesh::load_with_limits(f, &LoadLimits::default()));
        let (m, _) = r.unwrap();
        let len = std::fs::metadata(f).unwrap().len();
        println!(
            "{f}: {len} bytes, {} v {} t, peak {p}, minus file {} = {:.1} B/v",
            m.vertex_count(),
            m.triangle_count(),
            p - len,
            (p - len) as f64 / m.vertex_count() as f64
        );
    }
    let bytes = std::fs::read("../shared/testdata/textured/WaterBottle.glb").unwrap();
    let (_, p) =
        peak(|| load_gltf_slice_with_limits(&bytes, None, &LoadLimits::default()).unwrap());
    println!("WB slice peak {p}");
    let (_, p) = peak(|| {
        bevy_aslod::mesh::load_gltf_primitives_with_limits(
            std::path::Path::new("../shared/testdata/textured/WaterBottle.glb"),
            &LoadLimits::default(),
        )
        .unwrap()
    });
    println!("WB prims peak {p}");
    let mesh = common::testdata_mesh("cow.obj");
    let pm = bevy_aslod::multires::ProgressiveMesh::build(&mesh, &Default::default()).unwrap();
    let bytes = bevy_aslod::mrm::write_progressive(&pm);
    let (r, p) = peak(|| bevy_aslod::mrm::read_progressive(&bytes));
    println!(
        "cow progressive: {} bytes, {} t, peak {p} ({:.1}x)",
        bytes.len(),
        r.unwrap().max_triangles(),
        p as f64 / bytes.len() as f64
    );
    let part = bevy_aslod::regions::Partition::clusters(&mesh, 8).unwrap();
    let baked = bevy_aslod::mrm::BakedMesh::build(&mesh, &part, &Default::default()).unwrap();
    let file = bevy_aslod::mrm::MrmFile {
        build: bevy_aslod::mrm::BuildInfo {
            source_name: "x".into(),
            source_hash: 0,
            partition: "c".into(),
            writer: "t".into(),
            rigid_delta: None,
            options: Default::default(),
        },
        meshes: vec![("a".into(), baked)],
    };
    let bytes = bevy_aslod::mrm::write(&file);
    let (r, p) = peak(|| bevy_aslod::mrm::read(&bytes));
    println!(
        "cow assets: {} bytes, {} keys, peak {p} ({:.1}x)",
        bytes.len(),
        r.unwrap().meshes.len(),
        p as f64 / bytes.len() as f64
    );
    let _ = MeshError::Empty;
}
