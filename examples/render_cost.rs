//! What a level change costs the renderer, with rendering on (Vulkan; lavapipe without a GPU).
//!
//! `render_cost [--frames N] [--hysteresis E] [--scene grid|silvretta|aerobic]`: the plugin
//! bench's 1,000 patches × 16 regions under P = 1,000,000 (or Silvretta's terrain under 10,000,
//! or the aerobic class's three dancing mannequins under 5,000) rendered into a 32×18 image, so
//! rasterising costs next to nothing. For each way of
//! handing levels to the renderer ([`RegionUpload`]) it runs the camera path and a still
//! camera, interleaved, and prints per frame (medians): the plugin's own systems, the render
//! world's extraction, its mesh preparation (allocation, `RenderMesh`, the plugin's writes)
//! and its mesh instance rebuild, the bytes of mesh data handed to the GPU, and the whole
//! frame (pipelined rendering off, so `app.update()` includes the render world).
//!
//! `render_cost --check DIR [--cpu-building]`: the render test. Regions of three models and of
//! a dancing mannequin (`assets/mannequin.glb`, skinned) change level over several frames under
//! two cameras (one with a depth prepass, a shadow-casting light); then the dance pauses, the
//! models are replaced by plain meshes built fresh from the final levels and
//! the two pairs of screenshots are compared. Writes the PNGs and `check.json` into DIR.
//! `--cpu-building` turns Bevy's GPU mesh preprocessing off.
//!
//! `render_cost --instances 1000,10000 [--crowd 100] [--frames N]`: the instance bench. N
//! instances of one 20,480-triangle sphere scattered on a plane (and, with `--crowd`, N
//! dancing mannequins, skinned), drawn along one camera path over them (a 32×18 target):
//! (a) one shared full-detail mesh (Bevy's glTF scene); (b) the discrete LOD a Bevy user
//! builds today, a chain of meshoptimizer levels each half the one before, shared meshes
//! swapped by `VisibilityRange` at distances √2 apart; (c) `SharedLevels` (the crowd:
//! `MultiresScene`) under a budget equal to the median triangles (b) drew in view, and again
//! under the budget, found by secant steps, at which it draws as many in view (the spheres
//! then once more with one region each, under that budget; the crowd once more skinned on
//! the CPU, `NoSharedLevels`, under that budget). Prints per way (medians over
//! the path): our systems, Bevy's visibility checks (frustum culling and `VisibilityRange`),
//! the render world's extraction, preparation and instance rebuild, the bytes of `Mesh`
//! assets (vertex and index data, what the mesh allocator holds), the triangles and mesh
//! entities visible, the whole frame, and the PSNR against (a) of three views of the path
//! rendered at 1280×720 (dancers paused).
//!
//! `render_cost --check DIR --shared`: the same for 200 instances of one patch with
//! `SharedLevels`, at every distance: their regions drawn from the shared level meshes
//! against plain meshes built fresh at the same levels.

#[path = "../benches/common/clip.rs"]
mod clip;
mod common;
#[allow(dead_code)]
#[path = "../benches/common/models.rs"]
mod models;
#[path = "../benches/common/scene.rs"]
mod scene;

use common::terrain;

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::RenderTarget;
use bevy::camera::visibility::NoFrustumCulling;
use bevy::camera::visibility::{VisibilityRange, VisibilitySystems};
use bevy::core_pipeline::prepass::DepthPrepass;
use bevy::gltf::Gltf;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::mesh::RenderMesh;
use bevy::render::mesh::allocator::allocate_and_free_meshes;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::render::render_asset::{AssetExtractionSystems, ExtractedAssets, RenderAsset};
use bevy::render::render_resource::TextureFormat;
use bevy::render::settings::{RenderCreation, WgpuLimits, WgpuSettings, WgpuSettingsPriority};
use bevy::render::{ExtractSchedule, Render, RenderApp, RenderSystems};
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::bevy_mesh::to_bevy_mesh;
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodSystems, LodRegion, MultiresInstance, MultiresMesh,
    MultiresModel, MultiresScene, NoSharedLevels, PartitionSpec, PolygonBudget, RegionUpload,
    RegionUploadStats, SharedLevels,
};
use bevy_aslod::regions::{GridPlane, Partition, RegionCaches};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets");

/// What a level change costs the renderer (a bench), or the render test (`--check`).
#[derive(clap::Parser, Debug)]
struct Args {
    /// Measured frames per row of the bench.
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u32).range(1..))]
    frames: u32,
    /// The bench's scene.
    #[arg(long, default_value = "grid", value_parser = ["grid", "silvretta", "aerobic"])]
    scene: String,
    /// The hysteresis ε in triangles.
    #[arg(long, default_value_t = 0)]
    hysteresis: u32,
    /// Run the render test instead, writing its screenshots to DIR.
    #[arg(long, value_name = "DIR")]
    check: Option<PathBuf>,
    /// With `--check`: WebGL 2 limits, so Bevy builds the draws on the CPU.
    #[arg(long, requires = "check")]
    cpu_building: bool,
    /// With `--check`: 200 instances of one asset sharing their levels instead.
    #[arg(long, requires = "check")]
    shared: bool,
    /// Run the instance bench instead: N instances of one 20,480-triangle sphere drawn with
    /// no LOD, with meshoptimizer levels under `VisibilityRange`, and with `SharedLevels`
    /// (comma-separated counts).
    #[arg(long, value_name = "N,N", value_delimiter = ',')]
    instances: Vec<usize>,
    /// Run the instance bench on a crowd of N dancing mannequins (skinned) too, after the
    /// spheres: no LOD, meshoptimizer levels under `VisibilityRange`, `MultiresScene`.
    #[arg(long, value_name = "N")]
    crowd: Option<usize>,
}

fn main() {
    let args = <Args as clap::Parser>::parse();
    let result = match args.check {
        None if !args.instances.is_empty() || args.crowd.is_some() => {
            run_instances(&args.instances, args.crowd, args.frames as usize)
        }
        Some(dir) if args.shared => run_shared_check(&dir, args.cpu_building),
        Some(dir) => run_check(&dir, args.cpu_building),
        None => run_bench(&args.scene, args.frames as usize, args.hysteresis),
    };
    if let Err(e) = result {
        eprintln!("render_cost: {e}");
        std::process::exit(1);
    }
}

