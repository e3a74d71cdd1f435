//! What an instance costs the CPU each frame, without a renderer: N instances of one
//! 20,480-triangle sphere (as `make bench-instances` places them, one region each, or the
//! asset's 4 clusters), sharing level meshes by default, all in view of a camera high above
//! the field that drifts a little each frame, under a budget of 200 triangles per instance.
//! Prints per frame (medians): the plugin's systems (wall clock across its `Spawn` set and
//! across `Allocate` … `Upload`, nothing else running beside them), Bevy's
//! `VisibilitySystems::CheckVisibility` (the frustum culling of the same entities, timed the
//! same way), both per instance, and the process memory each instance adds (resident bytes
//! after spawning and settling the field, over the bytes before).
//!
//! `instance_cost [--counts 1000,10000,100000] [--frames 30]` (release: `make
//! bench-instance-cost`).

mod common;

use bevy::camera::visibility::VisibilitySystems;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::{RenderCreation, WgpuSettings};
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodSystems, AslodViewport, MultiresMesh, MultiresModel,
    PartitionSpec,
};
use clap::Parser;
use std::time::Instant;

#[derive(Parser)]
struct Args {
    /// Instance counts, one run each.
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
    counts: Vec<usize>,
    /// Frames measured per run (after 5 to settle).
    #[arg(long, default_value_t = 30)]
    frames: usize,
}

/// Wall-clock spans of the last frame, in milliseconds.
#[derive(Resource, Default)]
struct Spans {
    start: Option<Instant>,
    ours: f64,
    /// Of `ours`, the `Spawn` set's span.
    spawn: f64,
    visibility: f64,
}

/// Starts a span.
fn start(mut spans: ResMut<Spans>) {
    spans.start = Some(Instant::now());
}

/// Starts Bevy's visibility span (a system of its own: `start` runs twice before it).
fn start_visibility(spans: ResMut<Spans>) {
    start(spans);
}

/// Ends the `Spawn` set's span, which counts in our systems.
fn end_spawn(mut spans: ResMut<Spans>) {
    let ms = spans.start.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
    spans.spawn = ms;
    spans.ours += ms;
}

/// Adds the span since `start` to our systems.
fn end_ours(mut spans: ResMut<Spans>) {
    let ms = spans.start.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
    spans.ours += ms;
}

/// Ends Bevy's visibility span.
fn end_visibility(mut spans: ResMut<Spans>) {
    spans.visibility = spans.start.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
}

fn app(budget: u32) -> App {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            // No GPU and no render world: the main world's work alone.
            .set(RenderPlugin {
                render_creation: RenderCreation::Automatic(Box::new(WgpuSettings {
                    backends: None,
                    ..default()
                })),
                ..default()
            })
            .disable::<WinitPlugin>(),
    )
    .add_plugins(AslodPlugin::default().with_budget(budget))
    // No render target gives the camera a size: the allocation's viewport.
    .insert_resource(AslodViewport(Vec2::new(1920.0, 1080.0)))
    .init_resource::<Spans>()
    .add_systems(
        PostUpdate,
        (
            start.before(AslodSystems::Spawn),
            end_spawn
                .after(AslodSystems::Spawn)
                .before(TransformSystems::Propagate),
            start
                .after(TransformSystems::Propagate)
                .after(bevy::camera::CameraUpdateSystems)
                .before(AslodSystems::Allocate),
            end_ours
                .after(AslodSystems::Upload)
                .before(VisibilitySystems::VisibilityPropagate),
            start_visibility
                .after(AslodSystems::Upload)
                .after(VisibilitySystems::VisibilityPropagate)
                .before(VisibilitySystems::CheckVisibility),
            end_visibility
                .after(VisibilitySystems::CheckVisibility)
                .before(VisibilitySystems::MarkNewlyHiddenEntitiesInvisible),
        ),
    );
    app
}

/// The process's resident bytes.
fn resident_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

/// One run's medians.
struct Row {
    ours_ms: f64,
    visibility_ms: f64,
    bytes_per_instance: f64,
    triangles: f64,
    /// `AslodStats::allocation_ms` and `update_ms`.
    allocation_ms: f64,
    update_ms: f64,
    /// The `Spawn` set's wall clock.
    spawn_ms: f64,
}

