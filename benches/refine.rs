//! View-dependent refinement (`refine`), printed as two tables (release; medians):
//!
//! 1. Güdükbay et al.'s Table 1 for the cow, the bunny and the mannequin: vertices, faces,
//!    collapses, and the refined model's vertices and faces with the paper's setup (the model
//!    as large as fits an 800×600 view, Hoppe's three criteria: out of the frustum, facing
//!    away, or under τ pixels of error), with the time of a fresh extraction and of an
//!    incremental update per frame along a camera orbit (120 frames, 3° each).
//! 2. MOM's Figure 7 experiment on the bunny: a sphere of interest around the head with a
//!    growing radius, faces drawn against extraction time, beside a uniform level of the
//!    same face count reached by a polygon cache from full detail.
//!
//! `cargo bench --no-default-features --features mannequin --bench refine [-- --tolerance PX]`

use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use bevy_aslod::refine::{
    Criteria, ScreenSpaceError, SphereOfInterest, VariableCache, VariableMesh, View, extract,
};
use glam::{Quat, Vec3};
use std::hint::black_box;
use std::time::Instant;

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/meshes/");
const WIDTH: f32 = 800.0;
const HEIGHT: f32 = 600.0;
const FOV: f32 = 0.785; // 45°
const FRAMES: usize = 120;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let tolerance = args
        .iter()
        .position(|a| a == "--tolerance")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(1.0f32);
    // `cargo test --benches` runs benches once in debug: keep that short.
    let quick = args.iter().any(|a| a == "--test") || cfg!(debug_assertions);
    let repeats = if quick { 1 } else { 15 };

    let mut models = vec![
        ("Cow", load("cow.obj")),
        ("Bunny", load("stanford-bunny.obj")),
    ];
    #[cfg(feature = "mannequin")]
    models.push((
        "Mannequin",
        bevy_aslod::mannequin::generate(&bevy_aslod::mannequin::MannequinOptions::default())
            .expect("the default mannequin")
            .mesh,
    ));

    println!("Güdükbay et al. Table 1: {WIDTH}x{HEIGHT}, 45° field of view, the model as large as");
    println!("fits the view; frustum + back faces + screen-space error under {tolerance} px;");
    println!("fresh: one extraction from scratch; incremental: per frame along an orbit of");
    println!("{FRAMES} frames, 3° each (medians over {repeats} runs)");
    println!();
    println!(
        "| model | vertices | faces | collapses | refined vertices | refined faces | ratio | fresh ms | incremental ms | evaluated per frame | bytes/triangle (view data) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (name, mesh) in &models {
        table_1(name, mesh, tolerance, repeats);
    }
    println!();
    figure_7(&models[1].1, repeats);
}

fn load(name: &str) -> IndexedMesh {
    IndexedMesh::load(format!("{MESHES}{name}"))
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .0
}

/// The bounding sphere's centre and radius.
fn bounds(mesh: &IndexedMesh) -> (Vec3, f32) {
    let (lo, hi) = mesh.bounds().expect("non-empty");
    let centre = (lo + hi) * 0.5;
    let radius = mesh
        .positions
        .iter()
        .map(|p| p.distance(centre))
        .fold(0.0, f32::max);
    (centre, radius)
}