/// `DefaultPlugins` without a window or pipelined rendering, and the plugin.
fn render_app(cpu_building: bool, asset_root: Option<&str>) -> App {
    let mut app = App::new();
    let mut assets = AssetPlugin::default();
    if let Some(root) = asset_root {
        assets.file_path = root.into();
    }
    let plugins = DefaultPlugins
        .set(assets)
        .set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            ..default()
        })
        .set(RenderPlugin {
            // WebGL 2's limits (no compute) turn Bevy's GPU mesh preprocessing off, as on
            // devices without it.
            render_creation: RenderCreation::Automatic(Box::new(if cpu_building {
                WgpuSettings {
                    priority: WgpuSettingsPriority::WebGL2,
                    limits: WgpuLimits::downlevel_webgl2_defaults(),
                    ..default()
                }
            } else {
                WgpuSettings::default()
            })),
            ..default()
        })
        .disable::<WinitPlugin>()
        .disable::<PipelinedRenderingPlugin>();
    app.add_plugins((plugins, ScheduleRunnerPlugin::run_once()))
        .add_plugins(AslodPlugin::default())
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
            1.0 / 60.0,
        )));
    add_render_timers(&mut app);
    app.finish();
    app.cleanup();
    app
}

/// An offscreen colour target of `w`×`h` pixels.
fn target(app: &mut App, w: u32, h: u32) -> Handle<Image> {
    app.world_mut()
        .resource_mut::<Assets<Image>>()
        .add(Image::new_target_texture(
            w,
            h,
            TextureFormat::Rgba8Unorm,
            Some(TextureFormat::Rgba8UnormSrgb),
        ))
}

// ---------------------------------------------------------------------------------------
// Render-world timers.

/// What the render world did for meshes in the last frame, measured by systems placed
/// around Bevy's own (wall-clock time between them).
#[derive(Resource, Clone, Copy, Debug, Default)]
struct RenderCost {
    /// `ExtractSchedule`, from before render-asset and mesh-instance extraction to after.
    extract_ms: f64,
    /// `PrepareAssets`: from before `allocate_and_free_meshes` to after
    /// `prepare_assets::<RenderMesh>` and the plugin's writes.
    prepare_ms: f64,
    /// `PrepareMeshes`: the mesh instances' rebuild (`collect_meshes_for_gpu_building`).
    instances_ms: f64,
    /// Bytes of the meshes Bevy extracted this frame (vertices and indices, as
    /// `RenderMesh::byte_len` counts them): what its allocator writes to the GPU.
    bevy_bytes: u64,
}

#[derive(Resource, Default)]
struct RenderClock {
    extract: Option<Instant>,
    prepare: Option<Instant>,
    instances: Option<Instant>,
    cost: RenderCost,
}

/// The last frame's [`RenderCost`], shared with the main world.
#[derive(Resource, Clone, Default)]
struct SharedCost(Arc<Mutex<RenderCost>>);

/// Bevy's visibility checks in the main world (frustum culling and `VisibilityRange`s) in
/// the last frame: wall-clock time across `VisibilitySystems::CheckVisibility`, which starts
/// after the plugin's `Upload` here (so that the plugin's systems do not run beside it).
#[derive(Resource, Default)]
struct VisibilityClock {
    start: Option<Instant>,
    ms: f64,
}

fn add_render_timers(app: &mut App) {
    let shared = SharedCost::default();
    app.insert_resource(shared.clone())
        .init_resource::<VisibilityClock>()
        .add_systems(
            PostUpdate,
            (
                (|mut c: ResMut<VisibilityClock>| c.start = Some(Instant::now()))
                    .after(AslodSystems::Upload)
                    .after(VisibilitySystems::VisibilityPropagate)
                    .before(VisibilitySystems::CheckVisibility),
                (|mut c: ResMut<VisibilityClock>| {
                    c.ms = c.start.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3)
                })
                .after(VisibilitySystems::CheckVisibility)
                .before(VisibilitySystems::MarkNewlyHiddenEntitiesInvisible),
            ),
        );
    let Some(render) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render
        .insert_resource(shared)
        .init_resource::<RenderClock>()
        .add_systems(
            ExtractSchedule,
            (
                (|mut c: ResMut<RenderClock>| c.extract = Some(Instant::now()))
                    .before(AssetExtractionSystems)
                    .before(bevy::pbr::MeshExtractionSystems),
                (|mut c: ResMut<RenderClock>| {
                    c.cost.extract_ms = c.extract.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3)
                })
                .after(AssetExtractionSystems)
                .after(bevy::pbr::MeshExtractionSystems),
            ),
        )
        .add_systems(
            Render,
            (
                (|mut c: ResMut<RenderClock>, extracted: Res<ExtractedAssets<RenderMesh>>| {
                    c.prepare = Some(Instant::now());
                    c.cost.bevy_bytes = extracted
                        .extracted
                        .iter()
                        .filter_map(|(_, mesh)| RenderMesh::byte_len(mesh))
                        .sum::<usize>() as u64;
                })
                .in_set(RenderSystems::PrepareAssets)
                .before(allocate_and_free_meshes),
                prepare_end
                    .in_set(RenderSystems::PrepareMeshes)
                    .before(bevy::pbr::collect_meshes_for_gpu_building),
                instances_end
                    .in_set(RenderSystems::PrepareMeshes)
                    .after(prepare_end)
                    .after(bevy::pbr::collect_meshes_for_gpu_building),
            ),
        );
}

/// Stops the prepare clock (the plugin's writes follow Bevy's mesh preparation, in
/// `PrepareAssets`), starts the instances one.
fn prepare_end(mut c: ResMut<RenderClock>) {
    c.cost.prepare_ms = c.prepare.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
    c.instances = Some(Instant::now());
}

/// Stops the instances clock and publishes the frame's cost.
fn instances_end(mut c: ResMut<RenderClock>, shared: Res<SharedCost>) {
    c.cost.instances_ms = c.instances.map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
    *shared.0.lock().expect("cost") = c.cost;
}
fn render_cost(app: &App) -> RenderCost {
    *app.world().resource::<SharedCost>().0.lock().expect("cost")
}

fn upload_stats(app: &App) -> RegionUploadStats {
    app.get_sub_app(RenderApp)
        .and_then(|r| r.world().get_resource::<RegionUploadStats>().copied())
        .unwrap_or_default()
}

// ---------------------------------------------------------------------------------------
// The bench.

/// One frame's figures.
#[derive(Clone, Copy, Default)]
struct Frame {
    ours_ms: f64,
    cost: RenderCost,
    region_bytes: u64,
    index_bytes: u64,
    changed: usize,
    copies: u32,
    write_ms: f64,
    blended: usize,
    frame_ms: f64,
    triangles: u64,
}

