//! The plugin's per-frame work without Bevy, on one thread: the same 1,000 models × 16 regions
//! under P = 1,000,000 and the same camera path as `benches/plugin.rs`, run through the core
//! (`budget` and `regions`) directly. Against the plugin bench, it tells the crate's own cost
//! from Bevy's (queries, change detection, assets, the task pool), and it profiles cleanly.
//!
//! `cargo bench --no-default-features --bench frame_core` (`MODELS=N` for another count)

#[path = "common/scene.rs"]
mod scene;

use bevy_aslod::budget::{AllocationParams, Allocator, Obb, ProjectedAreaCamera, RegionInput};
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::regions::{GridPlane, Partition, Region, RegionCaches, RegionMesh};
use glam::{Affine3A, Mat4, Vec2, Vec3};
use std::time::Instant;

const WARMUP: usize = 10;
const FRAMES: usize = 120;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let models: usize = std::env::var("MODELS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000);
    println!(
        "bevy_aslod per-frame core work, one thread, no Bevy: {models} models x 16 regions, P = {}, {FRAMES} frames",
        models * 1_000
    );
    println!(
        "| hysteresis | projected areas ms | allocator ms | move caches + write buffers ms | total ms | buffers written per frame |"
    );
    println!("|---:|---:|---:|---:|---:|---:|");
    for hysteresis in [0, 8] {
        run(models, hysteresis);
    }
}

fn run(models: usize, hysteresis: u32) {
    let mesh = scene::patch(33);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 4, 4).expect("grid");
    let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default()).expect("patch");
    let obbs: Vec<Obb> = regions.regions().iter().map(Region::obb).collect();
    let side = scene::side(models);
    let transforms: Vec<Affine3A> = (0..models)
        .map(|i| Affine3A::from_translation(scene::model_position(i, side)))
        .collect();
    let n = regions.regions().len();
    let mut caches: Vec<RegionCaches> = (0..models).map(|_| RegionCaches::new(&regions)).collect();
    let mut buffers: Vec<Vec<Vec<u16>>> = (0..models).map(|_| vec![Vec::new(); n]).collect();
    let mut allocator = Allocator::new();
    let (mut inputs, mut counts) = (Vec::new(), Vec::new());
    let params = AllocationParams {
        hysteresis,
        ..AllocationParams::with_budget((models * 1_000) as u32)
    };
    let projection =
        Mat4::perspective_infinite_reverse_rh(std::f32::consts::FRAC_PI_4, 16.0 / 9.0, 0.1);
    let (mut areas, mut split, mut update, mut total) = (vec![], vec![], vec![], vec![]);
    let mut written = 0;
    for frame in 0..WARMUP + FRAMES {
        let t = frame as f32 / (WARMUP + FRAMES) as f32;
        let (eye, target) = scene::camera(t, side);
        let world_from_view = Mat4::look_at_rh(eye, target, Vec3::Y).inverse();
        let camera = ProjectedAreaCamera::from_world_from_view(
            world_from_view,
            projection,
            Vec2::new(1920.0, 1080.0),
        )
        .expect("camera");
        let start = Instant::now();
        inputs.clear();
        for (m, transform) in transforms.iter().enumerate() {
            let local = camera.for_model(transform).expect("invertible");
            for (r, region) in regions.regions().iter().enumerate() {
                inputs.push(RegionInput::from_area(
                    local.projected_area(&obbs[r]),
                    1.0,
                    region.min_triangles() as u32,
                    region.max_triangles() as u32,
                    caches[m].triangle_count(r) as u32,
                ));
            }
        }
        let projected = Instant::now();
        allocator
            .allocate(&params, &inputs, &mut counts)
            .expect("valid inputs");
        let allocated = Instant::now();
        let mut count = 0;
        for (m, (caches, buffers)) in caches.iter_mut().zip(&mut buffers).enumerate() {
            for r in 0..n {
                caches.set_triangle_count(&regions, r, counts[m * n + r] as usize);
            }
            for (r, buffer) in buffers.iter_mut().enumerate() {
                if caches.is_dirty(r) {
                    caches.write_indices_u16(&regions, r, buffer);
                    count += 1;
                }
            }
        }
        let done = Instant::now();
        if frame >= WARMUP {
            let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
            areas.push(ms(start, projected));
            split.push(ms(projected, allocated));
            update.push(ms(allocated, done));
            total.push(ms(start, done));
            written += count;
        }
    }
    println!(
        "| {hysteresis} | {:.3} | {:.3} | {:.3} | {:.3} | {} |",
        median(&mut areas),
        median(&mut split),
        median(&mut update),
        median(&mut total),
        written / FRAMES
    );
}
