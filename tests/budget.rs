//! The polygon budget: OBB fitting, projected OBB area against an independent brute-force
//! reference, and the α allocation's invariants (proptest).

use bevy_aslod::budget::{
    AllocationParams, Allocator, BudgetError, Obb, ProjectedAreaCamera, RegionInput, allocate,
    fit_aabb, fit_obb, fit_obb_pca, silhouette,
};
use glam::{Affine3A, DMat4, DVec2, DVec3, DVec4, Mat3, Mat4, Quat, Vec2, Vec3, Vec4Swizzles};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Seeded randomness (splitmix64).

struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    fn below(&mut self, n: u32) -> u32 {
        (self.next_u64() % u64::from(n)) as u32
    }

    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    fn unit_vec3(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(-1.0, 1.0);
            let len = v.length();
            if len > 0.1 && len <= 1.0 {
                return v / len;
            }
        }
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

// ---------------------------------------------------------------------------------------------
// OBB fitting.

fn box_points(rng: &mut Rng, rotation: Quat, center: Vec3, half: Vec3, extra: usize) -> Vec<Vec3> {
    let mut points: Vec<Vec3> = (0..8)
        .map(|i| {
            let s = |b: usize| if (i >> b) & 1 == 1 { 1.0 } else { -1.0 };
            center + rotation * (half * Vec3::new(s(0), s(1), s(2)))
        })
        .collect();
    for _ in 0..extra {
        // Points on the surface and inside.
        let mut local = rng.vec3(-1.0, 1.0);
        if rng.unit() < 0.5 {
            let k = rng.below(3) as usize;
            local[k] = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
        }
        points.push(center + rotation * (half * local));
    }
    points
}

fn load_obj_positions(name: &str) -> Vec<Vec3> {
    let path = format!(
        "{}/../shared/testdata/meshes/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter_map(|line| {
            let mut it = line.split_whitespace();
            (it.next() == Some("v")).then(|| {
                let mut c = it.map(|t| t.parse::<f32>().expect("a number"));
                Vec3::new(c.next().unwrap(), c.next().unwrap(), c.next().unwrap())
            })
        })
        .collect()
}

const MESHES: [&str; 4] = ["stanford-bunny.obj", "cow.obj", "fandisk.obj", "spot.obj"];

fn assert_contains(obb: &Obb, points: &[Vec3], what: &str) {
    let scale = obb
        .half_extents
        .max_element()
        .max(obb.center.abs().max_element());
    for &p in points {
        assert!(
            obb.contains_point(p, 1e-5 * scale.max(1.0)),
            "{what}: {p} is outside {obb:?}"
        );
    }
}

#[test]
fn rotated_boxes_come_back_within_one_percent() {
    let mut rng = Rng(1);
    let mut worst: f32 = 0.0;
    for round in 0..300 {
        let rotation = rng.rotation();
        let half = if round % 3 == 0 {
            Vec3::splat(rng.range(0.1, 5.0)) // a cube: PCA has no preferred axes
        } else {
            rng.vec3(0.05, 5.0)
        };
        let center = rng.vec3(-100.0, 100.0);
        let extra = [0, 20, 500][round % 3];
        let points = box_points(&mut rng, rotation, center, half, extra);
        let obb = fit_obb(&points).expect("finite input");
        let truth = 8.0 * half.x * half.y * half.z;
        let ratio = obb.volume() / truth;
        worst = worst.max((ratio - 1.0).abs());
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "round {round}: volume {} vs {truth}",
            obb.volume()
        );
        assert_contains(&obb, &points, "rotated box");
        assert!((obb.axes.determinant() - 1.0).abs() < 1e-5);
    }
    assert!(worst < 1e-3, "worst relative volume error {worst}");
}

#[test]
fn fit_obb_is_at_least_as_tight_as_pca_and_aabb_on_test_meshes() {
    for name in MESHES {
        let points = load_obj_positions(name);
        let ours = fit_obb(&points).unwrap();
        let pca = fit_obb_pca(&points).unwrap();
        let aabb = fit_aabb(&points).unwrap();
        assert_contains(&ours, &points, name);
        assert_contains(&pca, &points, name);
        assert!(
            ours.volume() <= pca.volume() * 1.000_01,
            "{name}: ours vs PCA"
        );
        assert!(
            ours.volume() <= aabb.volume() * 1.000_01,
            "{name}: ours vs AABB"
        );
    }
}

