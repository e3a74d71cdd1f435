//! The point–triangle kernel: Ericson's exact squared distance, in `f64` for thin triangles.

use glam::{DVec3, Vec3, Vec3A};

/// Exact squared distance from `p` to the triangle `(a, b, c)` (its closed surface, not its plane).
///
/// Ericson's closest-point-on-triangle (*Real-Time Collision Detection*, 5.1.5) for well-shaped
/// triangles. Thin ones (slivers, segments, points), on which its region tests can misfire, take
/// a slower `f64` path: the nearer of the plane (when the projection falls inside) and the three
/// edges. The result is never NaN for finite input.
#[must_use]
pub fn point_triangle_distance_sq(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let a = Vec3A::from(a);
    Tri::new(a, Vec3A::from(b), Vec3A::from(c)).d2(Vec3A::from(p))
}

/// A triangle prepared for distance queries: one corner, the two edges from it, and whether it
/// is too thin for the single-precision region tests.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tri {
    a: Vec3A,
    ab: Vec3A,
    ac: Vec3A,
    thin: bool,
}

/// A triangle is thin when `|ab × ac|² ≤ THIN · (longest edge)⁴`, i.e. its smallest angle is
/// below roughly `sqrt(THIN)` radians. Rounding in Ericson's `f32` region tests is far below this.
const THIN: f32 = 1e-6;

impl Tri {
    pub(super) fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Self {
        let (ab, ac) = (b - a, c - a);
        let longest = ab
            .length_squared()
            .max(ac.length_squared())
            .max((c - b).length_squared());
        let n2 = ab.cross(ac).length_squared();
        Self {
            a,
            ab,
            ac,
            thin: n2.is_nan() || n2 <= THIN * longest * longest,
        }
    }

    /// Squared distance from `p`.
    #[inline]
    pub(super) fn d2(&self, p: Vec3A) -> f32 {
        if self.thin {
            thin_d2(p - self.a, self.ab, self.ac)
        } else {
            ericson_d2(p - self.a, self.ab, self.ac)
        }
    }
}

/// Ericson's closest point on triangle `(0, ab, ac)` to `ap`, as a squared distance.
#[inline]
fn ericson_d2(ap: Vec3A, ab: Vec3A, ac: Vec3A) -> f32 {
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared(); // vertex a
    }
    let bp = ap - ab;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared(); // vertex b
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        // Edge ab; d1 - d3 = |ab|².
        let v = ratio(d1, d1 - d3);
        return (ap - ab * v).length_squared();
    }
    let cp = ap - ac;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared(); // vertex c
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        // Edge ac; d2 - d6 = |ac|².
        let w = ratio(d2, d2 - d6);
        return (ap - ac * w).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        // Edge bc; (d4 - d3) + (d5 - d6) = |bc|².
        let w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
        return (bp - (ac - ab) * w).length_squared();
    }
    // Face region: the distance to the plane, (n·ap)²/|n|², which is more accurate than going
    // through the barycentric coordinates (and exact for points on an axis-aligned plane).
    let n = ab.cross(ac);
    let (h, n2) = (n.dot(ap), n.length_squared());
    if n2 > 0.0 {
        h * (h / n2)
    } else {
        thin_d2(ap, ab, ac)
    }
}