/// One run: `n` instances of the sphere cut as `spec`.
fn run(n: usize, spec: PartitionSpec, frames: usize) -> Result<Row, String> {
    let sphere = Sphere::new(1.0).mesh().ico(31).map_err(|e| e.to_string())?;
    let asset = MultiresMesh::from_bevy_mesh(&sphere, spec).map_err(|e| e.to_string())?;
    let mut app = app((n * 200) as u32);
    let side = (n as f64).sqrt().ceil() as usize;
    let half = side as f32 * 2.0;
    let material = app
        .world_mut()
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::default());
    let asset = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset);
    // High enough that the whole field is in view (vertical field of view π/4).
    let height = half * 16.0 / 9.0 / (std::f32::consts::FRAC_PI_8).tan() * 0.6 + 10.0;
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                aspect_ratio: 16.0 / 9.0,
                far: height * 4.0,
                ..default()
            }),
            Transform::from_xyz(0.0, height, 0.01).looking_at(Vec3::ZERO, Vec3::Y),
        ))
        .id();
    for _ in 0..3 {
        app.update();
    }
    let before = resident_bytes();
    for i in 0..n {
        let at = Vec3::new(
            (i % side) as f32 * 4.0 - half,
            0.0,
            (i / side) as f32 * 4.0 - half,
        );
        app.world_mut().spawn((
            MultiresModel(asset.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
        ));
    }
    for _ in 0..5 {
        app.update();
    }
    let per_instance = resident_bytes().saturating_sub(before) as f64 / n as f64;
    let (mut ours, mut visibility, mut triangles) = (Vec::new(), Vec::new(), Vec::new());
    let (mut allocation, mut update, mut spawn) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..frames {
        // A slow drift: levels move every frame.
        let t = frame as f32 / frames.max(1) as f32;
        let eye = Vec3::new(half * 0.1 * t, height * (1.0 - 0.2 * t), 0.01);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(eye).looking_at(Vec3::new(eye.x, 0.0, 0.0), Vec3::Y);
        app.world_mut().resource_mut::<Spans>().ours = 0.0;
        app.update();
        let spans = app.world().resource::<Spans>();
        ours.push(spans.ours);
        spawn.push(spans.spawn);
        visibility.push(spans.visibility);
        let stats = app.world().resource::<AslodStats>();
        triangles.push(stats.triangles as f64);
        allocation.push(stats.allocation_ms);
        update.push(stats.update_ms);
    }
    Ok(Row {
        ours_ms: median(ours),
        visibility_ms: median(visibility),
        bytes_per_instance: per_instance,
        triangles: median(triangles),
        allocation_ms: median(allocation),
        update_ms: median(update),
        spawn_ms: median(spawn),
    })
}

fn main() -> Result<(), String> {
    let args = Args::parse();
    println!(
        "instance_cost: a 20,480-triangle sphere, all instances in view, no renderer, 200 triangles per instance; {}",
        common::machine()
    );
    println!(
        "| regions | instances | triangles | ours ms | CheckVisibility ms | ours / CheckVisibility | ours µs per instance | CheckVisibility µs per instance | KB per instance | allocation ms | update ms | Spawn set ms |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (name, spec) in [
        ("one", PartitionSpec::Single),
        ("4 clusters", PartitionSpec::Clusters(4)),
    ] {
        for &n in &args.counts {
            let row = run(n, spec, args.frames)?;
            let (ours, visibility) = (row.ours_ms, row.visibility_ms);
            println!(
                "| {name} | {n} | {:.0} | {ours:.2} | {visibility:.2} | {:.2} | {:.3} | {:.3} | {:.1} | {:.2} | {:.2} | {:.2} |",
                row.triangles,
                ours / visibility,
                ours * 1e3 / n as f64,
                visibility * 1e3 / n as f64,
                row.bytes_per_instance / 1024.0,
                row.allocation_ms,
                row.update_ms,
                row.spawn_ms
            );
        }
    }
    Ok(())
}
