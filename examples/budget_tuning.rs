//! Which polygon budget to choose, and a budget in milliseconds, judged along a camera path.
//!
//! Renders offscreen (an `Image` target, no window; lavapipe without a GPU), one `update` per
//! frame. A frame's time is the wall time of its `update`: pipelined rendering is off, so it
//! holds the render world's work and the driver's as well. Scenes (`--scene`):
//! - `terrain`: Silvretta's 135,200-triangle terrain in 6×6 regions (ASLOD Figure 8), flown
//!   over low from a corner towards the middle while the camera turns;
//! - `crowd`: `--count N` dancing mannequins (`assets/mannequin.glb`, skinned), the camera
//!   coming in from afar to a close-up and out again round the side;
//! - the path of a `.glb` or `.gltf` file: a scene of one's own as a `MultiresScene` (its first
//!   clip playing if it has one), the camera orbiting it, closest half-way.
//!
//! Every frame is a function of its number (the camera's place and each dancer's pose), so
//! every run of the path shows the same frames.
//!
//! **The sweep** (`budget_tuning --scene S --out DIR [--budgets P,P,...]`): plays the path at
//! full detail and at each budget (by default the scene's full-detail triangles halved 1 to 8
//! times, those under the scene's floor left out), `--repeat R` times, interleaved; then, dancers still, renders `--views V` points of
//! the path at `--error-size` at each budget and at full detail. Writes `sweep.csv` (per
//! budget: median and p95 frame, triangles drawn, PSNR against full detail over the views),
//! `frames.csv`, `error_vs_budget.png`, `frame_vs_budget.png` and `summary.json`, which names
//! the knee, the budget past which more triangles buy the least PSNR (the point of the PSNR
//! curve over log P furthest above the chord between its ends; none where the curve never
//! bends that way), and the cheapest budget whose median PSNR reaches `--good-psnr` (40 dB by
//! default).
//!
//! **The controller** (`--target-ms T`): plays the path under `PolygonBudget::target_ms(T,
//! --min..=--max)` and at a fixed `--budget P`, interleaved `--repeat` times. At frame
//! `--step-at F` (the middle by default; `--no-step` for none) 50 rocks spawn in view, a load
//! step: plain 5,120-triangle meshes, which the budget does not count (models under the
//! budget are no load step: it absorbs them). Writes `control.csv` (every frame of every
//! run), `control.png` (frame time and P along the path), `after_step.png` (the view ten
//! frames after the step) and `summary.json`: the fixed run's fastest and slowest frame; the
//! controlled runs' median and p95 frame against T; the frames the controller took after the
//! step to bring its smoothed frame time back within 10% of T (for 10 frames in a row); how
//! much P moves between frames in steady state (frames within 10% of T); and whether the
//! triangles stayed within P.

mod common;

use bevy::camera::RenderTarget;
use bevy::camera::primitives::Aabb;
use bevy::ecs::system::RunSystemOnce;
use bevy::gltf::Gltf;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::{WorldAsset, WorldAssetRoot};
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, FrameSource, FullDetail, MultiresInstance, MultiresMesh,
    MultiresModel, MultiresModelReady, MultiresScene, MultiresSceneConverted, MultiresSceneModels,
    PolygonBudget,
};
use bevy_aslod::regions::{GridPlane, Partition};
use clap::Parser;
use common::stats::median;
use common::terrain;
use serde_json::json;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The project's own assets (the mannequin).
const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets");
/// Models the load step spawns.
const STEP_MODELS: usize = 50;
/// Frames before each measured pass: pipelines, levels and the controller settle.
const WARMUP_FRAMES: u32 = 60;
/// Seconds of dance per frame of the path.
const DANCE_SECONDS_PER_FRAME: f32 = 1.0 / 30.0;
/// The band around the target within which the frame time counts as settled.
const SETTLE_BAND: f64 = 0.10;
/// Frames the smoothed frame time stays in that band to count as settled.
const SETTLED_FOR: usize = 10;

/// Which budget to choose: a sweep of budgets along a camera path, or a budget in ms.
#[derive(Parser, Debug)]
struct Args {
    /// `terrain`, `crowd`, or the path of a `.glb`/`.gltf` file.
    #[arg(long, default_value = "terrain")]
    scene: String,
    /// Dancers in the crowd.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=2000))]
    count: u32,
    /// The folder the reports go to.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Frames along the camera path.
    #[arg(long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(10..))]
    frames: u32,
    /// Passes of the path per budget (or per way, with `--target-ms`), interleaved.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=50))]
    repeat: u32,
    /// The image the frames are timed at.
    #[arg(long, value_name = "WxH", default_value = "240x135", value_parser = common::parse_size)]
    size: (u32, u32),
    /// The image the PSNR is measured at.
    #[arg(long, value_name = "WxH", default_value = "640x360", value_parser = common::parse_size)]
    error_size: (u32, u32),
    /// Points of the path where the PSNR is measured.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=64))]
    views: u32,
    /// The budgets of the sweep (default: full detail halved 1 to 8 times).
    #[arg(
        long,
        value_name = "P,P",
        value_delimiter = ',',
        conflicts_with = "target_ms"
    )]
    budgets: Vec<u32>,
    /// Aim at frames of this many milliseconds instead of sweeping.
    #[arg(long, value_name = "MS")]
    target_ms: Option<f32>,
    /// The PSNR (dB) against full detail a budget must reach to be suggested as good enough.
    #[arg(long, default_value_t = 40.0, conflicts_with = "target_ms")]
    good_psnr: f64,
    /// With `--target-ms`: the fixed budget run beside it (default: a quarter of full detail
    /// for the terrain and a glTF, 100,000 for the crowd).
    #[arg(long, requires = "target_ms")]
    budget: Option<u32>,
    /// With `--target-ms`: the smallest P the controller may set (default: what every model
    /// at its coarsest draws, the load step's too, and at least 500).
    #[arg(long, requires = "target_ms")]
    min: Option<u32>,
    /// With `--target-ms`: the largest P it may set (default: full detail).
    #[arg(long, requires = "target_ms")]
    max: Option<u32>,
    /// With `--target-ms`: the frame of the path at which 50 models spawn (default: the middle).
    #[arg(long, requires = "target_ms", conflicts_with = "no_step")]
    step_at: Option<u32>,
    /// With `--target-ms`: no load step.
    #[arg(long, requires = "target_ms")]
    no_step: bool,
    /// With `--target-ms`: Bevy's `RenderDiagnosticsPlugin`, so the controller reads GPU
    /// timestamps where the device has them (`FrameSource::GpuTimestamps`).
    #[arg(long, requires = "target_ms")]
    gpu_timestamps: bool,
}

