//! Four boxes at a time on the four lanes of a [`Vec4`]: the common case of
//! [`ProjectedAreaCamera::projected_areas`](super::ProjectedAreaCamera::projected_areas).

use super::silhouette::face_loop;
use crate::bounds::Obb;
use glam::{BVec4A, Mat4, Vec3, Vec4};

/// A camera's constants, each splat across the four lanes of a [`Vec4`], for measuring four
/// boxes at once (one per lane): the common case of
/// [`ProjectedAreaCamera::projected_area`](super::ProjectedAreaCamera::projected_area).
pub(super) struct Lanes {
    /// Rows x, y and w of `clip_from_world`'s upper 3×4 block: `m[row][column]`.
    m: [[Vec4; 3]; 3],
    /// `origin_clip`'s x, y and w.
    origin_clip: [Vec4; 3],
    origin: [Vec4; 3],
    near: [Vec4; 4],
    ndc_to_pixels: Vec4,
}

/// A 3-vector per lane.
type Lane3 = [Vec4; 3];

impl Lanes {
    /// A camera's constants, from its fields of the same names
    /// ([`ProjectedAreaCamera`](super::ProjectedAreaCamera)).
    #[inline]
    pub(super) fn new(
        clip_from_world: Mat4,
        origin: Vec3,
        origin_clip: Vec4,
        near: Vec4,
        ndc_to_pixels: f32,
    ) -> Self {
        let m = clip_from_world;
        let columns = [m.x_axis, m.y_axis, m.z_axis];
        let row = |pick: fn(Vec4) -> f32| columns.map(|c| Vec4::splat(pick(c)));
        let o = origin_clip;
        Self {
            m: [row(|c| c.x), row(|c| c.y), row(|c| c.w)],
            origin_clip: [o.x, o.y, o.w].map(Vec4::splat),
            origin: origin.to_array().map(Vec4::splat),
            near: near.to_array().map(Vec4::splat),
            ndc_to_pixels: Vec4::splat(ndc_to_pixels),
        }
    }

    /// Clip x, y and w of a direction (w = 0) given per lane.
    #[inline(always)]
    fn clip(&self, v: &Lane3) -> Lane3 {
        self.m
            .map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
    }

