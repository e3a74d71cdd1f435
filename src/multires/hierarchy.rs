//! The view-dependent data of a progressive mesh: per collapse, which vertex went onto which,
//! and bounds on everything the collapse and the collapses below it change (a bounding sphere,
//! a cone of normals and an error), for the `refine` module's criteria.
//!
//! "Below" a collapse are the collapses it depends on: for every triangle slot it removes or
//! changes, the last earlier collapse that touched that slot (MOM's dependency, per slot).
//! Every bound contains the bounds of those dependencies, so a test that is monotone in the
//! bounds (a sphere outside the frustum, a cone facing away, an error too small to see) never
//! asks to perform a collapse while keeping one it depends on. That is what lets the
//! incremental extraction look only at its front and still match a fresh one exactly.
//!
//! Stored per collapse: two vertex ids (4 bytes, 8 for meshes of more than 65,535 vertices);
//! the sphere's centre as an offset from `w` in 127ths of its radius (3 bytes); the radius and
//! the error as 16-bit floats relative to the bounding-box diagonal, rounded up (4 bytes); and
//! the cone as an octahedral axis in two bytes and a half-angle in π/255 steps, rounded up (3
//! bytes): 14 bytes per collapse, about 7 per triangle (a collapse removes two triangles), 9
//! for meshes past 65,535 vertices.

use super::records::{Unpacked, error_from_u16, error_to_u16};
use glam::{DVec3, Vec3};
use std::f64::consts::PI;

/// Added to every radius that contains others (relative to the diagonal), so containment
/// survives the rounding of the runtime tests with a margin (see [`ViewData::compute`]).
const RADIUS_SLACK: f64 = 1e-5;
/// Added to every cone angle that contains others (radians), for the same reason.
const ANGLE_SLACK: f64 = 1e-4;
/// A half-angle step of the stored cones.
const ANGLE_STEP: f64 = PI / 255.0;

/// The view-dependent data of every collapse, in step order.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ViewData {
    /// `[u, w]`: the position id (smallest vertex index at the position) of the vertex that
    /// went, and of the one it went onto (ear collapses included).
    pub(crate) moved: Moved,
    /// Centre of the bounding sphere, as an offset from `w` in 127ths of its radius (see
    /// [`sphere_centre`]).
    pub(crate) centre: Vec<[i8; 3]>,
    /// Radius of a sphere holding every triangle (before and after) of this collapse and
    /// every sphere below it, relative to the diagonal, rounded up.
    pub(crate) radius: Vec<u16>,
    /// The largest collapse error of this collapse and those below it, relative to the
    /// diagonal, rounded up.
    pub(crate) error: Vec<u16>,
    /// Cone of the normals of those triangles: octahedral axis (two `i8` as `u8`) and
    /// half-angle in [`ANGLE_STEP`]s (255: every direction).
    pub(crate) cone: Vec<[u8; 3]>,
    /// The bounding-box diagonal the relative values are scaled by.
    pub(crate) diagonal: f32,
}

/// The `[u, w]` pairs, in 16 bits for meshes of at most 65,535 vertices.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Moved {
    Narrow(Vec<[u16; 2]>),
    Wide(Vec<[u32; 2]>),
}

impl Moved {
    fn new(moved: Vec<[u32; 2]>, vertices: usize) -> Self {
        if vertices <= usize::from(u16::MAX) {
            Self::Narrow(moved.iter().map(|m| m.map(|v| v as u16)).collect())
        } else {
            Self::Wide(moved)
        }
    }

    /// `[u, w]` of collapse `i`.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> Option<[u32; 2]> {
        match self {
            Self::Narrow(m) => m.get(i).map(|m| m.map(u32::from)),
            Self::Wide(m) => m.get(i).copied(),
        }
    }

    fn len(&self) -> usize {
        match self {
            Self::Narrow(m) => m.len(),
            Self::Wide(m) => m.len(),
        }
    }

    fn bytes(&self) -> usize {
        match self {
            Self::Narrow(m) => m.len() * 4,
            Self::Wide(m) => m.len() * 8,
        }
    }
}

/// The centre of a stored sphere: `w` moved by `offset` 127ths of the radius `radius` (in the
/// mesh's units). The build places every sphere with this very function, so the containment
/// it checks is the containment the runtime sees.
#[inline]
pub(crate) fn sphere_centre(w: Vec3, offset: [i8; 3], radius: f32) -> Vec3 {
    w + Vec3::new(
        f32::from(offset[0]),
        f32::from(offset[1]),
        f32::from(offset[2]),
    ) * (radius / 127.0)
}

