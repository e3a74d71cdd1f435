//! ASLOD section 7 (Figures 9–11): the "aerobic class". Three mannequins dance out of phase
//! under one budget of 5,000 triangles; the budget moves between them as the camera flies
//! around and between the dancers, and the frame's triangle count stays constant.
//!
//! Controls: `C` switches between the scripted camera and a free one (WASD to fly, Q/E
//! down/up, Shift faster, drag with the left mouse button to look); Up/Down change the budget
//! P, Left/Right change α; `L` compares against the same scene without LOD (every region at
//! full detail); `O` the overlay of region boxes and triangle counts (Figure 10); Space
//! pauses the dance.
//!
//! Options:
//! - `--model PATH --clip NAME`: another glTF character and clip (default: the project's
//!   `assets/mannequin.glb` and its first clip, "Aerobics").
//! - `--count N`: N dancers (a crowd), at the same budget unless `--budget P` says otherwise.
//! - `--target-ms T`: a budget in milliseconds: the plugin sets P each frame, between 500 and
//!   `--budget`, so that frames take about T ms (`PolygonBudget::target_ms`); `frames.csv`
//!   has each frame's P.
//! - `--headless --frames N --report DIR`: renders offscreen (an `Image` render target, no
//!   window), plays the N scripted frames with LOD and without, and writes `frames.csv`,
//!   `frame_time.png` (Figure 11), `allocation.png`, three screenshots at the first, middle
//!   and last frame (Figure 9; the middle one with the overlay) and `summary.json` to DIR.
//!   `--size WIDTHxHEIGHT` sets the offscreen image (default 960x540).
//! - `--repeat R`: plays the scripted frames R times with LOD and R times without,
//!   interleaved (LOD, no LOD, LOD, ...) so a slow phase of the machine hits both series.
//!   `frames.csv` keeps every run; the chart and the summary use each frame's median over
//!   the runs.
//! - `--gpu-skinning`: the dancers share level meshes that Bevy skins on the GPU (the plugin's
//!   default for instances of one asset) instead of the paper's CPU blend on meshes of their
//!   own. The class keeps the paper's path by default: its figures count triangles, and a
//!   shared ladder shows up to a third fewer than allocated.
//! - `--sizes WxH,WxH,...`: one report per size, each in its own folder `DIR/WxH` (the
//!   example runs itself once per size), and `DIR/summary.json` holding every size's summary.
//!
//! Every frame of the scripted run is a function of its number: the camera's place and each
//! dancer's animation time are set from it, so every run shows the same frames.

mod common;

use bevy::camera::RenderTarget;
use bevy::camera::primitives::{Aabb, Frustum};
use bevy::gltf::Gltf;
use bevy::math::{Affine3A, Vec3A};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::budget::Obb;
use bevy_aslod::plugin::{
    AslodOverlay, AslodPlugin, AslodStats, CountInBudget, FullDetail, MultiresInstance,
    MultiresModelReady, MultiresScene, MultiresSceneModels, NoSharedLevels, PolygonBudget,
};
use clap::Parser;
use common::stats::{CpuTimes, per_frame_medians, series_stats};
use common::{FlyCamera, fly_camera};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The paper's budget for the aerobic class.
const BUDGET: u32 = 5_000;
/// Every dancer is scaled to this height (metres), whatever the model's units.
const DANCER_HEIGHT: f32 = 1.8;
/// Metres between neighbouring dancers.
const SPACING: f32 = 2.0;
/// Frames run before each measured pass, so uploads after a budget switch settle.
const SETTLE_FRAMES: u32 = 12;
/// Seconds of dance per scripted frame (120 frames: the mannequin's whole 6 s routine).
const DANCE_SECONDS_PER_FRAME: f32 = 0.05;
/// How long the headless run waits for the model, its clip and its players before it gives up.
const MAX_LOADING: Duration = Duration::from_secs(180);
/// Seconds the interactive scripted camera takes along its path and back.
const SCRIPT_SECONDS: f32 = 12.0;

fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    let args = Args::parse();
    if !args.sizes.is_empty() {
        std::process::exit(match report_per_size(&args, &raw) {
            Ok(()) => 0,
            Err(e) => {
                eprintln!("aerobic_class: {e}");
                1
            }
        });
    }
    let (asset_root, file) = match common::split_model_path(&args.model) {
        Ok(split) => split,
        Err(e) => {
            eprintln!("aerobic_class: {e}");
            std::process::exit(2);
        }
    };
    let mut app = App::new();
    common::add_default_plugins(
        &mut app,
        args.headless,
        "bevy_aslod: the aerobic class (ASLOD Figures 9-11)",
        Some(&asset_root),
    );
    app.add_plugins(AslodPlugin::default())
        .insert_resource(ClearColor(Color::srgb(0.80, 0.84, 0.90)))
        .insert_resource(GlobalAmbientLight {
            brightness: 500.0,
            ..default()
        })
        .insert_resource(match args.target_ms {
            Some(ms) => PolygonBudget::target_ms(ms, 500.min(args.budget)..=args.budget),
            None => PolygonBudget {
                total: args.budget,
                ..default()
            },
        })
        .insert_resource(Class::new(&args, &asset_root, file))
        .add_systems(Startup, setup)
        .add_systems(Update, (bind_clip, bind_players, place_dancers).chain());
    if !args.gpu_skinning {
        app.add_systems(Update, skin_on_cpu.before(place_dancers));
    }
    if args.headless {
        let dir = args
            .report
            .clone()
            .unwrap_or_else(|| PathBuf::from("aerobic-report"));
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("aerobic_class: cannot create {}: {e}", dir.display());
            std::process::exit(1);
        }
        app.insert_resource(Report::new(dir, args.frames, args.repeat, args.size))
            .add_systems(Update, update_label.after(place_dancers))
            .add_systems(Last, drive_report);
    } else {
        app.insert_resource(Interactive::default()).add_systems(
            Update,
            (keys, script_camera, fly_camera, update_label).after(place_dancers),
        );
    }
    app.run();
}

