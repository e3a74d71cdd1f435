//! Coarse against fine view-dependence (ASLOD section 4): at the same triangle count, how far
//! the shown surface strays from full detail, in pixels, under
//!
//! 1. one uniform level of the whole mesh (a [`PolygonCache`]),
//! 2. ASLOD's regions, their counts split by the α allocation (α = 3) over the projected
//!    areas of their boxes ([`RegionCaches`]),
//! 3. the variable-resolution level (frustum + back faces + the screen-space tolerance that
//!    [`ToleranceSearch::fit`] finds for the count, through the incremental path),
//!
//! along scripted camera paths (1280×720, 60° vertical field of view): a low fly-over of the
//! Silvretta terrain (6×6 grid regions, 10,000 triangles), orbits that come close around the
//! Stanford bunny (16 clusters; 5,000 and 20,000) and the mannequin at rest (its own 19 skin
//! regions; 3,000). It prints one markdown table: per scene, count and method, the median and
//! 95th percentile over frames of the largest projected error, the mean over frames of the
//! mean projected error, the median CPU time of the LOD work per frame, the triangles shown,
//! and for the variable level the screen-space tolerance τ the search settled on and the
//! updates it ran.
//!
//! The error of a frame: points sampled on the full-detail surface
//! ([`surface_samples`]: area samples plus every vertex), those inside the view frustum on
//! triangles facing the camera, each one's distance to the shown mesh (a [`Bvh`] of it), in
//! pixels at the point's view depth ([`View::pixels_at`]). Occlusion is not considered. The
//! time of a frame: uniform, moving the polygon cache to the count (nothing after the first
//! frame); regions, the projected areas of their boxes, the allocation, moving the region
//! caches and writing the changed regions' 16-bit index buffers; variable, the fit.
//!
//! `cargo bench --no-default-features --features distance,mannequin --bench coarse_fine`
//! (in debug, as `cargo test --benches` runs it, a short version: 4 frames, 2,000 samples, one
//! timed run, the middle 65×65 vertices of the terrain and a coarser mannequin at 1,000
//! triangles each).

use bevy_aslod::budget::{AllocationParams, Allocator, Obb, ProjectedAreaCamera, RegionInput};
use bevy_aslod::distance::{Bvh, DistanceOptions, MeshRef, surface_samples};
use bevy_aslod::mannequin::{MannequinOptions, generate};
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use bevy_aslod::refine::{Criteria, ToleranceSearch, VariableCache, VariableMesh, View};
use bevy_aslod::regions::{GridPlane, Partition, Region, RegionCaches, RegionMesh};
use glam::{Mat4, Vec2, Vec3};
use std::f32::consts::TAU;
use std::hint::black_box;
use std::time::Instant;

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/meshes/");
const WIDTH: f32 = 1280.0;
const HEIGHT: f32 = 720.0;
const FOV_Y: f32 = std::f32::consts::FRAC_PI_3; // 60°

/// How long a run is: frames along each path, area samples on each mesh, timed repeats.
#[derive(Clone, Copy)]
struct Run {
    frames: usize,
    samples: usize,
    repeats: usize,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    // `cargo test --benches` runs benches once in debug: keep that short.
    let quick = args.iter().any(|a| a == "--test") || cfg!(debug_assertions);
    let run = if quick {
        Run {
            frames: 4,
            samples: 2_000,
            repeats: 1,
        }
    } else {
        Run {
            frames: 120,
            samples: 100_000,
            repeats: 5,
        }
    };

    println!(
        "Coarse against fine view-dependence: {WIDTH}x{HEIGHT}, 60° vertical field of view, \
         {} frames per path, {} area samples + every vertex of the full-detail surface per \
         scene (those in the frustum on front-facing triangles), errors in pixels at each \
         sample's view depth; ms: median over frames x {} runs of the LOD work alone",
        run.frames, run.samples, run.repeats
    );
    println!();
    println!(
        "| scene | triangles | method | max px (median) | max px (p95) | mean px (mean) | ms / frame (median) | triangles shown (mean) | τ (median), updates per fit (mean) |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|");

    for scene in scenes(quick) {
        let prepared = Prepared::new(&scene, run);
        for &count in &scene.counts {
            prepared.compare(&scene, count, run);
        }
    }
}

/// A camera: where it is and where it looks.
#[derive(Clone, Copy)]
struct Camera {
    eye: Vec3,
    /// Unit length (`Mat4::look_to_rh` takes it as it is).
    forward: Vec3,
    near: f32,
}

impl Camera {
    fn view(&self) -> View {
        View::perspective(
            self.eye,
            self.forward,
            Vec3::Y,
            FOV_Y,
            WIDTH / HEIGHT,
            self.near,
            HEIGHT,
        )
        .expect("a valid camera")
    }

