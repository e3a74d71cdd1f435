//! Baked `.mrm` files against building, printed as a table (release; medians of interleaved
//! runs, so the machine's noise hits every column alike):
//!
//! - **build**: parse the OBJ and build the asset (regions in 16 clusters): what a game does
//!   on every start without a baked file;
//! - **load**: read the `.mrm` file and check and decode all of it ([`mrm::read`]);
//! - **bytes**: read the file's bytes into memory, nothing else (the floor for a load).
//!
//! Then the file's size per triangle, against Hoxha's estimate of about 90 bytes and the
//! source file's. RobotExpressive (skinned, every primitive) is compared with its `.glb`.
//!
//! `cargo bench --no-default-features --bench mrm`

use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::mrm::{self, BakedMesh, BuildInfo, MrmFile};
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::regions::Partition;
use bevy_aslod::skin::DEFAULT_RIGID_DELTA;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

const TESTDATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/");

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

fn info(name: &str, source: &[u8]) -> BuildInfo {
    BuildInfo {
        source_name: name.into(),
        source_hash: mrm::source_hash(source),
        partition: "clusters:16".into(),
        writer: "benches/mrm.rs".into(),
        rigid_delta: None,
        options: BuildOptions::default(),
    }
}

/// Builds an OBJ's asset in 16 clusters, from the file.
fn build_obj(path: &Path) -> MrmFile {
    let source = std::fs::read(path).expect("test mesh");
    let (mesh, _) = IndexedMesh::load(path).expect("test mesh");
    let partition = Partition::clusters(&mesh, 16).expect("partition");
    let baked = BakedMesh::build(&mesh, &partition, &BuildOptions::default()).expect("builds");
    let name = path.file_name().unwrap().to_string_lossy();
    MrmFile {
        build: info(&name, &source),
        meshes: vec![("Mesh0/Primitive0".into(), baked)],
    }
}

/// Builds every primitive of a glTF file (skinned ones by influence).
fn build_gltf(path: &Path) -> MrmFile {
    let source = std::fs::read(path).expect("test character");
    let single = |m: &IndexedMesh| Partition::grid(m, Default::default(), 1, 1);
    let options = BuildOptions::default();
    let meshes =
        mrm::bake_gltf(path, &single, &options, DEFAULT_RIGID_DELTA, &mut |_| {}).expect("builds");
    let name = path.file_name().unwrap().to_string_lossy();
    MrmFile {
        build: info(&name, &source),
        meshes,
    }
}

fn triangles(file: &MrmFile) -> usize {
    file.meshes
        .iter()
        .flat_map(|(_, m)| m.regions.regions())
        .map(|r| r.max_triangles())
        .sum()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    // `cargo test --benches` runs benches once in debug: keep that short.
    let quick = args.iter().any(|a| a == "--test") || cfg!(debug_assertions);
    let repeats = if quick { 1 } else { 11 };
    // `-- --profile-load`: only loads of the bunny, for a profiler.
    if args.iter().any(|a| a == "--profile-load") {
        let file = build_obj(&Path::new(TESTDATA).join("meshes/stanford-bunny.obj"));
        let bytes = mrm::write(&file);
        for _ in 0..500 {
            black_box(mrm::read(&bytes).expect("loads"));
        }
        return;
    }
    let out_dir = std::env::temp_dir().join(format!("aslod-mrm-bench-{}", std::process::id()));
    std::fs::create_dir_all(&out_dir).expect("temp dir");
    println!(
        "| mesh | triangles | build | load | bytes | build / load | load / bytes | file | B/tri | source | source B/tri |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    type Build = fn(&Path) -> MrmFile;
    let cases: [(&str, Build); 2] = [
        ("meshes/stanford-bunny.obj", build_obj),
        ("characters/RobotExpressive.glb", build_gltf),
    ];
    for (name, build) in cases {
        let path = Path::new(TESTDATA).join(name);
        let baked = out_dir.join("baked.mrm");
        let file = build(&path);
        std::fs::write(&baked, mrm::write(&file)).expect("write");
        let (mut b, mut l, mut r) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..repeats {
            let t = Instant::now();
            black_box(build(&path));
            b.push(ms(t));
            let t = Instant::now();
            let bytes = std::fs::read(&baked).expect("read");
            let back = mrm::read(&bytes).expect("loads");
            l.push(ms(t));
            assert!(back == file, "the file reads back as built");
            let t = Instant::now();
            black_box(std::fs::read(&baked).expect("read"));
            r.push(ms(t));
        }
        let (b, l, r) = (median(b), median(l), median(r));
        let size = std::fs::metadata(&baked).expect("file").len() as f64;
        let source = std::fs::metadata(&path).expect("source").len() as f64;
        let t = triangles(&file) as f64;
        println!(
            "| {} | {t} | {b:.1} ms | {l:.2} ms | {r:.2} ms | {:.0}× | {:.1}× | {:.2} MB | {:.1} | {:.2} MB | {:.1} |",
            path.file_name().unwrap().to_string_lossy(),
            b / l,
            l / r,
            size / 1e6,
            size / t,
            source / 1e6,
            source / t,
        );
    }
    std::fs::remove_dir_all(&out_dir).ok();
}
