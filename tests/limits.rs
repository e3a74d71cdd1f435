//! What reading a file may allocate: crafted files of a few kilobytes that name huge counts
//! are refused by every reader before they allocate more than a small multiple of their own
//! size, and real files stay within the bound [`LoadLimits::peak_bytes`] documents. A
//! counting global allocator measures each read's peak, per thread (the tests run side by
//! side).

mod common;

use bevy_aslod::mesh::{
    IndexedMesh, LoadLimits, MeshError, load_gltf_slice_with_limits, parse_obj_with_limits,
    parse_ply_with_limits,
};
use bevy_aslod::mrm::{self, BakedMesh, BuildInfo, MrmError, MrmFile};
use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
use bevy_aslod::regions::Partition;
use common::glb;
use common::reseal::{containers, reseal, table};
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

/// What a refused read names: the limit and the value the file asks for, or `None` for any
/// other error (a file that ends before the data it counts).
type Refusal = Option<(&'static str, u64)>;

fn mesh_refusal(e: MeshError) -> Refusal {
    match e {
        MeshError::LimitExceeded { limit, value, .. } => Some((limit, value)),
        _ => None,
    }
}

fn mrm_refusal(e: MrmError) -> Refusal {
    match e {
        MrmError::LimitExceeded { limit, value, .. } => Some((limit, value)),
        _ => None,
    }
}

/// A glTF of about a kilobyte: `nodes` nodes showing one mesh whose `POSITION` accessor
/// has no buffer view (the specification fills it with zeros) and `count` elements.
fn zero_filled(count: usize, nodes: usize) -> String {
    let list = |item: &str| vec![item; nodes].join(",");
    let roots: Vec<String> = (0..nodes).map(|n| n.to_string()).collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[0,0,0]}}]}}"#,
        roots.join(","),
        list(r#"{"mesh":0}"#)
    )
}

/// `bytes` with the first `u32` of section `tag` of the container at `start` set to
/// `value`, resealed.
fn patched(bytes: &[u8], start: usize, tag: &[u8; 4], value: u32) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let (_, at, _) = table(&out, start)
        .into_iter()
        .find(|&(e, ..)| &out[e..e + 4] == tag)
        .expect("the section is there");
    out[at..at + 4].copy_from_slice(&value.to_le_bytes());
    let starts = containers(&out);
    reseal(&mut out, &starts);
    out
}

fn cow() -> IndexedMesh {
    common::testdata_mesh("cow.obj")
}

fn build_info() -> BuildInfo {
    BuildInfo {
        source_name: "cow.obj".into(),
        source_hash: 0,
        partition: "clusters:4".into(),
        writer: "tests/limits.rs".into(),
        rigid_delta: None,
        options: BuildOptions::default(),
    }
}

fn baked_cow() -> Vec<u8> {
    let mesh = cow();
    let partition = Partition::clusters(&mesh, 4).unwrap();
    let baked = BakedMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
    mrm::write(&MrmFile {
        build: build_info(),
        meshes: vec![("cow".into(), baked)],
    })
}