#[test]
fn fit_obb_degenerate_inputs() {
    assert_eq!(fit_obb(&[]), None);
    assert_eq!(fit_obb(&[Vec3::ONE, Vec3::new(f32::NAN, 0.0, 0.0)]), None);
    assert_eq!(fit_obb(&[Vec3::INFINITY]), None);
    assert_eq!(fit_obb_pca(&[]), None);
    assert_eq!(fit_aabb(&[Vec3::NAN]), None);

    let single = fit_obb(&[Vec3::new(1.0, 2.0, 3.0); 3]).unwrap();
    assert_eq!(single.center, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(single.half_extents, Vec3::ZERO);

    let line: Vec<Vec3> = (0..10)
        .map(|i| Vec3::new(1.0, 2.0, 3.0) * i as f32)
        .collect();
    let obb = fit_obb(&line).unwrap();
    assert_contains(&obb, &line, "line");
    let mut h = obb.half_extents.to_array();
    h.sort_by(f32::total_cmp);
    assert!(h[0] < 1e-5 && h[1] < 1e-5, "line box {h:?}");
    assert!((h[2] - 0.5 * 9.0 * 14f32.sqrt()).abs() < 1e-3);

    // A flat rotated rectangle with points inside: a flat box of the rectangle's area.
    let mut rng = Rng(5);
    let rotation = rng.rotation();
    let flat: Vec<Vec3> = (0..200)
        .map(|i| {
            let local = if i < 4 {
                Vec3::new(
                    if i & 1 == 1 { 3.0 } else { -3.0 },
                    if i & 2 == 2 { 1.0 } else { -1.0 },
                    0.0,
                )
            } else {
                Vec3::new(rng.range(-3.0, 3.0), rng.range(-1.0, 1.0), 0.0)
            };
            rotation * local + Vec3::new(4.0, 5.0, 6.0)
        })
        .collect();
    let obb = fit_obb(&flat).unwrap();
    assert_contains(&obb, &flat, "flat");
    let mut h = obb.half_extents.to_array();
    h.sort_by(f32::total_cmp);
    assert!(h[0] < 1e-5, "flat box {h:?}");
    assert!(
        (4.0 * h[1] * h[2] - 12.0).abs() < 1e-3,
        "rectangle area {h:?}"
    );
}

#[test]
fn fit_obb_survives_awkward_point_sets() {
    let mut rng = Rng(11);
    for round in 0..40 {
        let rotation = rng.rotation();
        let mut points = Vec::new();
        match round % 4 {
            // A regular grid on a box's surface: many exactly coplanar and collinear points.
            0 => {
                for i in 0..=8 {
                    for j in 0..=8 {
                        let (u, v) = (i as f32 / 4.0 - 1.0, j as f32 / 4.0 - 1.0);
                        for face in [
                            Vec3::new(u, v, 1.0),
                            Vec3::new(u, v, -1.0),
                            Vec3::new(u, 1.0, v),
                            Vec3::new(u, -1.0, v),
                            Vec3::new(1.0, u, v),
                            Vec3::new(-1.0, u, v),
                        ] {
                            points.push(rotation * (face * Vec3::new(3.0, 2.0, 1.0)));
                        }
                    }
                }
            }
            // Points on a sphere, each three times.
            1 => {
                for _ in 0..300 {
                    let p = rng.unit_vec3() * 5.0;
                    points.extend([p, p, p]);
                }
            }
            // A thin sliver: almost flat.
            2 => {
                for _ in 0..500 {
                    let p = Vec3::new(
                        rng.range(-4.0, 4.0),
                        rng.range(-1.0, 1.0),
                        rng.range(-1e-6, 1e-6),
                    );
                    points.push(rotation * p + Vec3::splat(1000.0));
                }
            }
            // A few points only.
            _ => {
                for _ in 0..4 + round % 5 {
                    points.push(rng.vec3(-1.0, 1.0));
                }
            }
        }
        let ours = fit_obb(&points).unwrap();
        assert!(ours.is_finite(), "round {round}");
        assert_contains(&ours, &points, "awkward");
        if round % 4 == 2 {
            // At 1000 units from the origin f32 resolves 6e-5, so the sliver's thickness is
            // rounding noise and volumes cannot be compared; its rectangle can.
            let mut h = ours.half_extents.to_array();
            h.sort_by(f32::total_cmp);
            assert!(h[0] < 2e-4, "round {round}: {h:?}");
            assert!(
                (h[1] - 1.0).abs() < 0.02 && (h[2] - 4.0).abs() < 0.05,
                "round {round}: {h:?}"
            );
            continue;
        }
        let pca = fit_obb_pca(&points).unwrap();
        let aabb = fit_aabb(&points).unwrap();
        assert!(
            ours.volume() <= pca.volume() * 1.0001 + 1e-6,
            "round {round}: ours vs PCA"
        );
        assert!(
            ours.volume() <= aabb.volume() * 1.0001 + 1e-6,
            "round {round}: ours vs AABB"
        );
        if round % 4 == 0 {
            assert!(
                (ours.volume() / 48.0 - 1.0).abs() < 1e-3,
                "round {round}: {}",
                ours.volume()
            );
        }
    }
}

#[test]
fn transformed_obb_contains_the_transformed_points() {
    let mut rng = Rng(9);
    for _ in 0..100 {
        let rotation = rng.rotation();
        let points = box_points(&mut rng, rotation, Vec3::ZERO, Vec3::new(2.0, 1.0, 0.5), 50);
        let obb = fit_obb(&points).unwrap();
        let transform = glam::Affine3A::from_scale_rotation_translation(
            rng.vec3(0.2, 3.0),
            rng.rotation(),
            rng.vec3(-10.0, 10.0),
        );
        let moved = obb.transformed(&transform);
        let moved_points: Vec<Vec3> = points
            .iter()
            .map(|&p| transform.transform_point3(p))
            .collect();
        assert_contains(&moved, &moved_points, "transformed");
    }
}

/// The volume table of the report: ours vs PCA vs AABB on the test meshes and on rotated boxes.
/// Run with `cargo test --no-default-features --release --test budget -- --ignored --nocapture`.
#[test]
#[ignore = "prints a report"]
fn report_obb_volumes() {
    println!(
        "{:<22} {:>8} {:>12} {:>12} {:>12} {:>9} {:>9} {:>9}",
        "input", "points", "AABB", "PCA", "ours", "ours/AABB", "ours/PCA", "ms"
    );
    let row = |name: &str, points: &[Vec3]| {
        let start = std::time::Instant::now();
        let ours = fit_obb(points).unwrap();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let pca = fit_obb_pca(points).unwrap();
        let aabb = fit_aabb(points).unwrap();
        println!(
            "{:<22} {:>8} {:>12.5} {:>12.5} {:>12.5} {:>9.3} {:>9.3} {:>9.2}",
            name,
            points.len(),
            aabb.volume(),
            pca.volume(),
            ours.volume(),
            ours.volume() / aabb.volume(),
            ours.volume() / pca.volume(),
            ms
        );
    };
    for name in MESHES {
        row(name, &load_obj_positions(name));
    }
    let mut rng = Rng(42);
    let (mut vs_aabb, mut vs_pca, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    let count = 1000;
    for i in 0..count {
        let half = if i % 2 == 0 {
            Vec3::splat(1.0)
        } else {
            rng.vec3(0.1, 3.0)
        };
        let rotation = rng.rotation();
        let center = rng.vec3(-10.0, 10.0);
        let points = box_points(&mut rng, rotation, center, half, 100);
        let truth = f64::from(8.0 * half.x * half.y * half.z);
        let ours = f64::from(fit_obb(&points).unwrap().volume());
        vs_aabb += ours / f64::from(fit_aabb(&points).unwrap().volume());
        vs_pca += ours / f64::from(fit_obb_pca(&points).unwrap().volume());
        worst = worst.max((ours / truth - 1.0).abs());
    }
    println!(
        "rotated boxes ({count}, half cubes, 108 points each): mean ours/AABB {:.3}, mean ours/PCA {:.3}, worst |ours/true - 1| {:.2e}",
        vs_aabb / f64::from(count),
        vs_pca / f64::from(count),
        worst
    );
}

// ---------------------------------------------------------------------------------------------
// Projected area: the silhouette table against projected corner hulls.

/// The convex hull of 2D points by gift wrapping (not the monotone chain the library uses),
/// as indices into `points`, counter-clockwise. Points within a relative 1e-9 of an earlier one
/// count as that one (clipped faces share corners, computed twice).
fn gift_wrap(points: &[DVec2]) -> Vec<usize> {
    let scale = points
        .iter()
        .fold(1.0f64, |m, p| m.max(p.abs().max_element()));
    let tolerance = 1e-9 * scale;
    let unique: Vec<usize> = (0..points.len())
        .filter(|&i| (0..i).all(|j| points[j].distance(points[i]) > tolerance))
        .collect();
    if unique.len() < 3 {
        return unique;
    }
    let start = *unique
        .iter()
        .min_by(|&&a, &&b| {
            points[a]
                .x
                .total_cmp(&points[b].x)
                .then(points[a].y.total_cmp(&points[b].y))
        })
        .unwrap();
    let mut hull = vec![];
    let mut p = start;
    loop {
        hull.push(p);
        assert!(hull.len() <= unique.len(), "gift wrapping did not close");
        let mut q = usize::MAX;
        for &r in &unique {
            if r == p {
                continue;
            }
            if q == usize::MAX {
                q = r;
                continue;
            }
            let cross = (points[q] - points[p]).perp_dot(points[r] - points[p]);
            let farther =
                points[r].distance_squared(points[p]) > points[q].distance_squared(points[p]);
            // Keep the most clockwise candidate: every other point is then to its left.
            if cross < 0.0 || (cross == 0.0 && farther) {
                q = r;
            }
        }
        p = q;
        if p == start {
            break;
        }
    }
    hull
}

#[test]
fn silhouette_table_matches_projected_corner_hulls() {
    let mut valid = 0;
    for code in 0..64u8 {
        let mut eye = DVec3::ZERO;
        let mut possible = code != 0;
        for k in 0..3 {
            match (code >> (2 * k)) & 3 {
                0 => eye[k] = 0.2,
                1 => eye[k] = -3.1,
                2 => eye[k] = 3.3,
                _ => possible = false,
            }
        }
        let outline = silhouette(code);
        if !possible {
            assert!(outline.is_empty(), "code {code:06b} cannot occur");
            continue;
        }
        valid += 1;
        // Look at the unit box's centre from the eye; project its corners.
        let up = if eye.cross(DVec3::Y).length() > 1e-3 {
            DVec3::Y
        } else {
            DVec3::X
        };
        let clip =
            DMat4::perspective_rh(1.5, 1.0, 0.1, 100.0) * DMat4::look_at_rh(eye, DVec3::ZERO, up);
        let projected: Vec<DVec2> = (0..8)
            .map(|i| {
                let s = |b: usize| if (i >> b) & 1 == 1 { 1.0 } else { -1.0 };
                let v = clip * DVec4::new(s(0), s(1), s(2), 1.0);
                v.xy() / v.w
            })
            .collect();
        let hull = gift_wrap(&projected);
        assert_eq!(
            hull.len(),
            outline.len(),
            "code {code:06b}: hull {hull:?} vs {outline:?}"
        );
        // Same cycle, same (counter-clockwise) direction.
        let shift = hull
            .iter()
            .position(|&h| h == usize::from(outline[0]))
            .unwrap();
        for (k, &c) in outline.iter().enumerate() {
            assert_eq!(
                hull[(shift + k) % hull.len()],
                usize::from(c),
                "code {code:06b}: hull {hull:?} vs table {outline:?}"
            );
        }
    }
    assert_eq!(valid, 26);
}

// ---------------------------------------------------------------------------------------------
// Projected area: the brute-force reference.

#[derive(Clone, Copy, Debug, PartialEq)]
enum Projection {
    Perspective,
    InfiniteReverse,
    Orthographic,
    OrthographicReversed,
}

#[derive(Clone, Copy, Debug)]
struct Scene {
    view: Mat4,
    projection: Mat4,
    kind: Projection,
    viewport: Vec2,
}

impl Scene {
    fn camera(&self) -> ProjectedAreaCamera {
        ProjectedAreaCamera::new(self.view, self.projection, self.viewport).unwrap()
    }

    /// The visible side of the near plane in clip space, from what the test built (not from
    /// the matrix).
    fn near_plane(&self) -> DVec4 {
        match self.kind {
            Projection::Perspective | Projection::Orthographic => DVec4::new(0.0, 0.0, 1.0, 0.0),
            Projection::InfiniteReverse | Projection::OrthographicReversed => {
                DVec4::new(0.0, 0.0, -1.0, 1.0)
            }
        }
    }

    fn clip_from_world(&self) -> DMat4 {
        self.projection.as_dmat4() * self.view.as_dmat4()
    }

    /// Where the box lies against the near plane: all corners in front, all behind, or both.
    fn side(&self, obb: &Obb) -> Side {
        let near = self.near_plane();
        let m = self.clip_from_world();
        let d: Vec<f64> = reference_corners(obb)
            .iter()
            .map(|c| near.dot(m * c.extend(1.0)))
            .collect();
        if d.iter().all(|&x| x >= 0.0) {
            Side::Front
        } else if d.iter().all(|&x| x < 0.0) {
            Side::Behind
        } else {
            Side::Straddling
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    Front,
    Straddling,
    Behind,
}

fn reference_corners(obb: &Obb) -> [DVec3; 8] {
    let c = obb.center.as_dvec3();
    let h = obb.half_extents.as_dvec3();
    let a = [
        obb.axes.x_axis.as_dvec3(),
        obb.axes.y_axis.as_dvec3(),
        obb.axes.z_axis.as_dvec3(),
    ];
    std::array::from_fn(|i| {
        let mut p = c;
        for k in 0..3 {
            let s = if (i >> k) & 1 == 1 { 1.0 } else { -1.0 };
            p += a[k] * (s * h[k]);
        }
        p
    })
}

/// The brute-force area in pixels²: clip each of the six faces against the near plane in clip
/// space, divide, take the hull of everything (the projection of the near-clipped volume), clip
/// to the viewport. All in `f64`, sharing nothing with the fast path.
fn reference_area(scene: &Scene, obb: &Obb) -> f64 {
    reference_area_of_corners(scene, &reference_corners(obb))
}

/// [`reference_area`] of any eight corners in the same order (a parallelepiped too).
fn reference_area_of_corners(scene: &Scene, corners: &[DVec3; 8]) -> f64 {
    const FACES: [[usize; 4]; 6] = [
        [0, 2, 6, 4],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 5, 7, 6],
    ];
    let m = scene.clip_from_world();
    let near = scene.near_plane();
    let clip: Vec<DVec4> = corners.iter().map(|c| m * c.extend(1.0)).collect();
    let mut points: Vec<DVec2> = Vec::new();
    for face in FACES {
        let polygon: Vec<DVec4> = face.iter().map(|&i| clip[i]).collect();
        let mut clipped = Vec::new();
        for k in 0..4 {
            let (a, b) = (polygon[k], polygon[(k + 1) % 4]);
            let (da, db) = (near.dot(a), near.dot(b));
            if da >= 0.0 {
                clipped.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                clipped.push(a + (b - a) * (da / (da - db)));
            }
        }
        points.extend(clipped.iter().map(|v| v.xy() / v.w));
    }
    if points.len() < 3 {
        return 0.0;
    }
    let hull: Vec<DVec2> = gift_wrap(&points).iter().map(|&i| points[i]).collect();
    let mut polygon = hull;
    for (axis, bound) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)] {
        let inside = |p: DVec2| {
            if bound > 0.0 {
                p[axis] <= bound
            } else {
                p[axis] >= bound
            }
        };
        let mut out = Vec::new();
        for k in 0..polygon.len() {
            let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            if inside(a) {
                out.push(a);
            }
            if inside(a) != inside(b) {
                out.push(a + (b - a) * ((bound - a[axis]) / (b[axis] - a[axis])));
            }
        }
        polygon = out;
    }
    let mut twice = 0.0;
    for k in 0..polygon.len() {
        twice += polygon[k].perp_dot(polygon[(k + 1) % polygon.len()]);
    }
    (twice * 0.5).abs() * f64::from(scene.viewport.x) * f64::from(scene.viewport.y) / 4.0
}

fn random_scene(rng: &mut Rng) -> (Scene, f32) {
    let eye = rng.vec3(-20.0, 20.0);
    let target = eye + rng.unit_vec3();
    let mut up = rng.unit_vec3();
    while up.cross(target - eye).length() < 0.2 {
        up = rng.unit_vec3();
    }
    let view = Mat4::look_at_rh(eye, target, up);
    let viewport = Vec2::new(
        rng.range(64.0, 4096.0).round(),
        rng.range(64.0, 4096.0).round(),
    );
    let aspect = viewport.x / viewport.y;
    let near = 10f32.powf(rng.range(-2.0, 0.0));
    let kind = [
        Projection::Perspective,
        Projection::InfiniteReverse,
        Projection::Orthographic,
        Projection::OrthographicReversed,
    ][rng.below(4) as usize];
    let fov = rng.range(0.3, 2.2);
    let half_height = rng.range(0.5, 20.0);
    let half_width = half_height * aspect;
    let far = near * rng.range(100.0, 10_000.0);
    let projection = match kind {
        Projection::Perspective => Mat4::perspective_rh(fov, aspect, near, far),
        Projection::InfiniteReverse => Mat4::perspective_infinite_reverse_rh(fov, aspect, near),
        Projection::Orthographic => Mat4::orthographic_rh(
            -half_width,
            half_width,
            -half_height,
            half_height,
            near,
            far,
        ),
        Projection::OrthographicReversed => Mat4::orthographic_rh(
            -half_width,
            half_width,
            -half_height,
            half_height,
            far,
            near,
        ),
    };
    (
        Scene {
            view,
            projection,
            kind,
            viewport,
        },
        near,
    )
}

/// A random box for `scene`, from one of several situations: in view, straddling the near
/// plane, around the eye, behind the camera, huge, anywhere; sometimes flat.
fn random_box(rng: &mut Rng, scene: &Scene, near: f32) -> Obb {
    let world_from_view = scene.view.inverse();
    let eye = world_from_view.w_axis.xyz();
    let forward = -world_from_view.z_axis.xyz().normalize();
    let right = world_from_view.x_axis.xyz().normalize();
    let up = world_from_view.y_axis.xyz().normalize();
    let (center, mut half) = match rng.below(6) {
        0 => {
            let d = near * 2.0 + rng.range(0.0, 50.0);
            let lateral = d.max(5.0);
            (
                eye + forward * d
                    + right * rng.range(-lateral, lateral)
                    + up * rng.range(-lateral, lateral),
                rng.vec3(0.005, 0.4) * d.max(1.0),
            )
        }
        1 => {
            let d = near * rng.range(-1.0, 3.0);
            (
                eye + forward * d
                    + right * rng.range(-2.0, 2.0) * near
                    + up * rng.range(-2.0, 2.0) * near,
                rng.vec3(0.2, 3.0) * near,
            )
        }
        2 => {
            let half = rng.vec3(0.5, 5.0);
            (eye + rng.vec3(-0.9, 0.9) * half, half)
        }
        3 => (
            eye - forward * rng.range(near, 20.0) + rng.vec3(-3.0, 3.0),
            rng.vec3(0.1, 3.0),
        ),
        4 => (
            eye + forward * rng.range(5.0, 30.0) + rng.vec3(-20.0, 20.0),
            rng.vec3(5.0, 50.0),
        ),
        _ => (eye + rng.vec3(-30.0, 30.0), rng.vec3(0.01, 10.0)),
    };
    if rng.unit() < 0.15 {
        half[rng.below(3) as usize] = 0.0;
    }
    Obb::new(center, Mat3::from_quat(rng.rotation()), half)
}

#[derive(Default, Debug)]
struct ErrorStats {
    count: usize,
    /// Cases whose reference area is over 0.1 % of the viewport.
    sizable: usize,
    /// Cases that passed only thanks to the absolute floor (error above 1e-4 relative).
    needed_floor: usize,
    worst_relative: f64,
    worst_absolute_pixels: f64,
}

#[test]
fn projected_area_matches_brute_force_on_100k_random_boxes() {
    let mut rng = Rng(2024);
    let mut stats: [ErrorStats; 3] = Default::default();
    let mut by_projection = [0usize; 4];
    for case in 0..100_000 {
        let (scene, near) = random_scene(&mut rng);
        let obb = random_box(&mut rng, &scene, near);
        let fast = f64::from(scene.camera().projected_area(&obb));
        let reference = reference_area(&scene, &obb);
        let side = scene.side(&obb);
        let viewport_area = f64::from(scene.viewport.x * scene.viewport.y);
        let error = (fast - reference).abs();
        // 1e-4 relative, with a floor of 1e-9 of the viewport only so that a reference of
        // exactly zero tolerates a rounding residue (none occurs: `needed_floor` stays 0).
        let allowed = 1e-4 * reference + 1e-9 * viewport_area;
        assert!(
            error <= allowed && fast.is_finite(),
            "case {case} ({side:?}, {:?}): fast {fast}, reference {reference}\n{scene:?}\n{obb:?}",
            scene.kind
        );
        let s = &mut stats[side as usize];
        s.count += 1;
        s.needed_floor += usize::from(error > 1e-4 * reference);
        if reference > 1e-3 * viewport_area {
            s.sizable += 1;
            s.worst_relative = s.worst_relative.max(error / reference);
        }
        s.worst_absolute_pixels = s.worst_absolute_pixels.max(error);
        by_projection[scene.kind as usize] += 1;
    }
    println!("front, straddling, behind: {stats:#?}\nper projection: {by_projection:?}");
    for s in &stats {
        assert!(s.count > 1000, "every situation is exercised: {stats:?}");
    }
    // In practice the floor is unused, and sizable boxes agree to a few f32 roundings: boxes
    // wholly in view are measured in f32 (about 1e-6 at worst; thin outlines fall back to
    // f64), the others in f64 (to the rounding of the result).
    for s in &stats {
        assert!(s.worst_relative <= 1e-5 && s.needed_floor == 0, "{stats:?}");
    }
}

/// The batch (four boxes per step, measured by faces) holds the same precision as one box at
/// a time against the brute-force reference, whatever the batch's length (a short last chunk
/// is padded) and wherever the boxes lie; boxes it hands to `projected_area` agree bit for bit.
#[test]
fn batched_areas_match_brute_force() {
    let mut rng = Rng(31);
    let mut areas = Vec::new();
    let (mut compared, mut differ) = (0, 0);
    let mut worst_relative = 0.0f64;
    for case in 0..12_000 {
        let (scene, near) = random_scene(&mut rng);
        let camera = scene.camera();
        let boxes: Vec<Obb> = (0..rng.below(11))
            .map(|_| random_box(&mut rng, &scene, near))
            .collect();
        areas.clear();
        areas.resize(boxes.len(), f32::NAN);
        camera.projected_areas(&boxes, &mut areas);
        let viewport_area = f64::from(scene.viewport.x * scene.viewport.y);
        for (obb, &area) in boxes.iter().zip(&areas) {
            let reference = reference_area(&scene, obb);
            let error = (f64::from(area) - reference).abs();
            assert!(
                error <= 1e-4 * reference + 1e-9 * viewport_area && area.is_finite(),
                "case {case}: batch {area}, reference {reference}\n{scene:?}\n{obb:?}"
            );
            if reference > 1e-3 * viewport_area {
                worst_relative = worst_relative.max(error / reference);
            }
            compared += usize::from(reference > 0.0);
            differ += usize::from(area.to_bits() != camera.projected_area(obb).to_bits());
        }
    }
    println!(
        "in view: {compared}, differing from projected_area in the last bits: {differ}, worst relative error {worst_relative:e}"
    );
    assert!(compared > 10_000, "most boxes are in view: {compared}");
    assert!(worst_relative <= 1e-5, "{worst_relative}");
}

/// `may_see` is false only for boxes with no area, and true for every box with some.
#[test]
fn may_see_is_false_only_for_boxes_out_of_view() {
    let mut rng = Rng(57);
    let mut unseen = 0;
    for _ in 0..50_000 {
        let (scene, near) = random_scene(&mut rng);
        let camera = scene.camera();
        let obb = random_box(&mut rng, &scene, near);
        let area = camera.projected_area(&obb);
        if camera.may_see(&obb) {
            continue;
        }
        unseen += 1;
        assert_eq!(
            area, 0.0,
            "{obb:?} is out of view but has area {area}\n{scene:?}"
        );
        assert_eq!(reference_area(&scene, &obb), 0.0, "{obb:?}\n{scene:?}");
    }
    assert!(unseen > 5_000, "many boxes are out of view: {unseen}");
}

/// A box in a model's space, seen through a camera moved into that space, projects as its
/// eight corners do through the model's transform: rotations, translations, mirrors and
/// non-uniform scales (which make the box a parallelepiped in the world).
#[test]
fn camera_in_model_space_matches_the_transformed_corners() {
    let mut rng = Rng(77);
    let mut compared = 0;
    for case in 0..20_000 {
        let (scene, near) = random_scene(&mut rng);
        let world_box = random_box(&mut rng, &scene, near);
        let mut scale = if rng.unit() < 0.5 {
            Vec3::splat(rng.range(0.2, 5.0))
        } else {
            rng.vec3(0.2, 5.0)
        };
        if rng.unit() < 0.25 {
            scale.x = -scale.x; // mirrored
        }
        let rotation = rng.rotation();
        // Put the model where its box lands on the world box's centre.
        let local = Obb::new(
            rng.vec3(-2.0, 2.0),
            world_box.axes,
            world_box.half_extents / scale.abs().max_element(),
        );
        let partial = Affine3A::from_scale_rotation_translation(scale, rotation, Vec3::ZERO);
        let model =
            Affine3A::from_translation(world_box.center - partial.transform_point3(local.center))
                * partial;
        let camera = scene.camera().for_model(&model).expect("invertible");
        let fast = f64::from(camera.projected_area(&local));
        let world = Mat4::from(model).as_dmat4();
        let corners = reference_corners(&local).map(|c| (world * c.extend(1.0)).xyz());
        let reference = reference_area_of_corners(&scene, &corners);
        let viewport_area = f64::from(scene.viewport.x * scene.viewport.y);
        assert!(
            (fast - reference).abs() <= 1e-4 * reference + 1e-7 * viewport_area,
            "case {case}: fast {fast}, reference {reference}\n{scene:?}\n{local:?}\n{model:?}"
        );
        compared += usize::from(reference > 0.0);
    }
    assert!(compared > 5_000, "most boxes are in view: {compared}");
    // A transform that cannot be inverted has no model space.
    let flat = Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0));
    let (scene, _) = random_scene(&mut rng);
    assert!(scene.camera().for_model(&flat).is_none());
}

