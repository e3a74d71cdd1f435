//! Pieces the examples share: the app's plugins with or without a window, a fly camera,
//! loading a glTF character's clip, offscreen screenshots, and frame-time statistics.
#![allow(dead_code)]

pub mod chart;
pub mod field;
pub mod stats;
pub mod terrain;
pub mod tint;

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::primitives::Aabb;
use bevy::gltf::Gltf;
use bevy::input::mouse::AccumulatedMouseMotion;
use bevy::prelude::*;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::render::render_resource::TextureFormat;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_aslod::budget::Obb;
use bevy_aslod::plugin::{MultiresInstance, MultiresSceneModels};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// `DefaultPlugins` with assets read from `asset_root`: in a window titled `title`, or, when
/// `headless`, with no window at all (the examples render into an `Image`), run as fast as
/// the frames go.
pub fn add_default_plugins(app: &mut App, headless: bool, title: &str, asset_root: Option<&Path>) {
    let mut assets = AssetPlugin::default();
    if let Some(root) = asset_root {
        assets.file_path = root.to_string_lossy().into_owned();
    }
    if headless {
        app.add_plugins((
            DefaultPlugins
                .set(assets)
                .set(WindowPlugin {
                    primary_window: None,
                    exit_condition: ExitCondition::DontExit,
                    ..default()
                })
                .disable::<WinitPlugin>(),
            ScheduleRunnerPlugin::run_loop(Duration::ZERO),
        ));
    } else {
        app.add_plugins(DefaultPlugins.set(assets).set(WindowPlugin {
            primary_window: Some(Window {
                title: title.into(),
                ..default()
            }),
            ..default()
        }));
    }
}

/// A headless app for offscreen rendering, driven by `update` by hand: `DefaultPlugins`
/// without a window, winit or pipelined rendering (so each `update` draws its frame), assets
/// read from `asset_root` when given, and a clock of exactly 1/60 s per frame. The caller adds
/// its own plugins, then `finish` and `cleanup`.
pub fn offscreen_app(asset_root: Option<&Path>) -> App {
    offscreen_app_with_gltf(asset_root, bevy::gltf::GltfPlugin::default())
}

/// [`offscreen_app`] with a glTF loader of one's own (custom vertex attributes).
pub fn offscreen_app_with_gltf(asset_root: Option<&Path>, gltf: bevy::gltf::GltfPlugin) -> App {
    let mut assets = AssetPlugin::default();
    if let Some(root) = asset_root {
        assets.file_path = root.to_string_lossy().into_owned();
    }
    let plugins = DefaultPlugins
        .set(assets)
        .set(gltf)
        .set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            ..default()
        })
        .disable::<WinitPlugin>()
        .disable::<PipelinedRenderingPlugin>();
    let mut app = App::new();
    app.add_plugins((plugins, ScheduleRunnerPlugin::run_once()))
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
            1.0 / 60.0,
        )));
    app
}

/// `WIDTHxHEIGHT`, each side 16..=8192 pixels: a clap value parser for image sizes.
pub fn parse_size(size: &str) -> Result<(u32, u32), String> {
    size.split_once('x')
        .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
        .filter(|&(w, h)| (16..=8192).contains(&w) && (16..=8192).contains(&h))
        .ok_or(format!("not WIDTHxHEIGHT (16..=8192): {size}"))
}

/// `area` or `error`: a clap value parser for `--split` (`RegionSplit::Area` or
/// `RegionSplit::ScreenError`).
pub fn parse_split(split: &str) -> Result<bevy_aslod::plugin::RegionSplit, String> {
    use bevy_aslod::plugin::RegionSplit;
    match split {
        "area" => Ok(RegionSplit::Area),
        "error" => Ok(RegionSplit::ScreenError),
        _ => Err(format!("not `area` or `error`: {split}")),
    }
}

