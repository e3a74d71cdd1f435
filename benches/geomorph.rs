//! Popping with and without geomorphs (`regions::Geomorphs`), printed as a table (release):
//! the bunny (16 clusters), the Silvretta terrain (6×6 grid), the mannequin at rest (16
//! clusters) and the WaterBottle (8 clusters; UVs and tangents, which morph with the
//! positions), each along a camera path at 60 fps (1280×720, 60° vertical field of view)
//! that orbits far for two seconds, cuts to near, and orbits there for two more. Every
//! frame the budget is split by the α allocation over the regions' projected boxes, and
//! `Geomorphs::apply_allocation` applies it: a coarsening region keeps its old count until
//! its morph ends, and refinements take only what is free.
//!
//! Per frame it measures the largest screen-space movement of any vertex, with the frame's
//! camera (so only the geometry's change counts): a vertex shown in both frames by its own
//! two positions, one that appears from where its stand-in at the old level was shown, one
//! that vanishes to where its stand-in at the new level is shown. Also the shown triangles
//! against the budget, the CPU time of the morph bookkeeping (level requests, `update`, and
//! the positions and further attributes of every region whose vertices move), the bytes a
//! CPU write of those positions, normals and further attributes would upload, and the bytes the GPU path writes instead (the runs of
//! vertices a morph started on, `Geomorphs::take_restarted`, 56 B each). T = 1 s shows what
//! a longer morph does to the largest movement.
//!
//! The "(view-dependent)" rows refine each mesh as one variable-resolution model instead:
//! its level fitted to the budget every frame (`ToleranceSearch`, frustum and back faces)
//! and shown through `refine::VariableGeomorphs::follow` under the budget.
//!
//! `cargo bench --no-default-features --bench geomorph`

use bevy_aslod::budget::{AllocationParams, Allocator, Obb, ProjectedAreaCamera, RegionInput};
use bevy_aslod::mesh::{IndexedMesh, load_gltf, weld_positions};
use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
use bevy_aslod::refine::{
    Criteria, LevelCut, ToleranceSearch, VariableCache, VariableGeomorphs, VariableMesh, View,
};
use bevy_aslod::regions::{Geomorphs, GridPlane, Partition, Region, RegionCaches, RegionMesh};
use glam::{Mat4, Vec2, Vec3};
use std::collections::HashMap;
use std::time::Instant;

const WIDTH: f32 = 1280.0;
const HEIGHT: f32 = 720.0;
const FOV_Y: f32 = std::f32::consts::FRAC_PI_3;
const DT: f32 = 1.0 / 60.0;

#[path = "../examples/common/terrain.rs"]
mod terrain;

struct Scene {
    name: &'static str,
    mesh: IndexedMesh,
    partition: Partition,
    /// Share of the full mesh's triangles the budget allows.
    budget: f32,
}

fn scenes(quick: bool) -> Vec<Scene> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/");
    let (bunny, _) = IndexedMesh::load(format!(
        "{root}../shared/testdata/meshes/stanford-bunny.obj"
    ))
    .expect("the bunny");
    let terrain = terrain::terrain_middle(if quick { 65 } else { 129 });
    let mannequin = load_gltf(std::path::Path::new(&format!("{root}assets/mannequin.glb")))
        .expect("the mannequin")
        .mesh;
    let (bottle, _) =
        IndexedMesh::load(format!("{root}../shared/testdata/textured/WaterBottle.glb"))
            .expect("the bottle");
    vec![
        Scene {
            name: "bunny",
            partition: Partition::clusters(&bunny, 16).expect("clusters"),
            mesh: bunny,
            budget: 0.1,
        },
        Scene {
            name: "Silvretta",
            partition: Partition::grid(&terrain, GridPlane::XZ, 6, 6).expect("grid"),
            mesh: terrain,
            budget: 0.2,
        },
        Scene {
            name: "mannequin",
            partition: Partition::clusters(&mannequin, 16).expect("clusters"),
            mesh: mannequin,
            budget: 0.1,
        },
        Scene {
            name: "WaterBottle",
            partition: Partition::clusters(&bottle, 8).expect("clusters"),
            mesh: bottle,
            budget: 0.2,
        },
    ]
}

