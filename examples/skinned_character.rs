//! A glTF character, skinned and animated, as a multiresolution model (ASLOD section 5):
//! rigid regions ride their joints, deformable regions blend between their bones on the CPU,
//! and Bevy's own `AnimationPlayer` drives the skeleton.
//!
//! Controls: Up/Down change the budget P; `O` the overlay of region boxes and triangle counts;
//! Space pauses the clip; `C` switches between the orbiting camera and a free one (WASD, Q/E,
//! drag to look).
//!
//! Options: `--model PATH` (default RobotExpressive from the shared test data), `--clip NAME`
//! (default "Dance" when the model has it, else its first clip), `--budget P` (default
//! 5,000). `--headless --frames N --screenshot DIR` renders offscreen, waits N frames per
//! shot, and writes `character.png`, `character_overlay.png` and `counts.json` (triangles per
//! region, rigid or deformable, and what the blend cost) to DIR.

mod common;

use bevy::camera::RenderTarget;
use bevy::camera::primitives::Aabb;
use bevy::gltf::Gltf;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{
    AslodOverlay, AslodPlugin, AslodStats, MultiresInstance, MultiresMesh, MultiresModel,
    MultiresModelReady, MultiresScene, MultiresSceneModels, PolygonBudget,
};
use bevy_aslod::skin::SkinRegionKind;
use clap::Parser;
use common::{FlyCamera, fly_camera};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Offscreen image size.
const SHOT_SIZE: (u32, u32) = (800, 800);
/// The default budget.
const BUDGET: u32 = 5_000;
/// How long the headless run waits for the character and its clip before it gives up.
const MAX_LOADING: Duration = Duration::from_secs(180);
/// The clip played when the model has it and `--clip` names none.
const DEFAULT_CLIP: &str = "Dance";

fn main() {
    let args = Args::parse();
    let (asset_root, file) = match common::split_model_path(&args.model) {
        Ok(split) => split,
        Err(e) => {
            eprintln!("skinned_character: {e}");
            std::process::exit(2);
        }
    };
    let mut app = App::new();
    common::add_default_plugins(
        &mut app,
        args.headless,
        "bevy_aslod: a skinned multiresolution character",
        Some(&asset_root),
    );
    app.add_plugins(AslodPlugin::default().with_budget(args.budget))
        .insert_resource(ClearColor(Color::srgb(0.78, 0.82, 0.88)))
        .insert_resource(GlobalAmbientLight {
            brightness: 600.0,
            ..default()
        })
        .insert_resource(Character {
            file,
            clip_name: args.clip.clone(),
            gltf: Handle::default(),
            root: Entity::PLACEHOLDER,
            clip: None,
            framed: None,
            orbit: true,
            orbit_angle: 0.0,
        })
        .add_systems(Startup, setup)
        .add_systems(
            Update,
            (
                play_clip,
                frame_camera,
                orbit_camera,
                fly_camera,
                update_label,
            )
                .chain(),
        );
    if args.headless {
        let dir = args
            .screenshot
            .clone()
            .unwrap_or_else(|| PathBuf::from("character-shots"));
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("skinned_character: cannot create {}: {e}", dir.display());
            std::process::exit(1);
        }
        app.insert_resource(Shots {
            dir,
            frames: args.frames.max(2),
            wait: args.frames.max(2),
            index: 0,
            pending: false,
            attempts: 0,
            loading_since: None,
        })
        .add_systems(Update, drive_shots.after(update_label));
    } else {
        app.add_systems(Update, keys.before(play_clip));
    }
    app.run();
}

/// A glTF character as a skinned multiresolution model.
#[derive(Parser, Debug)]
struct Args {
    /// Render offscreen, no window: the shots, then exit.
    #[arg(long)]
    headless: bool,
    /// Frames to wait before each shot (at least 2).
    #[arg(long, default_value_t = 30)]
    frames: u32,
    /// Where the headless run writes (default: character-shots).
    #[arg(long, value_name = "DIR")]
    screenshot: Option<PathBuf>,
    /// The glTF character.
    #[arg(long, value_name = "PATH", default_value_os_t = default_model())]
    model: PathBuf,
    /// The clip to play (default: `Dance` where the model has it, else the first).
    #[arg(long, value_name = "NAME")]
    clip: Option<String>,
    /// The polygon budget P.
    #[arg(long, default_value_t = BUDGET, value_parser = clap::value_parser!(u32).range(1..))]
    budget: u32,
}