fn perspective_scene(projection: Mat4, kind: Projection) -> Scene {
    Scene {
        view: Mat4::look_at_rh(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y),
        projection,
        kind,
        viewport: Vec2::new(1600.0, 900.0),
    }
}

#[test]
fn square_seen_face_on_has_the_analytic_area() {
    // A flat square of half size s at distance d: (2·s·f/(aspect·d)) × (2·s·f/d) in NDC.
    let (fov, aspect, s, d) = (1.0f32, 16.0 / 9.0, 0.5f32, 4.0f32);
    let f = 1.0 / (fov / 2.0).tan();
    let expected = (2.0 * s * f / (aspect * d)) * (2.0 * s * f / d) * 1600.0 * 900.0 / 4.0;
    let square = Obb::new(
        Vec3::new(0.0, 0.0, -d),
        Mat3::IDENTITY,
        Vec3::new(s, s, 0.0),
    );
    for (projection, kind) in [
        (
            Mat4::perspective_rh(fov, aspect, 0.1, 100.0),
            Projection::Perspective,
        ),
        (
            Mat4::perspective_infinite_reverse_rh(fov, aspect, 0.1),
            Projection::InfiniteReverse,
        ),
    ] {
        let scene = perspective_scene(projection, kind);
        let area = scene.camera().projected_area(&square);
        assert!(
            (area - expected).abs() < 1e-4 * expected,
            "{area} vs {expected}"
        );
        let reference = reference_area(&scene, &square);
        assert!((f64::from(area) - reference).abs() < 1e-4 * reference);
    }
}