    fn projected_area_camera(&self) -> ProjectedAreaCamera {
        ProjectedAreaCamera::new(
            Mat4::look_to_rh(self.eye, self.forward, Vec3::Y),
            Mat4::perspective_infinite_reverse_rh(FOV_Y, WIDTH / HEIGHT, self.near),
            Vec2::new(WIDTH, HEIGHT),
        )
        .expect("a valid camera")
    }
}

/// A mesh, its partition into regions, the counts to compare at and the camera path.
struct Scene {
    name: &'static str,
    mesh: IndexedMesh,
    partition: Partition,
    counts: Vec<usize>,
    /// The camera at `t` in `0..=1` along the path.
    path: Box<dyn Fn(f32) -> Camera>,
}

fn scenes(quick: bool) -> Vec<Scene> {
    let mut scenes = Vec::new();

    let terrain = terrain::terrain_middle(if quick { 65 } else { terrain::SIDE });
    let top = terrain
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::NEG_INFINITY, f32::max);
    let (lo, hi) = terrain.bounds().expect("non-empty");
    let half = 0.5 * (hi.x - lo.x);
    scenes.push(Scene {
        name: "Silvretta (6x6 grid)",
        partition: Partition::grid(&terrain, GridPlane::XZ, 6, 6).expect("grid"),
        mesh: terrain,
        counts: vec![if quick { 1_000 } else { 10_000 }],
        path: Box::new(move |t| fly_over(half, top, t)),
    });

    let (bunny, _) = IndexedMesh::load(format!("{MESHES}stanford-bunny.obj")).expect("the bunny");
    let (centre, radius) = bounding_sphere(&bunny);
    scenes.push(Scene {
        name: "Bunny (16 clusters)",
        partition: Partition::clusters(&bunny, 16).expect("clusters"),
        mesh: bunny,
        counts: vec![5_000, 20_000],
        path: Box::new(move |t| orbit(centre, radius, t)),
    });

    let options = MannequinOptions::default();
    let options = if quick {
        options.with_cell_size(0.03)
    } else {
        options
    };
    let mannequin = generate(&options).expect("the mannequin");
    let (partition, _) =
        Partition::from_ids(&mannequin.mesh, &mannequin.region_of).expect("its regions");
    let (centre, radius) = bounding_sphere(&mannequin.mesh);
    scenes.push(Scene {
        name: "Mannequin at rest (19 skin regions)",
        partition,
        mesh: mannequin.mesh,
        counts: vec![if quick { 1_000 } else { 3_000 }],
        path: Box::new(move |t| orbit(centre, radius, t)),
    });
    scenes
}

/// A low fly-over of the terrain (`half` its half-width, `top` its highest point): in from
/// beyond one edge, across the middle, weaving a little, 12 units above the highest peak,
/// looking 18° down.
fn fly_over(half: f32, top: f32, t: f32) -> Camera {
    let z = -half * 1.8 + 2.2 * half * t;
    let x = 0.25 * half * (TAU * t).sin();
    let heading = Vec3::new(0.3 * (TAU * t).cos(), 0.0, 1.0).normalize();
    let pitch = 18f32.to_radians();
    Camera {
        eye: Vec3::new(x, top + 12.0, z),
        forward: (heading * pitch.cos() - Vec3::Y * pitch.sin()).normalize(),
        near: 0.5,
    }
}

/// An orbit around the model that comes close twice: one turn, the distance from the centre
/// between 1.1 and 3.5 bounding radii, the height swaying.
fn orbit(centre: Vec3, radius: f32, t: f32) -> Camera {
    let angle = TAU * t;
    let distance = radius * (2.3 + 1.2 * (2.0 * TAU * t).cos());
    let eye = centre
        + Vec3::new(
            distance * angle.sin(),
            0.4 * radius * (angle + 0.5).sin(),
            distance * angle.cos(),
        );
    Camera {
        eye,
        forward: (centre - eye).normalize(),
        near: 0.01 * radius,
    }
}

fn bounding_sphere(mesh: &IndexedMesh) -> (Vec3, f32) {
    let (lo, hi) = mesh.bounds().expect("non-empty");
    let centre = (lo + hi) * 0.5;
    let radius = mesh
        .positions
        .iter()
        .map(|p| p.distance(centre))
        .fold(0.0, f32::max);
    (centre, radius)
}

/// A sample on the full-detail surface and the normal of its triangle.
#[derive(Clone, Copy)]
struct Sample {
    position: Vec3,
    normal: Vec3,
}