/// The asset folder (the model's own) and the file name to load from it.
pub fn split_model_path(model: &Path) -> Result<(PathBuf, String), String> {
    let model = model
        .canonicalize()
        .map_err(|e| format!("cannot open the model {}: {e}", model.display()))?;
    let file = model
        .file_name()
        .and_then(|f| f.to_str())
        .ok_or_else(|| format!("{} has no usable file name", model.display()))?
        .to_owned();
    let root = model
        .parent()
        .ok_or_else(|| format!("{} has no folder", model.display()))?
        .to_path_buf();
    Ok((root, file))
}

/// The `MultiresScene` for the glTF `file` in the asset folder `root`: loading its assets
/// from the `.mrm` file baked beside it (`aslod bake model.glb -o model.mrm`) when there is
/// one, building them otherwise.
pub fn multires_scene(root: &Path, file: &str) -> bevy_aslod::plugin::MultiresScene {
    let scene = bevy_aslod::plugin::MultiresScene::default();
    let baked = Path::new(file).with_extension("mrm");
    match root.join(&baked).is_file() {
        true => scene.with_baked(baked.to_string_lossy()),
        false => scene,
    }
}

/// The clip called `name` (or the first one) of a loaded glTF, or an error that lists the
/// clips there are.
pub fn pick_clip(
    gltf: &Gltf,
    file: &str,
    name: Option<&str>,
) -> Result<Handle<AnimationClip>, String> {
    match name {
        Some(name) => gltf.named_animations.get(name).cloned().ok_or_else(|| {
            let mut names: Vec<&str> = gltf.named_animations.keys().map(|k| k.as_ref()).collect();
            names.sort_unstable();
            format!("{file} has no clip named {name:?}; it has {names:?}")
        }),
        None => gltf
            .animations
            .first()
            .cloned()
            .ok_or_else(|| format!("{file} has no animation")),
    }
}

/// The world-space bounds of a converted scene: its multiresolution models' region boxes and
/// its conventional (fixed-cost) meshes' boxes; `None` until every model has its instance
/// and boxes.
pub fn scene_bounds(
    models: &MultiresSceneModels,
    instances: &Query<(&MultiresInstance, &GlobalTransform)>,
    fixed: &Query<(&Aabb, &GlobalTransform)>,
) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for model in models.models() {
        let (instance, transform) = instances.get(model).ok()?;
        let boxes = region_world_boxes(instance, transform)?;
        for corner in boxes.iter().flat_map(|b| b.corners()) {
            lo = lo.min(corner);
            hi = hi.max(corner);
        }
    }
    for (aabb, transform) in models.fixed.iter().filter_map(|&e| fixed.get(e).ok()) {
        let obb =
            Obb::from_aabb(aabb.min().into(), aabb.max().into()).transformed(&transform.affine());
        for corner in obb.corners() {
            lo = lo.min(corner);
            hi = hi.max(corner);
        }
    }
    let size = hi - lo;
    (size.is_finite() && size.y > 0.0).then_some((lo, hi))
}

/// Every region's world box, in region order: moved with its bones for a skinned model
/// (`None` until the plugin's first `Allocate` after the model appears fills them), else the
/// region's bounds under the model's transform.
pub fn region_world_boxes(
    instance: &MultiresInstance,
    transform: &GlobalTransform,
) -> Option<Vec<Obb>> {
    match instance.skinned_world_boxes() {
        Some([]) => None,
        Some(boxes) => Some(boxes.to_vec()),
        None => {
            let affine = transform.affine();
            let regions = instance.regions().regions();
            Some(
                regions
                    .iter()
                    .map(|r| {
                        let (a, b) = r.bounds();
                        Obb::from_aabb(a, b).transformed(&affine)
                    })
                    .collect(),
            )
        }
    }
}

/// A camera the user flies: WASD, Q/E down/up, Shift faster, drag with the left mouse
/// button to look. `speed` is in world units per second; it does nothing while `enabled` is
/// false.
#[derive(Component, Debug)]
pub struct FlyCamera {
    pub enabled: bool,
    pub speed: f32,
}