impl ViewData {
    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.moved.bytes()
            + self.centre.len() * 3
            + self.radius.len() * 2
            + self.error.len() * 2
            + self.cone.len() * 3
    }

    /// Number of collapses.
    pub(crate) fn len(&self) -> usize {
        self.moved.len()
    }

    /// The decoded sphere of collapse `i`, in the mesh's units, given the positions.
    #[inline]
    pub(crate) fn sphere_of(&self, i: usize, positions: &[Vec3]) -> (Vec3, f32) {
        let radius = error_from_u16(self.radius[i]) * self.diagonal;
        let w = self
            .moved
            .get(i)
            .map_or(Vec3::ZERO, |m| positions[m[1] as usize]);
        (sphere_centre(w, self.centre[i], radius), radius)
    }

    /// The decoded error of collapse `i`, relative to the diagonal.
    #[inline]
    pub(crate) fn error_of(&self, i: usize) -> f32 {
        error_from_u16(self.error[i])
    }

    /// The decoded cone of collapse `i`: unit axis and half-angle (radians, `π` for a cone
    /// holding every direction).
    #[inline]
    pub(crate) fn cone_of(&self, i: usize) -> (Vec3, f32) {
        let [x, y, q] = self.cone[i];
        (
            oct_decode([x as i8, y as i8]).as_vec3(),
            (f64::from(q) * ANGLE_STEP) as f32,
        )
    }

    /// Computes the data by replaying the sequence `records` over `positions`.
    ///
    /// `moved[i]` and `own_error[i]` are collapse `i`'s vertices and its own error (relative
    /// to `diagonal`). Each bound is computed from the stored (rounded) bounds of the
    /// collapses below it and then rounded up itself, so containment holds for the stored
    /// values exactly, with [`RADIUS_SLACK`] and [`ANGLE_SLACK`] to spare.
    pub(crate) fn compute(
        positions: &[Vec3],
        records: &Unpacked,
        moved: Vec<[u32; 2]>,
        own_error: &[f32],
        diagonal: f32,
    ) -> Self {
        let steps = records.steps.len();
        let diagonal = if diagonal > 0.0 && diagonal.is_finite() {
            diagonal
        } else {
            1.0
        };
        let slots = records.indices.len() / 3;
        let mut tri = records.indices.clone();
        let mut last = vec![u32::MAX; slots];
        let mut count = slots;
        let (mut corner, mut pair) = (0, 0);
        let mut out = Self {
            moved: Moved::new(Vec::new(), 0),
            centre: Vec::with_capacity(steps),
            radius: Vec::with_capacity(steps),
            error: Vec::with_capacity(steps),
            cone: Vec::with_capacity(steps),
            diagonal,
        };
        // Decoded stored bounds, for the collapses above.
        let mut spheres: Vec<(Vec3, f32)> = Vec::with_capacity(steps);
        let mut error = Vec::with_capacity(steps);
        let mut cones: Vec<(DVec3, f64)> = Vec::with_capacity(steps);
        let (mut touched, mut deps, mut normals, mut points) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, &(nc, np, removed)) in records.steps.iter().enumerate() {
            touched.clear();
            touched.extend((count - removed..count).map(|s| s as u32));
            for &(c, _) in &records.corners[corner..corner + nc] {
                touched.push(c / 3);
            }
            touched.sort_unstable();
            touched.dedup();
            normals.clear();
            points.clear();
            for &s in &touched {
                let t = &tri[3 * s as usize..3 * s as usize + 3];
                points.extend(t.iter().map(|&v| positions[v as usize]));
                normals.extend(normal(t.iter().map(|&v| positions[v as usize].as_dvec3())));
            }
            deps.clear();
            deps.extend(
                touched
                    .iter()
                    .map(|&s| last[s as usize])
                    .filter(|&d| d != u32::MAX),
            );
            deps.sort_unstable();
            deps.dedup();
            // The collapse itself: changed triangles take their new corners.
            let pairs = &records.pairs[pair..pair + np];
            for &(c, p) in &records.corners[corner..corner + nc] {
                tri[c as usize] = pairs[p as usize][1];
            }
            for &(c, _) in &records.corners[corner..corner + nc] {
                let s = (c / 3) as usize;
                normals.extend(normal(
                    tri[3 * s..3 * s + 3]
                        .iter()
                        .map(|&v| positions[v as usize].as_dvec3()),
                ));
            }
            for &s in &touched {
                last[s as usize] = i as u32;
            }

            let w = positions[moved[i][1] as usize];
            let below: Vec<(Vec3, f32)> = deps.iter().map(|&d| spheres[d as usize]).collect();
            let (offset, stored) = place_sphere(w, &points, &below, diagonal);
            out.centre.push(offset);
            out.radius.push(stored);
            let radius = error_from_u16(stored) * diagonal;
            spheres.push((sphere_centre(w, offset, radius), radius));

            let mut e = f64::from(own_error[i].max(0.0));
            for &d in &deps {
                e = e.max(error[d as usize]);
            }
            let stored = error_to_u16(round_up(e));
            out.error.push(stored);
            error.push(f64::from(error_from_u16(stored)));

            let (code, cone) = bound_cone(&normals, deps.iter().map(|&d| cones[d as usize]));
            out.cone.push(code);
            cones.push(cone);

            count -= removed;
            corner += nc;
            pair += np;
        }
        out.moved = Moved::new(moved, positions.len());
        out
    }
}