fn run_bench(scene_name: &str, frames: usize, hysteresis: u32) -> Result<(), String> {
    let Bench {
        mut app,
        budget,
        camera,
        path,
    } = match scene_name {
        "grid" => grid_scene(hysteresis),
        "silvretta" => silvretta_scene(hysteresis),
        "aerobic" => aerobic_scene(hysteresis)?,
        other => {
            return Err(format!(
                "unknown scene {other:?} (grid, silvretta or aerobic)"
            ));
        }
    };
    // Pipelines compile slowly on a software rasteriser: let them, and the levels, settle.
    for _ in 0..120 {
        app.update();
    }
    let modes = [RegionUpload::IndicesOnly, RegionUpload::WholeMesh];
    let mut rows: Vec<(RegionUpload, bool, Vec<Frame>)> = Vec::new();
    for mode in modes {
        for still in [false, true] {
            rows.push((mode, still, Vec::new()));
        }
    }
    // Interleaved rounds, so a slow phase of the machine hits every row.
    let rounds = 3;
    for _ in 0..rounds {
        for row in &mut rows {
            let (mode, still, out) = (row.0, row.1, &mut row.2);
            *app.world_mut().resource_mut::<RegionUpload>() = mode;
            for frame in 0..10 + frames {
                let t = if still {
                    0.5
                } else {
                    frame as f32 / (10 + frames) as f32
                };
                *app.world_mut()
                    .get_mut::<Transform>(camera)
                    .ok_or("no camera")? = path(t);
                let start = Instant::now();
                app.update();
                let frame_ms = start.elapsed().as_secs_f64() * 1e3;
                if frame < 10 {
                    continue;
                }
                let stats = *app.world().resource::<AslodStats>();
                let up = upload_stats(&app);
                out.push(Frame {
                    ours_ms: stats.allocation_ms + stats.update_ms + stats.deform_ms,
                    cost: render_cost(&app),
                    region_bytes: up.index_bytes + up.vertex_bytes,
                    index_bytes: up.index_bytes,
                    changed: stats.regions_changed,
                    copies: up.copies,
                    write_ms: up.write_ms,
                    blended: stats.vertices_blended,
                    frame_ms,
                    triangles: stats.triangles,
                });
            }
        }
    }
    let cpu = common::cpu_name();
    println!(
        "render_cost {scene_name}: P = {budget}, hysteresis {hysteresis}, 32x18 target, {frames} frames x {rounds} rounds per row, {} build, {cpu}, {} cores",
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        std::thread::available_parallelism().map_or(0, usize::from)
    );
    println!(
        "| upload | camera | ours ms | extract ms | prepare ms | of which the plugin's writes ms | instances ms | render world ms | mesh bytes to GPU | of which index bytes of changed regions | regions changed | GPU copies | vertices blended | frame ms | triangles |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (mode, still, frames) in &rows {
        let med = |f: &dyn Fn(&Frame) -> f64| {
            let mut v: Vec<f64> = frames.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        println!(
            "| {mode:?} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.1} | {:.0} |",
            if *still { "still" } else { "moving" },
            med(&|f| f.ours_ms),
            med(&|f| f.cost.extract_ms),
            med(&|f| f.cost.prepare_ms),
            med(&|f| f.write_ms),
            med(&|f| f.cost.instances_ms),
            med(&|f| f.cost.extract_ms + f.cost.prepare_ms + f.cost.instances_ms),
            med(&|f| (f.cost.bevy_bytes + f.region_bytes) as f64),
            med(&|f| f.index_bytes as f64),
            med(&|f| f.changed as f64),
            med(&|f| f64::from(f.copies)),
            med(&|f| f.blended as f64),
            med(&|f| f.frame_ms),
            med(&|f| f.triangles as f64),
        );
    }
    Ok(())
}

/// A bench scene: the app, its budget, its camera and the camera's path over `t` in `0..1`.
struct Bench {
    app: App,
    budget: u32,
    camera: Entity,
    path: Box<dyn Fn(f32) -> Transform>,
}

/// A bench app with the budget, the hysteresis, a 32×18 camera and a light.
fn bench_app(budget: u32, hysteresis: u32, asset_root: Option<&str>) -> (App, Entity) {
    let mut app = render_app(false, asset_root);
    *app.world_mut().resource_mut::<PolygonBudget>() = PolygonBudget {
        total: budget,
        hysteresis,
        ..default()
    };
    let image = target(&mut app, 32, 18);
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            RenderTarget::Image(image.into()),
            Transform::default(),
        ))
        .id();
    app.world_mut().spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    (app, camera)
}

/// The plugin bench's scene: 1,000 bumpy patches in 4×4 regions under P = 1,000,000, the
/// camera sweeping along the front of the grid.
fn grid_scene(hysteresis: u32) -> Bench {
    const MODELS: usize = 1_000;
    let (mut app, camera) = bench_app(1_000_000, hysteresis, None);
    let mesh = scene::patch(33);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 4, 4).expect("grid");
    let asset = MultiresMesh::from_indexed(&mesh, &partition).expect("valid patch");
    let side = scene::side(MODELS);
    let at: Vec<Vec3> = (0..MODELS)
        .map(|i| scene::model_position(i, side))
        .collect();
    models::spawn_models(&mut app, asset, at);
    Bench {
        app,
        budget: 1_000_000,
        camera,
        path: Box::new(move |t| {
            let (eye, at) = scene::camera(t, side);
            Transform::from_translation(eye).looking_at(at, Vec3::Y)
        }),
    }
}

/// Silvretta (Figure 8): the 135,200-triangle terrain in 6×6 regions under P = 10,000, the
/// camera flying low from a corner towards the middle.
fn silvretta_scene(hysteresis: u32) -> Bench {
    let (mut app, camera) = bench_app(10_000, hysteresis, None);
    let mesh = terrain::terrain();
    let partition = Partition::grid(&mesh, GridPlane::XZ, 6, 6).expect("grid");
    let asset = MultiresMesh::from_indexed(&mesh, &partition).expect("valid terrain");
    models::spawn_models(&mut app, asset, [Vec3::ZERO]);
    let half = (terrain::SIDE - 1) as f32 * terrain::SPACING * 0.5;
    Bench {
        app,
        budget: 10_000,
        camera,
        path: Box::new(move |t| {
            let eye = Vec3::new(-half + 4.0, 1.2 * terrain::HEIGHT, -half + 4.0)
                .lerp(Vec3::new(half * 0.3, terrain::HEIGHT, half * 0.3), t);
            Transform::from_translation(eye).looking_at(eye + Vec3::new(1.0, -0.6, 1.0), Vec3::Y)
        }),
    }
}

/// The aerobic class: three mannequins (`assets/mannequin.glb`, skinned) dancing out of
/// phase under P = 5,000, the camera circling them.
fn aerobic_scene(hysteresis: u32) -> Result<Bench, String> {
    let (mut app, camera) = bench_app(5_000, hysteresis, Some(ASSETS));
    let gltf: Handle<Gltf> = app.world().resource::<AssetServer>().load("mannequin.glb");
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("mannequin.glb"));
    let dancers: Vec<Entity> = (0..3)
        .map(|i| {
            app.world_mut()
                .spawn((
                    WorldAssetRoot(scene.clone()),
                    MultiresScene::default(),
                    Transform::from_xyz(i as f32 * 1.5 - 1.5, 0.0, 0.0),
                ))
                .id()
        })
        .collect();
    clip::start_clip(&mut app, &gltf, &dancers, None, 0.7)?;
    Ok(Bench {
        app,
        budget: 5_000,
        camera,
        path: Box::new(|t| {
            let angle = t * std::f32::consts::TAU;
            let radius = 7.0 - 4.0 * (t * std::f32::consts::PI).sin();
            Transform::from_xyz(angle.sin() * radius, 1.6, angle.cos() * radius)
                .looking_at(Vec3::new(0.0, 0.9, 0.0), Vec3::Y)
        }),
    })
}

