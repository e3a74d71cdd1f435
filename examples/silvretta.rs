//! ASLOD Figure 8: a 261×261 fractal terrain cut into 6×6 regions under a 10,000-triangle budget.
//!
//! Controls: WASD to fly, Q/E down/up, Shift faster, drag with the left mouse button to look;
//! `1` the corner view, `2` the top view, `O` the region-box overlay, `R` shading by region
//! (red: as many triangles as the busiest region, blue: few).
//!
//! `--headless --frames N --screenshot DIR` renders offscreen (a camera with an `Image` render
//! target, no window), waits N frames per shot, and writes `corner.png`, `corner_regions.png`,
//! `top.png`, `top_regions.png` and `counts.json` to `DIR`. `counts.json` also holds the frame
//! time of the corner view at the budget against every region at full detail (135,200
//! triangles), 30 frames each, in the same run.

mod common;

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::tasks::{AsyncComputeTaskPool, Task, TaskPool, futures::check_ready};
use bevy_aslod::plugin::{
    AslodOverlay, AslodPlugin, AslodStats, FullDetail, Geomorph, LodRegion, MultiresError,
    MultiresInstance, MultiresMesh, MultiresModel, PolygonBudget, RegionSplit,
};
use bevy_aslod::regions::{GridPlane, Partition};
use clap::Parser;
use common::stats::median_p95;
use common::terrain::{HEIGHT, SIDE, SPACING, terrain};
use common::{FlyCamera, fly_camera};
use std::path::PathBuf;

/// The paper's budget for this figure.
const BUDGET: u32 = 10_000;
/// Offscreen image size.
const SHOT_SIZE: (u32, u32) = (960, 540);

fn main() {
    let args = Args::parse();
    let mut app = App::new();
    common::add_default_plugins(
        &mut app,
        args.headless,
        "bevy_aslod: Silvretta (ASLOD Figure 8)",
        None,
    );
    let budget = PolygonBudget {
        total: BUDGET,
        split: args.split,
        ..default()
    };
    app.add_plugins(AslodPlugin {
        budget,
        ..default()
    })
    .insert_resource(MorphTime(args.geomorph))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.75, 0.9)))
    .insert_resource(GlobalAmbientLight {
        brightness: 400.0,
        ..default()
    })
    .init_resource::<Shading>()
    .add_systems(Startup, setup)
    .add_systems(Update, (finish_terrain, apply_shading, update_label));
    if args.headless {
        let dir = args
            .screenshot
            .clone()
            .unwrap_or_else(|| PathBuf::from("silvretta-shots"));
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("silvretta: cannot create {}: {e}", dir.display());
            std::process::exit(1);
        }
        app.insert_resource(Shots::new(dir, args.frames))
            .add_systems(Update, drive_shots.before(apply_shading));
    } else {
        app.add_systems(Update, (fly_camera, keys));
    }
    app.run();
}

/// ASLOD Figure 8: a fractal terrain in 6x6 regions under a 10,000-triangle budget.
#[derive(Parser, Debug)]
struct Args {
    /// Render offscreen, no window: the shots and counts.json, then exit.
    #[arg(long)]
    headless: bool,
    /// Frames to wait before each shot.
    #[arg(long, default_value_t = 30)]
    frames: u32,
    /// Where the headless run writes (default: silvretta-shots).
    #[arg(long, value_name = "DIR")]
    screenshot: Option<PathBuf>,
    /// Geomorphs: spread each level change over this many seconds (0: at once).
    #[arg(long, default_value_t = 0.0, value_name = "SECONDS")]
    geomorph: f32,
    /// How the terrain's triangles are shared among its regions: `area`, as in the paper's
    /// figure (`RegionSplit::Area`: the top view spreads them evenly), or `error` (the
    /// plugin's default, `RegionSplit::ScreenError`: rough regions get more).
    #[arg(long, default_value = "area", value_parser = common::parse_split)]
    split: RegionSplit,
}

/// The terrain's [`Geomorph`] time (`--geomorph`).
#[derive(Resource)]
struct MorphTime(f32);

// ---------------------------------------------------------------------------------------------
// Scene.

/// The two preset views of the figure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum View {
    /// From a corner, low over the terrain.
    Corner,
    /// From straight above.
    Top,
}

impl View {
    fn transform(self) -> Transform {
        let half = (SIDE - 1) as f32 * SPACING * 0.5;
        match self {
            View::Corner => Transform::from_xyz(-half + 4.0, 1.2 * HEIGHT, -half + 4.0)
                .looking_at(Vec3::new(-half * 0.35, 0.0, -half * 0.35), Vec3::Y),
            View::Top => {
                Transform::from_xyz(0.0, 2.9 * half, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z)
            }
        }
    }
}