/// A stored sphere (offset from `w`, radius relative to `diagonal`) holding `points` and, with
/// [`RADIUS_SLACK`] to spare, the spheres `below`. Its centre is the middle of their bounding
/// box, as near as the offset's 127ths of the radius can put it; the radius is then measured
/// from the decoded centre and rounded up.
fn place_sphere(w: Vec3, points: &[Vec3], below: &[(Vec3, f32)], diagonal: f32) -> ([i8; 3], u16) {
    let slack = RADIUS_SLACK * f64::from(diagonal);
    let need = |c: Vec3| -> f64 {
        let c = c.as_dvec3();
        let mut r = 0.0f64;
        for p in points {
            r = r.max(p.as_dvec3().distance(c));
        }
        for &(centre, radius) in below {
            r = r.max(centre.as_dvec3().distance(c) + f64::from(radius) + slack);
        }
        r
    };
    let (mut lo, mut hi) = (w, w);
    for &p in points {
        (lo, hi) = (lo.min(p), hi.max(p));
    }
    for &(c, r) in below {
        (lo, hi) = (lo.min(c - r), hi.max(c + r));
    }
    let ideal = (lo + hi) * 0.5;
    let mut relative = need(ideal) / f64::from(diagonal);
    for _ in 0..6 {
        let stored = error_to_u16(round_up(relative));
        let radius = error_from_u16(stored) * diagonal;
        let offset = if radius > 0.0 {
            ((ideal - w) * (127.0 / radius))
                .round()
                .clamp(Vec3::splat(-127.0), Vec3::splat(127.0))
                .to_array()
                .map(|x| x as i8)
        } else {
            [0; 3]
        };
        let required = need(sphere_centre(w, offset, radius));
        if required <= f64::from(radius) {
            return (offset, stored);
        }
        relative = required / f64::from(diagonal) * 1.001;
    }
    // Centred on w: the offset is exact, so the radius measured from w holds.
    let stored = error_to_u16(round_up(need(w) / f64::from(diagonal) * 1.001));
    ([0; 3], stored)
}

/// `value` as an `f32` no smaller than it.
fn round_up(value: f64) -> f32 {
    let v = value as f32;
    if f64::from(v) < value { v.next_up() } else { v }
}

/// The unit normal of a triangle, or `None` when it has no area.
fn normal(mut points: impl Iterator<Item = DVec3>) -> Option<DVec3> {
    let (a, b, c) = (points.next()?, points.next()?, points.next()?);
    (b - a).cross(c - a).try_normalize()
}