// ---------------------------------------------------------------------------------------
// The render check.

fn run_check(dir: &Path, cpu_building: bool) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("create {}: {e}", dir.display()))?;
    let mut app = render_app(cpu_building, Some(ASSETS));
    app.world_mut().resource_mut::<PolygonBudget>().total = 20_000;
    let world = app.world_mut();
    let patch = scene::patch(33);
    let grid = Partition::grid(&patch, GridPlane::XZ, 4, 4).expect("grid");
    let patch = MultiresMesh::from_indexed(&patch, &grid).map_err(|e| e.to_string())?;
    let sphere = Sphere::new(3.0).mesh().ico(5).map_err(|e| e.to_string())?;
    let sphere = MultiresMesh::from_bevy_mesh(&sphere, PartitionSpec::Clusters(8))
        .map_err(|e| e.to_string())?;
    let (patch, sphere) = {
        let mut assets = world.resource_mut::<Assets<MultiresMesh>>();
        (assets.add(patch), assets.add(sphere))
    };
    let (grey, red) = {
        let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
        (
            materials.add(StandardMaterial::from_color(Color::srgb(0.8, 0.8, 0.75))),
            materials.add(StandardMaterial::from_color(Color::srgb(0.8, 0.2, 0.15))),
        )
    };
    let models = [
        world
            .spawn((
                MultiresModel(patch.clone()),
                MeshMaterial3d(grey.clone()),
                Transform::from_xyz(-8.0, 0.0, 0.0),
                // Meshes of their own: the check is of the writes into them.
                NoSharedLevels,
            ))
            .id(),
        world
            .spawn((
                MultiresModel(patch),
                MeshMaterial3d(grey),
                Transform::from_xyz(9.0, 0.0, -6.0),
                NoSharedLevels,
            ))
            .id(),
        world
            .spawn((
                MultiresModel(sphere),
                MeshMaterial3d(red),
                Transform::from_xyz(0.0, 4.0, 2.0),
            ))
            .id(),
    ];
    world.spawn((
        DirectionalLight {
            illuminance: 12_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    // A skinned model: the mannequin, dancing while the levels change (its deformable
    // regions' vertices are written every frame), then paused.
    let gltf: Handle<Gltf> = world.resource::<AssetServer>().load("mannequin.glb");
    let scene = world
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("mannequin.glb"));
    let dancer = world
        .spawn((
            WorldAssetRoot(scene),
            MultiresScene::default(),
            Transform::from_xyz(4.0, 0.0, 5.0).with_scale(Vec3::splat(3.0)),
        ))
        .id();
    let images = [target(&mut app, 192, 108), target(&mut app, 192, 108)];
    let world = app.world_mut();
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(images[0].clone().into()),
        DepthPrepass,
        Msaa::Off,
        Transform::from_xyz(-4.0, 12.0, 22.0).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
    ));
    world.spawn((
        Camera3d::default(),
        Camera {
            order: 1,
            ..default()
        },
        RenderTarget::Image(images[1].clone().into()),
        Msaa::Off,
        Transform::from_xyz(20.0, 6.0, -2.0).looking_at(Vec3::new(0.0, 1.0, -2.0), Vec3::Y),
    ));
    let captures = common::Captures::new(2);
    app.insert_resource(captures.clone());
    // The mannequin dances from the start.
    clip::start_clip(&mut app, &gltf, &[dancer], None, 0.7)?;

    let mut changes = 0usize;
    let shoot = |app: &mut App| common::capture(app, &images, &captures);
    common::wait_until_drawn(&mut app, &images, &captures, dir)?;

    let players: Vec<Entity> = app
        .world_mut()
        .query_filtered::<Entity, With<AnimationPlayer>>()
        .iter(app.world())
        .collect();

    // Change levels: a budget that swings up and down, two frames each, then settle.
    let mut blended = 0;
    for budget in [20_000, 1_500, 12_000, 600, 9_000, 2_500, 16_000, 4_000] {
        app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        for _ in 0..2 {
            app.update();
            let stats = app.world().resource::<AslodStats>();
            changes += stats.regions_changed;
            blended += stats.vertices_blended;
        }
    }
    for &p in &players {
        if let Some(mut player) = app.world_mut().get_mut::<AnimationPlayer>(p) {
            player.pause_all();
        }
    }
    let mut still = 0;
    for _ in 0..4 {
        app.update();
        still += app.world().resource::<AslodStats>().regions_changed;
    }
    let lod = shoot(&mut app)?;

    // The reference: every region as a plain mesh at its final level, made fresh.
    let mut counts = Vec::new();
    let mut plain = Vec::new();
    {
        let world = app.world_mut();
        let mut regions = world.query::<(
            &LodRegion,
            &Mesh3d,
            &MeshMaterial3d<StandardMaterial>,
            &GlobalTransform,
            Has<NoFrustumCulling>,
        )>();
        let mut fresh = Vec::new();
        for (_, mesh, material, transform, unculled) in regions.iter(world) {
            fresh.push((mesh.0.clone(), material.clone(), *transform, unculled));
        }
        for &model in &models {
            let instance = world.get::<MultiresInstance>(model).ok_or("no instance")?;
            counts.push(
                (0..instance.regions().regions().len())
                    .map(|r| instance.caches().triangle_count(r))
                    .collect::<Vec<_>>(),
            );
        }
        for (mesh, material, transform, unculled) in fresh {
            let copy = world
                .resource::<Assets<Mesh>>()
                .get(&mesh)
                .ok_or("a region mesh is gone")?
                .clone();
            let copy = world.resource_mut::<Assets<Mesh>>().add(copy);
            let mut entity = world.spawn((Mesh3d(copy), material, transform.compute_transform()));
            if unculled {
                entity.insert(NoFrustumCulling);
            }
            plain.push(entity.id());
        }
        for model in models.into_iter().chain([dancer]) {
            world.entity_mut(model).despawn();
        }
    }
    for _ in 0..6 {
        app.update();
    }
    let fresh = shoot(&mut app)?;
    let json = serde_json::json!({
        "gpu_building": !cpu_building,
        "regions_changed": changes,
        "vertices_blended": blended,
        "changed_while_still": still,
        "counts": counts,
        "plain_meshes": plain.len(),
    });
    write_check(dir, ("lod", &lod), &fresh, json)
}

