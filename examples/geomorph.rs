//! Geomorphs as the renderer draws them: a terrain under a budget that drops and comes back,
//! seen by a still camera, so every change between two frames is a level change. Drawn three
//! times (without geomorphs, with them written from the CPU, with `GeomorphMaterial`
//! interpolating them in the vertex shaders), one image per frame.
//!
//! `cargo run --release --example geomorph -- --out DIR` writes `frames.json` (per frame, the
//! share of pixels that changed since the previous frame, and how far the CPU and GPU runs
//! are apart) and `geomorph-frames.png`, a plot of the first against the others. `--check`
//! also fails when the GPU run does not draw what the CPU run does, or pops as much as the
//! run without geomorphs (the render test runs it). `--textured` gives the terrain UVs,
//! tangents, a checkered base colour and a bumpy normal map, so that the UVs and tangents
//! morph visibly too.

#[path = "common/mod.rs"]
mod common;

use bevy::asset::RenderAssetUsages;
use bevy::camera::RenderTarget;
use bevy::image::{ImageAddressMode, ImageSampler, ImageSamplerDescriptor};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, Geomorph, GeomorphMaterial, MultiresMesh, MultiresModel,
    PolygonBudget, RegionUploadStats,
};
use bevy_aslod::regions::{GridPlane, Partition};
use clap::Parser;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The morph time.
const T: f32 = 0.25;
/// Frames per second of the scripted clock (`common::offscreen_app` steps 1/60 s a frame).
const FPS: f64 = 60.0;
/// Image size: small, so lavapipe draws a frame quickly.
const SIZE: (u32, u32) = (320, 180);
/// The budget before the drop, during it, and when it is back.
const HIGH: u32 = 16_000;
const LOW: u32 = 2_500;
/// Frames drawn per run; the budget drops at `DROP` and comes back at `BACK`.
const FRAMES: usize = 48;
const DROP: usize = 4;
const BACK: usize = 24;

#[derive(Parser, Debug)]
struct Args {
    /// Where to write frames.json, the plot and (with `--frames`) every frame.
    #[arg(long, default_value = "geomorph-out")]
    out: PathBuf,
    /// Fail unless the GPU run draws what the CPU run does and pops less than no geomorphs.
    #[arg(long)]
    check: bool,
    /// Also save every frame as PNG.
    #[arg(long)]
    frames: bool,
    /// Give the terrain UVs, tangents, a checkered base colour and a bumpy normal map.
    #[arg(long)]
    textured: bool,
}

/// How a run changes levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Off,
    Cpu,
    Gpu,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::Off => "no geomorphs",
            Mode::Cpu => "geomorphs, CPU writes",
            Mode::Gpu => "geomorphs, GPU (GeomorphMaterial; on the CPU line)",
        }
    }

    fn key(self) -> &'static str {
        match self {
            Mode::Off => "off",
            Mode::Cpu => "cpu",
            Mode::Gpu => "gpu",
        }
    }
}

