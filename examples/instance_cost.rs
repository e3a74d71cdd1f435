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
//!
//! `--dancers 20,200`: a crowd instead, the mannequin's glTF scene (`assets/mannequin.glb`,
//! skinned, each copy its own skeleton) spawned that many times and dancing, three ways:
//! plain Bevy, `MultiresScene` (its instances share level meshes that Bevy skins), and
//! `MultiresScene` skinned on the CPU (`NoSharedLevels`). Prints the process memory each
//! dancer past the first count adds, and per frame our systems and `CheckVisibility`.

#[path = "../benches/common/clip.rs"]
mod clip;
mod common;

use bevy::camera::visibility::VisibilitySystems;
use bevy::gltf::Gltf;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::{RenderCreation, WgpuSettings};
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodSystems, AslodViewport, MultiresMesh, MultiresModel,
    MultiresScene, PartitionSpec,
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
    /// A crowd of dancing mannequins instead: the smaller count, then the larger.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    dancers: Vec<usize>,
    /// One crowd run (WAY: plain, gpu or cpu; N dancers), as `--dancers` starts them.
    #[arg(long, num_args = 2, value_names = ["WAY", "N"])]
    crowd_run: Vec<String>,
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

/// How the crowd is drawn.
#[derive(Clone, Copy, PartialEq)]
enum Crowd {
    Plain,
    Gpu,
    Cpu,
}

/// Spawns `n` mannequins drawn `way`, in rows 2 units apart, and runs the app until every
/// one is converted and dancing.
fn spawn_dancers(app: &mut App, way: Crowd, n: usize) -> Result<(), String> {
    let server = app.world().resource::<AssetServer>().clone();
    let gltf: Handle<Gltf> = server.load("mannequin.glb");
    let scene = server.load(GltfAssetLabel::Scene(0).from_asset("mannequin.glb"));
    // Loaded with everything it needs first: a dependency that lands later respawns a scene.
    for _ in 0..20_000 {
        if server.is_loaded_with_dependencies(&gltf) {
            break;
        }
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let roots: Vec<Entity> = (0..n)
        .map(|i| {
            let at = Vec3::new((i % 40) as f32 * 2.0 - 40.0, 0.0, (i / 40) as f32 * -2.0);
            let mut root = app.world_mut().spawn((
                WorldAssetRoot(scene.clone()),
                Transform::from_translation(at),
            ));
            if way != Crowd::Plain {
                root.insert(MultiresScene::default());
            }
            root.id()
        })
        .collect();
    if way == Crowd::Plain {
        // Plain scenes: wait for every copy's player.
        clip::wait_for_players(app, n)?;
        return clip::start_clip(app, &gltf, &[], None, 0.7);
    }
    clip::start_clip(app, &gltf, &roots, None, 0.7)?;
    if way == Crowd::Cpu {
        clip::skin_on_cpu(app, &roots);
    }
    Ok(())
}

/// One crowd run, in a process of its own (`--crowd-run WAY N`): the process's resident
/// bytes before and after `n` dancers are spawned drawn `way` and dancing, then the
/// per-frame medians. Prints one line: `crowd KB_ADDED OURS_MS VISIBILITY_MS MESHES MODELS`.
fn crowd_run(way: Crowd, n: usize, frames: usize) -> Result<(), String> {
    let mut app = app((n * 1_000) as u32);
    // `App::run` would do this; the glTF loader registers here.
    app.finish();
    app.cleanup();
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Transform::from_xyz(0.0, 3.0, 12.0).looking_at(Vec3::new(0.0, 1.0, -20.0), Vec3::Y),
        ))
        .id();
    let before = resident_bytes();
    spawn_dancers(&mut app, way, n)?;
    for _ in 0..10 {
        app.update();
    }
    let added = resident_bytes().saturating_sub(before);
    let (mut ours, mut visibility) = (Vec::new(), Vec::new());
    let (mut upload, mut changed, mut made) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..frames {
        // The camera walks into the crowd: levels move every frame.
        let at = Vec3::new(0.0, 3.0, 12.0 - 20.0 * frame as f32 / frames as f32);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(at).looking_at(at + Vec3::new(0.0, -0.1, -1.0), Vec3::Y);
        app.world_mut().resource_mut::<Spans>().ours = 0.0;
        app.update();
        let spans = app.world().resource::<Spans>();
        ours.push(spans.ours);
        visibility.push(spans.visibility);
        let stats = app.world().resource::<AslodStats>();
        upload.push(stats.upload_ms);
        changed.push(stats.regions_changed as f64);
        made.push(stats.upload_bytes as f64);
    }
    eprintln!(
        "upload {:.3} ms, regions changed {}, bytes made {}",
        median(upload),
        median(changed),
        median(made)
    );
    let meshes = app.world().resource::<Assets<Mesh>>().len();
    let models = app
        .world_mut()
        .query::<&MultiresModel>()
        .iter(app.world())
        .count();
    println!(
        "crowd {:.1} {:.3} {:.3} {meshes} {models}",
        added as f64 / 1024.0,
        median(ours),
        median(visibility)
    );
    Ok(())
}

/// The crowd: per way, a process for `counts[0]` dancers and one for `counts[1]`; the
/// memory each dancer past the first count adds, and the per-frame medians at the second.
fn run_crowd(counts: &[usize], frames: usize) -> Result<(), String> {
    let (&small, &large) = match counts {
        [small, large] if small < large => (small, large),
        _ => return Err("--dancers takes two counts, the smaller first".into()),
    };
    println!(
        "instance_cost --dancers: assets/mannequin.glb (30,180 triangles, skinned), dancing, no renderer, 1,000 triangles per dancer; {}",
        common::machine()
    );
    println!(
        "| way | KB per extra dancer ({small} -> {large}) | ours ms at {large} | CheckVisibility ms at {large} | ours µs per dancer | Mesh assets | models |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let run = |way: &str, n: usize| -> Result<Vec<f64>, String> {
        let output = std::process::Command::new(&exe)
            .args([
                "--crowd-run",
                way,
                &n.to_string(),
                "--frames",
                &frames.to_string(),
            ])
            .output()
            .map_err(|e| e.to_string())?;
        let text = String::from_utf8_lossy(&output.stdout);
        let line = text
            .lines()
            .find_map(|l| l.strip_prefix("crowd "))
            .ok_or_else(|| format!("{way} {n}: {}", String::from_utf8_lossy(&output.stderr)))?;
        Ok(line.split(' ').filter_map(|v| v.parse().ok()).collect())
    };
    for (name, way) in [
        ("plain Bevy", "plain"),
        ("MultiresScene, skinned by Bevy (default)", "gpu"),
        ("MultiresScene, skinned on the CPU", "cpu"),
    ] {
        let (a, b) = (run(way, small)?, run(way, large)?);
        println!(
            "| {name} | {:.0} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} |",
            (b[0] - a[0]) / (large - small) as f64,
            b[1],
            b[2],
            b[1] * 1e3 / large as f64,
            b[3],
            b[4]
        );
    }
    Ok(())
}

fn main() -> Result<(), String> {
    let args = Args::parse();
    if let [way, n] = args.crowd_run.as_slice() {
        let way = match way.as_str() {
            "plain" => Crowd::Plain,
            "gpu" => Crowd::Gpu,
            "cpu" => Crowd::Cpu,
            other => return Err(format!("no crowd way {other}")),
        };
        return crowd_run(way, n.parse().map_err(|_| "a count")?, args.frames);
    }
    if !args.dancers.is_empty() {
        return run_crowd(&args.dancers, args.frames);
    }
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
