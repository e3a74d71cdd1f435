//! Clipping, in `f64`: the part of a box in front of the near plane, and polygons against the
//! viewport.

use crate::bounds::{PointStack, monotone_chain};
use glam::{DVec2, DVec4, Vec4Swizzles};

/// Corner `i` of a box with centre `c` and half axes `a` (in whatever space, or any linear
/// function of them): bit `k` of `i` picks `+a[k]`.
#[inline]
pub(super) fn corner_clip<T>(c: T, a: &[T; 3], i: u8) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T>,
{
    let mut v = c;
    for (k, &ak) in a.iter().enumerate() {
        v = if (i >> k) & 1 == 1 { v + ak } else { v - ak };
    }
    v
}

/// The NDC area of the part of a box in front of the near plane, clipped to the viewport: the
/// hull of the projected corners in front of the plane and of the points where the box's edges
/// cross it. The box has clip-space centre `c` and half axes `a`; the near plane's signed
/// distance (visible where `≥ 0`) is `near_c` at the centre and changes by `near_a[k]` along
/// half axis `k`.
#[inline]
pub(super) fn front_area(c: DVec4, a: &[DVec4; 3], near_c: f64, near_a: &[f64; 3]) -> f64 {
    let corners: [DVec4; 8] = std::array::from_fn(|i| corner_clip(c, a, i as u8));
    let depth: [f64; 8] = std::array::from_fn(|i| corner_clip(near_c, near_a, i as u8));
    let mut points = Polygon::new();
    let mut add = |v: DVec4| {
        if v.w > 0.0 {
            points.push(v.xy() / v.w);
        }
    };
    for (i, &v) in corners.iter().enumerate() {
        if depth[i] >= 0.0 {
            add(v);
        }
    }
    for i in 0..8 {
        for axis in 0..3 {
            let j = i | (1 << axis);
            if j != i && (depth[i] < 0.0) != (depth[j] < 0.0) {
                let t = depth[i] / (depth[i] - depth[j]);
                add(corners[i] + (corners[j] - corners[i]) * t);
            }
        }
    }
    let mut polygon = points.convex_hull();
    polygon.clip_to_viewport(0);
    polygon.area()
}

/// The area of a simple polygon by the shoelace formula. The sum runs on offsets from the
/// first vertex, so a small polygon far from the origin keeps its digits.
#[inline]
pub(super) fn shoelace(p: &[DVec2]) -> f64 {
    if p.len() < 3 {
        return 0.0;
    }
    let o = p[0];
    let mut twice = 0.0;
    for w in p[1..].windows(2) {
        twice += (w[0] - o).perp_dot(w[1] - o);
    }
    (twice * 0.5).abs()
}

/// A small convex polygon (or point set) in NDC on the stack: at most 14 hull points, grown by
/// at most one vertex per viewport side when clipped.
#[derive(Clone, Copy)]
pub(super) struct Polygon {
    len: usize,
    points: [DVec2; Self::CAPACITY],
}

impl Polygon {
    const CAPACITY: usize = 24;

    #[inline]
    pub(super) fn new() -> Self {
        Self {
            len: 0,
            points: [DVec2::ZERO; Self::CAPACITY],
        }
    }

    #[inline]
    pub(super) fn push(&mut self, p: DVec2) {
        if self.len < Self::CAPACITY {
            self.points[self.len] = p;
            self.len += 1;
        }
    }

    #[inline]
    fn as_slice(&self) -> &[DVec2] {
        &self.points[..self.len]
    }

    #[inline]
    pub(super) fn area(&self) -> f64 {
        shoelace(self.as_slice())
    }

    /// Sutherland–Hodgman against `x ≥ −1`, `x ≤ 1`, `y ≥ −1`, `y ≤ 1`, skipping the sides
    /// whose bit is set in `inside` (known not to cut the polygon).
    pub(super) fn clip_to_viewport(&mut self, inside: u32) {
        for (side, axis, sign) in [(0, 0, -1.0f64), (1, 0, 1.0), (2, 1, -1.0), (3, 1, 1.0)] {
            if (inside >> side) & 1 == 1 {
                continue;
            }
            {
                // Keep sign · p[axis] ≤ 1.
                let input = *self;
                self.len = 0;
                let pts = input.as_slice();
                let Some(&last) = pts.last() else { return };
                let mut prev = last;
                let mut prev_in = sign * prev[axis] <= 1.0;
                for &p in pts {
                    let inside = sign * p[axis] <= 1.0;
                    if inside != prev_in {
                        let t = (sign - prev[axis]) / (p[axis] - prev[axis]);
                        let mut q = prev + (p - prev) * t;
                        q[axis] = sign; // exactly on the edge
                        self.push(q);
                    }
                    if inside {
                        self.push(p);
                    }
                    prev = p;
                    prev_in = inside;
                }
            }
        }
    }

    /// The convex hull of the points, counter-clockwise ([`monotone_chain`]).
    fn convex_hull(&self) -> Polygon {
        let mut sorted = *self;
        let pts = &mut sorted.points[..sorted.len];
        // Insertion sort: at most 14 points. By `>` on `(x, y)`, which takes −0 and +0 as
        // equal, as the chain needs; `convex_hull_2d`'s `total_cmp` puts −0 first, which can
        // lose a vertex when both zeros share the smallest or largest x.
        for i in 1..pts.len() {
            let mut j = i;
            while j > 0 && (pts[j - 1].x, pts[j - 1].y) > (pts[j].x, pts[j].y) {
                pts.swap(j - 1, j);
                j -= 1;
            }
        }
        let mut hull = Polygon::new();
        monotone_chain(pts, &mut hull);
        hull
    }
}

impl PointStack for Polygon {
    #[inline]
    fn clear(&mut self) {
        self.len = 0;
    }

    #[inline]
    fn push(&mut self, p: DVec2) {
        Polygon::push(self, p);
    }

    #[inline]
    fn pop(&mut self) {
        self.len = self.len.saturating_sub(1);
    }

    #[inline]
    fn as_slice(&self) -> &[DVec2] {
        Polygon::as_slice(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_clip_and_area() {
        let mut square = Polygon::new();
        for p in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
            square.push(DVec2::new(p.0, p.1));
        }
        assert_eq!(square.area(), 16.0);
        square.clip_to_viewport(0);
        assert_eq!(square.area(), 4.0);
        let mut triangle = Polygon::new();
        for p in [(0.0, 0.0), (4.0, 0.0), (0.0, 4.0)] {
            triangle.push(DVec2::new(p.0, p.1));
        }
        triangle.clip_to_viewport(0);
        assert!((triangle.area() - 1.0).abs() < 1e-6);
        let mut cloud = Polygon::new();
        for p in [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.5, 0.2),
            (1.0, 1.0),
            (0.0, 1.0),
            (0.5, 0.5),
        ] {
            cloud.push(DVec2::new(p.0, p.1));
        }
        let hull = cloud.convex_hull();
        assert_eq!(hull.len, 4);
        assert!((hull.area() - 1.0).abs() < 1e-6);
    }
}
