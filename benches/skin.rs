//! Linear blend skinning benchmarks: `blend` of 100,000 vertices with 1, 2 and 4 influences
//! each, positions and normals, on one core; the throughput is vertices per second (target:
//! at most 5 ns per vertex per influence). `blend_with_rigid` with every vertex rigid shows
//! the rigid path, `subset_10pc` the cost of skinning a tenth of the vertices, as a coarse
//! cache does (section 5.4), and `blend_region_1k` one region-sized batch that stays in cache,
//! as `Deform` blends them.

use bevy_aslod::skin::{Influences, blend, blend_with_rigid};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::{Mat4, Quat, Vec3};
use std::hint::black_box;

const VERTICES: usize = 100_000;
const JOINTS: u32 = 64;

/// xorshift64*, seeded: the same inputs every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.unit(), self.unit(), self.unit()) * 2.0 - Vec3::ONE
    }
}

struct Input {
    matrices: Vec<Mat4>,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    vertices: Vec<u32>,
}

impl Input {
    /// `blend` of `vertices`, with normals when `out_n` is given.
    fn blend(
        &self,
        influences: &Influences,
        vertices: &[u32],
        out_p: &mut [Vec3],
        out_n: Option<&mut [Vec3]>,
    ) {
        let normals = out_n.is_some().then_some(self.normals.as_slice());
        blend(
            &self.matrices,
            &self.positions,
            normals,
            influences,
            vertices,
            out_p,
            out_n,
        );
    }
}

fn input(rng: &mut Rng) -> Input {
    let matrices = (0..JOINTS)
        .map(|_| {
            let axis = rng.vec3().try_normalize().unwrap_or(Vec3::Y);
            Mat4::from_rotation_translation(
                Quat::from_axis_angle(axis, rng.unit() * 6.0),
                rng.vec3(),
            )
        })
        .collect();
    Input {
        matrices,
        positions: (0..VERTICES).map(|_| rng.vec3()).collect(),
        normals: (0..VERTICES)
            .map(|_| rng.vec3().try_normalize().unwrap_or(Vec3::Y))
            .collect(),
        vertices: (0..VERTICES as u32).collect(),
    }
}

/// `count` distinct random joints per vertex with random weights.
fn influences(rng: &mut Rng, count: usize) -> Influences {
    let mut joints = Vec::with_capacity(VERTICES);
    let mut weights = Vec::with_capacity(VERTICES);
    for _ in 0..VERTICES {
        let mut j = [0u16; 4];
        let mut w = [0f32; 4];
        for k in 0..count {
            // Distinct joints: consecutive from a random start.
            j[k] = ((rng.next() as u32 % JOINTS + k as u32 * 7) % JOINTS) as u16;
            w[k] = 0.1 + rng.unit();
        }
        joints.push(j);
        weights.push(w);
    }
    Influences::new(&joints, &weights, JOINTS as usize)
        .expect("valid weights")
        .0
}

fn blend_100k(c: &mut Criterion) {
    let mut rng = Rng(0x5eed_b1e4d);
    let input = input(&mut rng);
    let mut out_p = vec![Vec3::ZERO; VERTICES];
    let mut out_n = vec![Vec3::ZERO; VERTICES];
    let mut group = c.benchmark_group("blend_100k");
    group.throughput(Throughput::Elements(VERTICES as u64));
    for count in [1, 2, 4] {
        let inf = influences(&mut rng, count);
        group.bench_function(BenchmarkId::new("positions_normals", count), |b| {
            b.iter(|| {
                input.blend(
                    black_box(&inf),
                    &input.vertices,
                    &mut out_p,
                    Some(&mut out_n),
                );
                black_box(out_p[VERTICES / 2])
            })
        });
        group.bench_function(BenchmarkId::new("positions", count), |b| {
            b.iter(|| {
                input.blend(black_box(&inf), &input.vertices, &mut out_p, None);
                black_box(out_p[VERTICES / 2])
            })
        });
    }
    let inf = influences(&mut rng, 4);
    let rigid = vec![true; VERTICES];
    group.bench_function("rigid_positions_normals", |b| {
        b.iter(|| {
            blend_with_rigid(
                &input.matrices,
                &input.positions,
                Some(&input.normals),
                black_box(&inf),
                &rigid,
                &input.vertices,
                &mut out_p,
                Some(&mut out_n),
            );
            black_box(out_p[VERTICES / 2])
        })
    });
    group.finish();

    // A coarse cache refers to a scattered tenth of the vertices.
    let subset: Vec<u32> = (0..VERTICES as u32).filter(|v| v % 10 == 3).collect();
    let mut group = c.benchmark_group("blend_subset_10pc");
    group.throughput(Throughput::Elements(subset.len() as u64));
    group.bench_function("positions_normals_4", |b| {
        b.iter(|| {
            input.blend(black_box(&inf), &subset, &mut out_p, Some(&mut out_n));
            black_box(out_p[3])
        })
    });
    group.finish();

    // One region's worth (the mannequin's 19 regions hold about 800 vertices each), as
    // `Deform` blends them: the inputs and outputs stay in cache, so this is the arithmetic,
    // where the 100k runs above also stream 7.6 MB through memory per pass.
    const REGION: usize = 1_000;
    let region: Vec<u32> = (0..REGION as u32).collect();
    let mut group = c.benchmark_group("blend_region_1k");
    group.throughput(Throughput::Elements(REGION as u64));
    for count in [1, 2, 4] {
        let inf = influences(&mut rng, count);
        group.bench_function(BenchmarkId::new("positions_normals", count), |b| {
            b.iter(|| {
                input.blend(black_box(&inf), &region, &mut out_p, Some(&mut out_n));
                black_box(out_p[REGION / 2])
            })
        });
    }
    group.finish();
}

criterion_group!(benches, blend_100k);
criterion_main!(benches);
