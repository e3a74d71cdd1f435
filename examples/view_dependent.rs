//! View-dependent refinement (Güdükbay et al., Figures 9-11): the Stanford bunny refined per
//! frame for a phantom camera whose frustum is drawn, seen from a second camera.
//!
//! Controls: Left/Right orbit the phantom, Up/Down move it in and out; `1` frustum, `2` back
//! faces, `3` screen-space error (on: the most detail within the budget P; off: no budget);
//! `[`/`]` halve or double the least tolerance τ₀ (`0` none), PageUp/PageDown change P, `F`
//! the wireframe.
//!
//! `--headless --frames N --screenshot DIR` renders offscreen (no window), waits N frames per
//! shot, and writes `frustum.png` (detail inside the phantom's frustum only), `orientation.png`
//! (on the side facing it only), `screen_space.png` (under τ = 2 pixels of error from it) and
//! `counts.json` (the triangles of each).

mod common;

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::tasks::{AsyncComputeTaskPool, Task, TaskPool, futures::check_ready};
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, MultiresError, MultiresInstance, MultiresMesh, MultiresModel,
    PartitionSpec, PolygonBudget, RefineCamera, ViewDependent,
};
use bevy_aslod::prelude::BuildOptions;
use bevy_aslod::refine::Criteria;
use clap::Parser;
use std::path::PathBuf;

const BUNNY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/meshes/stanford-bunny.obj"
);
/// The phantom camera's vertical field of view.
const PHANTOM_FOV: f32 = 0.4;

/// Güdükbay et al.'s phantom camera over the Stanford bunny.
#[derive(Parser, Debug)]
struct Args {
    /// Render offscreen, no window: the three shots and counts.json, then exit.
    #[arg(long)]
    headless: bool,
    /// Frames to wait before each shot.
    #[arg(long, default_value_t = 30)]
    frames: u32,
    /// Where the headless run writes.
    #[arg(long, value_name = "DIR", default_value = "view-dependent-shots")]
    screenshot: PathBuf,
    /// The headless image size.
    #[arg(long, value_name = "WxH", default_value = "960x540", value_parser = common::parse_size)]
    size: (u32, u32),
}

fn main() {
    let args = Args::parse();
    let mut app = App::new();
    common::add_default_plugins(&mut app, args.headless, "bevy_aslod: view-dependent", None);
    app.add_plugins(AslodPlugin::default().with_budget(20_000))
        .insert_resource(ClearColor(Color::srgb(0.93, 0.93, 0.9)))
        .insert_resource(Wireframe(true))
        .insert_resource(Phantom {
            angle: 0.9,
            distance: 1.3,
        })
        .add_systems(Startup, setup)
        .add_systems(
            Update,
            (finish_bunny, place_phantom, draw_gizmos, label).chain(),
        );
    if args.headless {
        if let Err(e) = std::fs::create_dir_all(&args.screenshot) {
            eprintln!(
                "view_dependent: cannot create {}: {e}",
                args.screenshot.display()
            );
            std::process::exit(1);
        }
        app.insert_resource(Shots::new(args.screenshot, args.frames, args.size))
            .add_systems(
                Update,
                drive_shots.after(finish_bunny).before(place_phantom),
            );
    } else {
        app.add_systems(Update, keys.before(place_phantom));
    }
    app.run();
}

#[derive(Component)]
struct PhantomCamera;

/// Where the phantom is: its angle round the bunny and its distance.
#[derive(Resource)]
struct Phantom {
    angle: f32,
    distance: f32,
}

/// Whether the wireframe of the shown level is drawn.
#[derive(Resource)]
struct Wireframe(bool);

#[derive(Resource)]
struct Build(Task<Result<MultiresMesh, MultiresError>>);

#[derive(Resource)]
struct ShotTarget(Handle<Image>);