/// Saves the two sets of screenshots into `dir`, adds their differences (`views`) and how
/// varied the first set is (`varied`) to `json`, and writes it as `check.json`.
fn write_check(
    dir: &Path,
    (name, shots): (&str, &[Image]),
    fresh: &[Image],
    mut json: serde_json::Value,
) -> Result<(), String> {
    let mut views = Vec::new();
    for (i, (a, b)) in shots.iter().zip(fresh).enumerate() {
        common::save_image(a, &dir.join(format!("view{i}_{name}.png")))?;
        common::save_image(b, &dir.join(format!("view{i}_fresh.png")))?;
        let (max, frac) = common::compare(a, b);
        views.push(serde_json::json!({
            "max_channel_difference": max,
            "fraction_differing": frac,
        }));
    }
    json["views"] = views.into();
    json["varied"] = shots.iter().map(common::varied).collect::<Vec<_>>().into();
    std::fs::write(
        dir.join("check.json"),
        serde_json::to_string_pretty(&json).expect("json"),
    )
    .map_err(|e| format!("write check.json: {e}"))?;
    println!("{json}");
    Ok(())
}

/// `--check --shared`: 200 instances of one patch with [`SharedLevels`], at every distance
/// from two cameras (one with a depth prepass) under a shadow-casting light, change levels
/// under a swinging budget; then each region is drawn as a plain mesh built fresh at its
/// final level (a new cache walked straight there, the region's whole vertex table) and the
/// screenshots are compared.
fn run_shared_check(dir: &Path, cpu_building: bool) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("create {}: {e}", dir.display()))?;
    let mut app = render_app(cpu_building, Some(ASSETS));
    app.world_mut().resource_mut::<PolygonBudget>().total = 120_000;
    let world = app.world_mut();
    let patch = scene::patch(33);
    let grid = Partition::grid(&patch, GridPlane::XZ, 4, 4).expect("grid");
    let patch = MultiresMesh::from_indexed(&patch, &grid).map_err(|e| e.to_string())?;
    let patch = world.resource_mut::<Assets<MultiresMesh>>().add(patch);
    let grey = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::from_color(Color::srgb(0.8, 0.8, 0.75)));
    let models: Vec<Entity> = (0..200)
        .map(|i| {
            let at = Vec3::new(
                (i % 20) as f32 * 17.0 - 160.0,
                0.0,
                -((i / 20) as f32) * 17.0,
            );
            world
                .spawn((
                    MultiresModel(patch.clone()),
                    SharedLevels::default(),
                    MeshMaterial3d(grey.clone()),
                    Transform::from_translation(at),
                ))
                .id()
        })
        .collect();
    world.spawn((
        DirectionalLight {
            illuminance: 12_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let images = [target(&mut app, 192, 108), target(&mut app, 192, 108)];
    let world = app.world_mut();
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(images[0].clone().into()),
        DepthPrepass,
        Msaa::Off,
        Transform::from_xyz(0.0, 9.0, 14.0).looking_at(Vec3::new(0.0, 0.0, -40.0), Vec3::Y),
    ));
    world.spawn((
        Camera3d::default(),
        Camera {
            order: 1,
            ..default()
        },
        RenderTarget::Image(images[1].clone().into()),
        Msaa::Off,
        Transform::from_xyz(-170.0, 30.0, 20.0).looking_at(Vec3::new(-60.0, 0.0, -80.0), Vec3::Y),
    ));
    let captures = common::Captures::new(2);
    app.insert_resource(captures.clone());
    common::wait_until_drawn(&mut app, &images, &captures, dir)?;

    let mut changes = 0;
    let mut most_shared = 0;
    for budget in [120_000, 40_000, 200_000, 50_000, 100_000] {
        app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        for _ in 0..2 {
            app.update();
            let stats = app.world().resource::<AslodStats>();
            changes += stats.regions_changed;
            most_shared = most_shared.max(stats.shared_meshes);
        }
    }
    for _ in 0..4 {
        app.update();
    }
    let lod = common::capture(&mut app, &images, &captures)?;
    let stats = *app.world().resource::<AslodStats>();

    // The reference: every region a plain mesh built fresh at its final level.
    let world = app.world_mut();
    let mut counts = std::collections::BTreeSet::new();
    let mut fresh = Vec::new();
    for &model in &models {
        let instance = world.get::<MultiresInstance>(model).ok_or("no instance")?;
        let regions = instance.regions();
        let mut caches = RegionCaches::new(regions);
        for r in 0..regions.regions().len() {
            let count = instance.caches().triangle_count(r);
            caches.set_triangle_count(regions, r, count);
            counts.insert((r, count));
        }
        let transform = *world.get::<Transform>(model).ok_or("no transform")?;
        for r in 0..regions.regions().len() {
            let mut indices = Vec::new();
            caches.write_indices(regions, r, &mut indices);
            let table = regions.regions()[r].progressive_mesh().vertices();
            let vertices = IndexedMesh {
                joints: None,
                weights: None,
                ..table.clone()
            };
            fresh.push((to_bevy_mesh(&vertices, &indices), transform));
        }
    }
    let regions = fresh.len();
    for model in models {
        world.entity_mut(model).despawn();
    }
    for (mesh, transform) in fresh {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
        world.spawn((Mesh3d(mesh), MeshMaterial3d(grey.clone()), transform));
    }
    for _ in 0..6 {
        app.update();
    }
    let plain = common::capture(&mut app, &images, &captures)?;
    let json = serde_json::json!({
        "gpu_building": !cpu_building,
        "regions": regions,
        "regions_changed": changes,
        "distinct_levels": counts.len(),
        "shared_meshes": stats.shared_meshes,
        "most_shared_meshes": most_shared,
        "triangles": stats.triangles,
    });
    write_check(dir, ("shared", &lod), &plain, json)
}

// ---------------------------------------------------------------------------------------
// The instance bench.

/// The instance bench's sphere: 20,480 triangles, radius 1.
fn instance_sphere() -> Result<Mesh, String> {
    Sphere::new(1.0).mesh().ico(31).map_err(|e| e.to_string())
}

/// Instance `i` of `n`: a jittered square grid 4 units apart.
fn instance_position(i: usize, n: usize) -> Vec3 {
    let side = scene::side(n);
    let h = (i as u32).wrapping_mul(2_654_435_761);
    let jitter = |k: u32| ((h >> k) & 0xff) as f32 / 255.0 - 0.5;
    Vec3::new(
        (i % side) as f32 * 4.0 + jitter(0),
        1.0,
        (i / side) as f32 * 4.0 + jitter(8),
    )
}