fn main() {
    let args = Args::parse();
    if let Err(e) = run(&args) {
        eprintln!("budget_tuning: {e}");
        std::process::exit(1);
    }
}

fn run(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("create {}: {e}", args.out.display()))?;
    let mut scene = Scene::new(args)?;
    match args.target_ms {
        Some(ms) => control(&mut scene, args, ms),
        None => sweep(&mut scene, args),
    }
}

// ---------------------------------------------------------------------------------------
// The scenes.

/// What the scene is made of.
enum Kind {
    Terrain,
    Crowd,
    Gltf,
}

/// A scene ready to play: its app, camera, path and what the load step spawns.
struct Scene {
    app: App,
    kind: Kind,
    camera: Entity,
    /// The timing target and the PSNR target.
    small: Handle<Image>,
    large: Handle<Image>,
    /// The camera along the path, `u` in `0..=1`.
    path: Box<dyn Fn(f32) -> Transform>,
    /// Triangles of every model at full detail.
    full: u64,
    /// Triangles of every model at its coarsest (the least any budget draws), without and
    /// with the load step's models.
    floor: u64,
    floor_with_step: u64,
    /// Where the load step's models go.
    step_places: Vec<Vec3>,
    multires: MultiresScene,
    /// The step's models, while they live.
    spawned: Vec<Entity>,
    /// The rock the load step spawns outside the crowd.
    rock: Option<Handle<Mesh>>,
}

/// The animation every dancer plays, once the clip is loaded.
#[derive(Resource, Clone)]
struct Dance {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
    length: f32,
}

impl Scene {
    fn new(args: &Args) -> Result<Self, String> {
        let (root, file) = match args.scene.as_str() {
            "terrain" => (None, None),
            "crowd" => (
                Some(PathBuf::from(ASSETS)),
                Some("mannequin.glb".to_string()),
            ),
            path => {
                let (root, file) = common::split_model_path(Path::new(path))?;
                (Some(root), Some(file))
            }
        };
        let mut app = common::offscreen_app(root.as_deref());
        app.add_plugins(AslodPlugin::default());
        if args.gpu_timestamps {
            app.add_plugins(bevy::render::diagnostic::RenderDiagnosticsPlugin);
        }
        app.finish();
        app.cleanup();
        // The controller reads the real frame time (a manual clock would give it 1/60 s).
        app.insert_resource(TimeUpdateStrategy::Automatic);
        let (small, large) = {
            let mut images = app.world_mut().resource_mut::<Assets<Image>>();
            (
                common::offscreen_image(&mut images, args.size),
                common::offscreen_image(&mut images, args.error_size),
            )
        };
        let camera = app
            .world_mut()
            .spawn((
                Camera3d::default(),
                RenderTarget::Image(small.clone().into()),
                Transform::default(),
            ))
            .id();
        app.world_mut().spawn((
            DirectionalLight {
                illuminance: 8_000.0,
                ..default()
            },
            Transform::from_xyz(1.0, 2.0, 0.5).looking_at(Vec3::ZERO, Vec3::Y),
        ));
        app.insert_resource(GlobalAmbientLight {
            brightness: 300.0,
            ..default()
        });
        let mut scene = Self {
            app,
            kind: Kind::Terrain,
            camera,
            small,
            large,
            path: Box::new(|_| Transform::default()),
            full: 0,
            floor: 0,
            floor_with_step: 0,
            step_places: Vec::new(),
            multires: MultiresScene::default(),
            spawned: Vec::new(),
            rock: None,
        };
        match (args.scene.as_str(), root, file) {
            ("terrain", ..) => scene.terrain()?,
            ("crowd", _, Some(file)) => scene.crowd(&file, args.count as usize)?,
            (_, Some(root), Some(file)) => scene.gltf_scene(&root, &file)?,
            _ => unreachable!("every scene has its file"),
        }
        scene.full = scene.full_detail_triangles();
        scene.floor = scene.floor_triangles();
        Ok(scene)
    }

    fn terrain(&mut self) -> Result<(), String> {
        self.kind = Kind::Terrain;
        let mesh = terrain::terrain();
        let partition = Partition::grid(&mesh, GridPlane::XZ, 6, 6).map_err(|e| e.to_string())?;
        let asset = MultiresMesh::from_indexed(&mesh, &partition).map_err(|e| e.to_string())?;
        let world = self.app.world_mut();
        let asset = world.resource_mut::<Assets<MultiresMesh>>().add(asset);
        let material = world
            .resource_mut::<Assets<StandardMaterial>>()
            .add(StandardMaterial::from_color(Color::srgb(0.55, 0.6, 0.45)));
        world.spawn((
            MultiresModel(asset),
            MeshMaterial3d(material),
            Transform::default(),
        ));
        let half = (terrain::SIDE - 1) as f32 * terrain::SPACING * 0.5;
        self.path = Box::new(move |u| {
            let eye = Vec3::new(-half + 4.0, 1.2 * terrain::HEIGHT, -half + 4.0)
                .lerp(Vec3::new(half * 0.3, terrain::HEIGHT, half * 0.3), u);
            let turn = Quat::from_rotation_y((u - 0.5) * std::f32::consts::FRAC_PI_2);
            Transform::from_translation(eye)
                .looking_at(eye + turn * Vec3::new(1.0, -0.6, 1.0), Vec3::Y)
        });
        // Rocks on the ground ahead of the camera's middle stretch.
        self.step_places = (0..STEP_MODELS)
            .map(|i| {
                let along = -0.2 * half + 0.6 * half * (i as f32 / STEP_MODELS as f32);
                let across = ((i * 7) % 11) as f32 * 3.0 - 15.0;
                let (x, z) = (along + across, along - across);
                Vec3::new(x, terrain::height(x, z) + 1.0, z)
            })
            .collect();
        self.make_rock(2.0)
    }