#[derive(Component)]
struct MainCamera;

#[derive(Component)]
struct Label;

/// The terrain's own material and whether regions are shaded by their triangle count.
#[derive(Resource, Default)]
struct Shading {
    by_region: bool,
    terrain: Handle<StandardMaterial>,
    regions: Vec<Handle<StandardMaterial>>,
}

/// The terrain's asset being built on the async compute pool (seconds on two cores; the
/// window opens meanwhile), with its triangle count and when it began.
#[derive(Resource)]
struct TerrainBuild(
    Task<Result<(MultiresMesh, usize), MultiresError>>,
    std::time::Instant,
);

fn setup(
    mut commands: Commands,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    mut shading: ResMut<Shading>,
    shots: Option<Res<Shots>>,
) {
    let task = AsyncComputeTaskPool::get_or_init(TaskPool::default).spawn(async {
        let mesh = terrain();
        let partition = Partition::grid(&mesh, GridPlane::XZ, 6, 6)?;
        let asset = MultiresMesh::from_indexed(&mesh, &partition)?;
        Ok::<_, MultiresError>((asset, mesh.triangle_count()))
    });
    commands.insert_resource(TerrainBuild(task, std::time::Instant::now()));
    shading.terrain = materials.add(StandardMaterial {
        base_color: Color::srgb(0.55, 0.52, 0.45),
        perceptual_roughness: 0.95,
        ..default()
    });
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(-1.0, 0.9, 0.4).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        View::Corner.transform(),
        MainCamera,
        // The label and the overlay's counts are drawn into this camera's image too.
        IsDefaultUiCamera,
        FlyCamera {
            enabled: true,
            speed: 30.0,
        },
    ));
    if let Some(shots) = shots {
        let handle = common::offscreen_image(&mut images, (SHOT_SIZE.0, SHOT_SIZE.1));
        camera.insert(RenderTarget::Image(handle.clone().into()));
        commands.insert_resource(ShotTarget(handle));
        info!(
            "offscreen: {} frames per shot into {}",
            shots.frames,
            shots.dir.display()
        );
    }
    commands.spawn((
        Text::new(""),
        Node {
            position_type: PositionType::Absolute,
            top: px(8),
            left: px(8),
            ..default()
        },
        Label,
    ));
}

/// Spawns the terrain once its asset is built (or exits with the error).
fn finish_terrain(
    mut commands: Commands,
    build: Option<ResMut<TerrainBuild>>,
    mut multires: ResMut<Assets<MultiresMesh>>,
    shading: Res<Shading>,
    morph: Res<MorphTime>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(mut build) = build else {
        return;
    };
    let Some(result) = check_ready(&mut build.0) else {
        return;
    };
    commands.remove_resource::<TerrainBuild>();
    match result {
        Ok((asset, triangles)) => {
            info!(
                "terrain: {triangles} triangles in {} regions ({}..{} triangles), built in {:.1} s",
                asset.region_count(),
                asset.min_triangles(),
                asset.max_triangles(),
                build.1.elapsed().as_secs_f32()
            );
            commands.spawn((
                MultiresModel(multires.add(asset)),
                MeshMaterial3d(shading.terrain.clone()),
                Transform::default(),
                Geomorph(morph.0),
            ));
        }
        Err(e) => {
            error!("cannot build the terrain: {e}");
            exit.write(AppExit::error());
        }
    }
}

/// Heat colour per region (red: the most triangles, blue: the fewest), or the terrain's own.
fn apply_shading(
    mut shading: ResMut<Shading>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    models: Query<&MultiresInstance>,
    mut regions: Query<(&LodRegion, &mut MeshMaterial3d<StandardMaterial>)>,
) {
    let Ok(instance) = models.single() else {
        return;
    };
    let shading = &mut *shading;
    let caches = instance.caches();
    let n = caches.region_count();
    if shading.by_region {
        while shading.regions.len() < n {
            shading.regions.push(materials.add(StandardMaterial {
                perceptual_roughness: 0.95,
                ..default()
            }));
        }
        let counts: Vec<usize> = (0..n).map(|r| caches.triangle_count(r)).collect();
        // Relative to the busiest region: the colours show where the budget went.
        let hi = counts.iter().copied().max().unwrap_or(1).max(1) as f32;
        for (r, &count) in counts.iter().enumerate() {
            let t = count as f32 / hi;
            // Alternate the lightness like a chequerboard so neighbours stay apart.
            let light = if (r / 6 + r % 6) % 2 == 0 { 1.0 } else { 0.8 };
            let color = Color::srgb(
                (0.15 + 0.85 * t) * light,
                0.25 * light,
                (1.0 - 0.85 * t) * light,
            );
            if let Some(mut m) = materials.get_mut(&shading.regions[r])
                && m.base_color != color
            {
                m.base_color = color;
            }
        }
    }
    for (region, mut material) in &mut regions {
        let want = if shading.by_region {
            shading
                .regions
                .get(region.region)
                .cloned()
                .unwrap_or_default()
        } else {
            shading.terrain.clone()
        };
        if material.0 != want {
            material.0 = want;
        }
    }
}