/// What each method needs of a scene, built once.
struct Prepared {
    variable: VariableMesh,
    /// The source mesh's positions, which the regions' global indices point into.
    source_positions: Vec<Vec3>,
    regions: RegionMesh,
    obbs: Vec<Obb>,
    samples: Vec<Sample>,
    cameras: Vec<Camera>,
}

impl Prepared {
    fn new(scene: &Scene, run: Run) -> Self {
        let mesh = &scene.mesh;
        let view_dependent = BuildOptions::default().with_view_dependent(true);
        let variable = VariableMesh::new(
            ProgressiveMesh::build(mesh, &view_dependent).expect("the progressive mesh"),
        )
        .expect("view data");
        let regions = RegionMesh::build(mesh, &scene.partition, &BuildOptions::default())
            .expect("the regions");
        let obbs = regions.regions().iter().map(Region::obb).collect();
        let options = DistanceOptions::default()
            .with_samples(run.samples)
            .with_vertices(true);
        let samples = surface_samples(MeshRef::from(mesh), &options)
            .into_iter()
            .map(|(position, t)| {
                let c = &mesh.indices[3 * t as usize..][..3];
                let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[c[k] as usize]);
                Sample {
                    position,
                    normal: (b - a).cross(c - a),
                }
            })
            .collect();
        let cameras = (0..run.frames)
            .map(|f| (scene.path)(f as f32 / (run.frames - 1).max(1) as f32))
            .collect();
        Self {
            variable,
            source_positions: mesh.positions.clone(),
            regions,
            obbs,
            samples,
            cameras,
        }
    }

    /// Prints the three rows of one scene and count.
    fn compare(&self, scene: &Scene, count: usize, run: Run) {
        let methods: [(&str, Method); 3] = [
            ("uniform level", Method::Uniform),
            ("ASLOD regions (α = 3)", Method::Regions),
            ("variable resolution", Method::Variable),
        ];
        for (label, method) in methods {
            // The errors, once (they are deterministic).
            let mut state = State::new(self, method);
            let (mut max_px, mut mean_px, mut shown) = (Vec::new(), Vec::new(), Vec::new());
            let (mut tolerance, mut updates) = (Vec::new(), Vec::new());
            for camera in &self.cameras {
                if let Some((t, u)) = state.step(self, camera, count) {
                    tolerance.push(f64::from(t));
                    updates.push(f64::from(u));
                }
                let (positions, indices) = state.shown(self);
                let (max, mean) = self.error(camera, positions, &indices);
                max_px.push(max);
                mean_px.push(mean);
                shown.push((indices.len() / 3) as f64);
            }
            // The LOD work alone, from a fresh state each run.
            let mut ms = Vec::new();
            for _ in 0..run.repeats {
                let mut state = State::new(self, method);
                for camera in &self.cameras {
                    let start = Instant::now();
                    state.step(self, camera, count);
                    ms.push(start.elapsed().as_secs_f64() * 1e3);
                    black_box(&state);
                }
            }
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let search = if tolerance.is_empty() {
                "–".to_owned()
            } else {
                format!(
                    "{:.2} px, {:.1} updates",
                    percentile(&tolerance, 0.5),
                    mean(&updates)
                )
            };
            println!(
                "| {} | {} | {label} | {:.2} | {:.2} | {:.3} | {:.3} | {} | {search} |",
                scene.name,
                thousands(count),
                percentile(&max_px, 0.5),
                percentile(&max_px, 0.95),
                mean(&mean_px),
                percentile(&ms, 0.5),
                thousands(mean(&shown).round() as usize),
            );
        }
    }

    /// The largest and the mean error, in pixels, of the shown mesh from `camera`, over the
    /// samples in the frustum on front-facing triangles.
    fn error(&self, camera: &Camera, positions: &[Vec3], indices: &[u32]) -> (f64, f64) {
        let view = camera.view();
        let planes = view.planes();
        let visible: Vec<(Vec3, f32)> = self
            .samples
            .iter()
            .filter(|s| {
                s.normal.dot(camera.eye - s.position) > 0.0
                    && planes.iter().all(|p| p.dot(s.position.extend(1.0)) >= 0.0)
            })
            .map(|s| (s.position, (s.position - camera.eye).dot(camera.forward)))
            .collect();
        if visible.is_empty() {
            return (0.0, 0.0);
        }
        let bvh = Bvh::new(positions, indices);
        let measure = |chunk: &[(Vec3, f32)]| {
            let (mut max, mut sum, mut hint) = (0.0f64, 0.0f64, 0u32);
            for &(p, depth) in chunk {
                let (d2, t) = bvh.closest_point_with_hint(p, hint).expect("a shown mesh");
                hint = t;
                let px = view.pixels_at(d2.sqrt(), depth);
                max = max.max(px);
                sum += px;
            }
            (max, sum)
        };
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let chunk = visible.len().div_ceil(threads);
        let parts: Vec<(f64, f64)> = std::thread::scope(|s| {
            let handles: Vec<_> = visible
                .chunks(chunk)
                .map(|c| s.spawn(move || measure(c)))
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("a measuring thread"))
                .collect()
        });
        let max = parts.iter().map(|p| p.0).fold(0.0, f64::max);
        let sum: f64 = parts.iter().map(|p| p.1).sum();
        (max, sum / visible.len() as f64)
    }
}