#[test]
fn thin_and_far_boxes_in_view_keep_their_precision() {
    // A flat square seen nearly edge-on: its outline is a sliver whose f32 area would be a
    // small difference of large products. And boxes so far away that f32 overflows.
    let scene = perspective_scene(
        Mat4::perspective_infinite_reverse_rh(1.2, 16.0 / 9.0, 0.1),
        Projection::InfiniteReverse,
    );
    let camera = scene.camera();
    let center = Vec3::new(0.5, 0.3, -3.0);
    // Axes with the square's normal at `theta` from perpendicular to the view ray.
    let ray = center.normalize();
    let side = ray.cross(Vec3::Y).normalize();
    for theta in [1e-2f32, 1e-3, 1e-4, 1e-6] {
        let normal = (side * theta.cos() + ray * theta.sin()).normalize();
        let u = ray.cross(normal).normalize();
        let v = normal.cross(u);
        let obb = Obb::new(
            center,
            Mat3::from_cols(u, v, normal),
            Vec3::new(0.8, 0.8, 0.0),
        );
        let area = f64::from(camera.projected_area(&obb));
        let reference = reference_area(&scene, &obb);
        assert!(
            (area - reference).abs() <= 1e-4 * reference,
            "theta {theta}: {area} vs {reference}"
        );
    }
    for (distance, half) in [(3e19f32, 1e19f32), (1e30, 1e29)] {
        let obb = Obb::new(
            Vec3::new(0.0, 0.0, -distance),
            Mat3::IDENTITY,
            Vec3::splat(half),
        );
        let area = camera.projected_area(&obb);
        let reference = reference_area(&scene, &obb);
        assert!(
            area.is_finite() && (f64::from(area) - reference).abs() <= 1e-4 * reference,
            "{distance}: {area} vs {reference}"
        );
    }
}