fn update_label(stats: Res<AslodStats>, mut label: Query<&mut Text, With<Label>>) {
    for mut text in &mut label {
        let s = format!(
            "{} / {} triangles  ({} regions, {} changed, alloc {:.2} ms)\n1: corner  2: top  O: boxes  R: by region",
            stats.triangles,
            stats.budget,
            stats.regions,
            stats.regions_changed,
            stats.allocation_ms
        );
        if text.0 != s {
            text.0 = s;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Interactive controls.

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut camera: Query<&mut Transform, With<MainCamera>>,
    mut overlay: ResMut<AslodOverlay>,
    mut shading: ResMut<Shading>,
) {
    if input.just_pressed(KeyCode::KeyO) {
        overlay.0 = !overlay.0;
    }
    if input.just_pressed(KeyCode::KeyR) {
        shading.by_region = !shading.by_region;
    }
    let view = if input.just_pressed(KeyCode::Digit1) {
        Some(View::Corner)
    } else if input.just_pressed(KeyCode::Digit2) {
        Some(View::Top)
    } else {
        None
    };
    if let (Some(view), Ok(mut transform)) = (view, camera.single_mut()) {
        *transform = view.transform();
    }
}

// ---------------------------------------------------------------------------------------------
// Headless screenshots.

#[derive(Resource)]
struct ShotTarget(Handle<Image>);

/// The headless run: which shot is next, and what was recorded.
#[derive(Resource)]
struct Shots {
    dir: PathBuf,
    frames: u32,
    list: Vec<(&'static str, View, bool)>,
    index: usize,
    wait: u32,
    pending: bool,
    attempts: u32,
    views: serde_json::Map<String, serde_json::Value>,
    /// After the shots: frame periods (ms) at the budget, then at full detail.
    timing: Option<Timing>,
    done: bool,
}

/// The frame-time comparison of the corner view: [`TIMING_FRAMES`] frames under the budget,
/// then as many with every region at full detail ([`FullDetail`]), after a few to settle.
#[derive(Debug, Default)]
struct Timing {
    last: Option<std::time::Instant>,
    settle: u32,
    lod: Vec<f64>,
    full: Vec<f64>,
    triangles: [u64; 2],
}

/// Frames timed in each half of the comparison.
const TIMING_FRAMES: usize = 30;
/// Frames before each half is timed.
const TIMING_SETTLE: u32 = 5;

impl Shots {
    fn new(dir: PathBuf, frames: u32) -> Self {
        Self {
            dir,
            frames: frames.max(2),
            list: vec![
                ("corner", View::Corner, false),
                ("corner_regions", View::Corner, true),
                ("top", View::Top, false),
                ("top_regions", View::Top, true),
            ],
            index: 0,
            wait: frames.max(2),
            pending: false,
            attempts: 0,
            views: serde_json::Map::new(),
            timing: None,
            done: false,
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn drive_shots(
    mut commands: Commands,
    mut shots: ResMut<Shots>,
    mut shading: ResMut<Shading>,
    mut overlay: ResMut<AslodOverlay>,
    target: Option<Res<ShotTarget>>,
    mut camera: Query<&mut Transform, With<MainCamera>>,
    models: Query<&MultiresInstance>,
    mut full_detail: ResMut<FullDetail>,
    stats: Res<AslodStats>,
    mut exit: MessageWriter<AppExit>,
) {
    if shots.done {
        exit.write(AppExit::Success);
        return;
    }
    if shots.timing.is_some() {
        if let Ok(mut transform) = camera.single_mut() {
            transform.set_if_neq(View::Corner.transform());
        }
        shading.by_region = false;
        overlay.0 = false;
        if time_frames(&mut shots, &mut full_detail, &stats) {
            write_counts(&mut shots);
        }
        return;
    }
    let Some(&(name, view, by_region)) = shots.list.get(shots.index) else {
        return;
    };
    if let Ok(mut transform) = camera.single_mut() {
        let want = view.transform();
        if *transform != want {
            *transform = want;
        }
    }
    shading.by_region = by_region;
    overlay.0 = by_region;
    if shots.pending {
        return;
    }
    // The terrain is still building: the wait starts once it is there.
    let (Some(target), Ok(instance)) = (target, models.single()) else {
        return;
    };
    if shots.wait > 0 {
        shots.wait -= 1;
        return;
    }
    // Record the counts the frame is drawn with.
    if !by_region {
        let caches = instance.caches();
        let counts: Vec<usize> = (0..caches.region_count())
            .map(|r| caches.triangle_count(r))
            .collect();
        let eye = view.transform().translation;
        let distance = |r: usize| {
            let (lo, hi) = instance.regions().regions()[r].bounds();
            eye.distance((lo + hi) * 0.5)
        };
        let order = {
            let mut order: Vec<usize> = (0..counts.len()).collect();
            order.sort_by(|&a, &b| distance(a).total_cmp(&distance(b)));
            order
        };
        let total: usize = counts.iter().sum();
        info!("{name}: {total} triangles, per region {counts:?}");
        shots.views.insert(
            name.to_string(),
            serde_json::json!({
                "total": total,
                "regions": counts,
                "nearest_region": order.first(),
                "farthest_region": order.last(),
                "camera": eye.to_array(),
            }),
        );
    }
    shots.pending = true;
    commands
        .spawn(Screenshot::image(target.0.clone()))
        .observe(on_captured);
}

/// Saves a captured frame, or asks for another when nothing has been drawn yet.
fn on_captured(captured: On<ScreenshotCaptured>, mut shots: ResMut<Shots>) {
    let Some(&(name, _, _)) = shots.list.get(shots.index) else {
        return;
    };
    let varied = common::is_drawn(&captured);
    if !varied && shots.attempts < 40 {
        // The pipelines are still compiling (slow on a software rasteriser): try again.
        shots.attempts += 1;
        shots.wait = shots.frames / 2;
        shots.pending = false;
        return;
    }
    if !varied {
        warn!("{name}: the frame still looks blank; saving it anyway");
    }
    common::save_capture(&captured, &shots.dir.join(format!("{name}.png")));
    shots.attempts = 0;
    shots.index += 1;
    shots.wait = shots.frames;
    shots.pending = false;
    if shots.index == shots.list.len() {
        shots.timing = Some(Timing {
            settle: TIMING_SETTLE,
            ..default()
        });
    }
}

/// Times one frame of the comparison; `true` once both halves are done.
fn time_frames(shots: &mut Shots, full_detail: &mut FullDetail, stats: &AslodStats) -> bool {
    let Some(timing) = &mut shots.timing else {
        return false;
    };
    let now = std::time::Instant::now();
    let period = timing.last.map(|t| (now - t).as_secs_f64() * 1e3);
    timing.last = Some(now);
    if timing.settle > 0 {
        timing.settle -= 1;
        return false;
    }
    let Some(period) = period else {
        return false;
    };
    let half = usize::from(full_detail.0);
    timing.triangles[half] = stats.triangles;
    let list = if full_detail.0 {
        &mut timing.full
    } else {
        &mut timing.lod
    };
    list.push(period);
    if list.len() < TIMING_FRAMES {
        return false;
    }
    if !full_detail.0 {
        full_detail.0 = true;
        timing.settle = TIMING_SETTLE;
        return false;
    }
    full_detail.0 = false;
    true
}

/// Writes `counts.json`: per-view counts and the frame-time comparison.
fn write_counts(shots: &mut Shots) {
    let timing = shots.timing.take().unwrap_or_default();
    let frame_time = serde_json::json!({
        "view": "corner",
        "frames": TIMING_FRAMES,
        "budget": { "triangles": timing.triangles[0], "frame": median_p95(&timing.lod) },
        "full_detail": { "triangles": timing.triangles[1], "frame": median_p95(&timing.full) },
    });
    info!("frame time: {frame_time}");
    let max_total = shots
        .views
        .values()
        .filter_map(|v| v["total"].as_u64())
        .max()
        .unwrap_or(0);
    let json = serde_json::json!({
        "budget": BUDGET,
        "source_triangles": (SIDE - 1) * (SIDE - 1) * 2,
        "regions": 36,
        "total": max_total,
        "views": shots.views,
        "frame_time": frame_time,
    });
    let path = shots.dir.join("counts.json");
    match serde_json::to_string_pretty(&json) {
        Ok(text) => match std::fs::write(&path, text) {
            Ok(()) => info!("saved {}", path.display()),
            Err(e) => error!("cannot write {}: {e}", path.display()),
        },
        Err(e) => error!("cannot encode counts: {e}"),
    }
    shots.done = true;
}