/// ASLOD section 7: three dancing mannequins under one budget of 5,000 triangles.
#[derive(Parser, Debug)]
struct Args {
    /// Render offscreen, no window: play the scripted frames and write the report, then exit.
    #[arg(long)]
    headless: bool,
    /// Scripted frames per run (at least 2).
    #[arg(long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(2..))]
    frames: u32,
    /// Where the headless run writes its report (default: aerobic-report).
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// The glTF character.
    #[arg(long, value_name = "PATH", default_value_os_t = default_model())]
    model: PathBuf,
    /// The clip to dance (default: the first).
    #[arg(long, value_name = "NAME")]
    clip: Option<String>,
    /// Dancers: 3 is the class, more a crowd.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    count: u64,
    /// The polygon budget P (with `--target-ms`, the largest P allowed).
    #[arg(long, default_value_t = BUDGET, value_parser = clap::value_parser!(u32).range(1..))]
    budget: u32,
    /// Aim at frames of this many milliseconds, P between 500 and `--budget`.
    #[arg(long, value_name = "MS")]
    target_ms: Option<f32>,
    /// The offscreen image (WIDTHxHEIGHT).
    #[arg(long, value_name = "WxH", default_value = "960x540", value_parser = common::parse_size)]
    size: (u32, u32),
    /// Runs with LOD and without, interleaved.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    repeat: u32,
    /// One report per size, each by a run of its own, into DIR/WxH.
    #[arg(long, value_name = "WxH,...", value_delimiter = ',', value_parser = common::parse_size, requires = "headless")]
    sizes: Vec<(u32, u32)>,
    /// Share level meshes that Bevy skins on the GPU instead of the paper's CPU blend on
    /// meshes of each dancer's own (`NoSharedLevels`, the class's default).
    #[arg(long)]
    gpu_skinning: bool,
}

fn default_model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/mannequin.glb")
}

/// `--sizes`: runs this example once per size, with the other arguments as given, each into
/// `DIR/WxH`, then gathers their summaries into `DIR/summary.json`. Bevy's renderer is set
/// up once per process, so each size gets a process of its own.
fn report_per_size(args: &Args, raw: &[String]) -> Result<(), String> {
    let dir = args
        .report
        .clone()
        .unwrap_or_else(|| PathBuf::from("aerobic-report"));
    // Every argument but the size and report ones, which each run sets itself.
    let mut rest = Vec::new();
    let mut it = raw.iter();
    while let Some(arg) = it.next() {
        if matches!(arg.as_str(), "--sizes" | "--size" | "--report") {
            it.next();
        } else {
            rest.push(arg.clone());
        }
    }
    let exe = std::env::current_exe().map_err(|e| format!("cannot find this program: {e}"))?;
    let mut summaries = serde_json::Map::new();
    for &(w, h) in &args.sizes {
        let name = format!("{w}x{h}");
        let sub = dir.join(&name);
        eprintln!("aerobic_class: {name} into {}", sub.display());
        let status = std::process::Command::new(&exe)
            .args(&rest)
            .args(["--size", &name, "--report"])
            .arg(&sub)
            .status()
            .map_err(|e| format!("cannot run {}: {e}", exe.display()))?;
        if !status.success() {
            return Err(format!("the {name} run failed: {status}"));
        }
        let path = sub.join("summary.json");
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let summary =
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        summaries.insert(name, summary);
    }
    let path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(&serde_json::json!({ "sizes": summaries }))
        .map_err(|e| e.to_string())?;
    std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    eprintln!("aerobic_class: every size's summary in {}", path.display());
    println!(
        "{:>10} {:>9} {:>9} {:>6} {:>7} {:>7} {:>9} {:>9} {:>7} {:>7} {:>6}",
        "size",
        "LOD ms",
        "full ms",
        "ratio",
        "CV LOD",
        "CV full",
        "noise LOD",
        "noise full",
        "r LOD",
        "r full",
        "steal"
    );
    for (name, summary) in &summaries {
        let get = |series: &str, key: &str| summary[series][key].as_f64().unwrap_or(f64::NAN);
        let (with, without) = (
            get("with_lod", "median_ms"),
            get("without_lod", "median_ms"),
        );
        println!(
            "{name:>10} {with:>9.2} {without:>9.2} {:>6.2} {:>6.1}% {:>6.1}% {:>9.2} {:>9.2} {:>7.2} {:>7.2} {:>5.1}%",
            with / without,
            100.0 * get("with_lod", "cv"),
            100.0 * get("without_lod", "cv"),
            get("with_lod", "run_to_run_ms"),
            get("without_lod", "run_to_run_ms"),
            get("with_lod", "in_view_correlation"),
            get("without_lod", "in_view_correlation"),
            50.0 * (get("with_lod", "cpu_steal") + get("without_lod", "cpu_steal")),
        );
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The class: dancers, their clip, their places.

/// A dancer's scene root.
#[derive(Component)]
struct Dancer {
    index: usize,
}

/// An `AnimationPlayer` bound to a dancer's clip.
#[derive(Component)]
struct DancerPlayer {
    dancer: usize,
}

#[derive(Component)]
struct MainCamera;

#[derive(Component)]
struct Label;

/// The scene's shared state.
#[derive(Resource)]
struct Class {
    file: String,
    /// How each dancer becomes multiresolution (from the baked file beside the model).
    scene: MultiresScene,
    clip_name: Option<String>,
    gltf: Handle<Gltf>,
    /// The clip's graph, node and length in seconds, once loaded.
    clip: Option<(Handle<AnimationGraph>, AnimationNodeIndex, f32)>,
    /// Where each dancer stands (feet), in metres.
    layout: Vec<Vec3>,
    dancers: Vec<Entity>,
    /// Per dancer, triangles of its conventional (fixed-cost) meshes.
    fixed: Vec<usize>,
    /// Dancers are measured, scaled and shown.
    placed: bool,
    /// The budget P the run starts with (the report's).
    budget: u32,
}

impl Class {
    fn new(args: &Args, root: &Path, file: String) -> Self {
        Self {
            scene: common::multires_scene(root, &file),
            file,
            clip_name: args.clip.clone(),
            gltf: Handle::default(),
            clip: None,
            layout: layout(args.count as usize),
            dancers: Vec::new(),
            fixed: vec![0; args.count as usize],
            placed: false,
            budget: args.budget,
        }
    }

    /// Everything needed to run a scripted frame is there.
    fn ready(&self) -> bool {
        self.placed && self.clip.is_some()
    }

    /// Where the scripted camera is at `u` ∈ [0, 1] of its path.
    fn camera_at(&self, u: f32) -> Transform {
        camera_path(&self.layout, u)
    }

    /// Dancer `i`'s animation time at scripted frame `frame`: out of phase by an equal share
    /// of the clip.
    fn dance_time(&self, i: usize, frame: u32) -> f32 {
        let length = self.clip.as_ref().map_or(1.0, |c| c.2).max(1e-3);
        let phase = length * i as f32 / self.layout.len() as f32;
        (phase + frame as f32 * DANCE_SECONDS_PER_FRAME).rem_euclid(length)
    }
}

/// Dancers in rows of at most `⌈√N⌉` (three in a line), centred on the origin.
fn layout(count: usize) -> Vec<Vec3> {
    let columns = if count <= 3 {
        count
    } else {
        (count as f64).sqrt().ceil() as usize
    };
    let rows = count.div_ceil(columns);
    (0..count)
        .map(|i| {
            let (c, r) = (i % columns, i / columns);
            Vec3::new(
                (c as f32 - (columns - 1) as f32 * 0.5) * SPACING,
                0.0,
                (r as f32 - (rows - 1) as f32 * 0.5) * SPACING,
            )
        })
        .collect()
}

/// The scripted camera (Figure 9): close on the first dancer, along the line to the last,
/// back to see the whole class, round the side, and close behind the middle dancer. Each
/// dancer is near the camera at one time and far or out of view at another.
fn camera_path(layout: &[Vec3], u: f32) -> Transform {
    let first = layout[0];
    let last = layout[layout.len() - 1];
    let middle = layout[layout.len() / 2];
    let centre = layout.iter().copied().sum::<Vec3>() / layout.len() as f32;
    let extent = layout
        .iter()
        .map(|p| p.distance(centre))
        .fold(0.0f32, f32::max)
        + 1.0;
    let chest = Vec3::Y * 1.1;
    // (u, eye, target)
    let keys = [
        (0.0, first + Vec3::new(0.35, 1.45, 1.3), first + chest),
        (0.3, last + Vec3::new(-0.35, 1.45, 1.3), last + chest),
        (
            0.55,
            centre + Vec3::new(0.0, 0.9 + 0.5 * extent, 1.5 + 1.7 * extent),
            centre + Vec3::Y * 0.9,
        ),
        (
            0.78,
            centre + Vec3::new(1.0 + extent, 1.6, -0.6),
            centre + Vec3::Y * 0.9,
        ),
        (1.0, middle + Vec3::new(0.3, 1.35, -1.3), middle + chest),
    ];
    let u = u.clamp(0.0, 1.0);
    let k = keys
        .windows(2)
        .position(|w| u <= w[1].0)
        .unwrap_or(keys.len() - 2);
    let (a, b) = (keys[k], keys[k + 1]);
    let t = ((u - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
    let t = t * t * (3.0 - 2.0 * t);
    let eye = a.1.lerp(b.1, t);
    let target = a.2.lerp(b.2, t);
    Transform::from_translation(eye).looking_at(target, Vec3::Y)
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut class: ResMut<Class>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    report: Option<Res<Report>>,
) {
    class.gltf = asset_server.load(class.file.clone());
    let scene = asset_server.load(GltfAssetLabel::Scene(0).from_asset(class.file.clone()));
    let dancers: Vec<Entity> = class
        .layout
        .iter()
        .enumerate()
        .map(|(index, &at)| {
            commands
                .spawn((
                    WorldAssetRoot(scene.clone()),
                    class.scene.clone(),
                    Transform::from_translation(at),
                    // Shown once measured and scaled (`place_dancers`).
                    Visibility::Hidden,
                    Dancer { index },
                ))
                .id()
        })
        .collect();
    class.dancers = dancers;

    // The floor: two triangles, charged to the budget like any conventional mesh.
    let half = class
        .layout
        .iter()
        .map(|p| p.x.abs().max(p.z.abs()))
        .fold(0.0f32, f32::max)
        + 12.0;
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(2.0 * half, 2.0 * half))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.42, 0.36, 0.30),
            perceptual_roughness: 0.8,
            ..default()
        })),
        CountInBudget,
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 8_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        // Lavapipe shades on the CPU: without multisampling the frame is cheaper by more
        // than the triangles it draws.
        Msaa::Off,
        // The label and the overlay's counts are drawn into this camera's image too.
        IsDefaultUiCamera,
        class.camera_at(0.0),
        MainCamera,
        FlyCamera {
            enabled: false,
            speed: 2.5,
        },
    ));
    if let Some(report) = report {
        let handle = common::offscreen_image(&mut images, (report.size.0, report.size.1));
        camera.insert(RenderTarget::Image(handle.clone().into()));
        commands.insert_resource(ShotTarget(handle));
        info!(
            "offscreen: {} frames with and without LOD, report in {}",
            report.frames,
            report.dir.display()
        );
    }
    commands.spawn((
        Text::new(""),
        TextFont::from_font_size(15.0),
        TextColor(Color::BLACK),
        Node {
            position_type: PositionType::Absolute,
            top: px(8),
            left: px(8),
            ..default()
        },
        Label,
    ));
}

