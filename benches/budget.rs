//! Benchmarks of the polygon budget: projected OBB area per box, OBB fitting on mesh-sized point
//! sets, and the allocation of 100,000 regions. Seeded inputs, built before timing.
//!
//! `cargo bench --no-default-features --bench budget`. Per-box times are the batch time divided
//! by the batch size (`BOXES`); Criterion also prints the throughput.

use bevy_aslod::budget::{
    AllocationParams, Allocator, Obb, ProjectedAreaCamera, RegionInput, fit_obb, fit_obb_pca,
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4Swizzles};
use std::hint::black_box;
use std::time::Duration;

/// splitmix64.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
    }

    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    fn rotation(&mut self) -> Quat {
        loop {
            let q = Quat::from_xyzw(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let len = q.length();
            if len > 0.1 && len <= 1.0 {
                return q / len;
            }
        }
    }
}

const BOXES: usize = 4096;

/// Boxes for one camera: `spread` scales how far off the view axis they may sit (0: all well
/// inside the view; 1: many cross the viewport's edges or lie outside it).
fn boxes(rng: &mut Rng, camera_from_world: Mat4, spread: f32, straddle: bool) -> Vec<Obb> {
    let world_from_view = camera_from_world.inverse();
    let eye = world_from_view.w_axis.xyz();
    let forward = -world_from_view.z_axis.xyz();
    let right = world_from_view.x_axis.xyz();
    let up = world_from_view.y_axis.xyz();
    (0..BOXES)
        .map(|_| {
            let d = if straddle {
                rng.range(-0.5, 1.0)
            } else {
                rng.range(5.0, 60.0)
            };
            let lateral = 0.3 * d.abs().max(1.0) * (0.1 + spread);
            let center = eye
                + forward * d
                + right * rng.range(-lateral, lateral)
                + up * rng.range(-lateral, lateral);
            let half = if straddle {
                rng.vec3(0.2, 2.0)
            } else {
                rng.vec3(0.01, 0.08) * d
            };
            Obb::new(center, Mat3::from_quat(rng.rotation()), half)
        })
        .collect()
}

fn cameras(rng: &mut Rng) -> Vec<(Mat4, Mat4)> {
    let mut out = Vec::new();
    for i in 0..8 {
        let eye = rng.vec3(-20.0, 20.0);
        let view = Mat4::look_at_rh(eye, eye + rng.vec3(-1.0, 1.0), Vec3::Y);
        let projection = match i % 4 {
            0 | 1 => Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1),
            2 => Mat4::perspective_rh(1.0, 16.0 / 9.0, 0.1, 1000.0),
            _ => Mat4::orthographic_rh(-16.0, 16.0, -9.0, 9.0, 1000.0, 0.1),
        };
        out.push((view, projection));
    }
    out
}

fn bench_projected_area(c: &mut Criterion) {
    let mut group = c.benchmark_group("projected_area");
    group.throughput(Throughput::Elements(BOXES as u64));
    let mut rng = Rng(1);
    for (name, spread, straddle) in [
        ("in_view", 0.0, false),
        ("mixed_on_off_screen", 1.5, false),
        ("straddling_near_plane", 0.5, true),
    ] {
        let scenes: Vec<(ProjectedAreaCamera, Vec<Obb>)> = cameras(&mut rng)
            .into_iter()
            .map(|(view, projection)| {
                let camera =
                    ProjectedAreaCamera::new(view, projection, Vec2::new(1920.0, 1080.0)).unwrap();
                (camera, boxes(&mut rng, view, spread, straddle))
            })
            .collect();
        let mut k = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                let (camera, boxes) = &scenes[k % scenes.len()];
                k += 1;
                let mut sum = 0.0;
                for obb in boxes {
                    sum += camera.projected_area(black_box(obb));
                }
                sum
            })
        });
        // The same boxes through the four-lane batch (the plugin's path).
        let mut areas = vec![0.0; BOXES];
        group.bench_function(format!("{name}/batch"), |b| {
            b.iter(|| {
                let (camera, boxes) = &scenes[k % scenes.len()];
                k += 1;
                camera.projected_areas(black_box(boxes), &mut areas);
                areas.iter().sum::<f32>()
            })
        });
    }
    // Building the camera once per frame.
    let (view, projection) = cameras(&mut rng)[0];
    group.throughput(Throughput::Elements(1));
    group.bench_function("camera_new", |b| {
        b.iter(|| {
            ProjectedAreaCamera::new(
                black_box(view),
                black_box(projection),
                Vec2::new(1920.0, 1080.0),
            )
        })
    });
    group.finish();
}