/// A file of a few kilobytes that names a huge count is refused, naming the limit when
/// `limit` is given, before it allocates more than a small multiple of its own size.
#[test]
fn crafted_files_are_refused_before_they_allocate() {
    let defaults = LoadLimits::default();
    let gltf = |bytes: &[u8]| {
        load_gltf_slice_with_limits(bytes, None, &defaults)
            .map(drop)
            .map_err(mesh_refusal)
    };
    let obj = |bytes: &[u8]| {
        parse_obj_with_limits(std::str::from_utf8(bytes).unwrap(), &defaults)
            .map(drop)
            .map_err(mesh_refusal)
    };
    let ply = |bytes: &[u8]| {
        parse_ply_with_limits(bytes, &defaults)
            .map(drop)
            .map_err(mesh_refusal)
    };
    let progressive = |bytes: &[u8]| {
        mrm::read_progressive_with_limits(bytes, &defaults)
            .map(drop)
            .map_err(mrm_refusal)
    };
    let assets = |bytes: &[u8]| {
        mrm::read_with_limits(bytes, &defaults)
            .map(drop)
            .map_err(mrm_refusal)
    };

    // The bounded-import issue's file: 16,777,215 zero positions shown by 64 nodes (8.7 GB
    // of memory before the importer summed the counts first).
    let zeros = zero_filled(16_777_215, 64);
    // An index accessor of a thousand million indices, in a buffer that says it has 4 GB.
    let indices = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
        "accessors":[{"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[0,0,0]},
          {"bufferView":0,"componentType":5125,"count":1000000000,"type":"SCALAR"}],
        "bufferViews":[{"buffer":0,"byteLength":4000000000}],
        "buffers":[{"byteLength":4000000000,"uri":"big.bin"}]}"#;
    // Sixty-four buffers of 100 MB, all the same file.
    let buffers = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{}]}}"#,
        vec![r#"{"byteLength":100000000,"uri":"a.bin"}"#; 64].join(",")
    );
    // Two skins whose inverse bind matrices are 16,777,215 zero matrices each (2 GB).
    let skins = r#"{"asset":{"version":"2.0"},"nodes":[{}],
        "skins":[{"joints":[0],"inverseBindMatrices":0},{"joints":[0],"inverseBindMatrices":0}],
        "accessors":[{"componentType":5126,"count":16777215,"type":"MAT4"}]}"#;
    let huge_ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
        property float x\nproperty float y\nproperty float z\nend_header\n";
    let empty_ply = b"ply\nformat ascii 1.0\nelement vertex 4000000\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\n\
        property list uint uint vertex_indices\nend_header\n";
    let long_face = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\n\
        property list uint uint vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n\
        4000000000 0 1 2\n";
    let pm = ProgressiveMesh::build(
        &common::sphere(6, 8, &[0.0], false),
        &BuildOptions::default(),
    )
    .unwrap();
    let small_pm = mrm::write_progressive(&pm);
    let small_assets = {
        let mesh = common::sphere(6, 8, &[0.0], false);
        let partition = Partition::clusters(&mesh, 2).unwrap();
        let baked = BakedMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
        mrm::write(&MrmFile {
            build: build_info(),
            meshes: vec![("sphere".into(), baked)],
        })
    };
    // The innermost container is a region's: its `RGN ` header starts with its vertices.
    let region = *containers(&small_assets).last().unwrap();

    type Read<'a> = &'a dyn Fn(&[u8]) -> Result<(), Refusal>;
    let cases: Vec<(&str, Vec<u8>, Read<'_>, Option<&str>)> = vec![
        (
            "glTF, zero-filled positions",
            zeros.clone().into_bytes(),
            &gltf,
            Some("vertices"),
        ),
        (
            "GLB, zero-filled positions",
            glb(&zeros, &[]),
            &gltf,
            Some("vertices"),
        ),
        (
            "glTF, 4 GB of indices",
            indices.into(),
            &gltf,
            Some("triangles"),
        ),
        (
            "glTF, one buffer 64 times",
            buffers.into_bytes(),
            &gltf,
            Some("file_bytes"),
        ),
        (
            "glTF, zero-filled skins",
            skins.into(),
            &gltf,
            Some("decoded_bytes"),
        ),
        (
            "OBJ, a face past the vertices",
            b"v 0 0 0\nf 1 2 4000000000\n".to_vec(),
            &obj,
            None,
        ),
        (
            "PLY, 4e9 vertices in the header",
            huge_ply.to_vec(),
            &ply,
            Some("vertices"),
        ),
        (
            "PLY, 4e6 vertices and no data",
            empty_ply.to_vec(),
            &ply,
            None,
        ),
        ("PLY, a face of 4e9 corners", long_face.to_vec(), &ply, None),
        (
            ".mrm, 4e9 vertices",
            patched(&small_pm, 0, b"MESH", 4_000_000_000),
            &progressive,
            Some("vertices"),
        ),
        (
            ".mrm assets, 4e9 vertices",
            patched(
                &small_assets,
                containers(&small_assets)[1],
                b"HEAD",
                4_000_000_000,
            ),
            &assets,
            Some("vertices"),
        ),
        (
            ".mrm assets, a region of 4e9 vertices",
            patched(&small_assets, region, b"RGN ", 4_000_000_000),
            &assets,
            Some("decoded_bytes"),
        ),
    ];
    for (name, bytes, read, limit) in cases {
        assert!(bytes.len() <= 8 << 10, "{name}: {} bytes", bytes.len());
        let (result, bytes_peak) = peak(|| read(&bytes));
        let refusal = result.expect_err(name);
        if let Some(limit) = limit {
            assert_eq!(refusal.map(|r| r.0), Some(limit), "{name}");
        }
        println!(
            "{name}: {} bytes, peak {bytes_peak} bytes, refused: {refusal:?}",
            bytes.len()
        );
        // A small multiple of the file (parsing a glTF's JSON takes about 30 bytes a byte of
        // these; up to about 200 for a list of empty objects, `LoadLimits::JSON_FACTOR`).
        let bound = 64 * bytes.len() as u64 + (16 << 10);
        assert!(
            bytes_peak <= bound,
            "{name}: {bytes_peak} bytes allocated, above {bound}"
        );
    }
}