/// `num / den` clamped to `[0, 1]`, `0` when `den` is not positive.
#[inline]
fn ratio(num: f32, den: f32) -> f32 {
    if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Squared distance from `p` to triangle `(0, ab, ac)` for any shape, in `f64`: the three edges,
/// and the plane where the projection of `p` falls inside.
#[cold]
fn thin_d2(ap: Vec3A, ab: Vec3A, ac: Vec3A) -> f32 {
    fn segment(ap: DVec3, ab: DVec3) -> f64 {
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            (ap.dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (ap - ab * t).length_squared()
    }
    let (ap, ab, ac) = (ap.as_dvec3(), ab.as_dvec3(), ac.as_dvec3());
    let mut best = segment(ap, ab)
        .min(segment(ap, ac))
        .min(segment(ap - ab, ac - ab));
    let n = ab.cross(ac);
    let n2 = n.length_squared();
    if n2 > 0.0 {
        let t = n.dot(ap) / n2;
        let q = ap - n * t;
        let inside = ab.cross(q).dot(n) >= 0.0
            && (ac - ab).cross(q - ab).dot(n) >= 0.0
            && (-ac).cross(q - ac).dot(n) >= 0.0;
        if inside {
            best = best.min(t * t * n2);
        }
    }
    best as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::sample::{SplitMix64, tests::random_vec};

    /// Dense barycentric grid: an upper bound on the true distance, tight as the grid refines.
    fn grid_d2(p: Vec3, a: Vec3, b: Vec3, c: Vec3, n: usize) -> f32 {
        let mut best = f32::INFINITY;
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                let q = a + (b - a) * u + (c - a) * v;
                best = best.min(p.distance_squared(q));
            }
        }
        best
    }

    #[test]
    fn point_triangle_matches_dense_grid() {
        let mut rng = SplitMix64::new(7);
        for _ in 0..300 {
            let (a, b, c) = (
                random_vec(&mut rng, 1.0),
                random_vec(&mut rng, 1.0),
                random_vec(&mut rng, 1.0),
            );
            let p = random_vec(&mut rng, 2.0);
            let exact = point_triangle_distance_sq(p, a, b, c).sqrt();
            let grid = grid_d2(p, a, b, c, 200).sqrt();
            // The grid's spacing is at most ~2·sqrt(3)/200 ≈ 0.017.
            assert!(exact <= grid + 1e-5, "{exact} > {grid}");
            assert!(grid - exact < 0.02, "{exact} vs {grid}");
        }
    }

    #[test]
    fn thin_path_agrees_with_ericson() {
        let mut rng = SplitMix64::new(13);
        for _ in 0..2000 {
            let [a, b, c, p] = [1.0, 1.0, 1.0, 2.0].map(|s| Vec3A::from(random_vec(&mut rng, s)));
            let (ab, ac) = (b - a, c - a);
            let (fast, slow) = (ericson_d2(p - a, ab, ac), thin_d2(p - a, ab, ac));
            assert!((fast.sqrt() - slow.sqrt()).abs() < 1e-5, "{fast} vs {slow}");
        }
    }

    #[test]
    fn point_triangle_regions() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let d = |p: Vec3| point_triangle_distance_sq(p, a, b, c);
        assert_eq!(d(Vec3::new(0.25, 0.25, 2.0)), 4.0); // face
        assert_eq!(d(Vec3::new(-1.0, -1.0, 0.0)), 2.0); // vertex a
        assert_eq!(d(Vec3::new(2.0, 0.0, 0.0)), 1.0); // vertex b
        assert_eq!(d(Vec3::new(0.0, 3.0, 0.0)), 4.0); // vertex c
        assert_eq!(d(Vec3::new(0.5, -2.0, 0.0)), 4.0); // edge ab
        assert_eq!(d(Vec3::new(-3.0, 0.5, 0.0)), 9.0); // edge ac
        assert!((d(Vec3::new(1.0, 1.0, 0.0)) - 0.5).abs() < 1e-6); // edge bc
    }

    #[test]
    fn degenerate_triangles_are_finite() {
        let p = Vec3::new(0.3, 0.7, -0.2);
        // A point.
        let d = point_triangle_distance_sq(p, Vec3::ONE, Vec3::ONE, Vec3::ONE);
        assert!((d - p.distance_squared(Vec3::ONE)).abs() < 1e-6);
        // A segment, with a repeated corner in each position.
        let (s0, s1) = (Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0));
        let want = 0.7f32 * 0.7 + 0.2 * 0.2;
        for (a, b, c) in [(s0, s0, s1), (s0, s1, s0), (s1, s0, s0), (s0, s1, s1)] {
            let d = point_triangle_distance_sq(p, a, b, c);
            assert!((d - want).abs() < 1e-6, "{d} vs {want}");
        }
        // Collinear, distinct corners.
        let d = point_triangle_distance_sq(p, s0, Vec3::X, s1);
        assert!((d - want).abs() < 1e-6, "{d} vs {want}");
        // Sliver.
        let d = point_triangle_distance_sq(p, s0, s1, Vec3::new(1.0, 1e-20, 0.0));
        assert!(d.is_finite() && (d - want).abs() < 1e-5, "{d} vs {want}");
    }
}