/// The camera over the field at `t` in `0..1`: low along its diagonal, looking ahead.
fn instance_camera(t: f32, n: usize) -> Transform {
    let extent = scene::side(n) as f32 * 4.0;
    let eye = Vec3::new(0.1, 4.0, 0.0).lerp(Vec3::new(extent * 0.8, 4.0, extent * 0.7), t);
    Transform::from_translation(eye).looking_at(eye + Vec3::new(1.0, -0.25, 0.9), Vec3::Y)
}

/// A level: the source vertices it uses, and its triangles over them.
type Level = (Vec<u32>, Vec<u32>);

/// meshoptimizer's levels below full detail: each about half the one before, down to about
/// 300 triangles. Each is the source vertices it uses and its triangles over them (as a user
/// exporting levels would have them).
fn meshopt_levels(positions: &[[f32; 3]], indices: &[u32]) -> Result<Vec<Level>, String> {
    let adapter = meshopt::VertexDataAdapter::new(bytemuck::cast_slice(positions), 12, 0)
        .map_err(|e| e.to_string())?;
    let mut levels = Vec::new();
    let mut indices = indices.to_vec();
    while indices.len() / 3 > 600 {
        indices = meshopt::simplify(
            &indices,
            &adapter,
            indices.len() / 2,
            1.0,
            meshopt::SimplifyOptions::None,
            None,
        );
        let mut remap = vec![u32::MAX; positions.len()];
        let mut used = Vec::new();
        let local: Vec<u32> = indices
            .iter()
            .map(|&i| {
                if remap[i as usize] == u32::MAX {
                    remap[i as usize] = used.len() as u32;
                    used.push(i);
                }
                remap[i as usize]
            })
            .collect();
        levels.push((used, local));
    }
    Ok(levels)
}

/// meshoptimizer's chain of `mesh`: full detail, then [`meshopt_levels`].
fn meshopt_chain(mesh: &Mesh) -> Result<Vec<Mesh>, String> {
    let indexed = bevy_aslod::bevy_mesh::from_bevy_mesh(mesh).map_err(|e| e.to_string())?;
    let positions: Vec<[f32; 3]> = indexed.positions.iter().map(|p| p.to_array()).collect();
    let mut chain = vec![mesh.clone()];
    for (used, local) in meshopt_levels(&positions, &indexed.indices)? {
        chain.push(to_bevy_mesh(&indexed.subset(&used), &local));
    }
    Ok(chain)
}

/// meshoptimizer's levels of a skinned (or any indexed triangle) `mesh` below full detail,
/// every vertex attribute carried (joints and weights included).
fn meshopt_skinned_levels(mesh: &Mesh) -> Result<Vec<Mesh>, String> {
    use bevy::mesh::{Indices, VertexAttributeValues as V};
    let Some(V::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return Err("a skinned mesh without Float32x3 positions".into());
    };
    let indices: Vec<u32> = match mesh.indices() {
        Some(Indices::U16(i)) => i.iter().map(|&i| u32::from(i)).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => return Err("a skinned mesh without indices".into()),
    };
    fn pick<T: Copy>(values: &[T], used: &[u32]) -> Vec<T> {
        used.iter().map(|&i| values[i as usize]).collect()
    }
    let mut levels = Vec::new();
    for (used, local) in meshopt_levels(positions, &indices)? {
        let mut level = Mesh::new(mesh.primitive_topology(), mesh.asset_usage);
        for (attribute, values) in mesh.attributes() {
            let values = match values {
                V::Float32(v) => V::Float32(pick(v, &used)),
                V::Float32x2(v) => V::Float32x2(pick(v, &used)),
                V::Float32x3(v) => V::Float32x3(pick(v, &used)),
                V::Float32x4(v) => V::Float32x4(pick(v, &used)),
                V::Uint16x4(v) => V::Uint16x4(pick(v, &used)),
                V::Unorm16x4(v) => V::Unorm16x4(pick(v, &used)),
                V::Unorm8x4(v) => V::Unorm8x4(pick(v, &used)),
                V::Uint32(v) => V::Uint32(pick(v, &used)),
                _ => {
                    return Err(format!(
                        "attribute {} of format {:?} is not carried",
                        attribute.name, attribute.format
                    ));
                }
            };
            level.insert_attribute(*attribute, values);
        }
        level.insert_indices(Indices::U32(local));
        levels.push(level);
    }
    Ok(levels)
}

/// Where level `k` of (b)'s chain starts to show: from 6·√2^(k-1) units on, so a level's
/// triangles halve as its projected area does.
fn lod_distance(k: usize) -> f32 {
    if k == 0 {
        0.0
    } else {
        6.0 * std::f32::consts::SQRT_2.powi(k as i32 - 1)
    }
}

/// Level `k`'s range among `levels`.
fn lod_range(k: usize, levels: usize) -> VisibilityRange {
    let end = if k + 1 == levels {
        f32::MAX
    } else {
        lod_distance(k + 1)
    };
    VisibilityRange::abrupt(lod_distance(k), end)
}

/// (b) for skinned scenes: every skinned mesh entity shows full detail up to
/// [`lod_distance`]`(1)`, and a sibling per meshoptimizer level, with the same skin and
/// material, takes over from there.
fn add_skinned_chains(app: &mut App) -> Result<(), String> {
    let world = app.world_mut();
    let mut query = world.query_filtered::<(
        Entity,
        &Mesh3d,
        &SkinnedMesh,
        &MeshMaterial3d<StandardMaterial>,
        &Transform,
        &ChildOf,
    ), Without<VisibilityRange>>();
    let found: Vec<_> = query
        .iter(world)
        .map(|(e, mesh, skin, material, transform, parent)| {
            (
                e,
                mesh.0.clone(),
                skin.clone(),
                material.0.clone(),
                *transform,
                parent.parent(),
            )
        })
        .collect();
    let mut chains: HashMap<AssetId<Mesh>, Vec<Handle<Mesh>>> = HashMap::new();
    for (entity, mesh, skin, material, transform, parent) in found {
        if let std::collections::hash_map::Entry::Vacant(entry) = chains.entry(mesh.id()) {
            let source = world
                .resource::<Assets<Mesh>>()
                .get(&mesh)
                .ok_or("a skinned mesh that is not loaded")?;
            let levels = meshopt_skinned_levels(source)?;
            let mut meshes = world.resource_mut::<Assets<Mesh>>();
            entry.insert(levels.into_iter().map(|m| meshes.add(m)).collect());
        }
        let chain = &chains[&mesh.id()];
        let levels = chain.len() + 1;
        world.entity_mut(entity).insert(lod_range(0, levels));
        for (k, level) in chain.iter().enumerate() {
            world.spawn((
                Mesh3d(level.clone()),
                MeshMaterial3d(material.clone()),
                transform,
                skin.clone(),
                ChildOf(parent),
                lod_range(k + 1, levels),
            ));
        }
    }
    Ok(())
}