/// The camera at frame `f` of `frames`: far orbit, then a cut to a near one. Returns its
/// clip matrix, projected-area camera and eye.
fn camera(f: usize, frames: usize, centre: Vec3, radius: f32) -> (Mat4, ProjectedAreaCamera, Vec3) {
    let near_half = f >= frames / 2;
    let distance = if near_half { 1.3 } else { 6.0 } * radius;
    let angle = f as f32 * 0.01;
    let eye = centre + distance * Vec3::new(angle.sin(), 0.35, angle.cos()).normalize();
    let view = Mat4::look_at_rh(eye, centre, Vec3::Y);
    let projection = Mat4::perspective_infinite_reverse_rh(FOV_Y, WIDTH / HEIGHT, 0.01 * radius);
    let area = ProjectedAreaCamera::new(view, projection, Vec2::new(WIDTH, HEIGHT))
        .expect("a valid camera");
    (projection * view, area, eye)
}

fn to_screen(clip: &Mat4, p: Vec3) -> Option<Vec2> {
    let c = *clip * p.extend(1.0);
    (c.w > 1e-6).then(|| {
        let ndc = c.truncate() / c.w;
        Vec2::new((ndc.x + 1.0) * 0.5 * WIDTH, (1.0 - ndc.y) * 0.5 * HEIGHT)
    })
}

/// What one run along the path measured.
#[derive(Default)]
struct Run {
    /// Per frame: the largest movement in pixels.
    movement: Vec<f32>,
    /// The largest shown total over the budget.
    over_budget: f32,
    /// Per frame: morph bookkeeping in ms, bytes a CPU write of positions and normals
    /// would upload, bytes the GPU path writes (the vertices morphs started on, each with
    /// its position, normal and two morph attributes: 56 B).
    cpu_ms: Vec<f64>,
    bytes: Vec<usize>,
    gpu_bytes: Vec<usize>,
}