#[test]
fn box_straddling_the_near_plane_face_on_is_not_clipped_to_nothing() {
    // The front face is behind the near plane, so its outline (all the 1999 method would
    // project) clips away entirely; the sides and the back are still in view, and the visible
    // part is widest at the near plane.
    let (fov, aspect, near, s) = (1.0f32, 16.0 / 9.0, 1.0f32, 0.2f32);
    let f = 1.0 / (fov / 2.0).tan();
    let expected = (2.0 * s * f / (aspect * near)) * (2.0 * s * f / near) * 1600.0 * 900.0 / 4.0;
    let obb = Obb::new(
        Vec3::new(0.0, 0.0, -3.0),
        Mat3::IDENTITY,
        Vec3::new(s, s, 2.5),
    );
    for (projection, kind) in [
        (
            Mat4::perspective_rh(fov, aspect, near, 100.0),
            Projection::Perspective,
        ),
        (
            Mat4::perspective_infinite_reverse_rh(fov, aspect, near),
            Projection::InfiniteReverse,
        ),
    ] {
        let scene = perspective_scene(projection, kind);
        let area = scene.camera().projected_area(&obb);
        assert!(
            (area - expected).abs() < 1e-4 * expected,
            "{area} vs {expected}"
        );
        let reference = reference_area(&scene, &obb);
        assert!(
            (f64::from(area) - reference).abs() < 1e-4 * reference,
            "{area} vs {reference}"
        );
    }
}