/// The camera of frame `frame` of the orbit: the model as large as fits the view.
fn orbit_view(centre: Vec3, radius: f32, frame: usize) -> View {
    let distance = radius / (FOV * 0.5).sin();
    let turn = Quat::from_rotation_y((3.0 * frame as f32).to_radians());
    let eye = centre + turn * Vec3::new(0.0, 0.15 * radius, distance);
    View::perspective(
        eye,
        centre - eye,
        Vec3::Y,
        FOV,
        WIDTH / HEIGHT,
        0.01 * radius,
        HEIGHT,
    )
    .expect("a valid camera")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn table_1(name: &str, mesh: &IndexedMesh, tolerance: f32, repeats: usize) {
    let options = BuildOptions::default().with_view_dependent(true);
    let pm = ProgressiveMesh::build(mesh, &options).expect("builds");
    let plain = ProgressiveMesh::build(mesh, &BuildOptions::default()).expect("builds");
    let view_bytes = (pm.memory_bytes() - plain.memory_bytes()) as f64 / pm.max_triangles() as f64;
    let vm = VariableMesh::new(pm).expect("view data");
    let (centre, radius) = bounds(mesh);
    let criteria = Criteria::default()
        .with_frustum(true)
        .with_back_facing(true)
        .with_screen_space(Some(ScreenSpaceError::new(tolerance).expect("tolerance")));

    let view = orbit_view(centre, radius, 0);
    let mut indices = Vec::new();
    let mut fresh = Vec::new();
    let mut stats = None;
    for _ in 0..repeats.max(3) {
        let start = Instant::now();
        stats = Some(extract(&vm, &criteria, &view, &mut indices).expect("extracts"));
        fresh.push(start.elapsed().as_secs_f64() * 1e3);
        black_box(&indices);
    }
    let stats = stats.expect("ran");
    let used = {
        let mut seen = vec![false; mesh.vertex_count()];
        indices.iter().for_each(|&v| seen[v as usize] = true);
        seen.iter().filter(|&&s| s).count()
    };

    let mut per_frame = Vec::new();
    let mut evaluated = Vec::new();
    let views: Vec<View> = (0..=FRAMES)
        .map(|f| orbit_view(centre, radius, f))
        .collect();
    for _ in 0..repeats {
        let mut cache = VariableCache::new(&vm);
        cache.extract(&vm, &criteria, &views[0]).expect("extracts");
        for view in &views[1..] {
            let start = Instant::now();
            let s = cache.update(&vm, &criteria, view).expect("updates");
            per_frame.push(start.elapsed().as_secs_f64() * 1e3);
            evaluated.push(s.evaluated as f64);
            black_box(cache.indices());
        }
    }
    println!(
        "| {name} | {} | {} | {} | {used} | {} | {:.1} % | {:.2} | {:.3} | {:.0} | {view_bytes:.2} |",
        mesh.vertex_count(),
        mesh.triangle_count(),
        vm.collapse_count(),
        stats.triangles,
        100.0 * stats.triangles as f64 / mesh.triangle_count() as f64,
        median(fresh),
        median(per_frame),
        median(evaluated),
    );
}

fn figure_7(mesh: &IndexedMesh, repeats: usize) {
    let options = BuildOptions::default().with_view_dependent(true);
    let vm = VariableMesh::new(ProgressiveMesh::build(mesh, &options).expect("builds"))
        .expect("view data");
    let pm = vm.mesh();
    let (centre, radius) = bounds(mesh);
    // The head: the highest vertex.
    let head = mesh
        .positions
        .iter()
        .copied()
        .max_by(|a, b| a.y.total_cmp(&b.y))
        .expect("non-empty");
    let view = orbit_view(centre, radius, 0);
    println!(
        "MOM Figure 7 on the bunny: a sphere of interest at the head, growing; outside it the"
    );
    println!("mesh goes as coarse as it can. Fresh extraction time against a polygon cache moved");
    println!(
        "from full detail to a uniform level of the same face count (medians over {repeats} runs)"
    );
    println!();
    println!(
        "| radius (× bounding radius) | faces | variable: extraction ms | uniform: cache ms |"
    );
    println!("|---:|---:|---:|---:|");
    let mut indices = Vec::new();
    for r in [0.0f32, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0] {
        let sphere = SphereOfInterest::new(head, r * radius).expect("sphere");
        let mut times = Vec::new();
        let mut faces = 0;
        for _ in 0..repeats.max(3) {
            let start = Instant::now();
            faces = extract(&vm, &sphere, &view, &mut indices)
                .expect("extracts")
                .triangles;
            times.push(start.elapsed().as_secs_f64() * 1e3);
            black_box(&indices);
        }
        let mut uniform = Vec::new();
        for _ in 0..repeats.max(3) {
            let mut cache = PolygonCache::new(pm);
            let start = Instant::now();
            cache.set_triangle_count(pm, faces);
            uniform.push(start.elapsed().as_secs_f64() * 1e3);
            black_box(cache.indices());
        }
        println!(
            "| {r} | {faces} | {:.2} | {:.2} |",
            median(times),
            median(uniform)
        );
    }
}