/// A 64×64 repeating texture: a checkered base colour (sRGB), or a normal map of round bumps
/// (linear).
fn texture(colour: bool) -> Image {
    const N: usize = 64;
    let mut data = Vec::with_capacity(N * N * 4);
    for y in 0..N {
        for x in 0..N {
            let (u, v) = (x as f32 / N as f32, y as f32 / N as f32);
            if colour {
                let light = ((x / 16) + (y / 16)) % 2 == 0;
                data.extend(if light {
                    [200, 190, 170, 255]
                } else {
                    [90, 110, 80, 255]
                });
            } else {
                let (dx, dy) = (
                    (u * std::f32::consts::TAU * 2.0).cos(),
                    (v * std::f32::consts::TAU * 2.0).cos(),
                );
                let n = Vec3::new(-0.5 * dx, -0.5 * dy, 1.0).normalize();
                data.extend(n.to_array().map(|c| ((c * 0.5 + 0.5) * 255.0) as u8));
                data.push(255);
            }
        }
    }
    let format = if colour {
        TextureFormat::Rgba8UnormSrgb
    } else {
        TextureFormat::Rgba8Unorm
    };
    let mut image = Image::new(
        Extent3d {
            width: N as u32,
            height: N as u32,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        format,
        RenderAssetUsages::default(),
    );
    image.sampler = ImageSampler::Descriptor(ImageSamplerDescriptor {
        address_mode_u: ImageAddressMode::Repeat,
        address_mode_v: ImageAddressMode::Repeat,
        ..ImageSamplerDescriptor::linear()
    });
    image
}

fn main() {
    let args = Args::parse();
    if let Err(e) = run(&args) {
        eprintln!("geomorph: {e}");
        std::process::exit(1);
    }
}

fn run(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let mut app = render_app();
    let target = app
        .world_mut()
        .resource_mut::<Assets<Image>>()
        .add(Image::new_target_texture(
            SIZE.0,
            SIZE.1,
            TextureFormat::Rgba8Unorm,
            Some(TextureFormat::Rgba8UnormSrgb),
        ));
    let mut mesh = common::terrain::terrain_middle(97);
    if args.textured {
        mesh.uvs = Some(
            mesh.positions
                .iter()
                .map(|p| Vec2::new(p.x, p.z) * 0.25)
                .collect(),
        );
        mesh.generate_tangents().map_err(|e| e.to_string())?;
    }
    let grid = Partition::grid(&mesh, GridPlane::XZ, 4, 4).map_err(|e| e.to_string())?;
    let asset = MultiresMesh::from_indexed(&mesh, &grid).map_err(|e| e.to_string())?;
    let world = app.world_mut();
    let asset = world.resource_mut::<Assets<MultiresMesh>>().add(asset);
    let mut base = StandardMaterial {
        base_color: Color::srgb(0.6, 0.57, 0.5),
        perceptual_roughness: 0.9,
        ..default()
    };
    if args.textured {
        let mut images = world.resource_mut::<Assets<Image>>();
        base.base_color = Color::WHITE;
        base.base_color_texture = Some(images.add(texture(true)));
        base.normal_map_texture = Some(images.add(texture(false)));
    }
    let standard = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(base.clone());
    let morphing = world
        .resource_mut::<Assets<GeomorphMaterial>>()
        .add(GeomorphMaterial {
            base,
            extension: default(),
        });
    world.spawn((
        DirectionalLight {
            illuminance: 10_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-1.0, 0.5, 0.3).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(target.clone().into()),
        Msaa::Off,
        Transform::from_xyz(-30.0, 45.0, 70.0).looking_at(Vec3::new(0.0, 0.0, 5.0), Vec3::Y),
    ));
    let captured: Arc<Mutex<Option<Image>>> = Arc::default();

    let mut runs = Vec::new();
    for mode in [Mode::Off, Mode::Cpu, Mode::Gpu] {
        let start = Instant::now();
        let world = app.world_mut();
        world.resource_mut::<PolygonBudget>().total = HIGH;
        let mut model = world.spawn((MultiresModel(asset.clone()), Transform::default()));
        match mode {
            Mode::Off => model.insert(MeshMaterial3d(standard.clone())),
            Mode::Cpu => model.insert((MeshMaterial3d(standard.clone()), Geomorph(T))),
            Mode::Gpu => model.insert((MeshMaterial3d(morphing.clone()), Geomorph(T))),
        };
        let model = model.id();
        // Pipelines compile slowly on lavapipe: wait until the terrain is drawn and still.
        let mut last = capture(&mut app, &target, &captured)?;
        let mut still = 0;
        for _ in 0..200 {
            step(&mut app);
            let shot = capture(&mut app, &target, &captured)?;
            still = if common::varied(&shot) > 0.3 && common::compare(&shot, &last).1 == 0.0 {
                still + 1
            } else {
                0
            };
            last = shot;
            if still >= 3 {
                break;
            }
        }
        if still < 3 {
            common::save_image(
                &last,
                &args.out.join(format!("{}-not-ready.png", mode.key())),
            )?;
            return Err(format!(
                "{}: the terrain was not drawn, or kept changing",
                mode.name()
            ));
        }
        let mut frames = vec![last];
        let mut cost = Cost::default();
        for frame in 1..=FRAMES {
            let budget = if (DROP..BACK).contains(&frame) {
                LOW
            } else {
                HIGH
            };
            app.world_mut().resource_mut::<PolygonBudget>().total = budget;
            step(&mut app);
            cost.add(&app);
            frames.push(capture(&mut app, &target, &captured)?);
        }
        if args.frames {
            for (i, f) in frames.iter().enumerate() {
                common::save_image(f, &args.out.join(format!("{}-{i:03}.png", mode.key())))?;
            }
        }
        eprintln!(
            "{}: {} frames in {:.1} s",
            mode.name(),
            FRAMES,
            start.elapsed().as_secs_f32()
        );
        app.world_mut().despawn(model);
        runs.push((mode, frames, cost));
    }

    // Per frame: the share of pixels that changed since the previous frame (by more than 2
    // of 255 in a channel), and between the CPU and GPU runs.
    let changed: Vec<Vec<f64>> = runs
        .iter()
        .map(|(_, frames, _)| {
            frames
                .windows(2)
                .map(|w| common::compare(&w[0], &w[1]).1)
                .collect()
        })
        .collect();
    let apart: Vec<f64> = runs[1]
        .1
        .iter()
        .zip(&runs[2].1)
        .map(|(a, b)| common::compare(a, b).1)
        .collect();
    let summary = |c: &[f64]| {
        let max = c.iter().copied().fold(0.0, f64::max);
        let frames = c.iter().filter(|&&x| x > 0.0005).count();
        (max, frames)
    };
    let json = serde_json::json!({
        "size": [SIZE.0, SIZE.1],
        "morph_seconds": T,
        "fps": FPS,
        "budget": { "high": HIGH, "low": LOW, "drop_frame": DROP, "back_frame": BACK },
        "runs": runs.iter().zip(&changed).map(|((mode, _, cost), c)| {
            let (max, frames) = summary(c);
            serde_json::json!({
                "mode": mode.key(),
                "changed": c,
                "max_changed": max,
                "frames_changing": frames,
                "triangles": cost.triangles,
                "update_ms": cost.update_ms,
                "write_ms": cost.write_ms,
                "vertex_bytes": cost.vertex_bytes,
                "index_bytes": cost.index_bytes,
            })
        }).collect::<Vec<_>>(),
        "cpu_gpu_apart": apart,
        "cpu_gpu_apart_max": apart.iter().copied().fold(0.0, f64::max),
    });
    std::fs::write(
        args.out.join("frames.json"),
        serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?,
    )
    .map_err(|e| format!("write frames.json: {e}"))?;
    plot(&args.out.join("geomorph-frames.png"), &runs, &changed)?;
    println!(
        "{:<48} {:>9} {:>8} {:>11} {:>11} {:>10} {:>10}",
        "run", "max px %", "frames", "vertex KB", "index KB", "update ms", "write ms"
    );
    for ((mode, _, cost), c) in runs.iter().zip(&changed) {
        let (max, frames) = summary(c);
        let sum = |v: &[u64]| v.iter().sum::<u64>() as f64 / 1024.0;
        println!(
            "{:<48} {:>9.2} {:>8} {:>11.1} {:>11.1} {:>10.3} {:>10.3}",
            mode.name(),
            max * 100.0,
            frames,
            sum(&cost.vertex_bytes),
            sum(&cost.index_bytes),
            common::stats::median(&cost.update_ms),
            common::stats::median(&cost.write_ms),
        );
    }
    println!(
        "(max px %: the largest share of pixels changed between two frames; frames: frames \
         with a change; KB: all {FRAMES} frames together; ms: per-frame medians)"
    );
    println!(
        "CPU against GPU run: at most {:.3} % of pixels apart",
        json["cpu_gpu_apart_max"].as_f64().unwrap_or(1.0) * 100.0
    );
    if args.check {
        let (off, _) = summary(&changed[0]);
        let (gpu, gpu_frames) = summary(&changed[2]);
        let apart = json["cpu_gpu_apart_max"].as_f64().unwrap_or(1.0);
        if apart > 0.01 {
            return Err(format!(
                "the GPU run draws {:.2} % of pixels unlike the CPU run",
                apart * 100.0
            ));
        }
        if gpu * 3.0 > off || gpu_frames < 10 {
            return Err(format!(
                "geomorphs on the GPU pop: {:.2} % of pixels at once against {:.2} % without, over {gpu_frames} frames",
                gpu * 100.0,
                off * 100.0
            ));
        }
    }
    Ok(())
}

/// What each frame of a run cost: the plugin's systems (`AslodStats::update_ms`) and its
/// writes to the GPU (`RegionUploadStats`).
#[derive(Default)]
struct Cost {
    triangles: Vec<u64>,
    update_ms: Vec<f64>,
    write_ms: Vec<f64>,
    vertex_bytes: Vec<u64>,
    index_bytes: Vec<u64>,
}

impl Cost {
    fn add(&mut self, app: &App) {
        let stats = app.world().resource::<AslodStats>();
        let upload = app
            .get_sub_app(RenderApp)
            .and_then(|r| r.world().get_resource::<RegionUploadStats>().copied())
            .unwrap_or_default();
        self.triangles.push(stats.triangles);
        self.update_ms.push(stats.update_ms);
        self.write_ms.push(upload.write_ms);
        self.vertex_bytes.push(upload.vertex_bytes);
        self.index_bytes.push(upload.index_bytes);
    }
}

/// A headless app whose frames are drawn in `update` (no pipelined rendering), on a clock
/// of exactly 1/60 s per frame.
fn render_app() -> App {
    let mut app = common::offscreen_app(None);
    app.add_plugins(AslodPlugin::default().with_budget(HIGH))
        .insert_resource(ClearColor(Color::srgb(0.62, 0.75, 0.9)));
    app.finish();
    app.cleanup();
    app
}

/// One frame on: the clock runs for it, then stops while screenshots are read back.
fn step(app: &mut App) {
    app.world_mut().resource_mut::<Time<Virtual>>().unpause();
    app.update();
    app.world_mut().resource_mut::<Time<Virtual>>().pause();
}

/// The frame as drawn now (the clock stands still until it arrives, so every frame drawn
/// meanwhile is the same).
fn capture(
    app: &mut App,
    target: &Handle<Image>,
    slot: &Arc<Mutex<Option<Image>>>,
) -> Result<Image, String> {
    let pending = slot.clone();
    app.world_mut()
        .spawn(Screenshot::image(target.clone()))
        .observe(move |captured: On<ScreenshotCaptured>| {
            *pending.lock().expect("capture slot") = Some(captured.image.clone());
        });
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        app.update();
        if let Some(image) = slot.lock().expect("capture slot").take() {
            return Ok(image);
        }
    }
    Err("a screenshot did not arrive within two minutes".into())
}

/// Per run, the share of pixels changed between consecutive frames.
fn plot(
    path: &Path,
    runs: &[(Mode, Vec<Image>, Cost)],
    changed: &[Vec<f64>],
) -> Result<(), String> {
    use plotters::prelude::*;

    let top = changed
        .iter()
        .flatten()
        .copied()
        .fold(0.0, f64::max)
        .max(1e-3)
        * 100.0
        * 1.1;
    common::chart::draw(path, |area| {
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "Pixels changed since the previous frame: budget {HIGH} -> {LOW} at frame {DROP}, back at {BACK}, T = {T} s"
                ),
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(0f64..FRAMES as f64, 0f64..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("frame")
            .y_desc("% of pixels")
            .draw()
            .map_err(|e| e.to_string())?;
        let colours = [
            RGBColor(200, 40, 30),
            RGBColor(60, 60, 200),
            RGBColor(20, 140, 60),
        ];
        for (((mode, ..), c), colour) in runs.iter().zip(changed).zip(colours) {
            let points: Vec<(f64, f64)> = c
                .iter()
                .enumerate()
                .map(|(i, &x)| ((i + 1) as f64, x * 100.0))
                .collect();
            chart
                .draw_series(LineSeries::new(points, colour.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(mode.name())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())
    })
}