pub fn fly_camera(
    time: Res<Time>,
    input: Res<ButtonInput<KeyCode>>,
    mouse: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    mut cameras: Query<(&mut Transform, &FlyCamera)>,
) {
    for (mut transform, fly) in &mut cameras {
        if !fly.enabled {
            continue;
        }
        if mouse.pressed(MouseButton::Left) && motion.delta != Vec2::ZERO {
            let (yaw, pitch, _) = transform.rotation.to_euler(EulerRot::YXZ);
            let yaw = yaw - motion.delta.x * 0.003;
            let pitch = (pitch - motion.delta.y * 0.003).clamp(-1.54, 1.54);
            transform.rotation = Quat::from_euler(EulerRot::YXZ, yaw, pitch, 0.0);
        }
        let mut dir = Vec3::ZERO;
        for (key, d) in [
            (KeyCode::KeyW, *transform.forward()),
            (KeyCode::KeyS, *transform.back()),
            (KeyCode::KeyA, *transform.left()),
            (KeyCode::KeyD, *transform.right()),
            (KeyCode::KeyE, Vec3::Y),
            (KeyCode::KeyQ, Vec3::NEG_Y),
        ] {
            if input.pressed(key) {
                dir += d;
            }
        }
        let speed = if input.pressed(KeyCode::ShiftLeft) {
            fly.speed * 4.0
        } else {
            fly.speed
        };
        transform.translation += dir.normalize_or_zero() * speed * time.delta_secs();
    }
}

/// An offscreen render target of `size` pixels (sRGB view) for a camera's `RenderTarget`.
pub fn offscreen_image(images: &mut Assets<Image>, size: (u32, u32)) -> Handle<Image> {
    images.add(Image::new_target_texture(
        size.0,
        size.1,
        TextureFormat::Rgba8Unorm,
        Some(TextureFormat::Rgba8UnormSrgb),
    ))
}

/// Whether a captured frame shows something: more than a tenth of its pixels differ from
/// the first one (pipelines compile slowly on a software rasteriser, and until then the
/// frame is the clear colour).
pub fn is_drawn(captured: &ScreenshotCaptured) -> bool {
    captured.image.data.as_ref().is_some_and(|data| {
        let first = data.get(..4).unwrap_or(&[]);
        let differing = data.chunks_exact(4).filter(|p| *p != first).count();
        differing * 10 > data.len() / 4
    })
}

/// Saves a captured frame as PNG, logging the outcome.
pub fn save_capture(captured: &ScreenshotCaptured, path: &Path) -> bool {
    match captured.image.clone().try_into_dynamic() {
        Ok(img) => match img.to_rgb8().save(path) {
            Ok(()) => {
                info!("saved {}", path.display());
                true
            }
            Err(e) => {
                error!("cannot save {}: {e}", path.display());
                false
            }
        },
        Err(e) => {
            error!("cannot convert the screenshot: {e}");
            false
        }
    }
}

/// The share of an image's pixels that differ from its first one (the clear colour, in a
/// frame drawn before the pipelines are ready).
pub fn varied(image: &Image) -> f64 {
    let Some(data) = &image.data else { return 0.0 };
    let first = &data[..4];
    data.chunks_exact(4).filter(|p| p != &first).count() as f64 / (data.len() / 4) as f64
}

/// The largest channel difference between two images, and the share of pixels that differ
/// by more than 2 in a channel (images of other sizes differ everywhere).
pub fn compare(a: &Image, b: &Image) -> (u8, f64) {
    let (Some(a), Some(b)) = (&a.data, &b.data) else {
        return (255, 1.0);
    };
    if a.len() != b.len() {
        return (255, 1.0);
    }
    let mut max = 0;
    let mut differing = 0;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let d = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        max = max.max(d);
        differing += usize::from(d > 2);
    }
    (max, differing as f64 / (a.len() / 4) as f64)
}

/// Saves an image as PNG.
pub fn save_image(image: &Image, path: &Path) -> Result<(), String> {
    image
        .clone()
        .try_into_dynamic()
        .map_err(|e| e.to_string())?
        .to_rgb8()
        .save(path)
        .map_err(|e| format!("save {}: {e}", path.display()))
}