fn setup(mut commands: Commands, mut images: ResMut<Assets<Image>>, shots: Option<Res<Shots>>) {
    // Regions for when the refinement is off, and the whole bunny as one variable mesh.
    let task = AsyncComputeTaskPool::get_or_init(TaskPool::default).spawn(async {
        let (mut mesh, _) = IndexedMesh::load(BUNNY)?;
        // The scan has no normals: smooth ones, weighted by the triangles' areas.
        let mut normals = vec![Vec3::ZERO; mesh.positions.len()];
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            let n = (b - a).cross(c - a);
            t.iter().for_each(|&v| normals[v as usize] += n);
        }
        mesh.normals = Some(
            normals
                .into_iter()
                .map(|n| n.normalize_or(Vec3::Y))
                .collect(),
        );
        let partition = PartitionSpec::Clusters(16).partition(&mesh)?;
        MultiresMesh::from_indexed(&mesh, &partition)?
            .with_refinement(&mesh, &BuildOptions::default())
    });
    commands.insert_resource(Build(task));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(-1.0, 2.0, 1.5).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut viewer = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(-1.6, 1.5, 2.3).looking_at(Vec3::new(0.35, 0.65, 0.0), Vec3::Y),
    ));
    if let Some(shots) = shots {
        let handle = common::offscreen_image(&mut images, shots.size);
        viewer.insert(RenderTarget::Image(handle.clone().into()));
        commands.insert_resource(ShotTarget(handle));
    }
    // The phantom: it renders nothing, the bunny refines for it.
    commands.spawn((
        Camera3d::default(),
        Camera {
            is_active: false,
            ..default()
        },
        Projection::Perspective(PerspectiveProjection {
            fov: PHANTOM_FOV,
            aspect_ratio: 16.0 / 9.0,
            ..default()
        }),
        RefineCamera,
        PhantomCamera,
    ));
    commands.spawn((
        Text::default(),
        Node {
            position_type: PositionType::Absolute,
            top: px(8),
            left: px(8),
            ..default()
        },
        TextColor(Color::BLACK),
    ));
}

/// Spawns the bunny (ten times its size, standing at the origin) once its asset is built.
fn finish_bunny(
    mut commands: Commands,
    build: Option<ResMut<Build>>,
    mut multires: ResMut<Assets<MultiresMesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(mut build) = build else { return };
    let Some(result) = check_ready(&mut build.0) else {
        return;
    };
    commands.remove_resource::<Build>();
    match result {
        Ok(asset) => {
            commands.spawn((
                MultiresModel(multires.add(asset)),
                ViewDependent::default(),
                MeshMaterial3d(materials.add(Color::srgb(0.75, 0.62, 0.5))),
                Transform::from_scale(Vec3::splat(10.0))
                    .with_translation(Vec3::new(0.17, -0.33, 0.015)),
            ));
        }
        Err(e) => {
            error!("cannot build the bunny: {e}");
            exit.write(AppExit::error());
        }
    }
}

fn place_phantom(phantom: Res<Phantom>, mut camera: Single<&mut Transform, With<PhantomCamera>>) {
    let target = Vec3::new(-0.2, 1.0, 0.0);
    let eye = target + Quat::from_rotation_y(phantom.angle) * Vec3::new(0.0, 0.3, phantom.distance);
    camera.set_if_neq(Transform::from_translation(eye).looking_at(target, Vec3::Y));
}