fn load_positions(name: &str) -> Vec<Vec3> {
    let path = format!(
        "{}/../shared/testdata/meshes/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter_map(|line| {
            let mut it = line.split_whitespace();
            (it.next() == Some("v")).then(|| {
                let mut c = it.map(|t| t.parse::<f32>().unwrap());
                Vec3::new(c.next().unwrap(), c.next().unwrap(), c.next().unwrap())
            })
        })
        .collect()
}

fn bench_fit_obb(c: &mut Criterion) {
    let mut group = c.benchmark_group("fit_obb");
    group.sample_size(10);
    let bunny = load_positions("stanford-bunny.obj");
    // A region-sized piece: the bunny's points nearest one of its vertices.
    let seed = bunny[1000];
    let mut region = bunny.clone();
    region.sort_by(|a, b| {
        a.distance_squared(seed)
            .total_cmp(&b.distance_squared(seed))
    });
    region.truncate(2000);
    for (name, points) in [("bunny_35k", &bunny), ("bunny_region_2k", &region)] {
        group.bench_function(format!("{name}/ours"), |b| {
            b.iter(|| fit_obb(black_box(points)))
        });
        group.bench_function(format!("{name}/pca"), |b| {
            b.iter(|| fit_obb_pca(black_box(points)))
        });
    }
    group.finish();
}

fn bench_allocate(c: &mut Criterion) {
    let mut group = c.benchmark_group("allocate");
    const N: usize = 100_000;
    group.throughput(Throughput::Elements(N as u64));
    let mut rng = Rng(7);
    let regions: Vec<RegionInput> = (0..N)
        .map(|_| {
            let min = (rng.range(0.0, 50.0)) as u32;
            let area = if rng.range(0.0, 1.0) < 0.2 {
                0.0
            } else {
                10f32.powf(rng.range(-1.0, 6.0))
            };
            RegionInput::from_area(
                area,
                rng.range(0.5, 2.0),
                min,
                min + rng.range(0.0, 4000.0) as u32,
                rng.range(0.0, 3000.0) as u32,
            )
        })
        .collect();
    for (name, alpha, hysteresis) in [
        ("100k/alpha3", 3.0, 0),
        ("100k/alpha3_hysteresis16", 3.0, 16),
        ("100k/alpha1.7", 1.7, 0),
    ] {
        let params = AllocationParams {
            budget: 40_000_000,
            fixed_cost: 100_000,
            alpha,
            hysteresis,
        };
        let mut allocator = Allocator::new();
        let mut out = Vec::with_capacity(N);
        group.bench_function(name, |b| {
            b.iter(|| {
                allocator
                    .allocate(&params, black_box(&regions), &mut out)
                    .unwrap()
            })
        });
    }
    // The same allocator on one view after another: each iteration's first round starts from
    // the last level. Above, the view never changes, so that guess always holds; here two
    // views alternate whose levels lie far apart (every weight ×8), so it always misses.
    let far: Vec<RegionInput> = regions
        .iter()
        .map(|r| RegionInput {
            weight: r.weight * 8.0,
            ..*r
        })
        .collect();
    let params = AllocationParams {
        budget: 40_000_000,
        fixed_cost: 100_000,
        alpha: 3.0,
        hysteresis: 0,
    };
    let mut allocator = Allocator::new();
    let mut out = Vec::with_capacity(N);
    let mut flip = false;
    group.bench_function("100k/alpha3_views_far_apart", |b| {
        b.iter(|| {
            flip = !flip;
            let view = if flip { &far } else { &regions };
            allocator
                .allocate(&params, black_box(view), &mut out)
                .unwrap()
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_projected_area, bench_fit_obb, bench_allocate
}
criterion_main!(benches);