/// The angle between two unit vectors, accurate near 0 and π.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// A stored cone holding every normal of `normals` and every cone of `below`, and its decoded
/// axis and half-angle. The axis is chosen by merging the cones two at a time; the angle is
/// then measured from the stored (quantised) axis, so containment holds for the stored cone.
fn bound_cone(
    normals: &[DVec3],
    below: impl Iterator<Item = (DVec3, f64)> + Clone,
) -> ([u8; 3], (DVec3, f64)) {
    let sum: DVec3 = normals.iter().sum();
    let mut cone = sum.try_normalize().map(|axis| {
        let spread = normals.iter().map(|&n| angle(axis, n)).fold(0.0, f64::max);
        (axis, spread)
    });
    for c in below.clone() {
        cone = Some(match cone {
            None => c,
            Some(a) => merge(a, c),
        });
    }
    let Some((axis, _)) = cone.filter(|c| c.1 < PI) else {
        return ([0, 0, 255], (DVec3::Z, PI));
    };
    let code = oct_encode(axis);
    let axis = oct_decode(code);
    let mut theta = normals.iter().map(|&n| angle(axis, n)).fold(0.0, f64::max);
    let mut nested = false;
    for (a, t) in below {
        theta = theta.max(angle(axis, a) + t);
        nested = true;
    }
    if nested {
        theta += ANGLE_SLACK;
    }
    let steps = (theta / ANGLE_STEP).ceil().min(255.0) as u8;
    let decoded = f64::from(steps) * ANGLE_STEP;
    if decoded < theta {
        return ([0, 0, 255], (DVec3::Z, PI));
    }
    ([code[0] as u8, code[1] as u8, steps], (axis, decoded))
}

/// The smallest cone holding two cones.
fn merge(a: (DVec3, f64), b: (DVec3, f64)) -> (DVec3, f64) {
    let between = angle(a.0, b.0);
    if between + b.1 <= a.1 {
        return a;
    }
    if between + a.1 <= b.1 {
        return b;
    }
    let half = (a.1 + b.1 + between) * 0.5;
    if half >= PI || between <= 0.0 {
        return (a.0, PI);
    }
    // Rotate a's axis towards b's by `half - a.1`.
    let t = (half - a.1) / between;
    let perp = (b.0 - a.0 * a.0.dot(b.0)).normalize_or_zero();
    let turn = t * between;
    ((a.0 * turn.cos() + perp * turn.sin()).normalize(), half)
}

/// Octahedral encoding of a unit vector in two signed bytes.
fn oct_encode(n: DVec3) -> [i8; 2] {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs());
    let (x, y) = if n.z >= 0.0 {
        (n.x, n.y)
    } else {
        (
            (1.0 - n.y.abs()) * n.x.signum(),
            (1.0 - n.x.abs()) * n.y.signum(),
        )
    };
    [
        (x * 127.0).round().clamp(-127.0, 127.0) as i8,
        (y * 127.0).round().clamp(-127.0, 127.0) as i8,
    ]
}

/// The unit vector of an [`oct_encode`]d pair.
fn oct_decode(code: [i8; 2]) -> DVec3 {
    let (x, y) = (f64::from(code[0]) / 127.0, f64::from(code[1]) / 127.0);
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum())
    } else {
        (x, y)
    };
    DVec3::new(x, y, z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_codes_round_trip_within_a_degree() {
        let mut seed = 0x2545_f491_u64;
        for _ in 0..2000 {
            let mut next = || {
                seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
            };
            let Some(n) = DVec3::new(next(), next(), next()).try_normalize() else {
                continue;
            };
            assert!(angle(n, oct_decode(oct_encode(n))) < 1.5f64.to_radians());
        }
        for n in [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ] {
            assert!(angle(n, oct_decode(oct_encode(n))) < 1e-9);
        }
    }

    #[test]
    fn merged_cones_hold_both() {
        let a = (DVec3::X, 0.2);
        let b = (DVec3::Y, 0.3);
        let (axis, half) = merge(a, b);
        assert!(angle(axis, a.0) + a.1 <= half + 1e-9);
        assert!(angle(axis, b.0) + b.1 <= half + 1e-9);
        assert_eq!(merge(a, (DVec3::X, 0.1)), a);
        assert_eq!(merge((DVec3::X, 2.0), (-DVec3::X, 2.0)).1, PI);
    }

    #[test]
    fn stored_cones_hold_their_normals_and_the_cones_below() {
        let normals = [DVec3::Z, DVec3::new(0.1, 0.0, 1.0).normalize()];
        let below = [(DVec3::new(0.0, 0.3, 1.0).normalize(), 0.05)];
        let (_, (axis, half)) = bound_cone(&normals, below.iter().copied());
        for n in normals {
            assert!(angle(axis, n) <= half);
        }
        assert!(angle(axis, below[0].0) + below[0].1 < half);
        let (code, (_, full)) = bound_cone(&[DVec3::Z, -DVec3::Z], std::iter::empty());
        assert_eq!((code[2], full), (255, PI));
    }
}