/// Vertex and index bytes of every `Mesh` asset.
fn mesh_asset_bytes(app: &App) -> u64 {
    app.world()
        .resource::<Assets<Mesh>>()
        .iter()
        .map(|(_, mesh)| {
            let indices = match mesh.indices() {
                Some(bevy::mesh::Indices::U16(i)) => i.len() * 2,
                Some(bevy::mesh::Indices::U32(i)) => i.len() * 4,
                None => 0,
            };
            (mesh.count_vertices() * mesh.get_vertex_size() as usize + indices) as u64
        })
        .sum()
}

/// Triangles and mesh entities the cameras see (after frustum culling and visibility ranges).
fn visible(app: &mut App) -> (u64, u64) {
    let world = app.world_mut();
    let mut query = world.query::<(&Mesh3d, &ViewVisibility)>();
    let meshes = world.resource::<Assets<Mesh>>();
    let (mut triangles, mut entities) = (0, 0);
    for (mesh, seen) in query.iter(world) {
        if seen.get() {
            entities += 1;
            triangles += meshes
                .get(&mesh.0)
                .and_then(Mesh::indices)
                .map_or(0, |i| i.len() as u64 / 3);
        }
    }
    (triangles, entities)
}

/// One frame of the instance bench.
struct InstanceFrame {
    /// The plugin's systems: allocation, update and deformation.
    parts_ms: [f64; 3],
    /// Bevy's visibility checks ([`VisibilityClock`]).
    visibility_ms: f64,
    /// The render world's extraction, preparation and instance rebuild.
    render_ms: f64,
    /// [`mesh_asset_bytes`].
    mesh_bytes: u64,
    /// Triangles visible ([`visible`]).
    triangles: u64,
    /// Mesh entities visible.
    entities: u64,
    /// The plugin's total (every model, in view or not).
    total: u64,
    /// The whole frame.
    frame_ms: f64,
}

/// What the instance bench draws.
#[derive(Clone, Copy, PartialEq)]
enum Field {
    /// Instances of [`instance_sphere`].
    Spheres,
    /// A crowd of dancing mannequins (`assets/mannequin.glb`, skinned, 30,180 triangles).
    Crowd,
}

/// One way of drawing the instances: its app along the path, frame by frame, and the views
/// for the image error.
fn run_way(
    way: &str,
    field: Field,
    n: usize,
    frames: usize,
    budget: Option<u32>,
) -> Result<(Vec<InstanceFrame>, Vec<Image>), String> {
    let (mut app, camera) = bench_app(budget.unwrap_or(1), 0, Some(ASSETS));
    match field {
        Field::Spheres => spawn_spheres(&mut app, way, n)?,
        Field::Crowd => spawn_crowd(&mut app, way, n)?,
    }
    *app.world_mut()
        .get_mut::<Transform>(camera)
        .ok_or("no camera")? = instance_camera(0.0, n);
    // Pipelines compile slowly on a software rasteriser.
    for _ in 0..60 {
        app.update();
    }
    let mut out = Vec::new();
    for frame in 0..frames {
        *app.world_mut()
            .get_mut::<Transform>(camera)
            .ok_or("no camera")? = instance_camera(frame as f32 / frames as f32, n);
        let start = Instant::now();
        app.update();
        let frame_ms = start.elapsed().as_secs_f64() * 1e3;
        let stats = *app.world().resource::<AslodStats>();
        let (triangles, entities) = visible(&mut app);
        let cost = render_cost(&app);
        out.push(InstanceFrame {
            parts_ms: [stats.allocation_ms, stats.update_ms, stats.deform_ms],
            visibility_ms: app.world().resource::<VisibilityClock>().ms,
            render_ms: cost.extract_ms + cost.prepare_ms + cost.instances_ms,
            mesh_bytes: mesh_asset_bytes(&app),
            triangles,
            entities,
            total: stats.triangles,
            frame_ms,
        });
    }
    // Image error: the same camera at a few points of the path, rendered at 1280×720.
    let big = target(&mut app, 1280, 720);
    app.world_mut()
        .entity_mut(camera)
        .insert(RenderTarget::Image(big.clone().into()));
    let captures = common::Captures::new(1);
    app.insert_resource(captures.clone());
    // Dancers hold their pose, the same in every way, while the views are taken.
    for mut player in app
        .world_mut()
        .query::<&mut AnimationPlayer>()
        .iter_mut(app.world_mut())
    {
        player.pause_all();
    }
    let mut views = Vec::new();
    for t in ERROR_VIEWS {
        *app.world_mut()
            .get_mut::<Transform>(camera)
            .ok_or("no camera")? = instance_camera(t, n);
        for _ in 0..3 {
            app.update();
        }
        views.extend(common::capture(
            &mut app,
            std::slice::from_ref(&big),
            &captures,
        )?);
    }
    Ok((out, views))
}

/// `n` spheres drawn `way` (`a`, `b`, `c`, or `c1` for one region per instance).
fn spawn_spheres(app: &mut App, way: &str, n: usize) -> Result<(), String> {
    let sphere = instance_sphere()?;
    let material = app
        .world_mut()
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::from_color(Color::srgb(0.6, 0.7, 0.5)));
    match way {
        "a" => {
            let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(sphere);
            for i in 0..n {
                app.world_mut().spawn((
                    Mesh3d(mesh.clone()),
                    MeshMaterial3d(material.clone()),
                    Transform::from_translation(instance_position(i, n)),
                ));
            }
        }
        "b" => {
            let chain: Vec<Handle<Mesh>> = meshopt_chain(&sphere)?
                .into_iter()
                .map(|m| app.world_mut().resource_mut::<Assets<Mesh>>().add(m))
                .collect();
            for i in 0..n {
                let at = Transform::from_translation(instance_position(i, n));
                for (k, mesh) in chain.iter().enumerate() {
                    app.world_mut().spawn((
                        Mesh3d(mesh.clone()),
                        MeshMaterial3d(material.clone()),
                        at,
                        lod_range(k, chain.len()),
                    ));
                }
            }
        }
        _ => {
            // `c1`: the whole sphere as one region, one draw per instance as in (b).
            let spec = if way == "c1" {
                PartitionSpec::Single
            } else {
                PartitionSpec::Clusters(4)
            };
            let asset = MultiresMesh::from_bevy_mesh(&sphere, spec).map_err(|e| e.to_string())?;
            let asset = app
                .world_mut()
                .resource_mut::<Assets<MultiresMesh>>()
                .add(asset);
            for i in 0..n {
                app.world_mut().spawn((
                    MultiresModel(asset.clone()),
                    SharedLevels::default(),
                    MeshMaterial3d(material.clone()),
                    Transform::from_translation(instance_position(i, n)),
                ));
            }
        }
    }
    Ok(())
}

