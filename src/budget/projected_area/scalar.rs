//! One box at a time: the outline's area in `f32` around the centre's projection, or in `f64`
//! and clipped to the viewport where that is not enough.

use super::clip::{Polygon, corner_clip, shoelace};
use glam::{DVec2, DVec4, Vec3A, Vec3Swizzles, Vec4, Vec4Swizzles};

/// The NDC area of the outline `outline` (corner numbers, as
/// [`silhouette`](fn@super::silhouette) gives them) of a box with clip-space centre `c` and
/// half axes `a`, wholly in front of the near plane.
///
/// Each corner is measured from the centre's projection, not from the NDC origin: corner
/// `c + d` projects to `c.xy / c.w + (d.xy · c.w − c.xy · d.w) / (c.w · (c.w + d.w))`, and
/// `d.xy · c.w − c.xy · d.w` is linear in `d`, so it is a signed sum of three per-axis terms
/// computed once. The offsets are as small as the box and no digits go to its distance from
/// the view axis, which is what keeps `f32` enough here (the straightforward `v.xy / v.w` of
/// each corner rounds them to the centre's magnitude). The centre projects inside the outline,
/// so every term of the shoelace sum has the same sign and the sum does not cancel.
///
/// `None` where `f32` is not enough: a thin outline (where the terms themselves cancel), or
/// values out of its range.
#[inline]
pub(super) fn outline_area(c: Vec4, a: &[Vec4; 3], outline: &[u8]) -> Option<f32> {
    // Per axis `(d.xy · c.w − c.xy · d.w, d.w)` for `d = a[k]`; a corner's numerator and `w`
    // are the signed sum of the three plus `(0, 0, c.w)`. All eight corners, without a branch
    // on which sign each takes (the outline's corners differ from box to box).
    // The two products of each term, kept apart for the rounding check below.
    let products = a.map(|d| (d.xy() * c.w, c.xy() * d.w));
    let [x, y, z] = std::array::from_fn(|k| {
        let (p, q) = products[k];
        Vec3A::from((p - q).extend(a[k].w))
    });
    let base = Vec3A::new(0.0, 0.0, c.w);
    let (x0, x1) = (base - x, base + x);
    let (y0, y1) = (-y, y);
    let corners = [
        x0 + y0 - z,
        x1 + y0 - z,
        x0 + y1 - z,
        x1 + y1 - z,
        x0 + y0 + z,
        x1 + y0 + z,
        x0 + y1 + z,
        x1 + y1 + z,
    ];
    let project = |k: u8| {
        let v = corners[usize::from(k & 7)];
        v.xy() / v.z
    };
    let Some(&last) = outline.last() else {
        return Some(0.0);
    };
    let mut prev = project(last);
    let (mut twice, mut size) = (0.0f32, 0.0f32);
    for &k in outline {
        let p = project(k);
        let (u, v) = (prev.x * p.y, prev.y * p.x);
        twice += u - v;
        size += u.abs() + v.abs();
        prev = p;
    }
    let ww = c.w * c.w;
    let area = (twice * 0.5).abs() / ww;
    // A thin outline (a box seen nearly edge-on, a needle pointing at the eye) is a small
    // difference of larger values, where f32 keeps few digits. Two places cancel: the
    // shoelace products (`size` is their magnitude), and the per-axis terms, each good to
    // about an f32 rounding of its two products (`rounding`), which moves the area by about
    // that times the outline's size (`spread`). Past these bounds (about 1e-5 relative at
    // worst), and when f32 over- or underflows (boxes some 1e19 units away): `None`.
    let rounding: f32 = products
        .iter()
        .map(|(p, q)| p.abs().element_sum() + q.abs().element_sum())
        .sum();
    let spread =
        x.xy().abs().element_sum() + y.xy().abs().element_sum() + z.xy().abs().element_sum();
    let fine = size <= 16.0 * twice.abs() && rounding * spread <= 8.0 * twice.abs() * ww;
    (fine && area.is_finite() && ww.is_finite()).then_some(area)
}

/// The NDC area of the outline `outline` of a box with clip-space centre `c` and half axes `a`,
/// wholly in front of the near plane, in `f64` and clipped to the viewport: for the outlines
/// that [`outline_area`] cannot measure (clipped, thin, or out of `f32`'s range).
#[inline]
pub(super) fn clipped_outline_area(c: DVec4, a: &[DVec4; 3], outline: &[u8]) -> f64 {
    let sides = |v: DVec4| DVec4::splat(v.w) + DVec4::new(v.x, -v.x, v.y, -v.y);
    let sides_r = sides(a[0]).abs() + sides(a[1]).abs() + sides(a[2]).abs();
    let inside = (sides(c) - sides_r).cmpge(DVec4::ZERO);
    let mut corners = [DVec2::ZERO; 6];
    for (slot, &corner) in corners.iter_mut().zip(outline) {
        let v = corner_clip(c, a, corner);
        *slot = v.xy() / v.w;
    }
    let corners = &corners[..outline.len()];
    if inside.all() {
        shoelace(corners)
    } else {
        let mut polygon = Polygon::new();
        for &p in corners {
            polygon.push(p);
        }
        polygon.clip_to_viewport(inside.bitmask());
        polygon.area()
    }
}