    fn crowd(&mut self, file: &str, count: usize) -> Result<(), String> {
        self.kind = Kind::Crowd;
        let columns = (count as f64).sqrt().ceil() as usize;
        let place = |i: usize, columns: usize, rows: usize| {
            Vec3::new(
                ((i % columns) as f32 - (columns - 1) as f32 * 0.5) * 2.0,
                0.0,
                ((i / columns) as f32 - (rows - 1) as f32 * 0.5) * 2.0,
            )
        };
        let rows = count.div_ceil(columns);
        let at: Vec<Vec3> = (0..count).map(|i| place(i, columns, rows)).collect();
        // The step's dancers join in rows behind the crowd.
        // Rocks on the ground between the dancers nearest the middle.
        let mut between: Vec<Vec3> = (0..count)
            .map(|i| place(i, columns, rows) + Vec3::new(1.0, 0.3, 1.0))
            .collect();
        between.sort_by(|a, b| a.length_squared().total_cmp(&b.length_squared()));
        self.step_places = between.into_iter().take(STEP_MODELS).collect();
        self.make_rock(0.3)?;
        self.load_scene(file, &at)?;
        let extent = (columns.max(rows) as f32) * 1.0 + 1.0;
        self.path = Box::new(move |u| {
            // In from afar in front, to a close-up in the middle of the crowd, and out round
            // the side.
            let angle = u * std::f32::consts::PI;
            let radius = extent * (2.4 - 2.1 * (u * std::f32::consts::PI).sin());
            let eye = Vec3::new(
                angle.sin() * radius,
                1.6 + 0.4 * radius,
                angle.cos() * radius,
            );
            Transform::from_translation(eye).looking_at(Vec3::new(0.0, 0.9, 0.0), Vec3::Y)
        });
        Ok(())
    }

    fn gltf_scene(&mut self, root: &Path, file: &str) -> Result<(), String> {
        self.kind = Kind::Gltf;
        self.multires = common::multires_scene(root, file);
        self.load_scene(file, &[Vec3::ZERO])?;
        let (lo, hi) = self.bounds()?;
        let (centre, extent) = ((lo + hi) * 0.5, (hi - lo).length().max(1e-3));
        self.path = Box::new(move |u| {
            let angle = u * std::f32::consts::TAU;
            let radius = extent * (1.8 - 0.8 * (u * std::f32::consts::PI).sin());
            let eye = centre + Vec3::new(angle.sin() * radius, 0.25 * extent, angle.cos() * radius);
            Transform::from_translation(eye).looking_at(centre, Vec3::Y)
        });
        self.step_places = (0..STEP_MODELS)
            .map(|i| {
                let a = i as f32 * 2.4;
                centre + Vec3::new(a.sin(), 0.0, a.cos()) * extent * (0.8 + 0.02 * i as f32)
            })
            .collect();
        self.make_rock(extent * 0.05)
    }

    /// A 5,120-triangle sphere of radius `r`, the load step's rock: a plain Bevy mesh, which
    /// the budget does not count.
    fn make_rock(&mut self, r: f32) -> Result<(), String> {
        let sphere = Sphere::new(r).mesh().ico(4).map_err(|e| e.to_string())?;
        self.rock = Some(
            self.app
                .world_mut()
                .resource_mut::<Assets<Mesh>>()
                .add(sphere),
        );
        Ok(())
    }

    /// Spawns the glTF's first scene as a `MultiresScene` at each place and waits until every
    /// one is converted (and its clip, if any, loaded and playing).
    fn load_scene(&mut self, file: &str, at: &[Vec3]) -> Result<(), String> {
        let server = self.app.world().resource::<AssetServer>().clone();
        let gltf: Handle<Gltf> = server.load(file.to_string());
        let scene = server.load(GltfAssetLabel::Scene(0).from_asset(file.to_string()));
        let roots = self.spawn_roots(&scene, at);
        let mut messages = self
            .app
            .world()
            .resource::<Messages<MultiresSceneConverted>>()
            .get_cursor();
        let mut waiting: HashSet<Entity> = roots.iter().copied().collect();
        let start = Instant::now();
        loop {
            self.app.update();
            let world = self.app.world();
            for message in messages.read(world.resource::<Messages<MultiresSceneConverted>>()) {
                waiting.remove(&message.scene);
            }
            let converted = waiting.is_empty();
            let loaded = self.app.world().resource::<Assets<Gltf>>().get(&gltf);
            if let (true, Some(loaded)) = (converted, loaded) {
                if let Some(clip) = loaded.animations.first().cloned() {
                    let length = self
                        .app
                        .world()
                        .resource::<Assets<AnimationClip>>()
                        .get(&clip)
                        .map_or(1.0, AnimationClip::duration)
                        .max(1e-3);
                    let (graph, node) = AnimationGraph::from_clip(clip);
                    let graph = self
                        .app
                        .world_mut()
                        .resource_mut::<Assets<AnimationGraph>>()
                        .add(graph);
                    self.app.insert_resource(Dance {
                        graph,
                        node,
                        length,
                    });
                }
                break;
            }
            if start.elapsed() > Duration::from_secs(300) {
                return Err(format!("{file} did not load and convert in five minutes"));
            }
        }
        Ok(())
    }

    fn spawn_roots(&mut self, scene: &Handle<WorldAsset>, at: &[Vec3]) -> Vec<Entity> {
        at.iter()
            .enumerate()
            .map(|(i, &p)| {
                self.app
                    .world_mut()
                    .spawn((
                        WorldAssetRoot(scene.clone()),
                        self.multires.clone(),
                        Transform::from_translation(p)
                            .with_rotation(Quat::from_rotation_y(i as f32 * 2.4)),
                    ))
                    .id()
            })
            .collect()
    }

    /// The world bounds of the converted scenes, measured when the plugin says a model is
    /// ready ([`MultiresModelReady`]) until every model of every scene is.
    fn bounds(&mut self) -> Result<(Vec3, Vec3), String> {
        let mut ready = self
            .app
            .world()
            .resource::<Messages<MultiresModelReady>>()
            .get_cursor();
        for _ in 0..600 {
            self.app.update();
            let world = self.app.world();
            if ready
                .read(world.resource::<Messages<MultiresModelReady>>())
                .count()
                == 0
            {
                continue;
            }
            let bounds = self
                .app
                .world_mut()
                .run_system_once(
                    |roots: Query<&MultiresSceneModels>,
                     instances: Query<(&MultiresInstance, &GlobalTransform)>,
                     fixed: Query<(&Aabb, &GlobalTransform)>| {
                        roots
                            .iter()
                            .map(|m| common::scene_bounds(m, &instances, &fixed))
                            .collect::<Option<Vec<_>>>()
                            .and_then(|b| b.into_iter().reduce(|a, b| (a.0.min(b.0), a.1.max(b.1))))
                    },
                )
                .map_err(|e| e.to_string())?;
            if let Some(bounds) = bounds {
                return Ok(bounds);
            }
        }
        Err("the scene has no bounds: not every model of it became ready in 600 frames".into())
    }