    /// The areas of four boxes in pixels², and a bit per lane set where that area is final:
    /// the box is wholly behind the near plane or outside a side of the view (area 0), or
    /// wholly in view and measured well in `f32`. The other lanes' areas are unspecified:
    /// those boxes need
    /// [`ProjectedAreaCamera::projected_area`](super::ProjectedAreaCamera::projected_area).
    ///
    /// No silhouette here: the outline of a convex body in front of the eye is covered
    /// twice by the projections of its six faces (once by the faces turned to the eye, once
    /// by those turned away), so the area is half the sum of the faces' unsigned projected
    /// areas, whichever are which. A projected face is a quadrilateral, whose area is half the
    /// cross product of its diagonals. The corners are measured relative to the projection of
    /// the box's centre, as in [`outline_area`](super::scalar::outline_area), and the same two
    /// precision checks apply.
    #[inline(always)]
    pub(super) fn areas(&self, boxes: [&Obb; 4]) -> (Vec4, u32) {
        let lanes = |f: fn(&Obb) -> f32| Vec4::from_array(boxes.map(f));
        let o: Lane3 = [
            lanes(|b| b.center.x) - self.origin[0],
            lanes(|b| b.center.y) - self.origin[1],
            lanes(|b| b.center.z) - self.origin[2],
        ];
        let (hx, hy, hz) = (
            lanes(|b| b.half_extents.x),
            lanes(|b| b.half_extents.y),
            lanes(|b| b.half_extents.z),
        );
        // The half axes, scaled.
        let axes: [Lane3; 3] = [
            [
                lanes(|b| b.axes.x_axis.x) * hx,
                lanes(|b| b.axes.x_axis.y) * hx,
                lanes(|b| b.axes.x_axis.z) * hx,
            ],
            [
                lanes(|b| b.axes.y_axis.x) * hy,
                lanes(|b| b.axes.y_axis.y) * hy,
                lanes(|b| b.axes.y_axis.z) * hy,
            ],
            [
                lanes(|b| b.axes.z_axis.x) * hz,
                lanes(|b| b.axes.z_axis.y) * hz,
                lanes(|b| b.axes.z_axis.z) * hz,
            ],
        ];
        let clip_o = self.clip(&o);
        let c: Lane3 = std::array::from_fn(|r| clip_o[r] + self.origin_clip[r]);
        let a = axes.map(|v| self.clip(&v));

        // A linear function's range over the box is its value at the centre ± Σ |value at
        // the half axes|: the near plane, and the four side planes w ± x, w ± y.
        let n = &self.near;
        let near = |v: &Lane3| n[0] * v[0] + n[1] * v[1] + n[2] * v[2];
        let near_c = near(&o) + n[3];
        let near_r = near(&axes[0]).abs() + near(&axes[1]).abs() + near(&axes[2]).abs();
        let sides = |v: &Lane3| [v[2] + v[0], v[2] - v[0], v[2] + v[1], v[2] - v[1]];
        let sides_c = sides(&c);
        let sides_a = a.map(|v| sides(&v));
        let mut culled = (near_c + near_r).cmple(Vec4::ZERO);
        let mut inside = (near_c - near_r).cmpge(Vec4::ZERO);
        for k in 0..4 {
            let r = sides_a[0][k].abs() + sides_a[1][k].abs() + sides_a[2][k].abs();
            culled |= (sides_c[k] + r).cmplt(Vec4::ZERO);
            inside &= (sides_c[k] - r).cmpge(Vec4::ZERO);
        }

        // Per axis `d`: `d.xy · c.w − c.xy · d.w` (the two products kept for the rounding
        // check) and `d.w`. Corner `i` (bit k: +a[k]) has numerator Σ ±(that) and w
        // `c.w + Σ ±d.w`, and projects to numerator / w relative to the centre's projection,
        // scaled by c.w.
        let w = c[2];
        let px = a.map(|d| d[0] * w);
        let qx = a.map(|d| c[0] * d[2]);
        let py = a.map(|d| d[1] * w);
        let qy = a.map(|d| c[1] * d[2]);
        let x: [Vec4; 3] = std::array::from_fn(|k| px[k] - qx[k]);
        let y: [Vec4; 3] = std::array::from_fn(|k| py[k] - qy[k]);
        let signed = |v: &[Vec4; 3], base: Vec4, i: usize| {
            let pick = |k: usize| if (i >> k) & 1 == 1 { v[k] } else { -v[k] };
            base + pick(0) + pick(1) + pick(2)
        };
        let corners: [(Vec4, Vec4); 8] = std::array::from_fn(|i| {
            let inverse = Vec4::ONE / signed(&[a[0][2], a[1][2], a[2][2]], w, i);
            (
                signed(&x, Vec4::ZERO, i) * inverse,
                signed(&y, Vec4::ZERO, i) * inverse,
            )
        });
        let (mut sum, mut size) = (Vec4::ZERO, Vec4::ZERO);
        for [p, q, r, t] in FACE_DIAGONALS {
            let d1 = (corners[q].0 - corners[p].0, corners[q].1 - corners[p].1);
            let d2 = (corners[t].0 - corners[r].0, corners[t].1 - corners[r].1);
            let (u, v) = (d1.0 * d2.1, d1.1 * d2.0);
            sum += (u - v).abs();
            size += u.abs() + v.abs();
        }
        // Twice the outline's area, in the numerators' units (over c.w²).
        let twice = sum * 0.5;
        let ww = w * w;
        let area = twice * 0.5 / ww * self.ndc_to_pixels;
        // The same two checks as `outline_area`: products that cancel in the face areas, and
        // per-axis terms whose rounding moves the area by more than about 1e-5.
        let rounding = (0..3).fold(Vec4::ZERO, |acc, k| {
            acc + px[k].abs() + qx[k].abs() + py[k].abs() + qy[k].abs()
        });
        let spread = (0..3).fold(Vec4::ZERO, |acc, k| acc + x[k].abs() + y[k].abs());
        let fine = size.cmple(sum * 16.0)
            & (rounding * spread).cmple(twice * ww * 8.0)
            & finite(area)
            & finite(ww);
        let done = culled | (inside & fine);
        (Vec4::select(culled, Vec4::ZERO, area), done.bitmask())
    }
}

/// Each face's two diagonals as corner pairs `[p, q, r, t]` (`p`→`q` and `r`→`t`): the
/// opposite corners of its [`face_loop`], faces in the order −x, +x, −y, +y, −z, +z. (Which
/// way a diagonal runs only flips the sign of the face's cross product.)
const FACE_DIAGONALS: [[usize; 4]; 6] = {
    let mut out = [[0; 4]; 6];
    let mut face = 0;
    while face < 6 {
        let l = face_loop(face / 2, face % 2 == 1);
        out[face] = [l[0] as usize, l[2] as usize, l[1] as usize, l[3] as usize];
        face += 1;
    }
    out
};

/// Per lane: finite.
#[inline(always)]
fn finite(v: Vec4) -> BVec4A {
    v.abs().cmplt(Vec4::splat(f32::INFINITY))
}
