//! The plugin's per-frame CPU cost without rendering: 1,000 models × 16 regions under
//! P = 1,000,000, the camera moving. Prints a table of Allocate and SelectLod + Upload times:
//! with hysteresis ε = 0 and 8, and with `Geomorph(0.25)` on every model (ε = 0): written
//! from the CPU (every moving region's vertices, each frame), and as for `GeomorphMaterial`
//! (`GpuGeomorph`: the vertices a morph starts on, once; the GPU's work is not in the table).
//! A last run picks `RegionSplit::Area` or `ScreenError` at random per frame and prints
//! Allocate's median for each.
//!
//! `cargo bench --bench plugin`

mod common;
#[path = "common/models.rs"]
mod models;
#[path = "common/scene.rs"]
mod scene;

use bevy::prelude::*;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodViewport, Geomorph, GpuGeomorph, MultiresMesh, MultiresModel,
    PolygonBudget, RegionSplit,
};
use bevy_aslod::regions::{GridPlane, Partition};
use std::time::Instant;

const MODELS: usize = 1_000;
const BUDGET: u32 = 1_000_000;
const WARMUP: usize = 10;
const FRAMES: usize = 120;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    // ε = 0 follows every target; ε = 8 lets regions keep their level through small changes.
    for (hysteresis, morph) in [
        (0, None),
        (8, None),
        (0, Some((0.25, false))),
        (0, Some((0.25, true))),
    ] {
        run(hysteresis, morph, false);
        println!();
    }
    run(0, None, true);
}

/// One run: build the scene, fly the camera, print the table. `morph`: geomorph seconds,
/// and whether on the GPU path. `splits`: each frame takes `RegionSplit::Area` or
/// `ScreenError` at random, and Allocate's median is printed for each (what sharing by
/// error costs, in the same run).
fn run(hysteresis: u32, morph: Option<(f32, bool)>, splits: bool) {
    let mesh = scene::patch(33);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 4, 4).expect("grid");
    let asset = MultiresMesh::from_indexed(&mesh, &partition).expect("valid patch");
    let regions = asset.region_count();

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins.set(common::task_pools()),
        AssetPlugin::default(),
        TransformPlugin,
    ))
    .init_asset::<Mesh>()
    .init_asset::<StandardMaterial>()
    .add_plugins(
        AslodPlugin::default()
            .with_budget(BUDGET)
            .with_hysteresis(hysteresis),
    )
    .insert_resource(AslodViewport(Vec2::new(1920.0, 1080.0)));
    let side = scene::side(MODELS);
    models::spawn_models(
        &mut app,
        asset,
        (0..MODELS).map(|i| scene::model_position(i, side)),
    );
    if let Some((seconds, gpu)) = morph {
        let models: Vec<Entity> = app
            .world_mut()
            .query_filtered::<Entity, With<MultiresModel>>()
            .iter(app.world())
            .collect();
        for model in models {
            let mut model = app.world_mut().entity_mut(model);
            model.insert(Geomorph(seconds));
            if gpu {
                model.insert(GpuGeomorph);
            }
        }
    }
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                aspect_ratio: 16.0 / 9.0,
                ..default()
            }),
            Transform::default(),
        ))
        .id();

    let mut allocate = Vec::new();
    let mut select = Vec::new();
    let mut upload = Vec::new();
    let mut update = Vec::new();
    let mut frame_total = Vec::new();
    let mut frame_wall = Vec::new();
    let mut changed = 0usize;
    let mut max_triangles = 0u64;
    let (mut rng, mut by_split) = (0x9e37_79b9_7f4a_7c15u64, [Vec::new(), Vec::new()]);
    for frame in 0..WARMUP + FRAMES {
        let t = frame as f32 / (WARMUP + FRAMES) as f32;
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let split = usize::from(splits && rng & 1 == 1);
        app.world_mut().resource_mut::<PolygonBudget>().split =
            [RegionSplit::ScreenError, RegionSplit::Area][split];
        let (eye, target) = scene::camera(t, side);
        *app.world_mut()
            .get_mut::<Transform>(camera)
            .expect("camera") = Transform::from_translation(eye).looking_at(target, Vec3::Y);
        let start = Instant::now();
        app.update();
        let wall = start.elapsed().as_secs_f64() * 1e3;
        let stats = *app.world().resource::<AslodStats>();
        assert!(
            stats.triangles <= u64::from(BUDGET),
            "over budget: {stats:?}"
        );
        if frame >= WARMUP {
            by_split[split].push(stats.allocation_ms);
            allocate.push(stats.allocation_ms);
            select.push(stats.update_ms - stats.upload_ms);
            upload.push(stats.upload_ms);
            update.push(stats.update_ms);
            frame_total.push(stats.allocation_ms + stats.update_ms);
            changed += stats.regions_changed;
            max_triangles = max_triangles.max(stats.triangles);
            frame_wall.push(wall);
        }
    }
    for v in [
        &mut allocate,
        &mut select,
        &mut upload,
        &mut update,
        &mut frame_total,
        &mut frame_wall,
    ] {
        v.sort_by(f64::total_cmp);
    }
    println!(
        "bevy_aslod plugin: {MODELS} models x {regions} regions = {} region instances, P = {BUDGET}, hysteresis {hysteresis}, geomorphs {}, {FRAMES} frames, {}{}",
        MODELS * regions,
        morph.map_or("off".to_string(), |(s, gpu)| format!(
            "{s} s ({})",
            if gpu { "GPU path" } else { "CPU writes" }
        )),
        common::compute_threads(),
        if splits {
            ", region split picked at random per frame"
        } else {
            ""
        }
    );
    println!("| step | median ms | p90 ms | max ms |");
    println!("|---|---:|---:|---:|");
    for (name, v) in [
        ("Allocate", &allocate),
        ("SelectLod", &select),
        ("Upload", &upload),
        ("SelectLod + Upload", &update),
        ("Allocate + SelectLod + Upload", &frame_total),
        ("whole app.update() (MinimalPlugins)", &frame_wall),
    ] {
        println!(
            "| {name} | {:.3} | {:.3} | {:.3} |",
            percentile(v, 0.5),
            percentile(v, 0.9),
            v[v.len() - 1]
        );
    }
    println!(
        "regions changed per frame (mean): {:.0}; most triangles in a frame: {max_triangles} (full detail: {})",
        changed as f64 / FRAMES as f64,
        MODELS * 2 * 32 * 32
    );
    if splits {
        for (name, v) in ["ScreenError", "Area"].iter().zip(&mut by_split) {
            v.sort_by(f64::total_cmp);
            println!(
                "Allocate with RegionSplit::{name}: median {:.3} ms over {} frames",
                percentile(v, 0.5),
                v.len()
            );
        }
    }
    let median = percentile(&frame_total, 0.5);
    println!(
        "target <= 2 ms per frame: {}",
        if median <= 2.0 { "met" } else { "NOT met" }
    );
}