/// The limits at which `read` passes: each found from what `read` says it needs when that
/// limit is 0 and the others are off, then raised to what it still asks for (an OBJ's
/// vertices grow at its seams after its lines are counted; a PLY's triangles are counted as
/// they are read, so its refusal names one past the limit: those are doubled, then bisected
/// down to the least that passes).
fn limits_needed(read: &dyn Fn(&LoadLimits) -> Result<(), Refusal>) -> LoadLimits {
    let mut at = LoadLimits::UNLIMITED;
    for name in [
        "file_bytes",
        "json_bytes",
        "decoded_bytes",
        "vertices",
        "triangles",
        "joints",
        "keys",
    ] {
        let mut probe = LoadLimits::UNLIMITED;
        *field(&mut probe, name) = 0;
        *field(&mut at, name) = match read(&probe) {
            Err(Some((limit, value))) if limit == name => value,
            _ => 0,
        };
    }
    let mut doubled = Vec::new();
    for _ in 0..64 {
        match read(&at) {
            Ok(()) => {
                for name in doubled {
                    let (mut low, mut high) = (0, *field(&mut at, name));
                    while low < high {
                        let mid = low + (high - low) / 2;
                        *field(&mut at, name) = mid;
                        if read(&at).is_ok() {
                            high = mid;
                        } else {
                            low = mid + 1;
                        }
                    }
                    *field(&mut at, name) = high;
                }
                return at;
            }
            Err(Some((limit, value))) => {
                let current = field(&mut at, limit);
                if value <= *current + 1 {
                    *current = value.max(2 * *current);
                    doubled.push(limit);
                } else {
                    *current = value;
                }
            }
            Err(None) => panic!("the file does not read"),
        }
    }
    panic!("the limits did not settle");
}

fn field<'a>(limits: &'a mut LoadLimits, name: &str) -> &'a mut u64 {
    match name {
        "file_bytes" => &mut limits.file_bytes,
        "json_bytes" => &mut limits.json_bytes,
        "decoded_bytes" => &mut limits.decoded_bytes,
        "vertices" => &mut limits.vertices,
        "triangles" => &mut limits.triangles,
        "joints" => &mut limits.joints,
        "keys" => &mut limits.keys,
        other => panic!("no limit {other}"),
    }
}