#[test]
fn eye_inside_the_box_covers_the_viewport() {
    let mut rng = Rng(77);
    for _ in 0..200 {
        let (scene, _) = random_scene(&mut rng);
        let eye = scene.view.inverse().w_axis.xyz();
        let obb = Obb::new(
            eye + rng.vec3(-0.5, 0.5),
            Mat3::from_quat(rng.rotation()),
            rng.vec3(100.0, 200.0),
        );
        let camera = scene.camera();
        let area = camera.projected_area(&obb);
        let viewport = camera.viewport_area();
        assert!(
            (area - viewport).abs() <= 1e-5 * viewport,
            "{area} vs {viewport}"
        );
    }
}

#[test]
fn boxes_behind_the_camera_or_off_screen_have_no_area() {
    let scene = perspective_scene(
        Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1),
        Projection::InfiniteReverse,
    );
    let camera = scene.camera();
    let behind = Obb::new(Vec3::new(0.0, 0.0, 5.0), Mat3::IDENTITY, Vec3::splat(1.0));
    assert_eq!(camera.projected_area(&behind), 0.0);
    let beside = Obb::new(
        Vec3::new(100.0, 0.0, -5.0),
        Mat3::IDENTITY,
        Vec3::splat(1.0),
    );
    assert_eq!(camera.projected_area(&beside), 0.0);
    // Between the eye and the near plane.
    let too_close = Obb::new(
        Vec3::new(0.0, 0.0, -0.05),
        Mat3::IDENTITY,
        Vec3::splat(0.01),
    );
    assert_eq!(camera.projected_area(&too_close), 0.0);
    // Flat and seen edge-on.
    let edge_on = Obb::new(
        Vec3::new(0.0, 0.0, -5.0),
        Mat3::IDENTITY,
        Vec3::new(1.0, 0.0, 1.0),
    );
    assert!(camera.projected_area(&edge_on) < 1e-3);
}

#[test]
fn malformed_boxes_do_not_panic() {
    let scene = perspective_scene(
        Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1),
        Projection::InfiniteReverse,
    );
    let camera = scene.camera();
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -1e30] {
        for obb in [
            Obb::new(Vec3::new(0.0, 0.0, bad), Mat3::IDENTITY, Vec3::ONE),
            Obb::new(Vec3::new(0.0, 0.0, -5.0), Mat3::IDENTITY, Vec3::splat(bad)),
            Obb::new(
                Vec3::new(0.0, 0.0, -5.0),
                Mat3::from_diagonal(Vec3::splat(bad)),
                Vec3::ONE,
            ),
        ] {
            let area = camera.projected_area(&obb);
            assert!(area.is_nan() || (0.0..=camera.viewport_area() * 1.0001).contains(&area));
        }
    }
}

#[test]
fn orthographic_area_does_not_depend_on_distance() {
    for (near, far) in [(0.1, 100.0), (100.0, 0.1)] {
        let projection = Mat4::orthographic_rh(-8.0, 8.0, -4.5, 4.5, near, far);
        let camera =
            ProjectedAreaCamera::new(Mat4::IDENTITY, projection, Vec2::new(1600.0, 900.0)).unwrap();
        assert!(camera.is_orthographic());
        for z in [-1.0, -10.0, -90.0] {
            let obb = Obb::new(
                Vec3::new(1.0, 1.0, z),
                Mat3::IDENTITY,
                Vec3::new(1.0, 0.5, 0.3),
            );
            // 2 × 1 world units of a 16 × 9 view on 1600 × 900 pixels: 200 × 100 pixels.
            let area = camera.projected_area(&obb);
            assert!((area - 20_000.0).abs() < 0.05, "z {z}: {area}");
        }
    }
}

#[test]
fn camera_from_world_transform_matches_view_matrix() {
    let world_from_view = Mat4::from_rotation_translation(
        Quat::from_euler(glam::EulerRot::YXZ, 0.5, -0.2, 0.1),
        Vec3::new(3.0, 1.0, 8.0),
    );
    let projection = Mat4::perspective_infinite_reverse_rh(0.9, 1.5, 0.1);
    let viewport = Vec2::new(1200.0, 800.0);
    let a = ProjectedAreaCamera::new(world_from_view.inverse(), projection, viewport).unwrap();
    let b =
        ProjectedAreaCamera::from_world_from_view(world_from_view, projection, viewport).unwrap();
    let obb = Obb::new(
        Vec3::new(1.0, 0.0, 0.0),
        Mat3::from_rotation_y(0.4),
        Vec3::ONE,
    );
    let (x, y) = (a.projected_area(&obb), b.projected_area(&obb));
    assert!(x > 0.0 && (x - y).abs() <= 1e-4 * x, "{x} vs {y}");
    assert!(matches!(
        ProjectedAreaCamera::new(Mat4::IDENTITY, projection, Vec2::new(-1.0, 1.0)),
        Err(BudgetError::InvalidCamera(_))
    ));
}

// ---------------------------------------------------------------------------------------------
// Allocation.

fn region(weight: f32, min: u32, max: u32, current: u32) -> RegionInput {
    RegionInput {
        weight,
        min,
        max,
        current,
    }
}

#[test]
fn allocation_errors_name_the_problem() {
    let ok = [region(1.0, 0, 10, 0)];
    let mut out = vec![7];
    let params = AllocationParams::with_budget(100);
    for alpha in [0.0, -1.0, f32::NAN] {
        let p = AllocationParams { alpha, ..params };
        assert!(matches!(
            allocate(&p, &ok, &mut out),
            Err(BudgetError::InvalidAlpha(_))
        ));
        assert!(out.is_empty());
    }
    assert_eq!(
        allocate(&AllocationParams::with_budget(0), &ok, &mut out),
        Err(BudgetError::ZeroBudget)
    );
    for weight in [f32::NAN, f32::INFINITY, -1.0] {
        let regions = [region(1.0, 0, 1, 0), region(weight, 0, 1, 0)];
        let err = allocate(&params, &regions, &mut out).unwrap_err();
        assert!(
            matches!(err, BudgetError::InvalidWeight { region: 1, .. }),
            "{err}"
        );
    }
    assert_eq!(
        allocate(&params, &[region(1.0, 5, 4, 0)], &mut out),
        Err(BudgetError::MinAboveMax {
            region: 0,
            min: 5,
            max: 4
        })
    );
    // Not errors: an empty scene, and a fixed cost above the budget.
    let report = allocate(&params, &[], &mut out).unwrap();
    assert_eq!((report.total, out.len()), (0, 0));
    let p = AllocationParams {
        fixed_cost: 500,
        ..params
    };
    let report = allocate(&p, &[region(1.0, 3, 10, 0)], &mut out).unwrap();
    assert!(report.infeasible && report.available == 0 && out == vec![3]);
}

