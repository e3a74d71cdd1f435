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

/// Attribute quadrics (Hoppe 1999's metric, as meshoptimizer keeps them): per attribute
/// vertex, over the triangles merged into it, each attribute as the linear function
/// `g·p + d` that interpolates it over its triangle, so that
/// `error(p, a) = Σ w (g·p + d − a)²` (summed over the attributes) measures how far the
/// values `a` at the point `p` are from what those triangles showed there.
///
/// Stored as one position quadric per vertex (`Σ w (g·p + d)²` over every attribute, with the
/// total weight `Σ w`) and, per attribute, `Σ w (g, d)`; `a²` takes the weight.
#[derive(Clone, Debug, Default)]
pub(crate) struct AttributeQuadrics {
    stride: usize,
    positions: Vec<Quadric>,
    gradients: Vec<[f64; 4]>,
}

impl AttributeQuadrics {
    /// Empty quadrics for `vertices` attribute vertices of `stride` attributes each.
    pub(crate) fn new(vertices: usize, stride: usize) -> Self {
        Self {
            stride,
            positions: vec![Quadric::default(); vertices],
            gradients: vec![[0.0; 4]; vertices * stride],
        }
    }

    /// Adds triangle `(v0, v1, v2)` at `points` with the attribute `values` of its corners,
    /// weighted by `weight`, to each of its three vertices. A triangle without area adds
    /// nothing.
    pub(crate) fn add_triangle(
        &mut self,
        v: [u32; 3],
        points: [DVec3; 3],
        values: [&[f64]; 3],
        weight: f64,
    ) {
        let (e1, e2) = (points[1] - points[0], points[2] - points[0]);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        if n2 <= 0.0 || weight <= 0.0 {
            return;
        }
        // g·e1 = a1 − a0 and g·e2 = a2 − a0, with g in the triangle's plane.
        let (u1, u2) = (e2.cross(n) / n2, n.cross(e1) / n2);
        let mut q = Quadric {
            weight,
            ..Quadric::default()
        };
        let mut grads = vec![[0.0; 4]; self.stride];
        for (k, grad) in grads.iter_mut().enumerate() {
            let a0 = values[0][k];
            let g = u1 * (values[1][k] - a0) + u2 * (values[2][k] - a0);
            let d = a0 - g.dot(points[0]);
            q.add(&Quadric::from_plane(g, d, weight).without_weight());
            *grad = [weight * g.x, weight * g.y, weight * g.z, weight * d];
        }
        for &vertex in &v {
            let vertex = vertex as usize;
            self.positions[vertex].add(&q);
            for (k, grad) in grads.iter().enumerate() {
                let to = &mut self.gradients[vertex * self.stride + k];
                for i in 0..4 {
                    to[i] += grad[i];
                }
            }
        }
    }

    /// The attribute error of giving vertex `v`'s triangles the values `a` at `p`: the
    /// squared differences integrated over those triangles (each weighs its area), so an
    /// attribute off by 1 over a patch of size d costs what moving it by d does in a position
    /// quadric (meshoptimizer's units; `0` when nothing was merged into it).
    pub(crate) fn error(&self, v: u32, p: DVec3, a: &[f64]) -> f64 {
        let q = &self.positions[v as usize];
        if q.weight <= 0.0 {
            return 0.0;
        }
        let quad = q.a00 * p.x * p.x
            + q.a11 * p.y * p.y
            + q.a22 * p.z * p.z
            + 2.0 * (q.a10 * p.x * p.y + q.a20 * p.x * p.z + q.a21 * p.y * p.z);
        let mut r = quad + 2.0 * (q.b0 * p.x + q.b1 * p.y + q.b2 * p.z) + q.c;
        let grads = &self.gradients[v as usize * self.stride..(v as usize + 1) * self.stride];
        for (g, &a) in grads.iter().zip(a) {
            r += a * a * q.weight - 2.0 * a * (g[0] * p.x + g[1] * p.y + g[2] * p.z + g[3]);
        }
        // Rounding can make a sum of squares slightly negative.
        r.max(0.0)
    }

    /// Merges vertex `from`'s quadric into `into`'s.
    pub(crate) fn merge(&mut self, from: u32, into: u32) {
        let q = self.positions[from as usize];
        self.positions[into as usize].add(&q);
        for k in 0..self.stride {
            let g = self.gradients[from as usize * self.stride + k];
            let to = &mut self.gradients[into as usize * self.stride + k];
            for i in 0..4 {
                to[i] += g[i];
            }
        }
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

    #[test]
    fn attribute_quadric_measures_interpolation_error() {
        // A triangle in z = 0 whose attribute is x + 2y: exact values cost nothing anywhere in
        // the plane; a value off by 0.5 costs 0.25 times the weight.
        let points = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let values = [[0.0], [1.0], [2.0]];
        let mut q = AttributeQuadrics::new(3, 1);
        q.add_triangle([0, 1, 2], points, [&values[0], &values[1], &values[2]], 2.0);
        let p = DVec3::new(0.3, 0.6, 0.0);
        assert!(q.error(0, p, &[1.5]) < 1e-12);
        assert!((q.error(1, p, &[2.0]) - 0.5).abs() < 1e-12);
        q.merge(0, 1);
        assert!(
            (q.error(1, p, &[2.0]) - 1.0).abs() < 1e-12,
            "integrated: merged triangles add up"
        );
    }
}
