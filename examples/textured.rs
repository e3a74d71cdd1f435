//! Real assets judged in pixels: a glTF scene with its own materials and textures, drawn
//! offscreen (Vulkan; lavapipe without a GPU) from orbit views by plain Bevy (the reference),
//! as a `MultiresScene` at `FullDetail`, as a `MultiresScene` at fractions of its triangles,
//! and, at the same triangle counts per mesh, as meshoptimizer's `simplify_with_attributes`
//! levels drawn by plain Bevy (the plain scene with its meshes swapped for them).
//!
//! `textured [MODEL] [--views N] [--size PX] [--ratios 0.5,0.2,0.05] [--out DIR] [--no-peer]`
//! writes `DIR/report.json` (per view: how the full-detail image differs from the reference,
//! and per ratio the triangles, PSNR and mean absolute difference of ours and meshoptimizer's;
//! medians and the worst view), the first view's PNGs, and `compare.png` (reference, ours,
//! meshoptimizer at the smallest ratio), and prints a table. `MODEL` defaults to the shared
//! test data's `textured/WaterBottle.glb`. The render test runs it with `--views 2 --ratios
//! 0.05 --no-peer`. With `--copies N` it writes MODEL placed N times by one glTF
//! (`field.glb`) and draws one view across the field from beside its corner copy, reporting
//! the nearest and farthest copies' triangles (`--min-pixels P` sets
//! `PolygonBudget::min_pixels`).

mod common;

use bevy::asset::RenderAssetUsages;
use bevy::camera::RenderTarget;
use bevy::camera::primitives::Aabb;
use bevy::gltf::Gltf;
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::bevy_mesh::from_bevy_mesh;
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::plugin::{
    AslodPlugin, FullDetail, MultiresInstance, MultiresScene, MultiresSceneConverted,
    MultiresSceneModels, MultiresSourceMesh, NoSharedLevels, PolygonBudget, RegionSplit,
};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const WATER_BOTTLE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/textured/WaterBottle.glb"
);

/// meshoptimizer's attribute weights: normals (3), the first UV set (2) and, where the mesh
/// has them, vertex colours (RGBA, 4), relative to the
/// position error (its header: "the weights determine relative priority of attributes
/// between each other and wrt position"; its demo weighs normals 0.5).
const PEER_WEIGHTS: [f32; 9] = [0.5, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];

/// Rendered images of a glTF scene: plain Bevy, ours and meshoptimizer's.
#[derive(clap::Parser, Debug)]
struct Args {
    /// The glTF or GLB scene.
    #[arg(default_value = WATER_BOTTLE)]
    model: PathBuf,
    /// Orbit views around the scene.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=64))]
    views: u32,
    /// Width and height of each view in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=4096))]
    size: u32,
    /// Fractions of the scene's triangles to draw it at.
    #[arg(long, value_delimiter = ',', default_values_t = [0.5, 0.2, 0.05])]
    ratios: Vec<f64>,
    /// Where the report and the images go.
    #[arg(long, default_value = "out/textured")]
    out: PathBuf,
    /// Leave meshoptimizer's levels out.
    #[arg(long)]
    no_peer: bool,
    /// meshoptimizer's levels with its `Permissive` flag (past seams and non-manifold
    /// edges): the peer for assets its plain simplification cannot reduce, such as
    /// flat-shaded ones.
    #[arg(long)]
    peer_permissive: bool,
    /// Draw a procedural asset instead of MODEL: a bumpy sphere with vertex colours (bands
    /// that cross its tessellation), a second UV set and a custom attribute (`_TINT`, stripes
    /// of brightness that a material of the example's reads), written as `procedural.glb`
    /// into the output folder.
    #[arg(long)]
    procedural: bool,
    /// With `--procedural`: flat-shade the sphere (every triangle its own three vertices,
    /// with the face's normal: hard edges everywhere).
    #[arg(long)]
    flat: bool,
    /// Our build's `BuildOptions::normal_weight` (default: the crate's).
    #[arg(long)]
    normal_weight: Option<f64>,
    /// Our build's `BuildOptions::uv_weight` (default: the crate's).
    #[arg(long)]
    uv_weight: Option<f64>,
    /// Our build's `BuildOptions::color_weight` (default: the crate's).
    #[arg(long)]
    color_weight: Option<f64>,
    /// Place MODEL (a `.glb`) this many times (rounded up to a square) on a grid `spacing`
    /// apart, as one glTF whose nodes share its meshes (`field.glb` in the output folder), and
    /// draw one view across it from a corner, beside the nearest copy. The report gives the
    /// triangles of the nearest and the farthest copies.
    #[arg(long, default_value_t = 1)]
    copies: usize,
    /// `PolygonBudget::min_pixels`: models smaller on screen than this many pixels across
    /// show nothing and leave their share of the budget to the others (default: off).
    #[arg(long, default_value_t = 0.0)]
    min_pixels: f32,
    /// With `--copies`: time this many frames (medians, ms) of plain Bevy and of ours at
    /// full detail (the same triangles), sharing level meshes (the default) and with a mesh
    /// of its own per model (`NoSharedLevels`), each once its view is settled.
    #[arg(long, default_value_t = 0)]
    frame_times: usize,
    /// With `--copies`: metres between neighbouring copies.
    #[arg(long, default_value_t = 1.5)]
    spacing: f32,
    /// How a model's triangles are shared among its regions: `error`
    /// (`RegionSplit::ScreenError`, the plugin's default) or `area` (`RegionSplit::Area`).
    #[arg(long, default_value = "error", value_parser = common::parse_split)]
    split: RegionSplit,
}