#[test]
fn infeasible_budget_gives_everyone_their_minimum() {
    let regions = [region(5.0, 40, 100, 0), region(1.0, 70, 100, 0)];
    let mut out = Vec::new();
    let report = allocate(&AllocationParams::with_budget(100), &regions, &mut out).unwrap();
    assert_eq!(out, vec![40, 70]);
    assert!(report.infeasible);
    assert_eq!(report.total, 110);
}

#[test]
fn saturated_budget_gives_everyone_their_maximum() {
    let regions = [
        region(5.0, 0, 100, 0),
        region(1.0, 10, 200, 0),
        region(0.0, 5, 300, 0),
    ];
    let mut out = Vec::new();
    let report = allocate(&AllocationParams::with_budget(10_000), &regions, &mut out).unwrap();
    assert_eq!(out, vec![100, 200, 5]);
    assert!(report.saturated && !report.infeasible);
    assert_eq!(report.total, 305);
}

#[test]
fn large_allocation_of_100k_regions() {
    let mut rng = Rng(3);
    let regions: Vec<RegionInput> = (0..100_000)
        .map(|_| {
            let min = rng.below(50);
            region(
                if rng.unit() < 0.2 {
                    0.0
                } else {
                    10f32.powf(rng.range(-2.0, 6.0))
                },
                min,
                min + rng.below(5000),
                rng.below(3000),
            )
        })
        .collect();
    let params = AllocationParams {
        budget: 20_000_000,
        fixed_cost: 1_000_000,
        hysteresis: 8,
        ..Default::default()
    };
    let mut out = Vec::new();
    let mut allocator = Allocator::new();
    let report = allocator.allocate(&params, &regions, &mut out).unwrap();
    assert!(
        report.total <= 19_000_000 && !report.infeasible,
        "{report:?}"
    );
    assert!(report.total >= 19_000_000 - 100_000, "{report:?}");
    for (r, &p) in regions.iter().zip(&out) {
        assert!(r.min <= p && p <= r.max);
    }
    let mut again = Vec::new();
    assert_eq!(allocate(&params, &regions, &mut again).unwrap(), report);
    assert_eq!(again, out);
}

/// `(weight / max_weight)^(1/α)`, with the documented clamp: below 1e-200 it counts as 0.
fn share_of(weight: f32, max_weight: f32, alpha: f32) -> f64 {
    let s = if alpha.is_infinite() {
        1.0
    } else {
        (f64::from(weight) / f64::from(max_weight)).powf(1.0 / f64::from(alpha))
    };
    if s >= 1e-200 { s } else { 0.0 }
}

fn arb_weight() -> impl Strategy<Value = f32> {
    prop_oneof![
        1 => Just(0.0f32),
        6 => (-3.0f32..7.0).prop_map(|e| 10f32.powf(e)),
    ]
}

fn arb_alpha() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(1.0f32),
        Just(2.0f32),
        Just(3.0f32),
        Just(f32::INFINITY),
        Just(0.01f32),
        0.3f32..10.0,
    ]
}