    /// Triangles with every region at full detail.
    fn full_detail_triangles(&mut self) -> u64 {
        self.app.world_mut().resource_mut::<FullDetail>().0 = true;
        self.frame(0);
        self.frame(0);
        self.app.world_mut().resource_mut::<FullDetail>().0 = false;
        self.app.world().resource::<AslodStats>().triangles
    }

    /// Triangles with every region at its coarsest (a budget of 1).
    fn floor_triangles(&mut self) -> u64 {
        let budget = self.app.world().resource::<PolygonBudget>().clone();
        self.set_budget(
            PolygonBudget {
                total: 1,
                ..default()
            },
            false,
        );
        self.frame(0);
        self.frame(0);
        self.set_budget(budget, false);
        self.app.world().resource::<AslodStats>().triangles
    }

    /// Poses the scene for frame `frame` of `frames` (camera, dancers) and draws it; returns
    /// the frame's wall time in milliseconds.
    fn frame_at(&mut self, frame: u32, frames: u32) -> f64 {
        let u = frame as f32 / (frames - 1).max(1) as f32;
        self.pose(u, frame);
        let start = Instant::now();
        self.app.update();
        start.elapsed().as_secs_f64() * 1e3
    }

    fn frame(&mut self, frame: u32) -> f64 {
        self.frame_at(frame, 2)
    }

    /// The camera at `u` along the path, each dancer at its pose for `frame` (dancers are
    /// paused and seeked, so the pose does not depend on frame times).
    fn pose(&mut self, u: f32, frame: u32) {
        let transform = (self.path)(u);
        if let Some(mut t) = self.app.world_mut().get_mut::<Transform>(self.camera) {
            *t = transform;
        }
        let Some(dance) = self.app.world().get_resource::<Dance>().cloned() else {
            return;
        };
        let world = self.app.world_mut();
        let mut players =
            world.query::<(Entity, &mut AnimationPlayer, Has<AnimationGraphHandle>)>();
        let mut new = Vec::new();
        for (entity, mut player, has_graph) in players.iter_mut(world) {
            if !has_graph {
                new.push(entity);
                player.play(dance.node).pause();
            }
            let phase = (entity.index_u32() % 17) as f32 / 17.0 * dance.length;
            if let Some(active) = player.animation_mut(dance.node) {
                active.seek_to(
                    (phase + frame as f32 * DANCE_SECONDS_PER_FRAME).rem_euclid(dance.length),
                );
            }
        }
        for entity in new {
            world
                .entity_mut(entity)
                .insert(AnimationGraphHandle(dance.graph.clone()));
        }
    }

    /// Spawns the load step's models.
    fn step(&mut self) {
        let places = self.step_places.clone();
        self.spawned = match self.rock.clone() {
            Some(rock) => {
                let world = self.app.world_mut();
                let material = world
                    .resource_mut::<Assets<StandardMaterial>>()
                    .add(StandardMaterial::from_color(Color::srgb(0.5, 0.48, 0.45)));
                places
                    .iter()
                    .map(|&p| {
                        world
                            .spawn((
                                Mesh3d(rock.clone()),
                                MeshMaterial3d(material.clone()),
                                Transform::from_translation(p),
                            ))
                            .id()
                    })
                    .collect()
            }
            _ => Vec::new(),
        };
    }

    /// Despawns the load step's models.
    fn unstep(&mut self) {
        for entity in std::mem::take(&mut self.spawned) {
            if let Ok(e) = self.app.world_mut().get_entity_mut(entity) {
                e.despawn();
            }
        }
    }

    fn set_budget(&mut self, budget: PolygonBudget, full_detail: bool) {
        *self.app.world_mut().resource_mut::<PolygonBudget>() = budget;
        self.app.world_mut().resource_mut::<FullDetail>().0 = full_detail;
    }

    fn set_target(&mut self, image: &Handle<Image>) {
        self.app
            .world_mut()
            .entity_mut(self.camera)
            .insert(RenderTarget::Image(image.clone().into()));
    }

    /// Lets the pipelines compile (slowly on a software rasteriser) until the scene is drawn.
    fn wait_until_drawn(&mut self, dir: &Path) -> Result<(), String> {
        self.pose(0.5, 0);
        let captures = common::Captures::new(1);
        self.app.insert_resource(captures.clone());
        common::wait_until_drawn(
            &mut self.app,
            std::slice::from_ref(&self.small),
            &captures,
            dir,
        )?;
        // The step's models once, so their pipelines are compiled before any timed frame.
        self.step();
        for _ in 0..WARMUP_FRAMES {
            self.frame_at(0, 2);
        }
        self.floor_with_step = self.floor_triangles();
        self.unstep();
        Ok(())
    }

    /// A screenshot of the scene at `u` along the path at the PSNR size.
    fn view(&mut self, u: f32, frame: u32) -> Result<Image, String> {
        self.pose(u, frame);
        for _ in 0..4 {
            self.app.update();
        }
        let captures = common::Captures::new(1);
        self.app.insert_resource(captures.clone());
        let large = self.large.clone();
        Ok(common::capture(&mut self.app, std::slice::from_ref(&large), &captures)?.remove(0))
    }
}

// ---------------------------------------------------------------------------------------
// One frame of a run.

/// What a frame of a run recorded.
#[derive(Clone, Copy)]
struct Row {
    frame: u32,
    ms: f64,
    /// `PolygonBudget::total` after the frame (the controller's choice).
    budget: u32,
    /// The plugin's triangles.
    triangles: u64,
    /// The controller's smoothed frame time (0 without a target).
    smoothed_ms: f32,
    state: bevy_aslod::budget::ControllerState,
    source: FrameSource,
}