fn main() {
    let args = <Args as clap::Parser>::parse();
    if let Err(e) = run(&args) {
        eprintln!("textured: {e}");
        std::process::exit(1);
    }
}

/// Plain-scene entities whose meshes were swapped, with their own meshes.
type Swapped = Vec<(Entity, Handle<Mesh>)>;

/// The screenshots that arrived, by slot.
#[derive(Resource, Clone, Default)]
struct Captured(Arc<Mutex<Option<Image>>>);

/// The scene twice at one place (the plain one and the `MultiresScene`, one of them hidden),
/// a light, and a camera drawing into an image.
struct Stage {
    app: App,
    plain: Entity,
    ours: Entity,
    camera: Entity,
    target: Handle<Image>,
    captured: Captured,
}

fn run(args: &Args) -> Result<(), String> {
    if args.ratios.iter().any(|r| !(*r > 0.0 && *r <= 1.0)) {
        return Err(format!("ratios must be in (0, 1]: {:?}", args.ratios));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("create {}: {e}", args.out.display()))?;
    let model = if args.procedural {
        let path = args.out.join("procedural.glb");
        std::fs::write(&path, procedural_glb(args.flat))
            .map_err(|e| format!("write {}: {e}", path.display()))?;
        path
    } else {
        args.model.clone()
    };
    let side = (args.copies as f64).sqrt().ceil() as usize;
    let model = if args.copies > 1 {
        common::field::prop_field(&model, &args.out, side, args.spacing)
    } else {
        model
    };
    let (root, file) = common::split_model_path(&model)?;
    let mut options = BuildOptions::default();
    options.normal_weight = args.normal_weight.unwrap_or(options.normal_weight);
    options.uv_weight = args.uv_weight.unwrap_or(options.uv_weight);
    options.color_weight = args.color_weight.unwrap_or(options.color_weight);
    let scene = MultiresScene::default().with_build_options(options.clone());
    let mut stage = Stage::new(&root, &file, args.size, scene, args.procedural)?;
    let (center, radius) = stage.bounds()?;
    let full = stage.full_triangles();
    let mut views = Vec::new();
    let mut pictures = Vec::new();
    let mut coarse_attributes = Vec::new();
    let view_count = if args.copies > 1 { 1 } else { args.views };
    let mut frame_report = serde_json::Value::Null;
    for k in 0..view_count {
        let azimuth = std::f32::consts::TAU * k as f32 / args.views as f32 + 0.4;
        let elevation: f32 = if k % 2 == 0 { 0.35 } else { -0.15 };
        let eye = if args.copies > 1 {
            // Beside the corner copy, a little above the props, looking across the field.
            let half = (side as f32 - 1.0) * 0.5 * args.spacing;
            center
                + Vec3::new(
                    -half - 0.6 * args.spacing,
                    0.3 * args.spacing,
                    -half - 0.6 * args.spacing,
                )
        } else {
            center
                + radius
                    * 2.4
                    * Vec3::new(
                        elevation.cos() * azimuth.sin(),
                        elevation.sin(),
                        elevation.cos() * azimuth.cos(),
                    )
        };
        stage
            .app
            .world_mut()
            .entity_mut(stage.camera)
            .insert(Transform::from_translation(eye).looking_at(center, Vec3::Y));
        stage.show(true, false);
        let reference = stage.capture_stable()?;
        stage.show(false, true);
        stage.set_full_detail(true);
        let ours_full = stage.capture_stable()?;
        if args.copies > 1 && args.frame_times > 0 && k == 0 {
            let [plain, shared, own] = stage.frame_times(args.frame_times)?;
            println!(
                "{} copies, {full} triangles, frame medians of {} frames: plain Bevy {plain:.1} ms, \
                 ours sharing level meshes {shared:.1} ms ({:.2}x), ours with a mesh per model \
                 {own:.1} ms ({:.2}x)",
                side * side,
                args.frame_times,
                shared / plain,
                own / plain
            );
            frame_report = json!({ "plain_ms": plain, "shared_ms": shared, "own_ms": own });
        }
        let (max, fraction) = common::compare(&reference, &ours_full);
        let (psnr, mad) = common::psnr_mad(&reference, &ours_full);
        let mut rows = Vec::new();
        let mut shots = vec![
            ("reference".to_string(), reference.clone()),
            ("ours_full".to_string(), ours_full),
        ];
        for &ratio in &args.ratios {
            stage.set_full_detail(false);
            let budget = ((full as f64 * ratio).round() as u32).max(1);
            let mut polygons = stage.app.world_mut().resource_mut::<PolygonBudget>();
            polygons.total = budget;
            polygons.split = args.split;
            polygons.min_pixels = args.min_pixels;
            let ours = stage.capture_stable()?;
            let counts = stage.source_triangles();
            if k == 0 {
                coarse_attributes.push(json!({
                    "ratio": ratio,
                    "problems": stage.attribute_problems(),
                }));
            }
            let drawn: usize = stage.model_triangles();
            let (ours_psnr, ours_mad) = common::psnr_mad(&reference, &ours);
            let mut row = json!({
                "ratio": ratio,
                "budget": budget,
                "triangles": drawn,
                "ours": { "psnr": ours_psnr, "mad": ours_mad, "mean_color": mean_color(&ours) },
            });
            if args.copies > 1 {
                let (near, far, hidden) = stage.copy_triangles(eye, side * side);
                row["nearest_copy"] = json!(near);
                row["farthest_copy"] = json!(far);
                row["hidden_models"] = json!(hidden);
                println!(
                    "{} copies at a budget of {budget}: {drawn} triangles drawn, the nearest \
                     copy {near}, the farthest {far}, {hidden} models hidden; PSNR \
                     {ours_psnr:.2} dB against plain Bevy",
                    side * side
                );
            }
            shots.push((format!("ours_{ratio}"), ours));
            if !args.no_peer {
                let (swapped, peer_triangles) =
                    stage.swap_in_peer(&counts, args.peer_permissive)?;
                stage.show(true, false);
                let peer = stage.capture_stable()?;
                stage.restore(swapped);
                let (peer_psnr, peer_mad) = common::psnr_mad(&reference, &peer);
                row["meshopt"] =
                    json!({ "psnr": peer_psnr, "mad": peer_mad, "triangles": peer_triangles });
                shots.push((format!("meshopt_{ratio}"), peer));
                stage.show(false, true);
            }
            rows.push(row);
        }
        if k == 0 {
            for (name, image) in &shots {
                common::save_image(image, &args.out.join(format!("view0_{name}.png")))?;
            }
            pictures = shots;
        }
        views.push(json!({
            "view": k,
            "varied": common::varied(&reference),
            "mean_color": mean_color(&reference),
            "full_detail": {
                "fraction_over_2": fraction,
                "max_channel_difference": max,
                "psnr": psnr,
                "mad": mad,
            },
            "ratios": rows,
        }));
    }
    let smallest = args.ratios.iter().copied().fold(f64::INFINITY, f64::min);
    let picked: Vec<&Image> = [
        "reference".to_string(),
        format!("ours_{smallest}"),
        format!("meshopt_{smallest}"),
    ]
    .iter()
    .filter_map(|name| pictures.iter().find(|(n, _)| n == name).map(|(_, i)| i))
    .collect();
    common::save_image(&side_by_side(&picked), &args.out.join("compare.png"))?;
    let report = json!({
        "model": model.display().to_string(),
        "size": args.size,
        "full_triangles": full,
        "peer_weights": PEER_WEIGHTS,
        "attribute_weights": [options.normal_weight, options.uv_weight, options.color_weight],
        "views": views,
        "frame_times": frame_report,
        "summary": summary(&views, &args.ratios),
        "coarse_attributes": coarse_attributes,
    });
    std::fs::write(
        args.out.join("report.json"),
        serde_json::to_string_pretty(&report).expect("json"),
    )
    .map_err(|e| format!("write report.json: {e}"))?;
    print_table(&report);
    Ok(())
}