fn run(scene: &Scene, regions: &RegionMesh, obbs: &[Obb], duration: f32, frames: usize) -> Run {
    let (lo, hi) = scene.mesh.bounds().expect("non-empty");
    let (centre, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let budget = (scene.budget * scene.mesh.triangle_count() as f32) as u32;
    // Every region starts at its coarsest level (as a new model does), so the budget holds
    // from the first frame.
    let mut caches = RegionCaches::new(regions);
    for r in 0..regions.regions().len() {
        caches.set_triangle_count(regions, r, 0);
    }
    let mut morphs = Geomorphs::new(regions, duration);
    let mut allocator = Allocator::new();
    let (mut areas, mut inputs, mut counts) = (vec![0.0; obbs.len()], Vec::new(), Vec::new());
    let region_of = regions.partition().region_of();
    let mut shown: HashMap<u32, Vec3> = HashMap::new();
    let mut levels: Vec<usize> = (0..regions.regions().len())
        .map(|r| caches.level(r))
        .collect();
    let mut out = Run::default();
    let mut part = Vec::new();
    let (mut positions, mut attributes) = (Vec::new(), Vec::new());
    for f in 0..frames {
        let now = f as f32 * DT;
        let (clip, area_camera, _) = camera(f, frames, centre, radius);
        area_camera.projected_areas(obbs, &mut areas);
        // The view's allocation, whatever is morphing (`apply_allocation` holds the budget).
        inputs.clear();
        for (r, (region, &area)) in regions.regions().iter().zip(&areas).enumerate() {
            inputs.push(RegionInput::from_area(
                area,
                1.0,
                region.min_triangles() as u32,
                region.max_triangles() as u32,
                caches.triangle_count(r) as u32,
            ));
        }
        let params = AllocationParams::with_budget(budget);
        allocator
            .allocate(&params, &inputs, &mut counts)
            .expect("valid inputs");
        let start = Instant::now();
        morphs.apply_allocation(regions, &mut caches, &counts, budget as usize, now);
        morphs.update(regions, &mut caches, now);
        let mut bytes = 0;
        for r in 0..regions.regions().len() {
            if morphs.is_region_moving(regions, r) {
                morphs.write_positions(regions, r, now, &mut positions);
                morphs.write_attributes(regions, r, Some(now), &mut attributes);
                bytes += 24 * positions.len() + 4 * attributes.len();
            }
        }
        out.cpu_ms.push(start.elapsed().as_secs_f64() * 1e3);
        out.bytes.push(bytes);
        let runs = morphs.take_restarted(regions);
        out.gpu_bytes.push(
            runs.iter()
                .flatten()
                .map(|&(lo, hi)| 56 * (hi - lo + 1) as usize)
                .sum(),
        );
        let total: usize = (0..regions.regions().len())
            .map(|r| caches.triangle_count(r))
            .sum();
        out.over_budget = out.over_budget.max(total as f32 / budget as f32);
        // This frame's shown vertices.
        let mut now_shown: HashMap<u32, Vec3> = HashMap::new();
        for r in 0..regions.regions().len() {
            caches.write_global_indices(regions, r, &mut part);
            for &g in &part {
                now_shown
                    .entry(g)
                    .or_insert_with(|| morphs.position(g, now));
            }
        }
        let new_levels: Vec<usize> = (0..regions.regions().len())
            .map(|r| caches.level(r))
            .collect();
        let stand_in =
            |g: u32, levels: &[usize]| morphs.stand_in(g, levels[region_of[g as usize] as usize]);
        out.movement.push(largest_movement(
            (f, frames),
            &clip,
            &shown,
            &now_shown,
            |g| stand_in(g, &levels),
            |g| stand_in(g, &new_levels),
        ));
        shown = now_shown;
        levels = new_levels;
    }
    out
}

/// The largest screen movement of a vertex between the frame that showed `before` and the
/// one that shows `now` (vertex: where): a vertex in both by its two positions, one that
/// appears from where its stand-in at the old level was shown (`old_stand_in`), one that
/// vanishes to where its stand-in at the new level is shown (`new_stand_in`). `0` on the
/// first frame and at the cut (`(frame, frames)`).
fn largest_movement(
    (f, frames): (usize, usize),
    clip: &Mat4,
    before: &HashMap<u32, Vec3>,
    now: &HashMap<u32, Vec3>,
    old_stand_in: impl Fn(u32) -> u32,
    new_stand_in: impl Fn(u32) -> u32,
) -> f32 {
    let moved = |a: Vec3, b: Vec3| match (to_screen(clip, a), to_screen(clip, b)) {
        (Some(a), Some(b)) => a.distance(b),
        _ => 0.0,
    };
    let mut largest = 0.0f32;
    if f == 0 || f == frames / 2 {
        return largest;
    }
    for (&g, &p) in now {
        let was = match before.get(&g) {
            Some(&q) => q,
            None => before.get(&old_stand_in(g)).copied().unwrap_or(p),
        };
        largest = largest.max(moved(was, p));
    }
    for (&g, &q) in before {
        if !now.contains_key(&g) {
            let p = now.get(&new_stand_in(g)).copied().unwrap_or(q);
            largest = largest.max(moved(q, p));
        }
    }
    largest
}

/// The same path for the mesh refined as one view-dependent model: each frame its level is
/// fitted to the budget ([`ToleranceSearch`], frustum and back faces), and
/// `VariableGeomorphs::follow` shows it under the budget. Vertices are counted by position
/// (the first vertex there), as the collapses name them.
fn run_variable(scene: &Scene, vm: &VariableMesh, duration: f32, frames: usize) -> Run {
    let (lo, hi) = scene.mesh.bounds().expect("non-empty");
    let (centre, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let budget = (scene.budget * scene.mesh.triangle_count() as f32) as usize;
    let pm = vm.mesh();
    let position_of = weld_positions(&pm.vertices().positions).remap;
    // Per position: the first collapse that moves it, and onto which.
    let mut parent = vec![(usize::MAX, 0u32); position_of.len()];
    for step in (0..vm.collapse_count()).rev() {
        if let Some([u, w]) = vm.collapse(step) {
            parent[u as usize] = (step, w);
        }
    }
    let stand_in = |mut p: u32, level: &VariableCache| {
        while let Some(&(step, to)) = parent.get(p as usize) {
            if step == usize::MAX || !level.is_performed(step) {
                break;
            }
            p = to;
        }
        p
    };
    let mut target = VariableCache::new(vm);
    target
        .update(vm, &LevelCut(usize::MAX), &any_view())
        .expect("the coarsest level");
    let mut morphs = VariableGeomorphs::new(vm, &target, duration);
    let mut search = ToleranceSearch::default();
    let criteria = Criteria::default()
        .with_frustum(true)
        .with_back_facing(true);
    let mut out = Run::default();
    let (mut shown, mut level) = (HashMap::new(), morphs.shown().clone());
    let (mut positions, mut attributes) = (Vec::new(), Vec::new());
    for f in 0..frames {
        let now = f as f32 * DT;
        let (clip, _, eye) = camera(f, frames, centre, radius);
        let view = View::perspective(
            eye,
            centre - eye,
            Vec3::Y,
            FOV_Y,
            WIDTH / HEIGHT,
            0.01 * radius,
            HEIGHT,
        )
        .expect("a valid camera");
        search
            .fit(&mut target, vm, &criteria, &view, budget, 0.0)
            .expect("a fit");
        let start = Instant::now();
        let total = morphs
            .follow(vm, &target, budget, now)
            .expect("the same mesh");
        let mut bytes = 0;
        if morphs.is_morphing() {
            morphs.write_positions(now, &mut positions);
            morphs.write_attributes(Some(now), &mut attributes);
            bytes += 24 * positions.len() + 4 * attributes.len();
        }
        out.cpu_ms.push(start.elapsed().as_secs_f64() * 1e3);
        out.bytes.push(bytes);
        out.gpu_bytes.push(
            morphs
                .take_restarted()
                .iter()
                .map(|&(lo, hi)| 56 * (hi - lo + 1) as usize)
                .sum(),
        );
        out.over_budget = out.over_budget.max(total as f32 / budget as f32);
        let now_shown: HashMap<u32, Vec3> = morphs
            .shown()
            .indices()
            .iter()
            .map(|&v| (position_of[v as usize], morphs.position(v, now)))
            .collect();
        let new_level = morphs.shown();
        out.movement.push(largest_movement(
            (f, frames),
            &clip,
            &shown,
            &now_shown,
            |p| stand_in(p, &level),
            |p| stand_in(p, new_level),
        ));
        shown = now_shown;
        level.clone_from(new_level);
    }
    out
}

/// A camera for the criteria that ignore it.
fn any_view() -> View {
    View::perspective(Vec3::Z, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 1.0).expect("a valid camera")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--test") || cfg!(debug_assertions);
    let frames = if quick { 24 } else { 240 };
    println!(
        "| scene | T | largest movement, px (any frame) | frames over 1 px | 99th percentile px | shown / budget (max) | morph CPU per frame (median, max) | bytes a CPU write would upload per frame (median, max) | bytes the GPU path writes per frame (median, max) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for scene in scenes(quick) {
        let regions = RegionMesh::build(&scene.mesh, &scene.partition, &BuildOptions::default())
            .expect("builds");
        let obbs: Vec<Obb> = regions.regions().iter().map(Region::obb).collect();
        let options = BuildOptions::default().with_view_dependent(true);
        let pm = ProgressiveMesh::build(&scene.mesh, &options).expect("builds");
        let vm = VariableMesh::new(pm).expect("view data");
        let runs = [false, true]
            .into_iter()
            .flat_map(|fine| [(fine, 0.0), (fine, 0.25), (fine, 1.0)]);
        for (fine, duration) in runs {
            let r = if fine {
                run_variable(&scene, &vm, duration, frames)
            } else {
                run(&scene, &regions, &obbs, duration, frames)
            };
            let name = if fine { " (view-dependent)" } else { "" };
            let mut sorted = r.movement.clone();
            sorted.sort_by(f32::total_cmp);
            let p99 = sorted[(sorted.len() * 99 / 100).min(sorted.len() - 1)];
            let over = r.movement.iter().filter(|&&m| m > 1.0).count();
            let bytes: Vec<f64> = r.bytes.iter().map(|&b| b as f64).collect();
            let gpu: Vec<f64> = r.gpu_bytes.iter().map(|&b| b as f64).collect();
            println!(
                "| {}{name} | {duration} s | {:.1} | {over} of {} | {p99:.2} | {:.3} | {:.3} ms, {:.3} ms | {:.0} B, {:.0} B | {:.0} B, {:.0} B |",
                scene.name,
                sorted.last().copied().unwrap_or(0.0),
                r.movement.len(),
                r.over_budget,
                median(r.cpu_ms.clone()),
                r.cpu_ms.iter().copied().fold(0.0, f64::max),
                median(bytes.clone()),
                bytes.iter().copied().fold(0.0, f64::max),
                median(gpu.clone()),
                gpu.iter().copied().fold(0.0, f64::max),
            );
        }
    }
}