/// Plays the path: warm-up frames at its start, then `frames` measured ones, the load step's
/// models spawning at `step` and despawned after the run.
fn play(scene: &mut Scene, frames: u32, step: Option<u32>) -> Vec<Row> {
    for _ in 0..WARMUP_FRAMES {
        scene.frame_at(0, frames);
    }
    let mut rows = Vec::with_capacity(frames as usize);
    for frame in 0..frames {
        if step == Some(frame) {
            scene.step();
        }
        let ms = scene.frame_at(frame, frames);
        let world = scene.app.world();
        let stats = world.resource::<AslodStats>();
        rows.push(Row {
            frame,
            ms,
            budget: world.resource::<PolygonBudget>().total,
            triangles: stats.triangles,
            smoothed_ms: stats.frame_ms,
            state: stats.controller,
            source: stats.frame_source,
        });
    }
    scene.unstep();
    rows
}

/// The value at quantile `q` (nearest rank) of `values`.
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn write(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("write {}: {e}", path.display()))
}

fn machine() -> String {
    format!(
        "{} build, {}, {} threads",
        if cfg!(debug_assertions) {
            "dev"
        } else {
            "release"
        },
        common::cpu_name(),
        std::thread::available_parallelism().map_or(0, usize::from)
    )
}

// ---------------------------------------------------------------------------------------
// The sweep.

fn sweep(scene: &mut Scene, args: &Args) -> Result<(), String> {
    let mut budgets = if args.budgets.is_empty() {
        // Budgets under the floor (every model at its coarsest) all draw the floor.
        (1..=8)
            .rev()
            .map(|k| (scene.full >> k).max(1))
            .filter(|&p| p >= scene.floor)
            .map(|p| p.min(u64::from(u32::MAX)) as u32)
            .collect()
    } else {
        args.budgets.clone()
    };
    budgets.sort_unstable();
    budgets.dedup();
    scene.wait_until_drawn(&args.out)?;
    // `None`: full detail, the reference.
    let ways: Vec<Option<u32>> = budgets.iter().copied().map(Some).chain([None]).collect();
    let mut runs: Vec<Vec<Vec<Row>>> = vec![Vec::new(); ways.len()];
    for round in 0..args.repeat {
        for (w, way) in ways.iter().enumerate() {
            eprintln!("budget_tuning: round {}, {}", round + 1, label(*way));
            scene.set_budget(
                PolygonBudget {
                    total: way.unwrap_or(u32::MAX),
                    ..default()
                },
                way.is_none(),
            );
            runs[w].push(play(scene, args.frames, None));
        }
    }
    // The image error, dancers still: every way at each view, the reference first.
    scene.set_target(&scene.large.clone());
    let mut psnr: Vec<Vec<f64>> = vec![Vec::new(); ways.len()];
    for v in 0..args.views {
        let u = (v as f32 + 0.5) / args.views as f32;
        let frame = (u * (args.frames - 1) as f32) as u32;
        scene.set_budget(PolygonBudget::default(), true);
        let reference = scene.view(u, frame)?;
        common::save_image(&reference, &args.out.join(format!("view{v}_full.png")))?;
        for (w, way) in ways.iter().enumerate() {
            let Some(p) = way else {
                psnr[w].push(common::IDENTICAL_PSNR);
                continue;
            };
            scene.set_budget(
                PolygonBudget {
                    total: *p,
                    ..default()
                },
                false,
            );
            let image = scene.view(u, frame)?;
            if w == 0 || w + 2 == ways.len() {
                common::save_image(&image, &args.out.join(format!("view{v}_p{p}.png")))?;
            }
            psnr[w].push(common::psnr_mad(&image, &reference).0);
        }
    }
    scene.set_target(&scene.small.clone());

    let mut csv = String::from("budget,median_ms,p95_ms,triangles,psnr_median,psnr_worst\n");
    let mut frames_csv = String::from("budget,run,frame,frame_ms,triangles\n");
    let mut points = Vec::new();
    for (w, way) in ways.iter().enumerate() {
        let ms: Vec<f64> = runs[w].iter().flatten().map(|r| r.ms).collect();
        let tris: Vec<f64> = runs[w]
            .iter()
            .flatten()
            .map(|r| r.triangles as f64)
            .collect();
        let point = Point {
            budget: way.map_or(scene.full, u64::from),
            median_ms: median(&ms),
            p95_ms: quantile(&ms, 0.95),
            triangles: median(&tris),
            psnr: median(&psnr[w]),
            psnr_worst: psnr[w].iter().copied().fold(f64::INFINITY, f64::min),
        };
        csv += &format!(
            "{},{:.3},{:.3},{:.0},{:.2},{:.2}\n",
            way.map_or("full".to_string(), |p| p.to_string()),
            point.median_ms,
            point.p95_ms,
            point.triangles,
            point.psnr,
            point.psnr_worst
        );
        for (run, rows) in runs[w].iter().enumerate() {
            for r in rows {
                frames_csv += &format!(
                    "{},{run},{},{:.3},{}\n",
                    way.map_or("full".to_string(), |p| p.to_string()),
                    r.frame,
                    r.ms,
                    r.triangles
                );
            }
        }
        points.push(point);
    }
    write(&args.out.join("sweep.csv"), &csv)?;
    write(&args.out.join("frames.csv"), &frames_csv)?;
    let (swept, reference) = points.split_at(points.len() - 1);
    let knee = knee(swept);
    let good = swept.iter().position(|p| p.psnr >= args.good_psnr);
    let marks: Vec<(usize, String)> = knee
        .map(|k| (k, format!("knee: P = {}", swept[k].budget)))
        .into_iter()
        .chain(good.map(|g| {
            (
                g,
                format!("first at {} dB: P = {}", args.good_psnr, swept[g].budget),
            )
        }))
        .collect();
    charts::error_vs_budget(
        &args.out.join("error_vs_budget.png"),
        swept,
        &marks,
        &args.scene,
    )?;
    charts::frame_vs_budget(
        &args.out.join("frame_vs_budget.png"),
        swept,
        &reference[0],
        &marks,
        &args.scene,
        args.size,
    )?;
    let mark = |i: Option<usize>| {
        i.map(|k| {
            json!({
                "budget": swept[k].budget, "median_ms": swept[k].median_ms,
                "psnr_median": swept[k].psnr,
            })
        })
    };
    let summary = json!({
        "scene": args.scene,
        "machine": machine(),
        "size": format!("{}x{}", args.size.0, args.size.1),
        "error_size": format!("{}x{}", args.error_size.0, args.error_size.1),
        "frames": args.frames,
        "repeat": args.repeat,
        "views": args.views,
        "full_detail_triangles": scene.full,
        "full_detail": {"median_ms": reference[0].median_ms, "p95_ms": reference[0].p95_ms},
        "budgets": swept.iter().map(|p| json!({
            "budget": p.budget, "median_ms": p.median_ms, "p95_ms": p.p95_ms,
            "triangles": p.triangles, "psnr_median": p.psnr, "psnr_worst": p.psnr_worst,
        })).collect::<Vec<_>>(),
        "knee": mark(knee),
        "good_psnr": args.good_psnr,
        "first_good": mark(good),
    });
    write(
        &args.out.join("summary.json"),
        &serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?,
    )?;
    println!("{}", csv.trim_end());
    match knee {
        Some(k) => println!(
            "knee: P = {} ({:.1} dB, median frame {:.1} ms)",
            swept[k].budget, swept[k].psnr, swept[k].median_ms
        ),
        None => println!("knee: none (fewer than three budgets, or none above the chord)"),
    }
    match good {
        Some(g) => println!(
            "first budget at {} dB: P = {} ({:.1} dB, median frame {:.1} ms)",
            args.good_psnr, swept[g].budget, swept[g].psnr, swept[g].median_ms
        ),
        None => println!("no budget reaches {} dB", args.good_psnr),
    }
    Ok(())
}