impl Stage {
    /// Loads the scene twice, waits until both are loaded with their textures and the
    /// `MultiresScene` is converted. With `tint`, every mesh is drawn with the
    /// [`common::tint::TintMaterial`] that reads the custom attribute `_TINT`.
    fn new(
        root: &Path,
        file: &str,
        size: u32,
        multires: MultiresScene,
        tint: bool,
    ) -> Result<Self, String> {
        let mut app = common::offscreen_app_with_gltf(Some(root), common::tint::gltf_plugin());
        app.add_plugins(AslodPlugin::default())
            .insert_resource(ClearColor(Color::srgb(0.1, 0.1, 0.12)));
        if tint {
            common::tint::add_tint(&mut app);
        }
        app.finish();
        app.cleanup();
        let captured = Captured::default();
        app.insert_resource(captured.clone());
        let world = app.world_mut();
        let server = world.resource::<AssetServer>().clone();
        let gltf: Handle<Gltf> = server.load(file.to_owned());
        let scene = server.load(GltfAssetLabel::Scene(0).from_asset(file.to_owned()));
        let plain = world
            .spawn((WorldAssetRoot(scene.clone()), Transform::default()))
            .id();
        let ours = world
            .spawn((
                WorldAssetRoot(scene),
                multires,
                Transform::default(),
                Visibility::Hidden,
            ))
            .id();
        world.spawn((
            DirectionalLight {
                illuminance: 6_000.0,
                shadow_maps_enabled: false,
                ..default()
            },
            Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
        ));
        let target =
            common::offscreen_image(&mut world.resource_mut::<Assets<Image>>(), (size, size));
        let camera = world
            .spawn((
                Camera3d::default(),
                RenderTarget::Image(target.clone().into()),
                Msaa::Off,
                Transform::from_xyz(0.0, 0.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
            ))
            .id();
        // The plugin says when our copy is converted.
        let mut converted_cursor = app
            .world()
            .resource::<Messages<MultiresSceneConverted>>()
            .get_cursor();
        let mut converted = false;
        let start = Instant::now();
        loop {
            app.update();
            let world = app.world();
            let loaded = world
                .resource::<AssetServer>()
                .is_loaded_with_dependencies(&gltf);
            let messages = world.resource::<Messages<MultiresSceneConverted>>();
            converted |= converted_cursor.read(messages).any(|m| m.scene == ours);
            if loaded && converted {
                break;
            }
            if start.elapsed() > Duration::from_secs(300) {
                return Err(format!(
                    "{file} did not load and convert within five minutes (loaded: {loaded})"
                ));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        Ok(Self {
            app,
            plain,
            ours,
            camera,
            target,
            captured,
        })
    }

    /// Which scene is drawn.
    fn show(&mut self, plain: bool, ours: bool) {
        let visibility = |on: bool| {
            if on {
                Visibility::Inherited
            } else {
                Visibility::Hidden
            }
        };
        let world = self.app.world_mut();
        world.entity_mut(self.plain).insert(visibility(plain));
        world.entity_mut(self.ours).insert(visibility(ours));
    }

    /// The median of `n` frames' wall time (ms), after three to settle.
    fn median_frame(&mut self, n: usize) -> f64 {
        for _ in 0..3 {
            self.app.update();
        }
        let mut times: Vec<f64> = (0..n)
            .map(|_| {
                let start = Instant::now();
                self.app.update();
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(f64::total_cmp);
        times[times.len() / 2]
    }

    /// Frame medians of `n` frames, each once its view is settled: plain Bevy, ours as it
    /// is (the caller's `FullDetail` and budget), and ours with `NoSharedLevels` on every
    /// model (taken off again after).
    fn frame_times(&mut self, n: usize) -> Result<[f64; 3], String> {
        self.show(true, false);
        self.capture_stable()?;
        let plain = self.median_frame(n);
        self.show(false, true);
        self.capture_stable()?;
        let shared = self.median_frame(n);
        let models = self.models();
        for &model in &models {
            self.app
                .world_mut()
                .entity_mut(model)
                .insert(NoSharedLevels);
        }
        self.capture_stable()?;
        let own = self.median_frame(n);
        for &model in &models {
            self.app
                .world_mut()
                .entity_mut(model)
                .remove::<NoSharedLevels>();
        }
        self.capture_stable()?;
        Ok([plain, shared, own])
    }

    fn set_full_detail(&mut self, on: bool) {
        self.app.world_mut().insert_resource(FullDetail(on));
    }

    /// The converted scene's models.
    fn models(&self) -> Vec<Entity> {
        self.app
            .world()
            .get::<MultiresSceneModels>(self.ours)
            .map_or_else(Vec::new, |m| m.models().collect())
    }

    /// Every model's triangles at full detail, summed.
    fn full_triangles(&self) -> usize {
        self.models()
            .iter()
            .filter_map(|&m| self.app.world().get::<MultiresInstance>(m))
            .map(|i| {
                i.regions()
                    .regions()
                    .iter()
                    .map(|r| r.max_triangles())
                    .sum::<usize>()
            })
            .sum()
    }

    /// The triangles each model shows now, by the source mesh it was made from (found on the
    /// model, or on its parent for a skinned model); models of one source mesh are averaged.
    fn source_triangles(&self) -> Vec<(Handle<Mesh>, usize)> {
        let world = self.app.world();
        let mut by_source: Vec<(Handle<Mesh>, usize, usize)> = Vec::new();
        for model in self.models() {
            let Some(instance) = world.get::<MultiresInstance>(model) else {
                continue;
            };
            let holder = match world.get::<MultiresSourceMesh>(model) {
                Some(_) => Some(model),
                None => world.get::<ChildOf>(model).map(ChildOf::parent),
            };
            let Some(source) = holder.and_then(|h| world.get::<MultiresSourceMesh>(h)) else {
                continue;
            };
            match by_source.iter_mut().find(|(h, ..)| *h == source.0) {
                Some((_, sum, n)) => {
                    *sum += instance.triangle_count();
                    *n += 1;
                }
                None => by_source.push((source.0.clone(), instance.triangle_count(), 1)),
            }
        }
        by_source
            .into_iter()
            .map(|(h, sum, n)| (h, sum / n))
            .collect()
    }

    /// The triangles drawn of the copy nearest to `eye` and of the farthest, in a field of
    /// `copies` copies of one prop (the models sorted by distance, in groups of the models of
    /// one copy), and how many models are hidden (`PolygonBudget::min_pixels`).
    fn copy_triangles(&mut self, eye: Vec3, copies: usize) -> (usize, usize, usize) {
        let models = self.models();
        let world = self.app.world();
        let mut hidden = 0;
        let mut by_distance: Vec<(f32, usize)> = models
            .iter()
            .filter_map(|&m| {
                let instance = world.get::<MultiresInstance>(m)?;
                let at = world.get::<GlobalTransform>(m)?.translation();
                let drawn = drawn_triangles(world, instance);
                hidden += usize::from(drawn.is_none());
                Some((at.distance(eye), drawn.unwrap_or(0)))
            })
            .collect();
        by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
        let per_copy = (by_distance.len() / copies.max(1)).max(1);
        let sum = |models: &[(f32, usize)]| models.iter().map(|m| m.1).sum();
        let last = by_distance.len().saturating_sub(per_copy);
        (
            sum(&by_distance[..per_copy.min(by_distance.len())]),
            sum(&by_distance[last..]),
            hidden,
        )
    }

    /// The triangles all models show now (none for a hidden one).
    fn model_triangles(&self) -> usize {
        let world = self.app.world();
        self.models()
            .iter()
            .filter_map(|&m| world.get::<MultiresInstance>(m))
            .filter_map(|i| drawn_triangles(world, i))
            .sum()
    }

    /// The centre and radius of the plain scene's meshes' boxes.
    fn bounds(&mut self) -> Result<(Vec3, f32), String> {
        // Boxes are computed in the frames after the meshes arrive.
        for _ in 0..5 {
            self.app.update();
        }
        let world = self.app.world_mut();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let mut boxes = world.query::<(&Aabb, &GlobalTransform)>();
        for (aabb, transform) in boxes.iter(world) {
            let (min, max) = (Vec3::from(aabb.min()), Vec3::from(aabb.max()));
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { min.x } else { max.x },
                    if i & 2 == 0 { min.y } else { max.y },
                    if i & 4 == 0 { min.z } else { max.z },
                );
                let p = transform.transform_point(corner);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            return Err("the scene has no mesh with a bounding box".into());
        }
        Ok(((lo + hi) / 2.0, ((hi - lo).length() / 2.0).max(1e-3)))
    }

    /// A screenshot of the camera's image, taken once two in a row agree (pipelines compile
    /// and levels land over several frames).
    fn capture_stable(&mut self) -> Result<Image, String> {
        let mut last: Option<Image> = None;
        for _ in 0..100 {
            for _ in 0..3 {
                self.app.update();
            }
            let shot = self.capture()?;
            if let Some(last) = &last
                && common::varied(&shot) > 0.005
                && common::compare(last, &shot).0 == 0
            {
                return Ok(shot);
            }
            last = Some(shot);
        }
        Err("the view never settled: each screenshot differs from the one before".into())
    }

    fn capture(&mut self) -> Result<Image, String> {
        *self.captured.0.lock().expect("capture slot") = None;
        self.app
            .world_mut()
            .spawn(Screenshot::image(self.target.clone()))
            .observe(|captured: On<ScreenshotCaptured>, slot: Res<Captured>| {
                *slot.0.lock().expect("capture slot") = Some(captured.image.clone());
            });
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(120) {
            self.app.update();
            if let Some(image) = self.captured.0.lock().expect("capture slot").take() {
                return Ok(image);
            }
        }
        Err("a screenshot did not arrive within two minutes".into())
    }

    /// Gives every mesh entity of the plain scene meshoptimizer's level of its mesh at the
    /// triangles its model shows (`counts`, by source mesh), keeping its material, skin and
    /// transform. Returns the entities with their own meshes, for [`restore`](Self::restore),
    /// and the triangles the levels draw.
    fn swap_in_peer(
        &mut self,
        counts: &[(Handle<Mesh>, usize)],
        permissive: bool,
    ) -> Result<(Swapped, usize), String> {
        let world = self.app.world_mut();
        let mut levels = Vec::new();
        let mut triangles = 0;
        for (source, count) in counts {
            let mesh = world
                .resource::<Assets<Mesh>>()
                .get(source)
                .ok_or("a source mesh is gone")?
                .clone();
            let indices = meshopt_level(&mesh, *count, permissive)?;
            let mut level = mesh;
            level.insert_indices(Indices::U32(indices));
            levels.push((source.clone(), level));
        }
        let mut entities = world.query::<(Entity, &Mesh3d)>();
        let plain: Vec<(Entity, Handle<Mesh>)> = entities
            .iter(world)
            .filter(|(_, m)| counts.iter().any(|(h, _)| *h == m.0))
            .map(|(e, m)| (e, m.0.clone()))
            .collect();
        let levels: Vec<(Handle<Mesh>, Handle<Mesh>, usize)> = levels
            .into_iter()
            .map(|(source, level)| {
                let n = level.indices().map_or(0, |i| i.len() / 3);
                (source, world.resource_mut::<Assets<Mesh>>().add(level), n)
            })
            .collect();
        for (entity, mesh) in &plain {
            let (_, level, n) = levels
                .iter()
                .find(|(source, ..)| source == mesh)
                .expect("every swapped mesh has a level");
            triangles += n;
            world.entity_mut(*entity).insert(Mesh3d(level.clone()));
        }
        Ok((plain, triangles))
    }

    /// Gives the entities their own meshes back.
    fn restore(&mut self, swapped: Swapped) {
        for (entity, mesh) in swapped {
            self.app.world_mut().entity_mut(entity).insert(Mesh3d(mesh));
        }
    }

    /// What is wrong with the attributes the models draw now, against their source meshes:
    /// an attribute the source has and a region mesh lacks (joints and weights aside: the
    /// plugin skins on the CPU), or a float that is NaN or infinite.
    fn attribute_problems(&self) -> Vec<String> {
        let world = self.app.world();
        let meshes = world.resource::<Assets<Mesh>>();
        let mut problems = Vec::new();
        for model in self.models() {
            let source = world
                .get::<MultiresSourceMesh>(model)
                .and_then(|s| meshes.get(&s.0));
            let Some(instance) = world.get::<MultiresInstance>(model) else {
                continue;
            };
            for &region in instance.region_entities() {
                let Some(mesh) = world.get::<Mesh3d>(region).and_then(|m| meshes.get(&m.0)) else {
                    problems.push(format!("{region}: no mesh"));
                    continue;
                };
                if let Some(source) = source {
                    for (attribute, _) in source.attributes() {
                        let skin = [
                            Mesh::ATTRIBUTE_JOINT_INDEX.id,
                            Mesh::ATTRIBUTE_JOINT_WEIGHT.id,
                        ];
                        if !skin.contains(&attribute.id) && !mesh.contains_attribute(attribute.id) {
                            problems.push(format!("{region}: {} missing", attribute.name));
                        }
                    }
                }
                for (attribute, values) in mesh.attributes() {
                    if !finite(values) {
                        problems.push(format!(
                            "{region}: {} has NaN or infinite values",
                            attribute.name
                        ));
                    }
                }
            }
        }
        problems
    }
}

/// Whether every float of an attribute is finite.
fn finite(values: &VertexAttributeValues) -> bool {
    match values {
        VertexAttributeValues::Float32(v) => v.iter().all(|x| x.is_finite()),
        VertexAttributeValues::Float32x2(v) => v.iter().flatten().all(|x| x.is_finite()),
        VertexAttributeValues::Float32x3(v) => v.iter().flatten().all(|x| x.is_finite()),
        VertexAttributeValues::Float32x4(v) => v.iter().flatten().all(|x| x.is_finite()),
        _ => true,
    }
}

/// meshoptimizer's `simplify_with_attributes` level of `mesh` with `triangles` triangles
/// (normals, the first UV set and any colours weighted by [`PEER_WEIGHTS`]), as the index
/// buffer a Bevy user would draw; `permissive`: with its `Permissive` flag.
fn meshopt_level(mesh: &Mesh, triangles: usize, permissive: bool) -> Result<Vec<u32>, String> {
    let indexed = from_bevy_mesh(mesh).map_err(|e| e.to_string())?;
    let n = indexed.positions.len();
    let normals = indexed
        .normals
        .clone()
        .unwrap_or_else(|| vec![Vec3::ZERO; n]);
    let uvs = indexed.uvs.clone().unwrap_or_else(|| vec![Vec2::ZERO; n]);
    let colors = indexed
        .attribute(bevy_aslod::mesh::COLOR_ID)
        .and_then(|c| c.to_f32::<4>());
    let count = if colors.is_some() { 9 } else { 5 };
    let attributes: Vec<f32> = (0..n)
        .flat_map(|v| {
            let c = colors.as_ref().map_or([0.0; 4], |c| c[v]);
            let all = [
                normals[v].x,
                normals[v].y,
                normals[v].z,
                uvs[v].x,
                uvs[v].y,
                c[0],
                c[1],
                c[2],
                c[3],
            ];
            all.into_iter().take(count)
        })
        .collect();
    let positions: Vec<u8> = indexed
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let adapter = meshopt::VertexDataAdapter::new(&positions, 12, 0).map_err(|e| e.to_string())?;
    Ok(meshopt::simplify_with_attributes_and_locks(
        &indexed.indices,
        &adapter,
        &attributes,
        &PEER_WEIGHTS[..count],
        count * std::mem::size_of::<f32>(),
        &vec![false; n],
        3 * triangles,
        f32::MAX,
        if permissive {
            meshopt::SimplifyOptions::Permissive
        } else {
            meshopt::SimplifyOptions::None
        },
        None,
    ))
}

/// A bumpy UV sphere (48 × 96 quads, UV seam) as a GLB: positions, normals, `TEXCOORD_0`,
/// `TEXCOORD_1` (the same, halved), `COLOR_0` (RGBA bands around the sphere that cross its
/// rows at an angle), `_TINT` (a brightness: 16 stripes from pole to pole), a white material.
/// `flat`: every triangle gets its own three vertices with the face's normal.
fn procedural_glb(flat: bool) -> Vec<u8> {
    let (rings, segments) = (48u32, 96u32);
    let (mut positions, mut normals, mut uv0, mut uv1, mut colors, mut tints) = (
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
    );
    for r in 0..=rings {
        let v = r as f32 / rings as f32;
        let phi = std::f32::consts::PI * v;
        for s in 0..=segments {
            let u = s as f32 / segments as f32;
            let theta = std::f32::consts::TAU * u;
            let n = Vec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin());
            let bump = 1.0 + 0.04 * (5.0 * theta).sin() * (4.0 * phi).sin();
            positions.push(n * bump);
            normals.push(n);
            uv0.push([u, v]);
            uv1.push([u * 0.5, v * 0.5]);
            let band = ((3.0 * theta + 6.0 * phi).sin() * 0.5 + 0.5).round();
            colors.push([0.9, 0.25 + 0.6 * band, 0.2 + 0.5 * (1.0 - band), 1.0]);
            tints.push(if (s / 6) % 2 == 0 { 1.0f32 } else { 0.55 });
        }
    }
    let mut indices = Vec::new();
    let cols = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let (a, b) = (r * cols + s, (r + 1) * cols + s);
            indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    if flat {
        let corner = |v: &[u32]| v.iter().map(|&i| i as usize).collect::<Vec<_>>();
        let corners = corner(&indices);
        normals = corners
            .chunks_exact(3)
            .flat_map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| positions[t[k]]);
                let n = (b - a).cross(c - a).normalize_or_zero();
                [n; 3]
            })
            .collect();
        positions = corners.iter().map(|&i| positions[i]).collect();
        uv0 = corners.iter().map(|&i| uv0[i]).collect();
        uv1 = corners.iter().map(|&i| uv1[i]).collect();
        colors = corners.iter().map(|&i| colors[i]).collect();
        tints = corners.iter().map(|&i| tints[i]).collect();
        indices = (0..corners.len() as u32).collect();
    }
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: Vec<u8>| {
        let offset = bin.len();
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        bin.extend_from_slice(&bytes);
        bin.resize(bin.len().next_multiple_of(4), 0);
    };
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    push(floats(
        &positions
            .iter()
            .flat_map(|p| p.to_array())
            .collect::<Vec<_>>(),
    ));
    push(floats(
        &normals
            .iter()
            .flat_map(|p| p.to_array())
            .collect::<Vec<_>>(),
    ));
    push(floats(&uv0.concat()));
    push(floats(&uv1.concat()));
    push(floats(&colors.concat()));
    push(indices.iter().flat_map(|i| i.to_le_bytes()).collect());
    push(floats(&tints));
    let n = positions.len();
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let document = json!({
        "asset": {"version": "2.0", "generator": "bevy_aslod textured example"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 0.5}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1,
            "TEXCOORD_0": 2, "TEXCOORD_1": 3, "COLOR_0": 4, "_TINT": 6}, "indices": 5,
            "material": 0}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": lo.to_array(), "max": hi.to_array()},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 4, "componentType": 5126, "count": n, "type": "VEC4"},
            {"bufferView": 5, "componentType": 5125, "count": indices.len(), "type": "SCALAR"},
            {"bufferView": 6, "componentType": 5126, "count": n, "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    common::field::glb(&serde_json::to_vec(&document).expect("json"), &bin)
}

/// The mean RGB (of 255) of the pixels an image covers (not the clear colour): a level drawn
/// with NaN normals or a missing attribute comes out unlit or untextured, far from the
/// reference's, while a coarser shape keeps it.
fn mean_color(image: &Image) -> [f64; 3] {
    let Some(data) = &image.data else {
        return [0.0; 3];
    };
    let clear = &data[..4];
    let (mut sum, mut count) = ([0.0f64; 3], 0usize);
    for p in data.chunks_exact(4).filter(|p| *p != clear) {
        for c in 0..3 {
            sum[c] += f64::from(p[c]);
        }
        count += 1;
    }
    sum.map(|x| x / count.max(1) as f64)
}

/// Images of one size side by side, left to right.
fn side_by_side(images: &[&Image]) -> Image {
    let (w, h) = images.first().map_or((1, 1), |i| (i.width(), i.height()));
    let mut data = vec![0u8; (w * h * 4) as usize * images.len().max(1)];
    let row = (w * 4) as usize;
    for (k, image) in images.iter().enumerate() {
        let Some(pixels) = &image.data else { continue };
        for y in 0..h as usize {
            let to = y * row * images.len() + k * row;
            data[to..to + row].copy_from_slice(&pixels[y * row..(y + 1) * row]);
        }
    }
    Image::new(
        Extent3d {
            width: w * images.len().max(1) as u32,
            height: h,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}

/// Per ratio: the median and the worst view's PSNR and MAD of ours and meshoptimizer's.
fn summary(views: &[serde_json::Value], ratios: &[f64]) -> serde_json::Value {
    let column = |path: &[&str]| -> Vec<f64> {
        views
            .iter()
            .filter_map(|v| {
                let mut x = v;
                for p in path {
                    x = x.get(p)?;
                }
                x.as_f64()
            })
            .collect()
    };
    let worst_fraction = column(&["full_detail", "fraction_over_2"])
        .into_iter()
        .fold(0.0, f64::max);
    let rows: Vec<serde_json::Value> = ratios
        .iter()
        .enumerate()
        .map(|(i, ratio)| {
            let pick = |who: &str, what: &str| -> Vec<f64> {
                views
                    .iter()
                    .filter_map(|v| v["ratios"][i][who][what].as_f64())
                    .collect()
            };
            let stats = |who: &str| {
                let (psnr, mad) = (pick(who, "psnr"), pick(who, "mad"));
                if psnr.is_empty() {
                    return serde_json::Value::Null;
                }
                json!({
                    "median_psnr": common::stats::median(&psnr),
                    "worst_psnr": psnr.iter().copied().fold(f64::INFINITY, f64::min),
                    "median_mad": common::stats::median(&mad),
                    "worst_mad": mad.iter().copied().fold(0.0, f64::max),
                })
            };
            json!({ "ratio": ratio, "ours": stats("ours"), "meshopt": stats("meshopt") })
        })
        .collect();
    json!({
        "full_detail_worst_fraction_over_2": worst_fraction,
        "full_detail_median_psnr": common::stats::median(&column(&["full_detail", "psnr"])),
        "ratios": rows,
    })
}

/// The triangles a model shows, or `None` when every region entity of it is hidden
/// (`PolygonBudget::min_pixels`).
fn drawn_triangles(world: &World, instance: &MultiresInstance) -> Option<usize> {
    let shown = instance
        .region_entities()
        .iter()
        .any(|&r| world.get::<Visibility>(r) != Some(&Visibility::Hidden));
    shown.then(|| instance.triangle_count())
}

fn print_table(report: &serde_json::Value) {
    let s = &report["summary"];
    println!(
        "{}: {} triangles; full detail: worst view {:.4}% of pixels over 2/255, median PSNR {:.1} dB",
        report["model"].as_str().unwrap_or(""),
        report["full_triangles"],
        100.0
            * s["full_detail_worst_fraction_over_2"]
                .as_f64()
                .unwrap_or(f64::NAN),
        s["full_detail_median_psnr"].as_f64().unwrap_or(f64::NAN),
    );
    println!(
        "| ratio | ours PSNR median / worst | meshopt PSNR median / worst | ours MAD median | meshopt MAD median |"
    );
    println!("|---:|---:|---:|---:|---:|");
    for row in s["ratios"].as_array().into_iter().flatten() {
        let f = |who: &str, what: &str| row[who][what].as_f64().unwrap_or(f64::NAN);
        println!(
            "| {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.3} | {:.3} |",
            row["ratio"],
            f("ours", "median_psnr"),
            f("ours", "worst_psnr"),
            f("meshopt", "median_psnr"),
            f("meshopt", "worst_psnr"),
            f("ours", "median_mad"),
            f("meshopt", "median_mad"),
        );
    }
    if let Some(problems) = report["coarse_attributes"].as_array() {
        for p in problems {
            let list = p["problems"].as_array().map_or(0, Vec::len);
            println!("attributes at ratio {}: {list} problems", p["ratio"]);
        }
    }
}