/// The phantom's frustum (to a depth past the bunny) and the wireframe of the shown level.
fn draw_gizmos(
    mut gizmos: Gizmos,
    phantom: Single<(&GlobalTransform, &Projection), With<PhantomCamera>>,
    wireframe: Res<Wireframe>,
    levels: Query<(&GlobalTransform, &Mesh3d, &ViewVisibility)>,
    meshes: Res<Assets<Mesh>>,
) {
    let (eye, projection) = *phantom;
    if let Projection::Perspective(p) = projection {
        let far = 4.0;
        let (h, w) = (
            (p.fov * 0.5).tan() * far,
            (p.fov * 0.5).tan() * far * p.aspect_ratio,
        );
        let corners = [(-w, -h), (w, -h), (w, h), (-w, h)]
            .map(|(x, y)| eye.transform_point(Vec3::new(x, y, -far)));
        let red = Color::srgb(0.85, 0.1, 0.1);
        for (i, &c) in corners.iter().enumerate() {
            gizmos.line(eye.translation(), c, red);
            gizmos.line(c, corners[(i + 1) % 4], red);
        }
    }
    if !wireframe.0 {
        return;
    }
    for (transform, mesh, visible) in &levels {
        let Some(mesh) = meshes.get(&mesh.0).filter(|_| visible.get()) else {
            continue;
        };
        let (Some(indices), Some(positions)) = (
            mesh.indices(),
            mesh.attribute(Mesh::ATTRIBUTE_POSITION)
                .and_then(|a| a.as_float3()),
        ) else {
            continue;
        };
        let at = |i: usize| transform.transform_point(Vec3::from(positions[i]));
        let ink = Color::srgba(0.1, 0.1, 0.2, 0.6);
        let indices: Vec<usize> = indices.iter().collect();
        for t in indices.chunks_exact(3) {
            gizmos.linestrip([at(t[0]), at(t[1]), at(t[2]), at(t[0])], ink);
        }
    }
}

fn label(
    stats: Res<AslodStats>,
    models: Query<(&MultiresInstance, &ViewDependent)>,
    mut text: Single<&mut Text>,
) {
    let Ok((instance, settings)) = models.single() else {
        return;
    };
    let c = settings.criteria;
    let on = |b: bool| if b { "on" } else { "off" };
    let tau = instance
        .refinement()
        .map_or(String::new(), |r| format!("τ = {:.2} px", r.tolerance_px));
    text.0 = format!(
        "{} / {} triangles, {tau}\n1 frustum: {}  2 back faces: {}  3 screen-space (budget): {}  τ₀ = {:?}\n\
         Left/Right/Up/Down: phantom  [ ]: τ₀  PageUp/PageDown: P  F: wireframe",
        stats.triangles,
        stats.budget,
        on(c.frustum),
        on(c.back_facing),
        on(settings.budgeted),
        settings.tolerance_px,
    );
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    time: Res<Time>,
    mut phantom: ResMut<Phantom>,
    mut budget: ResMut<PolygonBudget>,
    mut wireframe: ResMut<Wireframe>,
    mut models: Query<&mut ViewDependent>,
) {
    let dt = time.delta_secs();
    let axis = |neg, pos| (input.pressed(pos) as i8 - input.pressed(neg) as i8) as f32 * dt;
    phantom.angle += axis(KeyCode::ArrowLeft, KeyCode::ArrowRight) * 1.2;
    phantom.distance =
        (phantom.distance + axis(KeyCode::ArrowUp, KeyCode::ArrowDown) * 1.5).clamp(0.6, 8.0);
    if input.just_pressed(KeyCode::PageUp) {
        budget.total = (budget.total * 3 / 2).min(200_000);
    }
    if input.just_pressed(KeyCode::PageDown) {
        budget.total = (budget.total * 2 / 3).max(500);
    }
    if input.just_pressed(KeyCode::KeyF) {
        wireframe.0 = !wireframe.0;
    }
    for mut settings in &mut models {
        let mut s = settings.clone();
        if input.just_pressed(KeyCode::Digit1) {
            s.criteria.frustum = !s.criteria.frustum;
        }
        if input.just_pressed(KeyCode::Digit2) {
            s.criteria.back_facing = !s.criteria.back_facing;
        }
        if input.just_pressed(KeyCode::Digit3) {
            s.budgeted = !s.budgeted;
        }
        if input.just_pressed(KeyCode::BracketLeft) {
            s.tolerance_px = s.tolerance_px.map(|t| t * 0.5).filter(|&t| t >= 0.125);
        }
        if input.just_pressed(KeyCode::BracketRight) {
            s.tolerance_px = Some(s.tolerance_px.map_or(0.25, |t| (t * 2.0).min(64.0)));
        }
        settings.set_if_neq(s);
    }
}