/// Finds the clip once the glTF is loaded and builds its animation graph.
fn bind_clip(
    mut class: ResMut<Class>,
    gltfs: Res<Assets<Gltf>>,
    clips: Res<Assets<AnimationClip>>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    asset_server: Res<AssetServer>,
    mut exit: MessageWriter<AppExit>,
) {
    if class.clip.is_some() {
        return;
    }
    if let Some(bevy::asset::LoadState::Failed(e)) = asset_server.get_load_state(&class.gltf) {
        error!("cannot load {}: {e}", class.file);
        exit.write(AppExit::error());
        return;
    }
    let Some(gltf) = gltfs.get(&class.gltf) else {
        return;
    };
    let clip = match common::pick_clip(gltf, &class.file, class.clip_name.as_deref()) {
        Ok(clip) => clip,
        Err(e) => {
            error!("{e}");
            exit.write(AppExit::error());
            return;
        }
    };
    let Some(length) = clips.get(&clip).map(AnimationClip::duration) else {
        return;
    };
    let (graph, node) = AnimationGraph::from_clip(clip);
    class.clip = Some((graphs.add(graph), node, length));
    info!("dancing {:?} ({length:.2} s)", class.clip_name);
}

/// Gives each dancer's `AnimationPlayer` the clip, out of phase with the others.
fn bind_players(
    mut commands: Commands,
    class: Res<Class>,
    mut players: Query<(Entity, &mut AnimationPlayer), Without<DancerPlayer>>,
    parents: Query<&ChildOf>,
    dancers: Query<&Dancer>,
    report: Option<Res<Report>>,
) {
    let Some((graph, node, _)) = class.clip.clone() else {
        return;
    };
    for (entity, mut player) in &mut players {
        let Some(dancer) = parents
            .iter_ancestors(entity)
            .find_map(|e| dancers.get(e).ok())
        else {
            continue;
        };
        let active = player.play(node).repeat();
        active.seek_to(class.dance_time(dancer.index, 0));
        if report.is_some() {
            // The report sets every frame's time itself.
            active.set_speed(0.0);
        }
        commands.entity(entity).insert((
            AnimationGraphHandle(graph.clone()),
            DancerPlayer {
                dancer: dancer.index,
            },
        ));
    }
}