/// Every real file of the test data (and a PLY and `.mrm` files written here) reads within
/// [`LoadLimits::peak_bytes`] of the limits it needs.
#[test]
fn real_files_stay_within_the_documented_bound() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata");
    let dir = std::env::temp_dir().join(format!("aslod-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ply = dir.join("cow.ply");
    let mesh = cow();
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\n\
         end_header\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    for p in &mesh.positions {
        text += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    for t in mesh.indices.chunks_exact(3) {
        text += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(&ply, text).unwrap();
    let embedded = dir.join("cow.gltf");
    std::fs::write(&embedded, embedded_gltf(&mesh)).unwrap();
    let mut files: Vec<String> = [
        "textured/FlightHelmet.glb",
        "textured/WaterBottle.glb",
        "characters/RobotExpressive.glb",
        "characters/KayKit_Knight.glb",
        "meshes/cow.obj",
        "meshes/stanford-bunny.obj",
    ]
    .iter()
    .map(|f| format!("{data}/{f}"))
    .collect();
    files.push(ply.display().to_string());
    files.push(embedded.display().to_string());
    for file in &files {
        let read = |limits: &LoadLimits| {
            IndexedMesh::load_with_limits(file, limits)
                .map(drop)
                .map_err(mesh_refusal)
        };
        check_bound(file, &read);
    }
    let progressive =
        mrm::write_progressive(&ProgressiveMesh::build(&mesh, &BuildOptions::default()).unwrap());
    let read = |limits: &LoadLimits| {
        mrm::read_progressive_with_limits(&progressive, limits)
            .map(drop)
            .map_err(mrm_refusal)
    };
    check_bound("cow, progressive .mrm", &read);
    let baked = baked_cow();
    let read = |limits: &LoadLimits| {
        mrm::read_with_limits(&baked, limits)
            .map(drop)
            .map_err(mrm_refusal)
    };
    check_bound("cow, baked .mrm", &read);
    std::fs::remove_dir_all(&dir).ok();
}

/// `mesh` as a `.gltf` whose one buffer is a base64 `data:` URI (positions, then indices).
fn embedded_gltf(mesh: &IndexedMesh) -> String {
    let mut bin: Vec<u8> = mesh
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let positions = bin.len();
    bin.extend(mesh.indices.iter().flat_map(|i| i.to_le_bytes()));
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((glam::Vec3::MAX, glam::Vec3::MIN), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    format!(
        r#"{{"asset":{{"version":"2.0"}},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":{:?},"max":{:?}}},
          {{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteLength":{positions}}},{{"buffer":0,"byteOffset":{positions},"byteLength":{}}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        mesh.positions.len(),
        lo.to_array(),
        hi.to_array(),
        mesh.indices.len(),
        bin.len() - positions,
        bin.len(),
        base64(&bin)
    )
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            out.push(if k <= chunk.len() {
                ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char
            } else {
                '='
            });
        }
    }
    out
}

fn check_bound(name: &str, read: &dyn Fn(&LoadLimits) -> Result<(), Refusal>) {
    let at = limits_needed(read);
    let (result, bytes_peak) = peak(|| read(&at));
    result.unwrap();
    let bound = at.peak_bytes();
    println!("{name}: peak {bytes_peak} bytes, bound {bound} ({at:?})");
    assert!(
        bytes_peak <= bound,
        "{name}: {bytes_peak} bytes, above the bound {bound}"
    );
}

/// `json_bytes` counts what parses into many small allocations: a `data:` URI of a
/// hundred kilobytes does not count, the objects around it do.
#[test]
fn json_bytes_counts_the_structure_not_long_strings() {
    let embedded = embedded_gltf(&cow());
    assert!(embedded.len() > 100_000);
    let limits = LoadLimits {
        json_bytes: 1_000,
        ..LoadLimits::default()
    };
    let read = |json: &str| load_gltf_slice_with_limits(json.as_bytes(), None, &limits);
    assert!(read(&embedded).is_ok());
    let structure = zero_filled(3, 100);
    assert!(structure.len() > 1_000);
    assert!(matches!(
        read(&structure),
        Err(MeshError::LimitExceeded {
            limit: "json_bytes",
            ..
        })
    ));
}