// ---------------------------------------------------------------------------------------------
// Headless screenshots.

/// The headless run: which shot is next, and the counts so far.
#[derive(Resource)]
struct Shots {
    dir: PathBuf,
    size: (u32, u32),
    frames: u32,
    index: usize,
    wait: u32,
    pending: bool,
    attempts: u32,
    counts: serde_json::Map<String, serde_json::Value>,
}

/// Each shot: its name and the settings it shows (no budget: the criterion alone decides).
fn shot(index: usize) -> Option<(&'static str, ViewDependent)> {
    let none = ViewDependent::default()
        .with_budgeted(false)
        .with_criteria(Criteria::default());
    Some(match index {
        0 => (
            "frustum",
            none.with_criteria(Criteria::default().with_frustum(true)),
        ),
        1 => (
            "orientation",
            none.with_criteria(Criteria::default().with_back_facing(true)),
        ),
        2 => ("screen_space", none.with_tolerance_px(Some(2.0))),
        _ => return None,
    })
}

impl Shots {
    fn new(dir: PathBuf, frames: u32, size: (u32, u32)) -> Self {
        Self {
            dir,
            size,
            frames: frames.max(2),
            index: 0,
            wait: frames.max(2),
            pending: false,
            attempts: 0,
            counts: serde_json::Map::new(),
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn drive_shots(
    mut commands: Commands,
    mut shots: ResMut<Shots>,
    target: Res<ShotTarget>,
    mut wireframe: ResMut<Wireframe>,
    mut models: Query<(&MultiresInstance, &MultiresModel, &mut ViewDependent)>,
    assets: Res<Assets<MultiresMesh>>,
    stats: Res<AslodStats>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some((name, settings)) = shot(shots.index) else {
        let counts = serde_json::Value::Object(std::mem::take(&mut shots.counts));
        let path = shots.dir.join("counts.json");
        if let Err(e) = std::fs::write(&path, format!("{counts:#}\n")) {
            error!("cannot write {}: {e}", path.display());
            exit.write(AppExit::error());
        } else {
            info!("wrote {}", path.display());
            exit.write(AppExit::Success);
        }
        return;
    };
    let Ok((instance, model, mut current)) = models.single_mut() else {
        return; // the bunny is still building
    };
    current.set_if_neq(settings);
    // The wireframe only on the frames captured: drawing it is most of a headless frame.
    wireframe.0 = shots.pending;
    if shots.pending {
        return;
    }
    if shots.wait > 0 {
        shots.wait -= 1;
        return;
    }
    let asset = assets.get(&model.0);
    let triangles = instance.triangle_count();
    info!("{name}: {triangles} triangles, {:?}", instance.refinement());
    shots.counts.insert(
        name.to_string(),
        serde_json::json!({
            "triangles": triangles,
            "full_detail": asset.map(MultiresMesh::max_triangles),
            "coarsest": asset.and_then(|a| a.variable()).map(|v| v.mesh().min_triangles()),
            "shown_by_the_plugin": stats.triangles,
        }),
    );
    shots.pending = true;
    wireframe.0 = true;
    commands
        .spawn(Screenshot::image(target.0.clone()))
        .observe(on_captured);
}

/// Saves a captured frame, or asks for another while nothing has been drawn yet.
fn on_captured(captured: On<ScreenshotCaptured>, mut shots: ResMut<Shots>) {
    let Some((name, _)) = shot(shots.index) else {
        return;
    };
    let drawn = common::is_drawn(&captured);
    if !drawn && shots.attempts < 40 {
        // The pipelines are still compiling (slow on a software rasteriser): try again.
        shots.attempts += 1;
        shots.wait = shots.frames / 2;
        shots.pending = false;
        return;
    }
    common::save_capture(&captured, &shots.dir.join(format!("{name}.png")));
    shots.attempts = 0;
    shots.index += 1;
    shots.wait = shots.frames;
    shots.pending = false;
}