fn label(way: Option<u32>) -> String {
    way.map_or("full detail".into(), |p| format!("P = {p}"))
}

/// One budget of the sweep.
#[derive(Clone, Copy)]
struct Point {
    budget: u64,
    median_ms: f64,
    p95_ms: f64,
    triangles: f64,
    /// PSNR against full detail over the views: median and worst.
    psnr: f64,
    psnr_worst: f64,
}

/// The PSNR a view counts with in the knee (identical views would flatten the curve).
const KNEE_PSNR_CAP: f64 = 60.0;

/// The knee of PSNR over log P (points in increasing P): the point furthest above the chord
/// between the first and the last, both normalised to `0..=1` (Satopää et al.'s Kneedle).
/// `None` for fewer than three points or a curve nowhere above its chord.
fn knee(points: &[Point]) -> Option<usize> {
    if points.len() < 3 {
        return None;
    }
    let x: Vec<f64> = points
        .iter()
        .map(|p| (p.budget.max(1) as f64).ln())
        .collect();
    let y: Vec<f64> = points.iter().map(|p| p.psnr.min(KNEE_PSNR_CAP)).collect();
    let (x0, x1) = (x[0], x[x.len() - 1]);
    let (y0, y1) = (y[0], y[y.len() - 1]);
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    (1..points.len() - 1)
        .map(|i| (i, (y[i] - y0) / (y1 - y0) - (x[i] - x0) / (x1 - x0)))
        .filter(|&(_, d)| d > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

// ---------------------------------------------------------------------------------------
// The controller.

fn control(scene: &mut Scene, args: &Args, target_ms: f32) -> Result<(), String> {
    let fixed = args.budget.unwrap_or(match scene.kind {
        Kind::Crowd => 100_000,
        _ => (scene.full / 4).max(1) as u32,
    });
    let max = args
        .max
        .unwrap_or(scene.full.min(u64::from(u32::MAX)) as u32);
    let step = (!args.no_step).then(|| args.step_at.unwrap_or(args.frames / 2));
    scene.wait_until_drawn(&args.out)?;
    let floor = if step.is_some() {
        scene.floor_with_step
    } else {
        scene.floor
    };
    let min = args
        .min
        .unwrap_or(floor.clamp(500, u64::from(u32::MAX)) as u32);
    if min > max {
        return Err(format!("--min {min} is above --max {max}"));
    }
    let mut fixed_runs = Vec::new();
    let mut control_runs = Vec::new();
    for round in 0..args.repeat {
        eprintln!("budget_tuning: round {}, P = {fixed}", round + 1);
        scene.set_budget(
            PolygonBudget {
                total: fixed,
                ..default()
            },
            false,
        );
        fixed_runs.push(play(scene, args.frames, step));
        eprintln!("budget_tuning: round {}, T = {target_ms} ms", round + 1);
        // A fresh controller each run, starting from the fixed budget.
        scene.set_budget(
            PolygonBudget {
                total: fixed,
                ..default()
            },
            false,
        );
        scene.frame_at(0, args.frames);
        let mut budget = PolygonBudget::target_ms(target_ms, min..=max);
        budget.total = fixed.clamp(min.max(1), max);
        scene.set_budget(budget, false);
        control_runs.push(play(scene, args.frames, step));
    }
    // What the path shows after the step, at the controlled run's final budget.
    if let Some(s) = step {
        let u = ((s + 10).min(args.frames - 1)) as f32 / (args.frames - 1) as f32;
        let last = control_runs
            .last()
            .and_then(|r| r.last())
            .map_or(fixed, |r| r.budget);
        scene.set_budget(
            PolygonBudget {
                total: last,
                ..default()
            },
            false,
        );
        scene.step();
        scene.set_target(&scene.large.clone());
        let image = scene.view(u, s + 10)?;
        common::save_image(&image, &args.out.join("after_step.png"))?;
        scene.unstep();
        scene.set_target(&scene.small.clone());
    }
    let mut csv =
        String::from("way,run,frame,frame_ms,budget,triangles,smoothed_ms,state,source\n");
    for (way, runs) in [("fixed", &fixed_runs), ("target", &control_runs)] {
        for (run, rows) in runs.iter().enumerate() {
            for r in rows {
                csv += &format!(
                    "{way},{run},{},{:.3},{},{},{:.3},{:?},{:?}\n",
                    r.frame, r.ms, r.budget, r.triangles, r.smoothed_ms, r.state, r.source
                );
            }
        }
    }
    write(&args.out.join("control.csv"), &csv)?;
    let fixed_ms: Vec<f64> = fixed_runs.iter().flatten().map(|r| r.ms).collect();
    let control_ms: Vec<f64> = control_runs.iter().flatten().map(|r| r.ms).collect();
    let t = f64::from(target_ms);
    let median_ms = median(&control_ms);
    let p95 = quantile(&control_ms, 0.95);
    let settle: Vec<Option<u32>> = control_runs
        .iter()
        .map(|rows| step.and_then(|s| settle_frames(rows, s, t)))
        .collect();
    let moves: Vec<f64> = control_runs
        .iter()
        .flat_map(|rows| steady_moves(rows, t))
        .collect();
    let over = control_runs
        .iter()
        .flatten()
        .filter(|r| r.triangles > u64::from(r.budget))
        .count();
    let summary = json!({
        "scene": args.scene,
        "machine": machine(),
        "size": format!("{}x{}", args.size.0, args.size.1),
        "frames": args.frames,
        "repeat": args.repeat,
        "step_at": step,
        "step_models": STEP_MODELS,
        "target_ms": t,
        "frame_source": format!("{:?}", control_runs.iter().flatten().last().map_or(FrameSource::None, |r| r.source)),
        "range": [min, max],
        "floor_triangles": floor,
        "fixed": {
            "budget": fixed,
            "fastest_ms": quantile(&fixed_ms, 0.0),
            "slowest_ms": quantile(&fixed_ms, 1.0),
            "median_ms": median(&fixed_ms),
            "p95_ms": quantile(&fixed_ms, 0.95),
            "target_between_fastest_and_slowest":
                (quantile(&fixed_ms, 0.0)..=quantile(&fixed_ms, 1.0)).contains(&t),
        },
        "target": {
            "median_ms": median_ms,
            "p95_ms": p95,
            "median_within_10_percent": (median_ms - t).abs() <= 0.1 * t,
            "p95_at_most_1_3_t": p95 <= 1.3 * t,
            "median_budget": median(&control_runs.iter().flatten().map(|r| f64::from(r.budget)).collect::<Vec<_>>()),
            "settle_frames_after_step": settle,
            "budget_around_step": control_runs.iter().map(|rows| step.map(|s| {
                let p = |range: std::ops::Range<u32>| median(&rows.iter()
                    .filter(|r| range.contains(&r.frame)).map(|r| f64::from(r.budget)).collect::<Vec<_>>());
                json!({"before": p(s.saturating_sub(10)..s), "after": p(s + 30..s + 40)})
            })).collect::<Vec<_>>(),
            "steady_budget_move_median": median(&moves),
            "steady_budget_move_p95": quantile(&moves, 0.95),
            "steady_budget_move_max": quantile(&moves, 1.0),
            "frames_over_budget": over,
        },
    });
    write(
        &args.out.join("summary.json"),
        &serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?,
    )?;
    charts::control(
        &args.out.join("control.png"),
        &fixed_runs,
        &control_runs,
        t,
        step,
        &args.scene,
        args.size,
    )?;
    println!(
        "{}",
        serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?
    );
    Ok(())
}

/// Frames after the step at `step` until the controller's smoothed frame time is back within
/// [`SETTLE_BAND`] of the target `t` and stays there for [`SETTLED_FOR`] frames; `None` when it
/// never is.
fn settle_frames(rows: &[Row], step: u32, t: f64) -> Option<u32> {
    let after: Vec<&Row> = rows.iter().filter(|r| r.frame >= step).collect();
    let inside: Vec<bool> = after
        .iter()
        .map(|r| (f64::from(r.smoothed_ms) - t).abs() <= SETTLE_BAND * t)
        .collect();
    inside
        .windows(SETTLED_FOR)
        .position(|w| w.iter().all(|&i| i))
        .map(|k| k as u32)
}

/// `|ΔP| / P` between consecutive frames in steady state: after the first 30 frames, both
/// frames' smoothed frame time within [`SETTLE_BAND`] of the target `t` (not recovering
/// from a load change, nor held at a bound while the path makes frames far faster or
/// slower than `t`).
fn steady_moves(rows: &[Row], t: f64) -> Vec<f64> {
    let steady = |r: &Row| r.frame >= 30 && (f64::from(r.smoothed_ms) - t).abs() <= SETTLE_BAND * t;
    rows.windows(2)
        .filter(|w| steady(&w[0]) && steady(&w[1]))
        .map(|w| {
            (f64::from(w[1].budget) - f64::from(w[0].budget)).abs() / f64::from(w[0].budget.max(1))
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Charts.

mod charts {
    use super::{Point, Row};
    use crate::common::chart::draw;
    use plotters::coord::combinators::LogCoord;
    use plotters::coord::types::RangedCoordf64;
    use plotters::prelude::*;
    use std::path::Path;

    /// The colours of the marked budgets (the knee, the first good one).
    const MARKS: [RGBColor; 2] = [BLACK, RGBColor(0, 140, 0)];

    fn err(e: impl std::fmt::Display) -> String {
        e.to_string()
    }

    /// A chart over P on a log scale.
    type BudgetChart<'a, 'b> =
        ChartContext<'a, BitMapBackend<'b>, Cartesian2d<LogCoord<f64>, RangedCoordf64>>;

    /// Circles the marked budgets at `y` and draws the legend at `position`.
    fn marks_and_legend<'a, 'b: 'a>(
        chart: &mut BudgetChart<'a, 'b>,
        points: &[Point],
        marks: &[(usize, String)],
        y: fn(&Point) -> f64,
        position: SeriesLabelPosition,
    ) -> Result<(), String> {
        for ((k, label), color) in marks.iter().zip(MARKS) {
            let p = &points[*k];
            chart
                .draw_series([Circle::new(
                    (p.budget as f64, y(p)),
                    7,
                    color.stroke_width(2),
                )])
                .map_err(err)?
                .label(label.as_str())
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(position)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.9))
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(err)
    }

    /// PSNR against full detail over P (log scale), the suggested budgets marked.
    pub fn error_vs_budget(
        path: &Path,
        points: &[Point],
        marks: &[(usize, String)],
        scene: &str,
    ) -> Result<(), String> {
        let lo = points.first().map_or(1, |p| p.budget).max(1) as f64;
        let hi = points.last().map_or(2, |p| p.budget).max(2) as f64;
        let top = points.iter().map(|p| p.psnr.min(60.0)).fold(10.0, f64::max) + 3.0;
        let bottom = points
            .iter()
            .map(|p| p.psnr_worst.min(60.0))
            .fold(top, f64::min)
            - 3.0;
        draw(path, |root| {
            let mut chart = ChartBuilder::on(root)
                .caption(
                    format!("{scene}: image error against P"),
                    ("sans-serif", 26),
                )
                .margin(16)
                .x_label_area_size(48)
                .y_label_area_size(64)
                .build_cartesian_2d((lo * 0.8..hi * 1.25).log_scale(), bottom.max(0.0)..top)
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("polygon budget P (triangles)")
                .y_desc("PSNR against full detail (dB)")
                .x_label_formatter(&|v| format!("{v:.0}"))
                .axis_desc_style(("sans-serif", 18))
                .label_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            chart
                .draw_series(LineSeries::new(
                    points.iter().map(|p| (p.budget as f64, p.psnr.min(60.0))),
                    RED.stroke_width(2),
                ))
                .map_err(err)?
                .label("median of the views")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED.stroke_width(2)));
            chart
                .draw_series(LineSeries::new(
                    points
                        .iter()
                        .map(|p| (p.budget as f64, p.psnr_worst.min(60.0))),
                    BLUE.mix(0.6).stroke_width(1),
                ))
                .map_err(err)?
                .label("worst view")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.mix(0.6)));
            marks_and_legend(
                &mut chart,
                points,
                marks,
                |p| p.psnr.min(60.0),
                SeriesLabelPosition::LowerRight,
            )
        })
    }

    /// Median and p95 frame over P (log scale), full detail as a line.
    pub fn frame_vs_budget(
        path: &Path,
        points: &[Point],
        full: &Point,
        marks: &[(usize, String)],
        scene: &str,
        size: (u32, u32),
    ) -> Result<(), String> {
        let lo = points.first().map_or(1, |p| p.budget).max(1) as f64;
        let hi = points.last().map_or(2, |p| p.budget).max(2) as f64;
        let top = points.iter().map(|p| p.p95_ms).fold(full.p95_ms, f64::max) * 1.15;
        draw(path, |root| {
            let mut chart = ChartBuilder::on(root)
                .caption(
                    format!("{scene}: frame time against P, {}x{}", size.0, size.1),
                    ("sans-serif", 26),
                )
                .margin(16)
                .x_label_area_size(48)
                .y_label_area_size(64)
                .build_cartesian_2d((lo * 0.8..hi * 1.25).log_scale(), 0f64..top)
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("polygon budget P (triangles)")
                .y_desc("frame time (ms)")
                .x_label_formatter(&|v| format!("{v:.0}"))
                .axis_desc_style(("sans-serif", 18))
                .label_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            for (name, color, value) in [
                (
                    "median",
                    RED,
                    (|p: &Point| p.median_ms) as fn(&Point) -> f64,
                ),
                ("p95", RGBColor(235, 150, 150), |p: &Point| p.p95_ms),
            ] {
                chart
                    .draw_series(LineSeries::new(
                        points.iter().map(|p| (p.budget as f64, value(p))),
                        color.stroke_width(2),
                    ))
                    .map_err(err)?
                    .label(name)
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2))
                    });
            }
            chart
                .draw_series(LineSeries::new(
                    [(lo * 0.8, full.median_ms), (hi * 1.25, full.median_ms)],
                    BLUE.stroke_width(1),
                ))
                .map_err(err)?
                .label(format!("full detail ({} triangles), median", full.budget))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE));
            marks_and_legend(
                &mut chart,
                points,
                marks,
                |p| p.median_ms,
                SeriesLabelPosition::UpperLeft,
            )
        })
    }

    /// Frame time (top) and P (bottom) along the path: the fixed budget's runs and the
    /// controlled ones, the target and the load step marked.
    pub fn control(
        path: &Path,
        fixed: &[Vec<Row>],
        target: &[Vec<Row>],
        t: f64,
        step: Option<u32>,
        scene: &str,
        size: (u32, u32),
    ) -> Result<(), String> {
        let frames = fixed.first().map_or(2, Vec::len).max(2) as u32;
        let all = fixed.iter().chain(target).flatten();
        let top_ms = all.clone().map(|r| r.ms).fold(t, f64::max).min(4.0 * t) * 1.1;
        let top_p = all.map(|r| f64::from(r.budget)).fold(1.0, f64::max) * 1.1;
        draw(path, |root| {
            let (upper, lower) = root.split_vertically(270);
            let mut chart = ChartBuilder::on(&upper)
                .caption(
                    format!(
                        "{scene}: frame time and P along the path, {}x{}",
                        size.0, size.1
                    ),
                    ("sans-serif", 22),
                )
                .margin(10)
                .x_label_area_size(28)
                .y_label_area_size(64)
                .build_cartesian_2d(0u32..frames, 0f64..top_ms)
                .map_err(err)?;
            chart
                .configure_mesh()
                .y_desc("frame (ms)")
                .axis_desc_style(("sans-serif", 16))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(err)?;
            for (runs, color, name) in [(fixed, BLUE, "fixed P"), (target, RED, "target")] {
                for (i, rows) in runs.iter().enumerate() {
                    let series = chart
                        .draw_series(LineSeries::new(
                            rows.iter().map(|r| (r.frame, r.ms.min(top_ms))),
                            color.mix(0.7),
                        ))
                        .map_err(err)?;
                    if i == 0 {
                        series
                            .label(name)
                            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
                    }
                }
            }
            chart
                .draw_series(LineSeries::new(
                    [(0, t), (frames, t)],
                    BLACK.stroke_width(1),
                ))
                .map_err(err)?
                .label(format!("T = {t} ms"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
            if let Some(s) = step {
                chart
                    .draw_series(LineSeries::new(
                        [(s, 0.0), (s, top_ms)],
                        GREEN.stroke_width(1),
                    ))
                    .map_err(err)?
                    .label("load step")
                    .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], GREEN));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .border_style(BLACK)
                .background_style(WHITE.mix(0.9))
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(err)?;
            let mut chart = ChartBuilder::on(&lower)
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(64)
                .build_cartesian_2d(0u32..frames, 0f64..top_p)
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("frame")
                .y_desc("P (triangles)")
                .y_label_formatter(&|v| format!("{v:.0}"))
                .axis_desc_style(("sans-serif", 16))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(err)?;
            for (runs, color) in [(fixed, BLUE), (target, RED)] {
                for rows in runs {
                    chart
                        .draw_series(LineSeries::new(
                            rows.iter().map(|r| (r.frame, f64::from(r.budget))),
                            color.mix(0.7),
                        ))
                        .map_err(err)?;
                }
            }
            if let Some(s) = step {
                chart
                    .draw_series(LineSeries::new(
                        [(s, 0.0), (s, top_p)],
                        GREEN.stroke_width(1),
                    ))
                    .map_err(err)?;
            }
            Ok(())
        })
    }
}
