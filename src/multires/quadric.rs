//! Garland–Heckbert error quadrics, in `f64` so that long collapse chains stay accurate.

use glam::DVec3;

/// A weighted sum of squared distances to planes: `Q(p) = pᵀAp + 2bᵀp + c`.
///
/// `weight` is the total weight behind the planes (√area per face, edge lengths for borders
/// and seams, plus the small regularization point); [`Quadric::error`] divides by it, so the
/// error is a mean squared distance whatever the tessellation (as meshoptimizer does).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Quadric {
    a00: f64,
    a11: f64,
    a22: f64,
    a10: f64,
    a20: f64,
    a21: f64,
    b0: f64,
    b1: f64,
    b2: f64,
    c: f64,
    weight: f64,
}

impl Quadric {
    /// The quadric of the plane `n·p + d = 0` (`n` unit length), scaled by `weight`.
    #[inline]
    pub(crate) fn from_plane(n: DVec3, d: f64, weight: f64) -> Self {
        Self {
            a00: weight * n.x * n.x,
            a11: weight * n.y * n.y,
            a22: weight * n.z * n.z,
            a10: weight * n.y * n.x,
            a20: weight * n.z * n.x,
            a21: weight * n.z * n.y,
            b0: weight * n.x * d,
            b1: weight * n.y * d,
            b2: weight * n.z * d,
            c: weight * d * d,
            weight,
        }
    }

    /// `weight` times the squared distance to the point `p`.
    #[inline]
    pub(crate) fn from_point(p: DVec3, weight: f64) -> Self {
        Self {
            a00: weight,
            a11: weight,
            a22: weight,
            a10: 0.0,
            a20: 0.0,
            a21: 0.0,
            b0: -weight * p.x,
            b1: -weight * p.y,
            b2: -weight * p.z,
            c: weight * p.length_squared(),
            weight,
        }
    }

    /// The same planes, contributing nothing to the normalising weight.
    #[inline]
    pub(crate) fn without_weight(mut self) -> Self {
        self.weight = 0.0;
        self
    }

    /// Adds `other` to `self`.
    #[inline]
    pub(crate) fn add(&mut self, other: &Self) {
        self.a00 += other.a00;
        self.a11 += other.a11;
        self.a22 += other.a22;
        self.a10 += other.a10;
        self.a20 += other.a20;
        self.a21 += other.a21;
        self.b0 += other.b0;
        self.b1 += other.b1;
        self.b2 += other.b2;
        self.c += other.c;
        self.weight += other.weight;
    }

    /// Area-weighted sum of squared distances from `p` to the planes (not normalised).
    #[inline]
    pub(crate) fn eval(&self, p: DVec3) -> f64 {
        let quad = self.a00 * p.x * p.x
            + self.a11 * p.y * p.y
            + self.a22 * p.z * p.z
            + 2.0 * (self.a10 * p.x * p.y + self.a20 * p.x * p.z + self.a21 * p.y * p.z);
        let r = quad + 2.0 * (self.b0 * p.x + self.b1 * p.y + self.b2 * p.z) + self.c;
        // Rounding can make a sum of squares slightly negative.
        r.max(0.0)
    }

    /// Total weight (area) of the planes merged into this quadric.
    #[inline]
    pub(crate) fn weight(&self) -> f64 {
        self.weight
    }

    /// Mean squared distance of `p` to the planes (`0` for an empty quadric).
    #[inline]
    pub(crate) fn error(&self, p: DVec3) -> f64 {
        if self.weight <= 0.0 {
            return 0.0;
        }
        self.eval(p) / self.weight
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_quadric_measures_squared_distance() {
        // The plane y = 1.
        let q = Quadric::from_plane(DVec3::Y, -1.0, 2.0);
        assert!((q.eval(DVec3::new(5.0, 3.0, -7.0)) - 2.0 * 4.0).abs() < 1e-12);
        let mut sum = q;
        sum.add(&Quadric::from_plane(DVec3::X, 0.0, 2.0));
        // distance² to y=1 is 4, to x=0 is 25; mean = (2*4 + 2*25) / 4.
        let e = sum.error(DVec3::new(5.0, 3.0, -7.0));
        assert!((e - 14.5).abs() < 1e-12, "{e}");
    }

    #[test]
    fn general_plane_matches_direct_distance() {
        let n = DVec3::new(1.0, 2.0, -2.0).normalize();
        let d = 0.7;
        let q = Quadric::from_plane(n, d, 1.0);
        for p in [DVec3::new(0.3, -1.0, 4.0), DVec3::new(-2.0, 0.5, 0.25)] {
            let dist = n.dot(p) + d;
            assert!((q.eval(p) - dist * dist).abs() < 1e-12);
        }
    }
}