fn arb_regions() -> impl Strategy<Value = Vec<RegionInput>> {
    prop::collection::vec(
        (arb_weight(), 0u32..2000, 0u32..20_000, 0u32..25_000)
            .prop_map(|(w, min, span, current)| region(w, min, min + span, current)),
        0..60,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Bounds, the budget, the minimum for invisible regions, determinism.
    #[test]
    fn allocation_invariants(
        regions in arb_regions(),
        budget in 1u32..400_000,
        fixed in 0u32..100_000,
        alpha in arb_alpha(),
        hysteresis in prop_oneof![Just(0u32), 1u32..500],
    ) {
        let params = AllocationParams { budget, fixed_cost: fixed, alpha, hysteresis };
        let mut out = Vec::new();
        let report = allocate(&params, &regions, &mut out).unwrap();
        let available = u64::from(budget.saturating_sub(fixed));
        let min_total: u64 = regions.iter().map(|r| u64::from(r.min)).sum();
        let total: u64 = out.iter().map(|&p| u64::from(p)).sum();
        prop_assert_eq!(out.len(), regions.len());
        prop_assert_eq!(report.total, total);
        prop_assert_eq!(report.infeasible, available < min_total);
        if report.infeasible {
            prop_assert!(out.iter().zip(&regions).all(|(&p, r)| p == r.min));
        } else {
            prop_assert!(total <= available, "total {} over {}", total, available);
        }
        for (r, &p) in regions.iter().zip(&out) {
            prop_assert!(r.min <= p && p <= r.max, "{} not in [{}, {}]", p, r.min, r.max);
            if r.weight == 0.0 {
                prop_assert_eq!(p, r.min);
            }
        }
        // Hysteresis only ever holds a region at its current count, within ε of the target.
        let targets = {
            let mut t = Vec::new();
            allocate(&AllocationParams { hysteresis: 0, ..params }, &regions, &mut t).unwrap();
            t
        };
        for ((r, &p), &t) in regions.iter().zip(&out).zip(&targets) {
            prop_assert!(p == t || (p == r.current && p.abs_diff(t) <= hysteresis));
        }
        // Without hysteresis the whole budget is used whenever it can be.
        if hysteresis == 0 && !report.infeasible && !report.saturated {
            prop_assert_eq!(total, available);
        }
        // The same input, through a used allocator, gives the same output.
        let mut allocator = Allocator::new();
        let mut scratch = Vec::new();
        allocator.allocate(&AllocationParams { budget: budget / 2 + 1, ..params }, &regions, &mut scratch).unwrap();
        let mut again = Vec::new();
        prop_assert_eq!(allocator.allocate(&params, &regions, &mut again).unwrap(), report);
        prop_assert_eq!(again, out);
    }

    /// Where nothing is clamped the α formula holds to the triangle.
    #[test]
    fn unclamped_allocation_follows_the_formula(
        weights in prop::collection::vec((-3.0f32..7.0).prop_map(|e| 10f32.powf(e)), 1..60),
        budget in 1u32..4_000_000,
        alpha in arb_alpha(),
    ) {
        let regions: Vec<_> = weights.iter().map(|&w| region(w, 0, u32::MAX, 0)).collect();
        let mut out = Vec::new();
        let report = allocate(&AllocationParams { budget, alpha, ..Default::default() }, &regions, &mut out).unwrap();
        prop_assert_eq!(report.total, u64::from(budget));
        let max_weight = weights.iter().fold(0.0f32, |m, &w| m.max(w));
        let share = |w: f32| share_of(w, max_weight, alpha);
        let sum: f64 = weights.iter().map(|&w| share(w)).sum();
        for (&w, &p) in weights.iter().zip(&out) {
            let exact = f64::from(budget) * share(w) / sum;
            prop_assert!((f64::from(p) - exact).abs() < 1.0 + 1e-9 * exact, "p {} vs {}", p, exact);
        }
    }

    /// Water-filling: the regions strictly inside their bounds share one scale λ; those at
    /// their max would want more, those at their min less.
    #[test]
    fn clamped_allocation_is_water_filling(
        regions in arb_regions(),
        budget in 1u32..400_000,
        alpha in arb_alpha(),
    ) {
        let params = AllocationParams { budget, alpha, ..Default::default() };
        let mut out = Vec::new();
        let report = allocate(&params, &regions, &mut out).unwrap();
        prop_assume!(!report.infeasible && !report.saturated);
        let max_weight = regions.iter().fold(0.0f32, |m, r| m.max(r.weight));
        let s: Vec<f64> = regions.iter().map(|r| {
            if r.weight > 0.0 { share_of(r.weight, max_weight, alpha) } else { 0.0 }
        }).collect();
        let free: Vec<usize> = (0..regions.len())
            .filter(|&i| s[i] > 0.0 && out[i] > regions[i].min && out[i] < regions[i].max)
            .collect();
        prop_assume!(free.len() >= 2);
        let lambda = free.iter().map(|&i| f64::from(out[i])).sum::<f64>()
            / free.iter().map(|&i| s[i]).sum::<f64>();
        for (i, r) in regions.iter().enumerate() {
            if s[i] == 0.0 {
                continue;
            }
            let want = lambda * s[i];
            let p = f64::from(out[i]);
            let slack = 2.0 + 1e-6 * want;
            if out[i] == r.max && r.max > r.min {
                prop_assert!(want >= p - slack, "region {} at max {} wants {}", i, p, want);
            } else if out[i] == r.min && r.max > r.min {
                prop_assert!(want <= p + slack, "region {} at min {} wants {}", i, p, want);
            } else if r.max > r.min {
                prop_assert!((want - p).abs() <= slack, "region {} has {} wants {}", i, p, want);
            }
        }
    }

    /// At equal priority, a larger area never gets fewer triangles: within one allocation,
    /// and when one region's area grows (up to the one triangle of rounding).
    #[test]
    fn allocation_is_monotone_in_area(
        areas in prop::collection::vec(0.0f32..1e6, 1..60),
        grow in 1.0f32..100.0,
        which in any::<prop::sample::Index>(),
        budget in 1u32..400_000,
        alpha in arb_alpha(),
        (min, span) in (0u32..100, 0u32..20_000),
    ) {
        let params = AllocationParams { budget, alpha, ..Default::default() };
        let regions: Vec<_> = areas.iter().map(|&a| RegionInput::from_area(a, 2.0, min, min + span, 0)).collect();
        let mut out = Vec::new();
        allocate(&params, &regions, &mut out).unwrap();
        for i in 0..areas.len() {
            for j in 0..areas.len() {
                if areas[i] > areas[j] {
                    prop_assert!(out[i] >= out[j], "area {} gets {} < {} for area {}", areas[i], out[i], out[j], areas[j]);
                }
            }
        }
        let k = which.index(areas.len());
        let mut bigger = regions.clone();
        bigger[k].weight *= grow;
        let mut out2 = Vec::new();
        allocate(&params, &bigger, &mut out2).unwrap();
        prop_assert!(out2[k] + 1 >= out[k], "growing region {} took it from {} to {}", k, out[k], out2[k]);
    }

    /// α → ∞ is the equal split; α = 1 is proportional to area.
    #[test]
    fn alpha_limits(
        areas in prop::collection::vec(1e-2f32..1e6, 1..60),
        budget in 1u32..4_000_000,
    ) {
        let regions: Vec<_> = areas.iter().map(|&a| RegionInput::from_area(a, 1.0, 0, u32::MAX, 0)).collect();
        let n = areas.len() as f64;
        let mut out = Vec::new();
        for alpha in [f32::INFINITY, 1e9] {
            allocate(&AllocationParams { budget, alpha, ..Default::default() }, &regions, &mut out).unwrap();
            for &p in &out {
                prop_assert!((f64::from(p) - f64::from(budget) / n).abs() < 1.0 + 1e-6 * f64::from(budget) / n);
            }
        }
        allocate(&AllocationParams { budget, alpha: 1.0, ..Default::default() }, &regions, &mut out).unwrap();
        let total: f64 = areas.iter().map(|&a| f64::from(a)).sum();
        for (&a, &p) in areas.iter().zip(&out) {
            let exact = f64::from(budget) * f64::from(a) / total;
            prop_assert!((f64::from(p) - exact).abs() < 1.0 + 1e-9 * exact, "{} vs {}", p, exact);
        }
    }
}

/// The continuous water-filling targets by plain bisection on λ: the slow reference.
fn reference_targets(regions: &[RegionInput], alpha: f32, available: f64) -> Vec<f64> {
    let max_weight = regions.iter().fold(0.0f32, |m, r| m.max(r.weight));
    let s: Vec<f64> = regions
        .iter()
        .map(|r| {
            if r.weight > 0.0 && r.max > r.min {
                share_of(r.weight, max_weight, alpha)
            } else {
                0.0
            }
        })
        .collect();
    let g = |lambda: f64| -> f64 {
        regions
            .iter()
            .zip(&s)
            .map(|(r, &s)| (lambda * s).clamp(f64::from(r.min), f64::from(r.max)))
            .sum()
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while g(hi) < available && hi < 1e300 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) <= available {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    regions
        .iter()
        .zip(&s)
        .map(|(r, &s)| (lo * s).clamp(f64::from(r.min), f64::from(r.max)))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Thousands of regions, so the sampled pivots (not the small-input path) do the work,
    /// with many equal weights and bounds (equal breakpoints): within a triangle of bisection.
    #[test]
    fn large_allocation_matches_bisection(
        seed in any::<u64>(),
        n in 100usize..3000,
        alpha in arb_alpha(),
        budget_per_region in 1u32..3000,
    ) {
        let mut rng = Rng(seed);
        let regions: Vec<RegionInput> = (0..n)
            .map(|_| {
                let weight = match rng.below(4) {
                    0 => 0.0,
                    1 => [1.0, 10.0, 100.0][rng.below(3) as usize],
                    _ => 10f32.powf(rng.range(-2.0, 5.0)),
                };
                let min = [0, 10, rng.below(200)][rng.below(3) as usize];
                let max = min + [0, 1000, rng.below(5000)][rng.below(3) as usize];
                region(weight, min, max, 0)
            })
            .collect();
        let budget = (budget_per_region as usize * n).min(u32::MAX as usize) as u32;
        let params = AllocationParams { budget, alpha, ..Default::default() };
        let mut out = Vec::new();
        let report = allocate(&params, &regions, &mut out).unwrap();
        prop_assume!(!report.infeasible);
        let targets = reference_targets(&regions, alpha, f64::from(budget));
        for (i, (&p, &t)) in out.iter().zip(&targets).enumerate() {
            prop_assert!(
                (f64::from(p) - t).abs() <= 1.0 + 1e-6 * t,
                "region {}: {} vs bisection {}", i, p, t
            );
        }
    }
}

#[test]
fn alpha_table_in_the_docs_is_right() {
    // Two regions whose weights differ by 100: the larger one's share for each α.
    let regions = [region(100.0, 0, u32::MAX, 0), region(1.0, 0, u32::MAX, 0)];
    let mut out = Vec::new();
    for (alpha, percent) in [
        (1.0, 99),
        (2.0, 91),
        (3.0, 82),
        (6.0, 68),
        (f32::INFINITY, 50),
    ] {
        allocate(
            &AllocationParams {
                budget: 100_000,
                alpha,
                ..Default::default()
            },
            &regions,
            &mut out,
        )
        .unwrap();
        assert_eq!(
            (f64::from(out[0]) / 1000.0).round() as u32,
            percent,
            "α = {alpha}"
        );
    }
}