#[derive(Clone, Copy)]
enum Method {
    Uniform,
    Regions,
    Variable,
}

/// One method's level, kept from frame to frame.
enum State {
    Uniform(PolygonCache),
    Regions {
        caches: RegionCaches,
        allocator: Allocator,
        areas: Vec<f32>,
        inputs: Vec<RegionInput>,
        counts: Vec<u32>,
        buffers: Vec<Vec<u16>>,
    },
    Variable(VariableCache, ToleranceSearch),
}

impl State {
    fn new(p: &Prepared, method: Method) -> Self {
        match method {
            Method::Uniform => Self::Uniform(PolygonCache::new(p.variable.mesh())),
            Method::Regions => {
                let n = p.regions.regions().len();
                Self::Regions {
                    caches: RegionCaches::new(&p.regions),
                    allocator: Allocator::new(),
                    areas: vec![0.0; n],
                    inputs: Vec::with_capacity(n),
                    counts: Vec::with_capacity(n),
                    buffers: vec![Vec::new(); n],
                }
            }
            Method::Variable => {
                Self::Variable(VariableCache::new(&p.variable), ToleranceSearch::default())
            }
        }
    }

    /// The LOD work of one frame; for the variable level, the tolerance found (pixels) and
    /// the updates the search ran.
    fn step(&mut self, p: &Prepared, camera: &Camera, count: usize) -> Option<(f32, u32)> {
        match self {
            Self::Uniform(cache) => {
                cache.set_triangle_count(p.variable.mesh(), count);
                None
            }
            Self::Regions {
                caches,
                allocator,
                areas,
                inputs,
                counts,
                buffers,
            } => {
                camera
                    .projected_area_camera()
                    .projected_areas(&p.obbs, areas);
                inputs.clear();
                for (r, (region, &area)) in p.regions.regions().iter().zip(areas.iter()).enumerate()
                {
                    inputs.push(RegionInput::from_area(
                        area,
                        1.0,
                        region.min_triangles() as u32,
                        region.max_triangles() as u32,
                        caches.triangle_count(r) as u32,
                    ));
                }
                allocator
                    .allocate(&AllocationParams::with_budget(count as u32), inputs, counts)
                    .expect("valid inputs");
                for (r, &c) in counts.iter().enumerate() {
                    caches.set_triangle_count(&p.regions, r, c as usize);
                }
                for (r, buffer) in buffers.iter_mut().enumerate() {
                    if caches.is_dirty(r) {
                        caches.write_indices_u16(&p.regions, r, buffer);
                    }
                }
                None
            }
            Self::Variable(cache, search) => {
                let criteria = Criteria::default()
                    .with_frustum(true)
                    .with_back_facing(true);
                let fit = search
                    .fit(cache, &p.variable, &criteria, &camera.view(), count, 0.0)
                    .expect("a fit");
                Some((fit.tolerance_px, fit.updates))
            }
        }
    }

    /// The shown mesh: positions and a triangle list into them.
    fn shown<'a>(&self, p: &'a Prepared) -> (&'a [Vec3], Vec<u32>) {
        match self {
            Self::Uniform(cache) => (
                &p.variable.mesh().vertices().positions,
                cache.indices().to_vec(),
            ),
            Self::Regions { buffers, .. } => {
                let mut indices = Vec::new();
                for (region, buffer) in p.regions.regions().iter().zip(buffers) {
                    let global = region.global_vertices();
                    indices.extend(buffer.iter().map(|&i| global[usize::from(i)]));
                }
                (&p.source_positions, indices)
            }
            Self::Variable(cache, _) => (
                &p.variable.mesh().vertices().positions,
                cache.indices().to_vec(),
            ),
        }
    }
}

fn percentile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i]
}

fn thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The Silvretta example's terrain, 261×261 vertices (135,200 triangles);
/// `terrain_middle(side)` takes the middle of it (the short debug run).
#[path = "../examples/common/terrain.rs"]
mod terrain;
