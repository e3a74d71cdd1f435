//! Issue 6's scaling target: 100 RobotExpressive instances dancing under P = 100,000. Loads
//! the robot with Bevy's glTF loader (no GPU: the renderer has no backend), converts every
//! instance with `MultiresScene`, plays "Dance" out of phase, and prints the plugin's
//! per-frame CPU time in Deform and Upload, first while they dance, then while every
//! animation is paused (bones still: Deform should blend nothing).
//!
//! `cargo bench --bench skinned_crowd`

#[allow(dead_code)]
#[path = "common/clip.rs"]
mod clip;
mod common;

use bevy::app::ScheduleRunnerPlugin;
use bevy::gltf::Gltf;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::{RenderCreation, WgpuSettings};
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{AslodPlugin, AslodStats, AslodViewport, MultiresScene};
use std::time::Duration;

const TESTDATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/characters");
const ROBOT: &str = "RobotExpressive.glb";
const COUNT: usize = 100;
const BUDGET: u32 = 100_000;
const WARMUP: usize = 20;
const FRAMES: usize = 240;

fn main() {
    // `cargo bench` passes `--bench`; under `cargo test` this is a short smoke run.
    let frames = if std::env::args().any(|a| a == "--bench") {
        FRAMES
    } else {
        10
    };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(AssetPlugin {
                file_path: TESTDATA.into(),
                ..default()
            })
            .set(RenderPlugin {
                render_creation: RenderCreation::Automatic(Box::new(WgpuSettings {
                    backends: None,
                    ..default()
                })),
                ..default()
            })
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .set(common::task_pools())
            .disable::<WinitPlugin>(),
        ScheduleRunnerPlugin::run_once(),
    ))
    .add_plugins(AslodPlugin::default().with_budget(BUDGET))
    .insert_resource(AslodViewport(Vec2::new(1920.0, 1080.0)))
    // Time advances 1/60 s per frame whatever the machine does.
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    app.finish();
    app.cleanup();

    let gltf: Handle<Gltf> = app.world().resource::<AssetServer>().load(ROBOT);
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset(ROBOT));
    let roots: Vec<Entity> = (0..COUNT)
        .map(|i| {
            let (x, z) = ((i % 10) as f32 * 5.0 - 22.5, (i / 10) as f32 * 5.0 - 22.5);
            app.world_mut()
                .spawn((
                    WorldAssetRoot(scene.clone()),
                    MultiresScene::default(),
                    Transform::from_xyz(x, 0.0, z),
                ))
                .id()
        })
        .collect();
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 30.0, 60.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));

    // Load, convert, and start the clip on every player, out of phase.
    clip::start_clip(&mut app, &gltf, &roots, Some("Dance"), 0.037)
        .expect("the robots load and convert");

    let mut rows = Vec::new();
    for paused in [false, true] {
        if paused {
            for mut player in app
                .world_mut()
                .query::<&mut AnimationPlayer>()
                .iter_mut(app.world_mut())
                .collect::<Vec<_>>()
            {
                player.pause_all();
            }
        }
        let (mut deform, mut upload, mut total, mut blended, mut triangles) =
            (Vec::new(), Vec::new(), Vec::new(), 0usize, 0u64);
        for frame in 0..WARMUP + frames {
            app.update();
            if frame < WARMUP {
                continue;
            }
            let stats = *app.world().resource::<AslodStats>();
            deform.push(stats.deform_ms);
            upload.push(stats.upload_ms);
            total.push(stats.deform_ms + stats.upload_ms);
            blended += stats.vertices_blended;
            triangles = stats.triangles + u64::from(stats.fixed_cost);
        }
        rows.push((
            paused,
            median(&mut deform),
            median(&mut upload),
            median(&mut total),
            p95(&mut total),
            blended / frames,
            triangles,
        ));
    }
    println!(
        "{COUNT} RobotExpressive instances, P = {BUDGET}, {frames} frames ({} build, {})",
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "optimised"
        },
        common::compute_threads()
    );
    println!(
        "| bones | Deform ms (median) | Upload ms (median) | Deform + Upload ms (median) | p95 | vertices blended / frame | triangles |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (paused, d, u, t, p, b, tris) in rows {
        println!(
            "| {} | {d:.3} | {u:.3} | {t:.3} | {p:.3} | {b} | {tris} |",
            if paused { "still (paused)" } else { "dancing" }
        );
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn p95(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() as f64 * 0.95) as usize).min(v.len() - 1)]
}