fn default_model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/characters/RobotExpressive.glb")
}

#[derive(Component)]
struct MainCamera;

#[derive(Component)]
struct Label;

#[derive(Resource)]
struct Character {
    file: String,
    clip_name: Option<String>,
    gltf: Handle<Gltf>,
    root: Entity,
    /// The clip's graph and node once it plays.
    clip: Option<(Handle<AnimationGraph>, AnimationNodeIndex)>,
    /// Centre and height of the character as first posed, once measured.
    framed: Option<(Vec3, f32)>,
    orbit: bool,
    orbit_angle: f32,
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut character: ResMut<Character>,
    mut images: ResMut<Assets<Image>>,
    shots: Option<Res<Shots>>,
) {
    character.gltf = asset_server.load(character.file.clone());
    let scene = asset_server.load(GltfAssetLabel::Scene(0).from_asset(character.file.clone()));
    character.root = commands
        .spawn((
            WorldAssetRoot(scene),
            MultiresScene::default(),
            Transform::default(),
        ))
        .id();
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(1.0, 2.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 2.0, 8.0).looking_at(Vec3::Y, Vec3::Y),
        // The label and the overlay's counts are drawn into this camera's image too.
        IsDefaultUiCamera,
        MainCamera,
        FlyCamera {
            enabled: false,
            speed: 2.0,
        },
    ));
    if shots.is_some() {
        let handle = common::offscreen_image(&mut images, (SHOT_SIZE.0, SHOT_SIZE.1));
        camera.insert(RenderTarget::Image(handle.clone().into()));
        commands.insert_resource(ShotTarget(handle));
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

/// Starts the clip on the scene's `AnimationPlayer` once the glTF and the player are there.
fn play_clip(
    mut commands: Commands,
    mut character: ResMut<Character>,
    gltfs: Res<Assets<Gltf>>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    asset_server: Res<AssetServer>,
    mut players: Query<(Entity, &mut AnimationPlayer), Without<AnimationGraphHandle>>,
    mut exit: MessageWriter<AppExit>,
) {
    if character.clip.is_some() {
        return;
    }
    if let Some(bevy::asset::LoadState::Failed(e)) = asset_server.get_load_state(&character.gltf) {
        error!("cannot load {}: {e}", character.file);
        exit.write(AppExit::error());
        return;
    }
    let Some(gltf) = gltfs.get(&character.gltf) else {
        return;
    };
    let Some((entity, mut player)) = players.iter_mut().next() else {
        return;
    };
    let name = character.clip_name.clone().or_else(|| {
        gltf.named_animations
            .contains_key(DEFAULT_CLIP)
            .then(|| DEFAULT_CLIP.to_owned())
    });
    let clip = match common::pick_clip(gltf, &character.file, name.as_deref()) {
        Ok(clip) => clip,
        Err(e) => {
            error!("{e}");
            exit.write(AppExit::error());
            return;
        }
    };
    let (graph, node) = AnimationGraph::from_clip(clip);
    let graph = graphs.add(graph);
    player.play(node).repeat();
    commands
        .entity(entity)
        .insert(AnimationGraphHandle(graph.clone()));
    info!("playing {:?}", name.as_deref().unwrap_or("the first clip"));
    character.clip_name = name;
    character.clip = Some((graph, node));
}

/// Measures the character once its models are ready (the plugin's [`MultiresModelReady`]
/// messages) and aims the camera at it.
fn frame_camera(
    mut ready: MessageReader<MultiresModelReady>,
    mut character: ResMut<Character>,
    roots: Query<&MultiresSceneModels>,
    instances: Query<(&MultiresInstance, &GlobalTransform)>,
    fixed: Query<(&Aabb, &GlobalTransform)>,
    mut camera: Query<&mut Transform, With<MainCamera>>,
) {
    if ready.read().count() == 0 || character.framed.is_some() {
        return;
    }
    let Ok(models) = roots.get(character.root) else {
        return;
    };
    let Some((lo, hi)) = common::scene_bounds(models, &instances, &fixed) else {
        return;
    };
    let (centre, height) = ((lo + hi) * 0.5, hi.y - lo.y);
    info!("character: {height:.3} units tall");
    character.framed = Some((centre, height));
    if let Ok(mut transform) = camera.single_mut() {
        *transform = orbit_view(centre, height, 0.0);
    }
}

fn orbit_view(centre: Vec3, height: f32, angle: f32) -> Transform {
    let eye = centre + Vec3::new(angle.sin(), 0.25, angle.cos()) * 1.9 * height;
    Transform::from_translation(eye).looking_at(centre, Vec3::Y)
}

fn orbit_camera(
    time: Res<Time>,
    mut character: ResMut<Character>,
    shots: Option<Res<Shots>>,
    mut camera: Query<&mut Transform, With<MainCamera>>,
) {
    let Some((centre, height)) = character.framed else {
        return;
    };
    if !character.orbit || shots.is_some() {
        return;
    }
    character.orbit_angle += time.delta_secs() * 0.3;
    if let Ok(mut transform) = camera.single_mut() {
        *transform = orbit_view(centre, height, character.orbit_angle);
    }
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut character: ResMut<Character>,
    mut budget: ResMut<PolygonBudget>,
    mut overlay: ResMut<AslodOverlay>,
    mut players: Query<&mut AnimationPlayer>,
    mut cameras: Query<&mut FlyCamera>,
) {
    if input.just_pressed(KeyCode::KeyO) {
        overlay.0 = !overlay.0;
    }
    if input.just_pressed(KeyCode::ArrowUp) {
        budget.total = ((budget.total as f32 * 1.25) as u32).min(10_000_000);
    }
    if input.just_pressed(KeyCode::ArrowDown) {
        budget.total = ((budget.total as f32 * 0.8) as u32).max(50);
    }
    if input.just_pressed(KeyCode::KeyC) {
        character.orbit = !character.orbit;
        for mut fly in &mut cameras {
            fly.enabled = !character.orbit;
        }
    }
    if input.just_pressed(KeyCode::Space) {
        for mut player in &mut players {
            if player.all_paused() {
                player.resume_all();
            } else {
                player.pause_all();
            }
        }
    }
}

fn update_label(
    stats: Res<AslodStats>,
    budget: Res<PolygonBudget>,
    mut label: Query<&mut Text, With<Label>>,
) {
    let text = format!(
        "{} triangles ({} multiresolution + {} fixed) / P = {}\n\
         deform {:.2} ms, {} vertices blended, {} regions changed\n\
         Up/Down: P  O: overlay  Space: pause  C: camera",
        stats.triangles + u64::from(stats.fixed_cost),
        stats.triangles,
        stats.fixed_cost,
        budget.total,
        stats.deform_ms,
        stats.vertices_blended,
        stats.regions_changed,
    );
    for mut label in &mut label {
        if label.0 != text {
            label.0.clone_from(&text);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Headless screenshots.

#[derive(Resource)]
struct ShotTarget(Handle<Image>);

const SHOT_NAMES: [&str; 2] = ["character", "character_overlay"];

#[derive(Resource)]
struct Shots {
    dir: PathBuf,
    frames: u32,
    wait: u32,
    index: usize,
    pending: bool,
    attempts: u32,
    /// When the wait for the character began (see [`MAX_LOADING`]).
    loading_since: Option<Instant>,
}

#[allow(clippy::too_many_arguments)]
fn drive_shots(
    mut commands: Commands,
    mut shots: ResMut<Shots>,
    character: Res<Character>,
    mut overlay: ResMut<AslodOverlay>,
    target: Option<Res<ShotTarget>>,
    stats: Res<AslodStats>,
    roots: Query<&MultiresSceneModels>,
    instances: Query<(&MultiresModel, &MultiresInstance)>,
    assets: Res<Assets<MultiresMesh>>,
    mut exit: MessageWriter<AppExit>,
) {
    if character.framed.is_none() || character.clip.is_none() {
        let since = *shots.loading_since.get_or_insert_with(Instant::now);
        if since.elapsed() > MAX_LOADING {
            error!(
                "{} is not ready after {} s: framed {}, clip playing {} (it needs an AnimationPlayer and a clip)",
                character.file,
                MAX_LOADING.as_secs(),
                character.framed.is_some(),
                character.clip.is_some()
            );
            exit.write(AppExit::error());
        }
        return;
    }
    if shots.pending {
        return;
    }
    if shots.index == SHOT_NAMES.len() {
        let result = roots
            .get(character.root)
            .map_err(|e| e.to_string())
            .and_then(|models| {
                write_counts(&shots.dir, &character, &stats, models, &instances, &assets)
            });
        match result {
            Ok(()) => exit.write(AppExit::Success),
            Err(e) => {
                error!("cannot write counts.json: {e}");
                exit.write(AppExit::error())
            }
        };
        return;
    }
    overlay.0 = SHOT_NAMES[shots.index].ends_with("overlay");
    if shots.wait > 0 {
        shots.wait -= 1;
        return;
    }
    let Some(target) = target else {
        return;
    };
    shots.pending = true;
    commands
        .spawn(Screenshot::image(target.0.clone()))
        .observe(on_captured);
}

fn on_captured(captured: On<ScreenshotCaptured>, mut shots: ResMut<Shots>) {
    shots.pending = false;
    let Some(name) = SHOT_NAMES.get(shots.index) else {
        return;
    };
    if !common::is_drawn(&captured) && shots.attempts < 60 {
        shots.attempts += 1;
        shots.wait = 5;
        return;
    }
    common::save_capture(&captured, &shots.dir.join(format!("{name}.png")));
    shots.attempts = 0;
    shots.index += 1;
    shots.wait = shots.frames;
}

fn write_counts(
    dir: &Path,
    character: &Character,
    stats: &AslodStats,
    models: &MultiresSceneModels,
    instances: &Query<(&MultiresModel, &MultiresInstance)>,
    assets: &Assets<MultiresMesh>,
) -> Result<(), String> {
    let mut regions = Vec::new();
    for (m, model) in models.models().enumerate() {
        let Ok((handle, instance)) = instances.get(model) else {
            continue;
        };
        let kinds = assets
            .get(&handle.0)
            .and_then(|a| a.skin().map(|s| s.kinds().to_vec()));
        for (r, region) in instance.regions().regions().iter().enumerate() {
            let kind = match kinds.as_ref().and_then(|k| k.get(r)) {
                Some(SkinRegionKind::Rigid { .. }) => "rigid",
                Some(SkinRegionKind::Deformable { .. }) => "deformable",
                None => "static",
            };
            regions.push(serde_json::json!({
                "model": m,
                "region": r,
                "kind": kind,
                "triangles": instance.caches().triangle_count(r),
                "min": region.min_triangles(),
                "max": region.max_triangles(),
            }));
        }
    }
    let json = serde_json::json!({
        "model": character.file,
        "clip": character.clip_name,
        "budget": stats.budget,
        "triangles": stats.triangles + u64::from(stats.fixed_cost),
        "multires_triangles": stats.triangles,
        "fixed_triangles": stats.fixed_cost,
        "skinned_models": models.skinned.len(),
        "fixed_meshes": models.fixed.len(),
        "vertices_with_more_than_two_influences": models.more_than_two,
        "vertices_blended_last_frame": stats.vertices_blended,
        "deform_ms_last_frame": stats.deform_ms,
        "regions": regions,
    });
    let path = dir.join("counts.json");
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    info!("saved {}", path.display());
    Ok(())
}
