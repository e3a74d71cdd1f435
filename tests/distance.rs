//! Integration tests of `bevy_aslod::distance`: sampled Hausdorff / RMS mesh distance and its BVH.

use bevy_aslod::distance::{
    Bvh, DistanceOptions, MeshRef, mesh_distance, one_sided, point_triangle_distance_sq,
};
use glam::Vec3;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A small deterministic generator for test data (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[-1, 1)`.
    fn signed(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 23) as f32 - 1.0
    }

    fn vec(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.signed(), self.signed(), self.signed()) * scale
    }
}

struct Mesh {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
}

impl Mesh {
    fn as_ref(&self) -> MeshRef<'_> {
        MeshRef::new(&self.positions, &self.indices)
    }
}

/// The unit square in the XY plane at height `z`, as two triangles.
fn square(z: f32) -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(0.0, 0.0, z),
            Vec3::new(1.0, 0.0, z),
            Vec3::new(1.0, 1.0, z),
            Vec3::new(0.0, 1.0, z),
        ],
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// An icosphere of radius 1: the icosahedron with every triangle split in four `levels` times,
/// every vertex on the sphere.
fn icosphere(levels: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut indices: Vec<u32> = vec![
        0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7,
        1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9,
        8, 1,
    ];
    for _ in 0..levels {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |i: u32, j: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((i.min(j), i.max(j))).or_insert_with(|| {
                let m = (positions[i as usize] + positions[j as usize]).normalize();
                positions.push(m);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(indices.len() * 4);
        for t in indices.chunks_exact(3) {
            let (a, b, c) = (t[0], t[1], t[2]);
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend([a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca]);
        }
        indices = next;
    }
    Mesh { positions, indices }
}

/// Smallest distance from the origin to the plane of any triangle of `mesh`.
fn min_plane_distance(mesh: &Mesh) -> f32 {
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            let n = (b - a).cross(c - a).normalize();
            n.dot(a).abs()
        })
        .fold(f32::INFINITY, f32::min)
}

fn bunny_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/meshes/stanford-bunny.obj")
}

/// A minimal OBJ reader (`v` and `f` lines; `f` corners may be `v`, `v/t`, `v//n` or `v/t/n`,
/// negative indices count from the end; polygons are fan-triangulated).
fn load_obj(path: &PathBuf) -> Option<Mesh> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words.take(3).map(|w| w.parse().unwrap()).collect();
                positions.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let corners: Vec<u32> = words
                    .map(|w| {
                        let i: i64 = w.split('/').next().unwrap().parse().unwrap();
                        if i < 0 {
                            (positions.len() as i64 + i) as u32
                        } else {
                            (i - 1) as u32
                        }
                    })
                    .collect();
                for k in 1..corners.len().saturating_sub(1) {
                    indices.extend([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Some(Mesh { positions, indices })
}

fn bunny() -> Option<Mesh> {
    let mesh = load_obj(&bunny_path());
    if mesh.is_none() {
        eprintln!("skipping: {} not found", bunny_path().display());
    }
    mesh
}

/// `mesh` with every vertex moved by up to `amount` along each axis.
fn jittered(mesh: &Mesh, amount: f32, seed: u64) -> Mesh {
    let mut rng = Rng(seed);
    Mesh {
        positions: mesh
            .positions
            .iter()
            .map(|&p| p + rng.vec(amount))
            .collect(),
        indices: mesh.indices.clone(),
    }
}

fn opts(samples: usize) -> DistanceOptions {
    DistanceOptions::default().with_samples(samples)
}

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[test]
fn identical_meshes_give_zero() {
    let sphere = icosphere(3);
    let d = mesh_distance(sphere.as_ref(), sphere.as_ref(), &opts(20_000));
    // Samples are computed in f32 on the triangles themselves: only rounding remains.
    assert!(d.hausdorff_abs < 1e-6, "{d:?}");
    assert!(d.rms_abs < 1e-6, "{d:?}");
    assert!((d.diagonal - 12f32.sqrt()).abs() < 1e-3, "{d:?}");

    let square = square(0.0);
    let d = mesh_distance(square.as_ref(), square.as_ref(), &opts(1000));
    assert_eq!(d.hausdorff_abs, 0.0, "{d:?}");
    assert_eq!(d.rms_abs, 0.0, "{d:?}");
}

#[test]
fn offset_square() {
    let (a, b) = (square(0.0), square(0.1));
    let d = mesh_distance(a.as_ref(), b.as_ref(), &opts(10_000));
    assert!((d.hausdorff_abs - 0.1).abs() < 1e-6, "{d:?}");
    assert!((d.rms_abs - 0.1).abs() < 1e-6, "{d:?}");
    assert!((d.a_to_b_abs - 0.1).abs() < 1e-6, "{d:?}");
    assert!((d.b_to_a_abs - 0.1).abs() < 1e-6, "{d:?}");
    assert!((d.diagonal - 2f32.sqrt()).abs() < 1e-6, "{d:?}");
    assert!((d.hausdorff - 0.1 / 2f32.sqrt()).abs() < 1e-6, "{d:?}");
    assert!((d.rms - 0.1 / 2f32.sqrt()).abs() < 1e-6, "{d:?}");
}

#[test]
fn half_square_against_whole() {
    // b is the lower-left half of a (below the diagonal x + y = 1). Points of a's upper-right
    // half are (x + y - 1)/sqrt(2) from b, at most sqrt(1/2) at the corner (1, 1); b → a is 0.
    let a = square(0.0);
    let b = Mesh {
        positions: a.positions.clone(),
        indices: vec![0, 1, 3],
    };
    let d = mesh_distance(a.as_ref(), b.as_ref(), &opts(50_000));
    let corner = 0.5f32.sqrt();
    assert!((d.a_to_b_abs - corner).abs() < 1e-6, "{d:?}");
    assert_eq!(d.b_to_a_abs, 0.0, "{d:?}");
    // Over the upper-right half the distance t has density 2(c - t)/c² on [0, c] (c = corner),
    // so its mean square is c²/6; over the rest of a, and all of b, it is 0. Both directions draw
    // the same number of samples: the combined mean square is (c²/6 · 1/2 + 0) / 2 = c²/24.
    let expected = (corner * corner / 24.0).sqrt();
    assert!(
        (d.rms_abs - expected).abs() < 0.01 * expected,
        "{d:?} vs {expected}"
    );
}

#[test]
fn refinement_reaches_a_sharp_peak() {
    // b is the outline of the unit square (four zero-area triangles), so the distance from a point
    // of the square a to b is a pyramid peaking at 0.5 in the centre, which lies on the diagonal
    // edge between a's two triangles. Few samples miss the tip; the refinement climbs to it.
    let a = square(0.0);
    let b = Mesh {
        positions: a.positions.clone(),
        indices: vec![0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 0, 0],
    };
    let sampled = DistanceOptions::default().with_samples(50).with_refine(0);
    let plain = mesh_distance(a.as_ref(), b.as_ref(), &sampled);
    let refined = mesh_distance(a.as_ref(), b.as_ref(), &sampled.with_refine(4));
    eprintln!("sampled {plain:?}\nrefined {refined:?}");
    assert!(
        plain.a_to_b_abs < 0.5 && plain.a_to_b_abs > 0.3,
        "{plain:?}"
    );
    assert!((refined.a_to_b_abs - 0.5).abs() < 1e-3, "{refined:?}");
    assert!(refined.a_to_b_abs <= 0.5 + 1e-6, "{refined:?}");
    assert_eq!(refined.b_to_a_abs, 0.0);
    // Refinement only touches the maximum.
    assert_eq!(plain.rms_abs, refined.rms_abs);
}

#[test]
fn fine_sphere_against_coarse() {
    let (fine, coarse) = (icosphere(5), icosphere(1));
    let d = mesh_distance(fine.as_ref(), coarse.as_ref(), &DistanceOptions::default());
    let (hc, hf) = (min_plane_distance(&coarse), min_plane_distance(&fine));
    // Both surfaces lie between radius h and 1 along every ray from the centre, so no point is
    // farther than 1 - hc from the other surface.
    let upper = 1.0 - hc;
    // The fine vertex nearest the centre of coarse's deepest face is at radius 1; its distance to
    // the (convex) coarse surface is at least its height over that face's plane, so the true
    // distance exceeds hf - hc, and the sampled one comes close.
    let lower = hf - hc;
    eprintln!("sphere: {d:?}, bounds [{lower}, {upper}]");
    assert!(d.hausdorff_abs <= upper + 1e-5, "{d:?} > {upper}");
    assert!(d.hausdorff_abs >= 0.97 * lower, "{d:?} < {lower}");
    // The coarse mesh is inside the fine one: each direction sees about the same gap.
    assert!(d.a_to_b_abs <= upper + 1e-5 && d.b_to_a_abs <= upper + 1e-5);
    assert!(
        d.rms_abs > 0.1 * upper && d.rms_abs < d.hausdorff_abs,
        "{d:?}"
    );
}

#[test]
fn closest_point_matches_brute_force() {
    let mut rng = Rng(0x1234_5678);
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for t in 0..500u32 {
        let centre = rng.vec(10.0);
        // Some triangles are degenerate: a repeated corner or collinear corners.
        let (a, b) = (centre + rng.vec(1.0), centre + rng.vec(1.0));
        let c = match t % 10 {
            0 => a,
            1 => a + (b - a) * 2.0,
            _ => centre + rng.vec(1.0),
        };
        positions.extend([a, b, c]);
        indices.extend([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    let bvh = Bvh::new(&positions, &indices);
    assert_eq!(bvh.len(), 500);
    for q in 0..1000 {
        let p = rng.vec(14.0);
        let (brute, _) = indices
            .chunks_exact(3)
            .enumerate()
            .map(|(i, t)| {
                let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
                (point_triangle_distance_sq(p, a, b, c), i)
            })
            .fold((f32::INFINITY, 0), |x, y| if y.0 < x.0 { y } else { x });
        let (d2, tri) = bvh.closest_point(p).expect("non-empty");
        assert!(d2.is_finite());
        assert_eq!(d2, brute, "query {q} at {p}");
        let t = &indices[3 * tri as usize..][..3];
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        assert_eq!(point_triangle_distance_sq(p, a, b, c), d2, "query {q}");
        let (hinted, _) = bvh.closest_point_with_hint(p, q % 500).expect("non-empty");
        assert_eq!(hinted, brute, "hinted query {q}");
    }
}

#[test]
fn symmetric() {
    let (a, b) = (icosphere(3), icosphere(1));
    let o = opts(30_000);
    let ab = mesh_distance(a.as_ref(), b.as_ref(), &o);
    let ba = mesh_distance(b.as_ref(), a.as_ref(), &o);
    assert_eq!(ab.hausdorff_abs, ba.hausdorff_abs);
    assert_eq!(ab.rms_abs, ba.rms_abs);
    assert_eq!(ab.a_to_b_abs, ba.b_to_a_abs);
    assert_eq!(ab.b_to_a_abs, ba.a_to_b_abs);
}

#[test]
fn deterministic() {
    let a = icosphere(3);
    let b = jittered(&a, 0.01, 99);
    let o = DistanceOptions::default()
        .with_samples(50_000)
        .with_seed(42);
    let first = mesh_distance(a.as_ref(), b.as_ref(), &o);
    assert_eq!(first, mesh_distance(a.as_ref(), b.as_ref(), &o));
    for threads in [1, 2, 3, 7] {
        let o = o.with_threads(threads);
        assert_eq!(
            first,
            mesh_distance(a.as_ref(), b.as_ref(), &o),
            "{threads}"
        );
    }
    // Another seed moves the samples (and so the numbers), but only slightly.
    let other = mesh_distance(a.as_ref(), b.as_ref(), &o.with_seed(7));
    assert_ne!(first.rms_abs, other.rms_abs);
    assert!((first.rms_abs - other.rms_abs).abs() < 0.02 * first.rms_abs);
    assert!((first.hausdorff_abs - other.hausdorff_abs).abs() < 0.1 * first.hausdorff_abs);
}

#[test]
fn one_sided_matches_mesh_distance() {
    let (a, b) = (icosphere(3), icosphere(1));
    let o = opts(20_000);
    let d = mesh_distance(a.as_ref(), b.as_ref(), &o);
    let (max_ab, rms_ab) = one_sided(a.as_ref(), &Bvh::new(&b.positions, &b.indices), &o);
    let (max_ba, rms_ba) = one_sided(b.as_ref(), &Bvh::new(&a.positions, &a.indices), &o);
    assert_eq!(max_ab, d.a_to_b_abs);
    assert_eq!(max_ba, d.b_to_a_abs);
    let combined = ((rms_ab * rms_ab + rms_ba * rms_ba) / 2.0).sqrt();
    assert!(
        (combined - d.rms_abs).abs() < 1e-6 * d.rms_abs,
        "{combined} vs {d:?}"
    );
}

#[test]
fn empty_and_invalid_input() {
    let square = square(0.0);
    let empty = Mesh {
        positions: vec![],
        indices: vec![],
    };
    let o = opts(1000);
    let d = mesh_distance(square.as_ref(), empty.as_ref(), &o);
    assert_eq!(d.hausdorff_abs, f32::INFINITY);
    assert_eq!(d.rms_abs, f32::INFINITY);
    assert_eq!(d.a_to_b_abs, f32::INFINITY);
    assert_eq!(d.b_to_a_abs, 0.0);
    let d = mesh_distance(empty.as_ref(), square.as_ref(), &o);
    assert_eq!(d.hausdorff, f32::INFINITY);
    assert_eq!(d.diagonal, 0.0);
    let d = mesh_distance(empty.as_ref(), empty.as_ref(), &o);
    assert_eq!(
        (d.hausdorff, d.rms, d.hausdorff_abs, d.rms_abs),
        (0.0, 0.0, 0.0, 0.0)
    );

    // Out-of-range indices, non-finite corners and a trailing partial triangle are ignored;
    // unreferenced vertices are not sampled.
    let mut broken = Mesh {
        positions: square.positions.clone(),
        indices: square.indices.clone(),
    };
    broken.positions.extend([Vec3::NAN, Vec3::splat(100.0)]);
    broken.indices.extend([0, 1, 9, 0, 1, 4, 2, 3]);
    let d = mesh_distance(square.as_ref(), broken.as_ref(), &o);
    assert_eq!(d.hausdorff_abs, 0.0, "{d:?}");
    assert!(Bvh::new(&[], &[0, 1, 2]).is_empty());
    assert_eq!(Bvh::new(&[], &[]).closest_point(Vec3::ZERO), None);
    assert_eq!(one_sided(empty.as_ref(), &Bvh::default(), &o), (0.0, 0.0));
    // No samples asked for: nothing measured, but no NaN either.
    let nothing = o.with_samples(0).with_vertices(false);
    let d = mesh_distance(square.as_ref(), broken.as_ref(), &nothing);
    assert_eq!((d.hausdorff_abs, d.rms_abs), (0.0, 0.0), "{d:?}");
    let d = mesh_distance(square.as_ref(), empty.as_ref(), &nothing);
    assert_eq!(d.hausdorff_abs, f32::INFINITY, "{d:?}");
    assert_eq!(
        one_sided(square.as_ref(), &Bvh::default(), &o),
        (f32::INFINITY, f32::INFINITY)
    );
}

#[test]
fn degenerate_triangles_never_give_nan() {
    // Only zero-area triangles: no area samples, so the RMS falls back to the vertices.
    let positions = vec![Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0), Vec3::Y];
    let line = Mesh {
        positions: positions.clone(),
        indices: vec![0, 1, 2, 1, 1, 1, 3, 3, 3],
    };
    let square = square(0.5);
    for o in [opts(1000), opts(0)] {
        let d = mesh_distance(line.as_ref(), square.as_ref(), &o);
        assert!(!d.hausdorff_abs.is_nan() && !d.rms_abs.is_nan(), "{d:?}");
        // Every vertex of the line mesh is at height 0, 0.5 below the square... except (2, 0, 0),
        // which is also 1 away sideways; every square point is within reach of the line mesh.
        assert!(
            d.a_to_b_abs >= 0.5 && d.a_to_b_abs <= (1.25f32).sqrt() + 1e-6,
            "{d:?}"
        );
        assert!(d.rms_abs.is_finite() && d.rms_abs > 0.0, "{d:?}");
    }
    let d = mesh_distance(line.as_ref(), line.as_ref(), &opts(1000));
    assert_eq!((d.hausdorff_abs, d.rms_abs), (0.0, 0.0), "{d:?}");
}

#[test]
fn bunny_against_jittered_bunny() {
    let Some(bunny) = bunny() else { return };
    assert_eq!(bunny.indices.len() / 3, 69_451);
    let base = mesh_distance(bunny.as_ref(), bunny.as_ref(), &opts(50_000));
    assert!(base.hausdorff < 1e-6, "{base:?}");

    let amount = 1e-3 * base.diagonal;
    let jitter = jittered(&bunny, amount, 5);
    let d = mesh_distance(bunny.as_ref(), jitter.as_ref(), &opts(50_000));
    eprintln!("bunny vs jittered by {amount}: {d:?}");
    // Every point moves by at most amount·sqrt(3) (a convex combination of its corners' moves).
    let bound = amount * 3f32.sqrt();
    assert!(d.hausdorff_abs <= bound * 1.0001, "{d:?} > {bound}");
    assert!(d.hausdorff_abs > 0.3 * amount, "{d:?}");
    assert!(
        d.rms_abs > 0.1 * amount && d.rms_abs < d.hausdorff_abs,
        "{d:?}"
    );
    assert!((d.hausdorff - d.hausdorff_abs / d.diagonal).abs() < 1e-9);
}

/// Timing of the use case this module exists for: the bunny against a 10 % meshoptimizer
/// simplification (which indexes into the original vertex buffer). Run with
/// `cargo test --release --test distance -- --ignored --nocapture`.
#[test]
#[ignore = "timing print; run in release"]
fn bunny_timing() {
    let Some(bunny) = bunny() else { return };
    let data = meshopt::typed_to_bytes(&bunny.positions);
    let adapter = meshopt::VertexDataAdapter::new(data, std::mem::size_of::<Vec3>(), 0)
        .expect("vertex adapter");
    for fraction in [0.5, 0.1, 0.02] {
        let target = ((bunny.indices.len() / 3) as f64 * fraction) as usize * 3;
        let simplified = Mesh {
            positions: bunny.positions.clone(),
            indices: meshopt::simplify(
                &bunny.indices,
                &adapter,
                target,
                1.0,
                meshopt::SimplifyOptions::None,
                None,
            ),
        };
        for threads in [1, 0] {
            let o = DistanceOptions::default().with_threads(threads);
            let start = Instant::now();
            let d = mesh_distance(bunny.as_ref(), simplified.as_ref(), &o);
            let elapsed = start.elapsed();
            eprintln!(
                "bunny {} tris vs meshopt {:.0}% ({} tris), {} samples/side, threads {}: {:.1} ms \
                 → hausdorff {:.3e} rms {:.3e} (relative)",
                bunny.indices.len() / 3,
                fraction * 100.0,
                simplified.indices.len() / 3,
                o.samples,
                threads,
                elapsed.as_secs_f64() * 1e3,
                d.hausdorff,
                d.rms,
            );
        }
    }
    // Dropping every other triangle: holes, so larger distances and deeper searches.
    let holes = Mesh {
        positions: bunny.positions.clone(),
        indices: bunny
            .indices
            .chunks_exact(3)
            .step_by(2)
            .flatten()
            .copied()
            .collect(),
    };
    let start = Instant::now();
    let d = mesh_distance(bunny.as_ref(), holes.as_ref(), &DistanceOptions::default());
    eprintln!(
        "bunny vs every other triangle: {:.1} ms → {d:?}",
        start.elapsed().as_secs_f64() * 1e3
    );
}