/// Unless `--gpu-skinning`: each dancer's skinned models, once converted, keep meshes of
/// their own, which the plugin blends on the CPU.
fn skin_on_cpu(
    mut commands: Commands,
    converted: Query<&MultiresSceneModels, (With<Dancer>, Added<MultiresSceneModels>)>,
) {
    for models in &converted {
        for &model in &models.skinned {
            commands.entity(model).insert(NoSharedLevels);
        }
    }
}

/// Once every dancer's models are ready (the plugin's [`MultiresModelReady`] messages, read
/// in the frame after the plugin posed them), measures the first dancer, scales every dancer
/// to [`DANCER_HEIGHT`] with its feet on the floor, and shows them.
#[allow(clippy::too_many_arguments)]
fn place_dancers(
    mut ready: MessageReader<MultiresModelReady>,
    mut class: ResMut<Class>,
    mut roots: Query<(&mut Transform, &mut Visibility, &MultiresSceneModels), With<Dancer>>,
    instances: Query<(&MultiresInstance, &GlobalTransform)>,
    fixed_boxes: Query<(&Aabb, &GlobalTransform)>,
    meshes: Query<&Mesh3d>,
    mesh_assets: Res<Assets<Mesh>>,
) {
    if ready.read().count() == 0 || class.placed || class.dancers.is_empty() {
        return;
    }
    if class.dancers.iter().any(|&d| roots.get(d).is_err()) {
        return; // not every scene is converted yet
    }
    let Ok((first, _, models)) = roots.get(class.dancers[0]) else {
        return;
    };
    let Some((lo, hi)) = common::scene_bounds(models, &instances, &fixed_boxes) else {
        return; // a model of it is not ready yet: its message comes later
    };
    let height = hi.y - lo.y;
    // Measured with the root at layout[0] and scale 1: in the root's space the model spans
    // lo - at .. hi - at.
    let at = first.translation;
    let scale = DANCER_HEIGHT / height;
    let offset = Vec3::new(
        (lo.x + hi.x) * 0.5 - at.x,
        lo.y - at.y,
        (lo.z + hi.z) * 0.5 - at.z,
    );
    info!(
        "{}: {height:.3} units tall, scaled by {scale:.4} to {DANCER_HEIGHT} m",
        class.file
    );
    let dancers = class.dancers.clone();
    for (i, &d) in dancers.iter().enumerate() {
        let Ok((mut transform, mut visibility, models)) = roots.get_mut(d) else {
            continue;
        };
        transform.scale = Vec3::splat(scale);
        transform.translation = class.layout[i] - offset * scale;
        *visibility = Visibility::Inherited;
        class.fixed[i] = models
            .fixed
            .iter()
            .filter_map(|&e| meshes.get(e).ok())
            .filter_map(|m| mesh_assets.get(&m.0))
            .map(triangles_of)
            .sum();
    }
    class.placed = true;
}

fn triangles_of(mesh: &Mesh) -> usize {
    match mesh.indices() {
        Some(indices) => indices.len() / 3,
        None => mesh.count_vertices() / 3,
    }
}

/// Triangles each dancer shows now (multiresolution regions and fixed meshes).
fn dancer_triangles(
    class: &Class,
    roots: &Query<&MultiresSceneModels, With<Dancer>>,
    instances: &Query<&MultiresInstance>,
) -> Vec<usize> {
    class
        .dancers
        .iter()
        .enumerate()
        .map(|(i, &d)| {
            let multires: usize = roots.get(d).map_or(0, |models| {
                models
                    .models()
                    .filter_map(|m| instances.get(m).ok())
                    .map(MultiresInstance::triangle_count)
                    .sum()
            });
            multires + class.fixed[i]
        })
        .collect()
}

/// Triangles the dancers would show at full detail in `frustum`: every region whose world box
/// ([`common::region_world_boxes`]) meets the frustum counts all its triangles, and each
/// dancer's fixed meshes count whole.
fn full_detail_in_view(
    class: &Class,
    roots: &Query<&MultiresSceneModels, With<Dancer>>,
    instances: &Query<(&MultiresInstance, &GlobalTransform)>,
    frustum: &Frustum,
) -> u64 {
    let meets = |obb: &Obb| {
        let local = Aabb {
            center: Vec3A::ZERO,
            half_extents: obb.half_extents.into(),
        };
        frustum.intersects_obb(
            &local,
            &Affine3A::from_mat3_translation(obb.axes, obb.center),
            true,
            false,
        )
    };
    let mut total = 0;
    for (i, &d) in class.dancers.iter().enumerate() {
        total += class.fixed[i] as u64;
        let Ok(models) = roots.get(d) else {
            continue;
        };
        for (instance, transform) in models.models().filter_map(|m| instances.get(m).ok()) {
            let boxes = common::region_world_boxes(instance, transform).unwrap_or_default();
            let regions = instance.regions().regions();
            total += regions
                .iter()
                .zip(&boxes)
                .filter(|(_, obb)| meets(obb))
                .map(|(region, _)| region.max_triangles() as u64)
                .sum::<u64>();
        }
    }
    total
}