/// A crowd of `n` mannequins drawn `way`, dancing out of phase: (a) Bevy's glTF scene, (b)
/// the same with [`add_skinned_chains`], (c) `MultiresScene`.
fn spawn_crowd(app: &mut App, way: &str, n: usize) -> Result<(), String> {
    let gltf: Handle<Gltf> = app.world().resource::<AssetServer>().load("mannequin.glb");
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("mannequin.glb"));
    let roots: Vec<Entity> = (0..n)
        .map(|i| {
            let at = Transform::from_translation(instance_position(i, n) - Vec3::Y)
                .with_rotation(Quat::from_rotation_y(i as f32 * 2.4));
            let mut root = app.world_mut().spawn((WorldAssetRoot(scene.clone()), at));
            if way.starts_with('c') {
                root.insert(MultiresScene::default());
            }
            root.id()
        })
        .collect();
    if way.starts_with('c') {
        clip::start_clip(app, &gltf, &roots, None, 0.7)?;
        if way == "c-cpu" {
            clip::skin_on_cpu(app, &roots);
        }
        return Ok(());
    }
    // Plain scenes: wait for every instance's player, then start the clip on all of them.
    clip::wait_for_players(app, n)?;
    if way == "b" {
        add_skinned_chains(app)?;
    }
    clip::start_clip(app, &gltf, &[], None, 0.7)
}

/// Where along the path the image error is taken.
const ERROR_VIEWS: [f32; 3] = [0.2, 0.5, 0.8];

fn run_instances(counts: &[usize], crowd: Option<usize>, frames: usize) -> Result<(), String> {
    println!(
        "render_cost --instances: a 20,480-triangle sphere, a crowd of mannequins (30,180 triangles, skinned, dancing), 32x18 target, image error at 1280x720; {}",
        common::machine()
    );
    println!(
        "| scene | instances | way | budget | ours ms | Bevy visibility ms | render world ms | mesh bytes | triangles visible | mesh entities visible | frame ms | PSNR against (a), median of 3 views (worst) |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let scenes = counts
        .iter()
        .map(|&n| (Field::Spheres, n))
        .chain(crowd.map(|n| (Field::Crowd, n)));
    for (field, n) in scenes {
        let (scene, shared) = match field {
            Field::Spheres => ("spheres", " SharedLevels"),
            Field::Crowd => ("mannequins", " MultiresScene"),
        };
        let mut rows = Vec::new();
        let (a, reference) = run_way("a", field, n, frames, None)?;
        rows.push(("(a) no LOD".to_string(), None, a, reference.clone()));
        let (b, b_views) = run_way("b", field, n, frames, None)?;
        let budget = median(&b, &|f| f.triangles as f64) as u32;
        rows.push((
            "(b) meshopt chain + VisibilityRange".to_string(),
            None,
            b,
            b_views,
        ));
        let (c, c_views) = run_way("c", field, n, frames, Some(budget.max(1)))?;
        // The plugin's budget counts every model, out-of-view ones at their coarsest (and
        // regions of models in view that are culled): for equal triangles *in view*, P is
        // searched by secant steps from P + what the first run spent out of view.
        let visible_of = |frames: &[InstanceFrame]| median(frames, &|f| f.triangles as f64);
        let target = f64::from(budget);
        let mut last = (f64::from(budget), visible_of(&c));
        let mut matched = budget
            .saturating_add(median(&c, &|f| f.total.saturating_sub(f.triangles) as f64) as u32);
        let over = c.iter().filter(|f| f.total > u64::from(budget)).count();
        rows.push((format!("(c){shared}"), Some(budget), c, c_views));
        let mut runs = 0;
        let (c2, c2_views) = loop {
            let (c2, c2_views) = run_way("c", field, n, frames, Some(matched.max(1)))?;
            runs += 1;
            let visible = visible_of(&c2);
            if (visible - target).abs() <= 0.03 * target || runs == 4 {
                break (c2, c2_views);
            }
            let slope = (visible - last.1) / (f64::from(matched) - last.0);
            last = (f64::from(matched), visible);
            let step = if slope > 0.0 {
                (target - visible) / slope
            } else {
                target - visible
            };
            matched = (f64::from(matched) + step).clamp(1.0, f64::from(u32::MAX)) as u32;
        };
        let over_matched = c2.iter().filter(|f| f.total > u64::from(matched)).count();
        rows.push((
            format!("(c){shared}, equal triangles in view"),
            Some(matched),
            c2,
            c2_views,
        ));
        if field == Field::Crowd {
            // The paper's CPU blend (each dancer its own meshes) under the same budget.
            let (cc, cc_views) = run_way("c-cpu", field, n, frames, Some(matched.max(1)))?;
            rows.push((
                format!("(c){shared}, skinned on the CPU (NoSharedLevels), same budget"),
                Some(matched),
                cc,
                cc_views,
            ));
        }
        if field == Field::Spheres {
            // One region per instance (one draw each, as in (b)) under the same budget.
            let (c1, c1_views) = run_way("c1", field, n, frames, Some(matched.max(1)))?;
            rows.push((
                format!("(c){shared}, one region, same budget"),
                Some(matched),
                c1,
                c1_views,
            ));
        }
        for (way, budget, frames, views) in &rows {
            let mut psnr: Vec<f64> = views
                .iter()
                .zip(&reference)
                .map(|(v, r)| common::psnr_mad(v, r).0)
                .collect();
            psnr.sort_by(f64::total_cmp);
            println!(
                "| {scene} | {n} | {way} | {} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} ({:.1}) |",
                budget.map_or("–".to_string(), |b| b.to_string()),
                median(frames, &|f| f.parts_ms.iter().sum()),
                median(frames, &|f| f.visibility_ms),
                median(frames, &|f| f.render_ms),
                median(frames, &|f| f.mesh_bytes as f64),
                median(frames, &|f| f.triangles as f64),
                median(frames, &|f| f.entities as f64),
                median(frames, &|f| f.frame_ms),
                psnr.get(psnr.len() / 2).copied().unwrap_or(0.0),
                psnr.first().copied().unwrap_or(0.0),
            );
        }
        for (way, _, frames, _) in rows.iter().filter(|r| r.1.is_some()) {
            let part = |k: usize| median(frames, &|f| f.parts_ms[k]);
            println!(
                "{scene} {n} {way}: ours = allocation {:.2} + update {:.2} + deform {:.2} ms (medians)",
                part(0),
                part(1),
                part(2)
            );
        }
        println!(
            "{scene} (c): the plugin's total exceeded P in {over} and {over_matched} of {frames} frames (its floor: every model at its coarsest)"
        );
    }
    Ok(())
}

/// The median of `f` over `frames`.
fn median(frames: &[InstanceFrame], f: &dyn Fn(&InstanceFrame) -> f64) -> f64 {
    let mut v: Vec<f64> = frames.iter().map(f).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}