/// The PSNR reported for identical images (dB; JSON has no infinity).
pub const IDENTICAL_PSNR: f64 = 100.0;

/// PSNR (dB, over RGB; [`IDENTICAL_PSNR`] for identical images) and mean absolute difference
/// (per channel, of 255) between two images of one size, over the pixels where either shows
/// the scene (not the clear colour, which is the first pixel's: the views keep the scene off
/// the corners), so the background does not dilute them.
pub fn psnr_mad(a: &Image, b: &Image) -> (f64, f64) {
    let (Some(a), Some(b)) = (&a.data, &b.data) else {
        return (0.0, 255.0);
    };
    let clear = &a[..4];
    let (mut squared, mut absolute, mut count) = (0.0f64, 0.0f64, 0usize);
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        if pa == clear && pb == clear {
            continue;
        }
        for c in 0..3 {
            let d = f64::from(pa[c]) - f64::from(pb[c]);
            squared += d * d;
            absolute += d.abs();
            count += 1;
        }
    }
    let mse = squared / count.max(1) as f64;
    let psnr = if mse == 0.0 {
        IDENTICAL_PSNR
    } else {
        (10.0 * (255.0 * 255.0 / mse).log10()).min(IDENTICAL_PSNR)
    };
    (psnr, absolute / count.max(1) as f64)
}

/// The last capture of each camera (a resource [`capture`] fills).
#[derive(Resource, Clone, Default)]
pub struct Captures(pub Arc<Mutex<Vec<Option<Image>>>>);

impl Captures {
    /// Room for `cameras` captures; insert it as a resource before [`capture`].
    pub fn new(cameras: usize) -> Self {
        Self(Arc::new(Mutex::new(vec![None; cameras])))
    }
}

/// Screenshots of `images`, taken a few frames from now.
pub fn capture(
    app: &mut App,
    images: &[Handle<Image>],
    captures: &Captures,
) -> Result<Vec<Image>, String> {
    captures
        .0
        .lock()
        .expect("captures")
        .iter_mut()
        .for_each(|c| *c = None);
    for (i, image) in images.iter().enumerate() {
        app.world_mut()
            .spawn(Screenshot::image(image.clone()))
            .observe(
                move |captured: On<ScreenshotCaptured>, captures: Res<Captures>| {
                    captures.0.lock().expect("captures")[i] = Some(captured.image.clone());
                },
            );
    }
    // Readbacks arrive a few frames later, later still while pipelines compile on a
    // busy machine.
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        app.update();
        let done = captures
            .0
            .lock()
            .expect("captures")
            .iter()
            .all(Option::is_some);
        if done {
            return Ok(captures
                .0
                .lock()
                .expect("captures")
                .iter()
                .map(|c| c.clone().expect("captured"))
                .collect());
        }
    }
    Err("the screenshots did not arrive within two minutes".into())
}

/// Lets the pipelines compile (slowly on lavapipe) until every view shows the scene.
pub fn wait_until_drawn(
    app: &mut App,
    images: &[Handle<Image>],
    captures: &Captures,
    dir: &Path,
) -> Result<(), String> {
    let mut shots = Vec::new();
    for _ in 0..60 {
        for _ in 0..5 {
            app.update();
        }
        shots = capture(app, images, captures)?;
        // A blank frame is all clear colour; a slim model (a bottle seen whole) covers
        // only a tenth of the view.
        if shots.iter().all(|s| varied(s) > 0.02) {
            return Ok(());
        }
    }
    for (i, shot) in shots.iter().enumerate() {
        save_image(shot, &dir.join(format!("view{i}_blank.png")))?;
    }
    Err(format!(
        "the scene was never drawn (fraction of pixels unlike the first: {:?}); see {}",
        shots.iter().map(varied).collect::<Vec<_>>(),
        dir.display()
    ))
}

/// The build and the machine, for a bench's title: `release build, <CPU>, N cores`.
pub fn machine() -> String {
    format!(
        "{} build, {}, {} cores",
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        cpu_name(),
        std::thread::available_parallelism().map_or(0, usize::from)
    )
}

/// The CPU's model name.
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}