/// Sets the camera and every dancer's pose for scripted frame `frame` of `frames`.
fn apply_frame(
    class: &Class,
    frame: u32,
    frames: u32,
    camera: &mut Query<(&mut Transform, &Frustum), With<MainCamera>>,
    players: &mut Query<(&DancerPlayer, &mut AnimationPlayer)>,
) {
    let u = frame.saturating_sub(1) as f32 / (frames - 1).max(1) as f32;
    if let Ok((mut transform, _)) = camera.single_mut() {
        *transform = class.camera_at(u);
    }
    let Some((_, node, _)) = class.clip else {
        return;
    };
    for (dancer, mut player) in players.iter_mut() {
        if let Some(active) = player.animation_mut(node) {
            active.seek_to(class.dance_time(dancer.dancer, frame));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Interactive mode.

#[derive(Resource, Default)]
struct Interactive {
    free_camera: bool,
    paused: bool,
    script_time: f32,
}

#[allow(clippy::too_many_arguments)]
fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut budget: ResMut<PolygonBudget>,
    mut full_detail: ResMut<FullDetail>,
    mut overlay: ResMut<AslodOverlay>,
    mut state: ResMut<Interactive>,
    mut players: Query<&mut AnimationPlayer, With<DancerPlayer>>,
    mut cameras: Query<&mut FlyCamera>,
) {
    if input.just_pressed(KeyCode::KeyO) {
        overlay.0 = !overlay.0;
    }
    if input.just_pressed(KeyCode::KeyC) {
        state.free_camera = !state.free_camera;
        for mut fly in &mut cameras {
            fly.enabled = state.free_camera;
        }
    }
    if input.just_pressed(KeyCode::KeyL) {
        // Off: every region at full detail, through the same pipeline.
        full_detail.0 = !full_detail.0;
    }
    if input.just_pressed(KeyCode::ArrowUp) || input.just_pressed(KeyCode::ArrowDown) {
        let factor = if input.just_pressed(KeyCode::ArrowUp) {
            1.25
        } else {
            0.8
        };
        budget.total = ((budget.total as f32 * factor).round() as u32).clamp(100, 10_000_000);
    }
    if input.just_pressed(KeyCode::ArrowRight) {
        budget.alpha = (budget.alpha + 0.5).min(10.0);
    }
    if input.just_pressed(KeyCode::ArrowLeft) {
        budget.alpha = (budget.alpha - 0.5).max(0.5);
    }
    if input.just_pressed(KeyCode::Space) {
        state.paused = !state.paused;
        for mut player in &mut players {
            if state.paused {
                player.pause_all();
            } else {
                player.resume_all();
            }
        }
    }
}

fn script_camera(
    time: Res<Time>,
    class: Res<Class>,
    mut state: ResMut<Interactive>,
    mut camera: Query<&mut Transform, With<MainCamera>>,
) {
    if state.free_camera || !class.placed {
        return;
    }
    state.script_time = (state.script_time + time.delta_secs()) % SCRIPT_SECONDS;
    // There and back, so the path loops without a jump.
    let u = state.script_time / SCRIPT_SECONDS * 2.0;
    let u = if u > 1.0 { 2.0 - u } else { u };
    if let Ok(mut transform) = camera.single_mut() {
        *transform = class.camera_at(u);
    }
}

#[allow(clippy::too_many_arguments)]
fn update_label(
    time: Res<Time>,
    class: Res<Class>,
    budget: Res<PolygonBudget>,
    full_detail: Res<FullDetail>,
    stats: Res<AslodStats>,
    state: Option<Res<Interactive>>,
    roots: Query<&MultiresSceneModels, With<Dancer>>,
    instances: Query<&MultiresInstance>,
    mut label: Query<&mut Text, With<Label>>,
) {
    let counts = dancer_triangles(&class, &roots, &instances);
    let shown: Vec<String> = counts.iter().take(8).map(|c| c.to_string()).collect();
    let Some(state) = state else {
        // The report's screenshots: the counts only (frame times would differ run to run).
        let text = format!(
            "{} triangles / P = {}\nper mannequin: {}{}",
            stats.triangles + u64::from(stats.fixed_cost),
            class.budget,
            shown.join(" / "),
            if counts.len() > 8 { " ..." } else { "" },
        );
        for mut label in &mut label {
            if label.0 != text {
                label.0.clone_from(&text);
            }
        }
        return;
    };
    let text = format!(
        "{} triangles in use / P = {}  (alpha {:.1}, LOD {})\nper dancer: {}{}\nframe {:.1} ms, deform {:.2} ms, {} regions changed\n\
         Up/Down: P  Left/Right: alpha  L: LOD  O: overlay  C: {} camera  Space: pause",
        stats.triangles + u64::from(stats.fixed_cost),
        budget.total,
        budget.alpha,
        if full_detail.0 { "off" } else { "on" },
        shown.join(" / "),
        if counts.len() > 8 { " ..." } else { "" },
        time.delta_secs() * 1000.0,
        stats.deform_ms,
        stats.regions_changed,
        if state.free_camera {
            "scripted"
        } else {
            "free"
        },
    );
    for mut label in &mut label {
        if label.0 != text {
            label.0.clone_from(&text);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The headless report.

#[derive(Resource)]
struct ShotTarget(Handle<Image>);

/// Where the headless run is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Waiting for the model, its clip and the dancers' placement.
    Loading,
    /// Rendering frame 1 until a screenshot shows something (pipelines compile slowly on a
    /// software rasteriser).
    Warmup,
    /// Running the scripted frames of run `run` (0-based); `frame` 0 is the settling before
    /// frame 1.
    Run {
        lod: bool,
        run: u32,
        frame: u32,
        settle: u32,
    },
    /// Taking screenshot `index` of [`Report::shots`].
    Shots { index: usize },
    /// Writing the report.
    Done,
    /// The report is written; the app is on its way out.
    Exiting,
}

/// One measured frame.
#[derive(Clone, Debug, Default)]
struct Row {
    ms: f64,
    dancers: Vec<usize>,
    total: u64,
    /// Triangles the dancers would show at full detail in the camera's view (regions whose
    /// box meets the frustum, plus fixed meshes): what a frame without LOD has to draw.
    in_view: u64,
    /// The plugin's own CPU time: Allocate, Deform, SelectLod + Upload.
    allocate_ms: f64,
    deform_ms: f64,
    update_ms: f64,
    /// The budget P of the frame.
    budget: u32,
}

#[derive(Resource)]
struct Report {
    dir: PathBuf,
    frames: u32,
    /// Offscreen image size.
    size: (u32, u32),
    /// Runs of the scripted frames per series (`--repeat`).
    repeat: u32,
    stage: Stage,
    last: Option<Instant>,
    /// Per run, its frames: with LOD and without.
    lod: Vec<Vec<Row>>,
    no_lod: Vec<Vec<Row>>,
    /// (frame, with overlay)
    shots: Vec<(u32, bool)>,
    wait: u32,
    pending: bool,
    attempts: u32,
    /// A warm-up screenshot came back non-blank.
    drawn: bool,
    /// When the wait for the model began (see [`MAX_LOADING`]).
    loading_since: Option<Instant>,
    /// Screenshots taken, and the names of those saved.
    shots_done: usize,
    saved: Vec<String>,
    /// The machine's CPU time (`/proc/stat`) when the current run's frame 1 began, and per
    /// series (LOD, no LOD) the CPU time summed over its runs' frames.
    cpu_mark: Option<CpuTimes>,
    cpu: [CpuTimes; 2],
}

impl Report {
    fn new(dir: PathBuf, frames: u32, repeat: u32, size: (u32, u32)) -> Self {
        Self {
            dir,
            frames,
            size,
            repeat,
            stage: Stage::Loading,
            last: None,
            lod: Vec::new(),
            no_lod: Vec::new(),
            shots: vec![(1, false), (frames.div_ceil(2), true), (frames, false)],
            wait: 0,
            pending: false,
            attempts: 0,
            drawn: false,
            loading_since: None,
            shots_done: 0,
            saved: Vec::new(),
            cpu_mark: None,
            cpu: [CpuTimes::default(); 2],
        }
    }
}

/// Runs in `Last`: records the frame just finished and sets up the next one.
#[allow(clippy::too_many_arguments)]
fn drive_report(
    mut commands: Commands,
    mut report: ResMut<Report>,
    class: Res<Class>,
    mut full_detail: ResMut<FullDetail>,
    mut overlay: ResMut<AslodOverlay>,
    stats: Res<AslodStats>,
    target: Option<Res<ShotTarget>>,
    roots: Query<&MultiresSceneModels, With<Dancer>>,
    instances: Query<&MultiresInstance>,
    placed: Query<(&MultiresInstance, &GlobalTransform)>,
    mut camera: Query<(&mut Transform, &Frustum), With<MainCamera>>,
    mut players: Query<(&DancerPlayer, &mut AnimationPlayer)>,
    mut exit: MessageWriter<AppExit>,
) {
    let now = Instant::now();
    let period = report.last.map(|t| (now - t).as_secs_f64() * 1000.0);
    report.last = Some(now);
    let frames = report.frames;
    match report.stage {
        Stage::Loading => {
            let bound = players.iter().count() >= class.dancers.len();
            if class.ready() && bound {
                info!("class ready: {} dancers", class.dancers.len());
                report.stage = Stage::Warmup;
                report.wait = 3;
                apply_frame(&class, 1, frames, &mut camera, &mut players);
            } else {
                let started = *report.loading_since.get_or_insert(now);
                if now - started > MAX_LOADING {
                    error!(
                        "the class is not ready after {} s: clip {}, dancers placed {}, players {} of {} (a model without skinned or multiresolution meshes cannot dance)",
                        MAX_LOADING.as_secs(),
                        if class.clip.is_some() {
                            "found"
                        } else {
                            "not found"
                        },
                        class.placed,
                        players.iter().count(),
                        class.dancers.len()
                    );
                    exit.write(AppExit::error());
                    report.stage = Stage::Exiting;
                }
            }
        }
        Stage::Warmup => {
            if report.drawn {
                report.stage = Stage::Run {
                    lod: true,
                    run: 0,
                    frame: 0,
                    settle: SETTLE_FRAMES,
                };
                full_detail.0 = false;
            } else {
                request_shot(&mut commands, &mut report, target.as_deref());
            }
        }
        Stage::Run {
            lod,
            run,
            frame,
            settle,
        } => {
            if frame > 0 {
                let in_view = camera.single().map_or(0, |(_, frustum)| {
                    full_detail_in_view(&class, &roots, &placed, frustum)
                });
                let row = Row {
                    ms: period.unwrap_or(0.0),
                    dancers: dancer_triangles(&class, &roots, &instances),
                    total: stats.triangles + u64::from(stats.fixed_cost),
                    in_view,
                    allocate_ms: stats.allocation_ms,
                    deform_ms: stats.deform_ms,
                    update_ms: stats.update_ms,
                    budget: stats.budget,
                };
                let series = if lod {
                    &mut report.lod
                } else {
                    &mut report.no_lod
                };
                if series.len() <= run as usize {
                    series.push(Vec::new());
                }
                series[run as usize].push(row);
            }
            // Settle, then the frames; after a series' run the other series' same run, LOD
            // first (LOD, no LOD, LOD, ...).
            let next = if settle > 0 {
                Stage::Run {
                    lod,
                    run,
                    frame: 0,
                    settle: settle - 1,
                }
            } else if frame < frames {
                Stage::Run {
                    lod,
                    run,
                    frame: frame + 1,
                    settle: 0,
                }
            } else if lod {
                info!(
                    "run {} of {} with LOD done; now at full detail",
                    run + 1,
                    report.repeat
                );
                full_detail.0 = true;
                Stage::Run {
                    lod: false,
                    run,
                    frame: 0,
                    settle: SETTLE_FRAMES,
                }
            } else if run + 1 < report.repeat {
                full_detail.0 = false;
                Stage::Run {
                    lod: true,
                    run: run + 1,
                    frame: 0,
                    settle: SETTLE_FRAMES,
                }
            } else {
                full_detail.0 = false;
                report.wait = 4;
                Stage::Shots { index: 0 }
            };
            // The machine's CPU time over each run's measured frames (the frame that ends
            // here was set up in the previous call).
            if frame == frames
                && settle == 0
                && let Some(mark) = report.cpu_mark.take()
            {
                report.cpu[usize::from(!lod)].add(CpuTimes::now().since(mark));
            }
            if let Stage::Run { frame: 1, .. } = next {
                report.cpu_mark = Some(CpuTimes::now());
            }
            report.stage = next;
            if let Stage::Run { frame, .. } = next {
                apply_frame(&class, frame.max(1), frames, &mut camera, &mut players);
            }
        }
        Stage::Shots { index } => {
            let Some(&(frame, with_overlay)) = report.shots.get(index) else {
                report.stage = Stage::Done;
                return;
            };
            apply_frame(&class, frame, frames, &mut camera, &mut players);
            overlay.0 = with_overlay;
            if report.shots_done > index {
                overlay.0 = false;
                report.wait = 4;
                report.stage = Stage::Shots { index: index + 1 };
            } else {
                request_shot(&mut commands, &mut report, target.as_deref());
            }
        }
        Stage::Done => {
            match write_report(&report, &class) {
                Ok(()) => {
                    exit.write(AppExit::Success);
                }
                Err(e) => {
                    error!("cannot write the report: {e}");
                    exit.write(AppExit::error());
                }
            }
            report.stage = Stage::Exiting;
        }
        Stage::Exiting => {}
    }
}

/// Asks for a screenshot after `wait` frames, unless one is in flight.
fn request_shot(commands: &mut Commands, report: &mut Report, target: Option<&ShotTarget>) {
    if report.pending {
        return;
    }
    if report.wait > 0 {
        report.wait -= 1;
        return;
    }
    let Some(target) = target else {
        return;
    };
    report.pending = true;
    commands
        .spawn(Screenshot::image(target.0.clone()))
        .observe(on_captured);
}

/// Saves a captured frame (or, while warming up, notes that something is drawn).
fn on_captured(captured: On<ScreenshotCaptured>, mut report: ResMut<Report>) {
    report.pending = false;
    let varied = common::is_drawn(&captured);
    match report.stage {
        Stage::Warmup => {
            if varied || report.attempts >= 60 {
                if !varied {
                    warn!(
                        "the frame still looks blank after {} tries",
                        report.attempts
                    );
                }
                report.drawn = true;
                report.attempts = 0;
            } else {
                report.attempts += 1;
                report.wait = 5;
            }
        }
        Stage::Shots { index } => {
            let Some(&(frame, with_overlay)) = report.shots.get(index) else {
                return;
            };
            let name = format!(
                "frame_{frame:03}{}.png",
                if with_overlay { "_overlay" } else { "" }
            );
            if !varied {
                warn!("{name} looks blank");
            }
            if common::save_capture(&captured, &report.dir.join(&name)) {
                report.saved.push(name);
            }
            report.shots_done += 1;
        }
        _ => {}
    }
}

/// Each run's frame times.
fn times(runs: &[Vec<Row>]) -> Vec<Vec<f64>> {
    runs.iter()
        .map(|run| run.iter().map(|r| r.ms).collect())
        .collect()
}

fn write_report(report: &Report, class: &Class) -> Result<(), String> {
    let n = class.dancers.len();
    let runs = report.lod.len().min(report.no_lod.len());
    let frames = report.lod[..runs]
        .iter()
        .chain(&report.no_lod[..runs])
        .map(Vec::len)
        .min()
        .unwrap_or(0);
    if frames == 0 {
        return Err("no frames were recorded".into());
    }
    // frames.csv: every run, LOD and no-LOD side by side.
    let mut csv = String::from("run,frame,frame_ms");
    for i in 0..n {
        csv += &format!(",mannequin_{}", i + 1);
    }
    csv += ",total,no_lod_frame_ms,no_lod_total,in_view_full_detail,allocate_ms,deform_ms,update_ms,no_lod_deform_ms,no_lod_update_ms,budget\n";
    for run in 0..runs {
        for f in 0..frames {
            let (a, b) = (&report.lod[run][f], &report.no_lod[run][f]);
            csv += &format!("{},{},{:.3}", run + 1, f + 1, a.ms);
            for c in &a.dancers {
                csv += &format!(",{c}");
            }
            csv += &format!(
                ",{},{:.3},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{}\n",
                a.total,
                b.ms,
                b.total,
                b.in_view,
                a.allocate_ms,
                a.deform_ms,
                a.update_ms,
                b.deform_ms,
                b.update_ms,
                a.budget
            );
        }
    }
    let path = report.dir.join("frames.csv");
    std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;

    // summary.json. Every run shows the same frames, so the triangle counts of the first
    // run stand for all of them (the budget targets are checked over every run).
    let every_lod: Vec<&Row> = report.lod[..runs]
        .iter()
        .flat_map(|r| &r[..frames])
        .collect();
    let lod = &report.lod[0][..frames];
    let no_lod = &report.no_lod[0][..frames];
    let largest = every_lod.iter().map(|r| r.total).max().unwrap_or(0);
    let smallest = every_lod.iter().map(|r| r.total).min().unwrap_or(0);
    let full_above = (0..frames).filter(|&f| no_lod[f].total > u64::from(class.budget));
    let filled = full_above
        .clone()
        .all(|f| lod[f].total * 10 >= u64::from(class.budget) * 9);
    let smallest_when_full_above = full_above.map(|f| lod[f].total).min();
    let dancers: Vec<serde_json::Value> = (0..n)
        .map(|i| {
            let counts: Vec<usize> = lod.iter().map(|r| r.dancers[i]).collect();
            let shares: Vec<f64> = lod
                .iter()
                .map(|r| {
                    let sum: usize = r.dancers.iter().sum();
                    if sum == 0 {
                        0.0
                    } else {
                        r.dancers[i] as f64 / sum as f64
                    }
                })
                .collect();
            let (lo, hi) = (
                counts.iter().copied().min().unwrap_or(0),
                counts.iter().copied().max().unwrap_or(0),
            );
            serde_json::json!({
                "min_triangles": lo,
                "max_triangles": hi,
                "ratio": if lo > 0 { hi as f64 / lo as f64 } else { f64::INFINITY },
                "share_min": shares.iter().copied().fold(f64::INFINITY, f64::min),
                "share_max": shares.iter().copied().fold(0.0, f64::max),
            })
        })
        .collect();
    let in_view: Vec<f64> = no_lod.iter().map(|r| r.in_view as f64).collect();
    let mut with = series_stats(&times(&report.lod[..runs]), frames, &in_view);
    let mut without = series_stats(&times(&report.no_lod[..runs]), frames, &in_view);
    for (series, cpu) in [(&mut with, report.cpu[0]), (&mut without, report.cpu[1])] {
        let (idle, steal) = cpu.shares();
        series["cpu_idle"] = idle.into();
        series["cpu_steal"] = steal.into();
    }
    let get = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let cv_bound = (get(&without, "cv") / 3.0).max(0.05);
    let targets = serde_json::json!({
        "total_within_budget": largest <= u64::from(class.budget),
        "total_at_least_90_percent_when_full_detail_exceeds_budget": filled,
        "each_mannequin_varies_3x": dancers.iter().all(|d| d["ratio"].as_f64().unwrap_or(f64::INFINITY) >= 3.0),
        "cv_at_most_max_of_third_of_no_lod_or_5_percent": get(&with, "cv") <= cv_bound,
        "median_at_most_half_of_no_lod": get(&with, "median_ms") <= 0.5 * get(&without, "median_ms"),
    });
    let summary = serde_json::json!({
        "model": class.file,
        "clip": class.clip_name,
        "dancers": n,
        "budget": class.budget,
        "frames": frames,
        "repeat": runs,
        "screen": [report.size.0, report.size.1],
        "build": if cfg!(debug_assertions) { "debug" } else { "release" },
        "with_lod": with,
        "without_lod": without,
        "largest_total": largest,
        "smallest_total": smallest,
        "smallest_total_when_full_detail_exceeds_budget": smallest_when_full_above,
        "full_detail_total": no_lod.iter().map(|r| r.total).max(),
        "full_detail_in_view_min": no_lod.iter().map(|r| r.in_view).min(),
        "full_detail_in_view_max": no_lod.iter().map(|r| r.in_view).max(),
        "mannequins": dancers,
        "targets": targets,
        "screenshots": report.saved,
    });
    let path = report.dir.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    info!("summary: {summary}");

    charts::frame_time(
        &report.dir.join("frame_time.png"),
        &charts::Series {
            runs: &report.lod[..runs],
            medians: per_frame_medians(&times(&report.lod[..runs]), frames),
            label: format!("with LOD (P = {} triangles)", class.budget),
        },
        &charts::Series {
            runs: &report.no_lod[..runs],
            medians: per_frame_medians(&times(&report.no_lod[..runs]), frames),
            label: format!(
                "no LOD ({} triangles)",
                no_lod.iter().map(|r| r.total).max().unwrap_or(0)
            ),
        },
        report.size,
    )?;
    charts::allocation(&report.dir.join("allocation.png"), lod, class.budget)?;
    Ok(())
}

/// The report's charts, drawn with `plotters` into an RGB buffer and saved as PNG.
mod charts {
    use super::Row;
    use crate::common::chart::draw;
    use plotters::prelude::*;
    use std::path::Path;

    /// One series of the frame-time chart: its runs and each frame's median over them.
    pub struct Series<'a> {
        pub runs: &'a [Vec<Row>],
        pub medians: Vec<f64>,
        pub label: String,
    }

    /// Figure 11: frame time per frame, with LOD and at full detail; each frame's median over
    /// the runs as a line, every run's frames as faint dots behind it.
    pub fn frame_time(
        path: &Path,
        lod: &Series<'_>,
        no_lod: &Series<'_>,
        size: (u32, u32),
    ) -> Result<(), String> {
        let frames = lod.medians.len() as u32;
        // Outliers in single runs would flatten the medians: the axis stops above the largest
        // median (dots above it are drawn at the top edge).
        let top = lod
            .medians
            .iter()
            .chain(&no_lod.medians)
            .copied()
            .fold(1.0f64, f64::max)
            * 1.25;
        let runs = lod.runs.len();
        let caption = if runs > 1 {
            format!("Frame time, {}x{}: median of {runs} runs", size.0, size.1)
        } else {
            format!("Frame time per frame, {}x{}", size.0, size.1)
        };
        draw(path, |root| {
            let mut chart = ChartBuilder::on(root)
                .caption(caption, ("sans-serif", 26))
                .margin(16)
                .x_label_area_size(48)
                .y_label_area_size(64)
                .build_cartesian_2d(1u32..frames.max(2), 0f64..top)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("frame")
                .y_desc("frame time (ms)")
                .y_label_formatter(&|v| format!("{v:.0}"))
                .axis_desc_style(("sans-serif", 18))
                .label_style(("sans-serif", 15))
                .draw()
                .map_err(|e| e.to_string())?;
            for (series, color) in [(lod, RED), (no_lod, BLUE)] {
                if runs > 1 {
                    chart
                        .draw_series(series.runs.iter().flat_map(|run| {
                            run.iter().enumerate().map(move |(f, r)| {
                                Circle::new(
                                    (f as u32 + 1, r.ms.min(top)),
                                    2,
                                    color.mix(0.3).filled(),
                                )
                            })
                        }))
                        .map_err(|e| e.to_string())?;
                }
                chart
                    .draw_series(LineSeries::new(
                        series
                            .medians
                            .iter()
                            .enumerate()
                            .map(|(f, &ms)| (f as u32 + 1, ms)),
                        color.stroke_width(2),
                    ))
                    .map_err(|e| e.to_string())?
                    .label(series.label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 16))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())
        })
    }

    /// Each mannequin's triangles per frame (the first eight in a crowd), and the total.
    pub fn allocation(path: &Path, lod: &[Row], budget: u32) -> Result<(), String> {
        let frames = lod.len() as u32;
        let top = lod
            .iter()
            .map(|r| r.total)
            .max()
            .unwrap_or(1)
            .max(u64::from(budget)) as f64
            * 1.08;
        draw(path, |root| {
            let mut chart = ChartBuilder::on(root)
                .caption("Triangles per mannequin", ("sans-serif", 26))
                .margin(16)
                .x_label_area_size(48)
                .y_label_area_size(72)
                .build_cartesian_2d(1u32..frames.max(2), 0f64..top)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("frame")
                .y_desc("triangles")
                .y_label_formatter(&|v| format!("{v:.0}"))
                .axis_desc_style(("sans-serif", 18))
                .label_style(("sans-serif", 15))
                .draw()
                .map_err(|e| e.to_string())?;
            let dancers = lod.first().map_or(0, |r| r.dancers.len());
            for i in 0..dancers.min(8) {
                let color = Palette99::pick(i).to_rgba();
                chart
                    .draw_series(LineSeries::new(
                        lod.iter()
                            .enumerate()
                            .map(|(f, r)| (f as u32 + 1, r.dancers[i] as f64)),
                        color.stroke_width(2),
                    ))
                    .map_err(|e| e.to_string())?
                    .label(format!("mannequin {}", i + 1))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
                    });
            }
            chart
                .draw_series(LineSeries::new(
                    lod.iter()
                        .enumerate()
                        .map(|(f, r)| (f as u32 + 1, r.total as f64)),
                    BLACK.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label("total (with the floor)")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(2))
                });
            chart
                .draw_series(LineSeries::new(
                    [(1, f64::from(budget)), (frames.max(2), f64::from(budget))],
                    BLACK.mix(0.5).stroke_width(1),
                ))
                .map_err(|e| e.to_string())?
                .label(format!("budget P = {budget}"))
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.mix(0.5)));
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 16))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())
        })
    }
}
