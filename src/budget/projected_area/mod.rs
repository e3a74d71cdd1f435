//! The screen area of an oriented box; the method is on [`ProjectedAreaCamera`].
//!
//! This file holds the camera and the per-box dispatch; the paths it picks are beside it:
//! `silhouette` (the outline table), `scalar` (one box's outline, in `f32` or `f64`), `lanes`
//! (four boxes at a time) and `clip` (the near plane and the viewport).

mod clip;
mod lanes;
mod scalar;
mod silhouette;

pub use silhouette::silhouette;

use super::BudgetError;
use crate::bounds::Obb;
use glam::{Affine3A, DMat4, DVec3, DVec4, Mat4, Vec2, Vec3, Vec4, Vec4Swizzles};
use lanes::Lanes;

/// A camera prepared for [`projected_area`](Self::projected_area): build one per camera per
/// frame, then query every box. Areas are in pixels² of the viewport it was made with.
///
/// # Method
///
/// Schmalstieg & Tobler, "Fast projected area computation for three-dimensional bounding
/// boxes" (1999), made exact for what the 1999 method leaves out. The eye, moved into the
/// box's frame, lies outside some of the six face planes. One bit per
/// plane gives a 6-bit code; the code picks a row of a 64-entry table that lists the corners of
/// the box's outline in order ([`silhouette`](fn@silhouette)). Only those 4 or 6 corners are
/// projected, and the shoelace formula gives the outline's area. Beyond the paper:
///
/// - **Near plane.** A box wholly behind the near plane has no area. A box that straddles it is
///   clipped as a volume: its visible part is the convex hull of the corners in front and the
///   points where its 12 edges cross the plane, all in clip space before the perspective divide.
///   Clipping only the outline loop is not enough: seen face-on with its front face behind the
///   near plane, the outline is the front face and would clip away to nothing while the sides
///   and back are in view. The eye inside the box is a case of this, and gives the whole
///   viewport whenever the box reaches past the near plane across the view.
/// - **Viewport.** The outline is clipped to the viewport (Sutherland–Hodgman), so off-screen
///   parts do not count; boxes wholly outside a side plane cost five dot products.
/// - **Orthographic cameras.** The eye is a direction (a point at infinity); the same code and
///   table apply.
/// - **Precision.** A box wholly inside the view is measured in `f32`, each outline corner
///   relative to the projection of the box's centre (so a small box far off the view axis
///   keeps its digits), unless its outline is thin (seen nearly edge-on, where the `f32`
///   products would cancel) or out of `f32`'s range. Those, and boxes that the viewport or
///   the near plane clip, are measured in `f64`.
///
/// Everything is in clip space, so any projection matrix with wgpu's depth range `0..=1` works:
/// `perspective_rh`, Bevy's `perspective_infinite_reverse_rh` (also with an oblique near plane,
/// as Bevy's mirror cameras set), `orthographic_rh` with either depth direction. The far plane
/// is not clipped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedAreaCamera {
    /// `clip_from_world`, applied to offsets from `origin`.
    clip_from_world: Mat4,
    /// A reference point near the camera; boxes are transformed relative to it for precision.
    origin: Vec3,
    /// `clip_from_world · (origin, 1)`, computed in `f64`.
    origin_clip: Vec4,
    /// `clip_from_world` in `f64`, for the rare boxes that straddle the near plane.
    clip_from_world_f64: DMat4,
    /// `origin_clip` in `f64`.
    origin_clip_f64: DVec4,
    /// `near` in `f64`.
    near_f64: DVec4,
    /// The visible side of the near plane in clip space.
    near_clip: DVec4,
    /// `eye` in `f64`.
    eye_f64: DVec4,
    /// The centre of projection in world space (or the model's, see `for_model`):
    /// `(position, 1)`, or for an orthographic camera `(unit direction towards the viewer, 0)`.
    eye: Vec4,
    /// The near plane in world space, relative to `origin`: visible where
    /// `near.xyz · (x − origin) + near.w ≥ 0`. Made in `f64` from the clip-space plane, which
    /// in `f32` loses digits to cancellation (reverse-Z puts the near plane at z ≈ w ≈ 1).
    near: Vec4,
    /// Viewport size in pixels.
    viewport: Vec2,
    /// NDC area to pixel area: `width · height / 4`.
    ndc_to_pixels: f32,
}

impl ProjectedAreaCamera {
    /// Prepares a camera from its view matrix (`view_from_world`, the inverse of the camera's
    /// world transform), its projection (`clip_from_view`) and the viewport size in pixels.
    ///
    /// The view space is right-handed and looks down `−Z` (Bevy, glam `*_rh`). The projection
    /// must map visible depth to `0..=1`, either way round: `Mat4::perspective_rh`,
    /// `Mat4::perspective_infinite_reverse_rh` (Bevy's default), `Mat4::orthographic_rh` (also
    /// with near and far swapped, as Bevy's orthographic projection does). OpenGL-style `*_gl`
    /// matrices (depth `−1..=1`) would clip at the wrong depth. Orthographic projections are
    /// recognised from the matrix (the eye is at infinity).
    ///
    /// # Errors
    ///
    /// [`BudgetError::InvalidCamera`] when a matrix is not finite or not invertible, the
    /// projection has no single centre of projection, or the viewport is not a positive,
    /// finite size.
    ///
    /// ```
    /// use bevy_aslod::budget::{Obb, ProjectedAreaCamera};
    /// use glam::{Mat4, Vec2, Vec3};
    ///
    /// let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y);
    /// let projection = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1);
    /// let camera = ProjectedAreaCamera::new(view, projection, Vec2::new(1920.0, 1080.0))?;
    /// let area = camera.projected_area(&Obb::from_aabb(Vec3::splat(-1.0), Vec3::splat(1.0)));
    /// assert!(area > 0.0 && area < camera.viewport_area());
    /// # Ok::<(), bevy_aslod::budget::BudgetError>(())
    /// ```
    pub fn new(
        view_from_world: Mat4,
        clip_from_view: Mat4,
        viewport_size: Vec2,
    ) -> Result<Self, BudgetError> {
        if !view_from_world.is_finite() || !clip_from_view.is_finite() {
            return Err(BudgetError::InvalidCamera("a matrix is not finite"));
        }
        if !(viewport_size.is_finite() && viewport_size.cmpgt(Vec2::ZERO).all()) {
            return Err(BudgetError::InvalidCamera(
                "the viewport size is not positive and finite",
            ));
        }
        let view = view_from_world.as_dmat4();
        let det = view.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(BudgetError::InvalidCamera(
                "the view matrix is not invertible",
            ));
        }
        let world_from_view = view.inverse();
        let projection = clip_from_view.as_dmat4();

        // The centre of projection is the point that clip x, y and w all vanish on.
        let mut eye_view = null_vector(projection.row(0), projection.row(1), projection.row(3));
        let size = eye_view.length();
        if !(size > 0.0 && size.is_finite()) {
            return Err(BudgetError::InvalidCamera(
                "the projection has no single centre of projection",
            ));
        }
        eye_view /= size;
        let orthographic = eye_view.w.abs() <= 1e-9 * eye_view.xyz().length();
        if orthographic {
            // A direction: towards the viewer is +Z in a right-handed view space.
            eye_view.w = 0.0;
            eye_view = eye_view.normalize();
            if eye_view.z < 0.0 {
                eye_view = -eye_view;
            }
        } else {
            eye_view /= eye_view.w;
        }
        // Depth 0..=1 has two candidate near planes, z = 0 and z = w; the eye lies outside the
        // near one. (Its clip position is (0, 0, z, 0), so the sign of z decides.)
        let eye_clip = projection * eye_view;
        let near_clip = if eye_clip.z < 0.0 {
            DVec4::new(0.0, 0.0, 1.0, 0.0) // z ≥ 0: standard depth
        } else if eye_clip.z > 0.0 {
            DVec4::new(0.0, 0.0, -1.0, 1.0) // w − z ≥ 0: reverse depth
        } else {
            return Err(BudgetError::InvalidCamera(
                "the near plane cannot be told from the projection",
            ));
        };

        let clip_from_world = projection * view;
        let eye = world_from_view * eye_view;
        let origin = if orthographic {
            world_from_view.w_axis.xyz()
        } else {
            eye.xyz()
        };
        let eye = if orthographic {
            eye.xyz().normalize().extend(0.0)
        } else {
            eye
        };
        Ok(Self::assemble(
            clip_from_world,
            eye,
            origin,
            near_clip,
            viewport_size,
        ))
    }

    /// The camera's fields from `clip_from_space` (any space: world, or a model's), the eye
    /// and a reference point in that space, and the visible side of the near plane in clip
    /// space.
    fn assemble(
        clip_from_space: DMat4,
        eye: DVec4,
        origin: DVec3,
        near_clip: DVec4,
        viewport_size: Vec2,
    ) -> Self {
        // Round the origin first: boxes are offset from the f32 origin, so its clip position
        // must be that of the f32 origin too, or the rounding moves the eye.
        let origin = origin.as_vec3().as_dvec3();
        let origin_clip = clip_from_space * origin.extend(1.0);
        let near_space = clip_from_space.transpose() * near_clip;
        let near = near_space.xyz().extend(near_clip.dot(origin_clip));
        Self {
            clip_from_world: clip_from_space.as_mat4(),
            origin: origin.as_vec3(),
            origin_clip: origin_clip.as_vec4(),
            clip_from_world_f64: clip_from_space,
            origin_clip_f64: origin_clip,
            near_f64: near,
            near_clip,
            eye_f64: eye,
            eye: eye.as_vec4(),
            near: near.as_vec4(),
            viewport: viewport_size,
            ndc_to_pixels: viewport_size.x * viewport_size.y * 0.25,
        }
    }

    /// The same camera seen from a model's own space: boxes given in the model's space then
    /// project as they do through `world_from_model`. One call per model instead of one
    /// [`Obb::transformed`] per box, and exact where that one is conservative (a non-uniform
    /// scale or shear makes a box a parallelepiped, which is projected as it is).
    ///
    /// Returns `None` when `world_from_model` is not invertible or not finite.
    ///
    /// ```
    /// use bevy_aslod::budget::{Obb, ProjectedAreaCamera};
    /// use glam::{Affine3A, Mat3, Mat4, Vec2, Vec3};
    ///
    /// let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y);
    /// let projection = Mat4::perspective_rh(1.0, 1.0, 0.1, 100.0);
    /// let camera = ProjectedAreaCamera::new(view, projection, Vec2::splat(512.0)).unwrap();
    /// let model = Affine3A::from_translation(Vec3::new(1.0, 0.0, 0.0));
    /// let local = Obb::new(Vec3::ZERO, Mat3::IDENTITY, Vec3::splat(0.5));
    /// let in_model = camera.for_model(&model).unwrap().projected_area(&local);
    /// let in_world = camera.projected_area(&local.transformed(&model));
    /// assert!((in_model - in_world).abs() <= 1e-3 * in_world);
    /// ```
    #[must_use]
    pub fn for_model(&self, world_from_model: &Affine3A) -> Option<Self> {
        let world_from_model = Mat4::from(*world_from_model).as_dmat4();
        let det = world_from_model.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let model_from_world = world_from_model.inverse();
        let eye = model_from_world * self.eye_f64;
        let eye = if self.eye_f64.w == 0.0 {
            eye.xyz().try_normalize()?.extend(0.0)
        } else {
            eye / eye.w
        };
        let origin = (model_from_world * self.origin.as_dvec3().extend(1.0)).xyz();
        let camera = Self::assemble(
            self.clip_from_world_f64 * world_from_model,
            eye,
            origin,
            self.near_clip,
            self.viewport,
        );
        (camera.clip_from_world_f64.is_finite() && camera.eye_f64.is_finite()).then_some(camera)
    }

    /// Like [`new`](Self::new), from the camera's world transform (`world_from_view`, e.g.
    /// Bevy's `GlobalTransform::to_matrix()`) instead of the view matrix.
    ///
    /// # Errors
    ///
    /// As [`new`](Self::new).
    pub fn from_world_from_view(
        world_from_view: Mat4,
        clip_from_view: Mat4,
        viewport_size: Vec2,
    ) -> Result<Self, BudgetError> {
        let det = world_from_view.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(BudgetError::InvalidCamera(
                "the camera transform is not invertible",
            ));
        }
        let view = DMat4::inverse(&world_from_view.as_dmat4()).as_mat4();
        Self::new(view, clip_from_view, viewport_size)
    }

    /// The viewport's area in pixels², the most [`projected_area`](Self::projected_area) returns.
    #[inline]
    #[must_use]
    pub fn viewport_area(&self) -> f32 {
        self.viewport.x * self.viewport.y
    }

    /// The viewport size in pixels.
    #[inline]
    #[must_use]
    pub fn viewport_size(&self) -> Vec2 {
        self.viewport
    }

    /// Whether the projection is orthographic (its eye is at infinity).
    #[inline]
    #[must_use]
    pub fn is_orthographic(&self) -> bool {
        self.eye.w == 0.0
    }

    /// The centre of projection in world space (in the model's space for a camera from
    /// [`for_model`](Self::for_model)): `(position, 1)` for a perspective camera,
    /// `(unit direction towards the viewer, 0)` for an orthographic one.
    #[inline]
    #[must_use]
    pub fn eye(&self) -> Vec4 {
        self.eye
    }

    /// [`projected_area`](Self::projected_area) of every box in `obbs`, into `out` (one area
    /// per box, in order), about three times faster per box for boxes in view. Four boxes at
    /// a time go through the common case (wholly off-screen, or wholly in view and not thin)
    /// on the four lanes of a SIMD vector; the others go through `projected_area` one by
    /// one. The common case is measured by faces, not by the outline, so its areas can differ
    /// from `projected_area`'s in the last bits (both are within about 1e-6 of the exact
    /// area; the tests hold them to 1e-5).
    ///
    /// ```
    /// use bevy_aslod::budget::{Obb, ProjectedAreaCamera};
    /// use glam::{Mat3, Mat4, Vec2, Vec3};
    ///
    /// let view = Mat4::look_at_rh(Vec3::new(0.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y);
    /// let projection = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1);
    /// let camera = ProjectedAreaCamera::new(view, projection, Vec2::new(1920.0, 1080.0)).unwrap();
    /// let boxes: Vec<Obb> = (0..7)
    ///     .map(|i| Obb::new(Vec3::new(i as f32 - 3.0, 0.0, -2.0 * i as f32), Mat3::IDENTITY, Vec3::splat(0.5)))
    ///     .collect();
    /// let mut areas = vec![0.0; boxes.len()];
    /// camera.projected_areas(&boxes, &mut areas);
    /// for (obb, &area) in boxes.iter().zip(&areas) {
    ///     let single = camera.projected_area(obb);
    ///     assert!((area - single).abs() <= 1e-5 * single);
    /// }
    /// ```
    ///
    /// # Panics
    /// Panics when `out` is shorter than `obbs`.
    pub fn projected_areas(&self, obbs: &[Obb], out: &mut [f32]) {
        assert!(
            out.len() >= obbs.len(),
            "{} boxes but room for {} areas",
            obbs.len(),
            out.len()
        );
        let lanes = Lanes::new(
            self.clip_from_world,
            self.origin,
            self.origin_clip,
            self.near,
            self.ndc_to_pixels,
        );
        for (boxes, out) in obbs.chunks(4).zip(out.chunks_mut(4)) {
            // A short last chunk repeats its first box in the spare lanes.
            let quad = std::array::from_fn(|k| boxes.get(k).unwrap_or(&boxes[0]));
            let (areas, done) = lanes.areas(quad);
            for (k, (slot, obb)) in out.iter_mut().zip(boxes).enumerate() {
                *slot = if (done >> k) & 1 == 1 {
                    areas[k]
                } else {
                    self.projected_area(obb)
                };
            }
        }
    }

    /// The area in pixels² that `obb` covers on the viewport: clipped to the near plane and to
    /// the viewport, `0` for a box wholly behind the camera or off-screen. A box the eye is
    /// inside covers the whole viewport (when it reaches past the near plane).
    ///
    /// Flat boxes (a zero half extent) are fine. A box with a non-finite field gives an
    /// unspecified value, possibly NaN, which [`allocate`](super::allocate) rejects.
    #[must_use]
    pub fn projected_area(&self, obb: &Obb) -> f32 {
        let Reach {
            c,
            a,
            near_c,
            near_r,
            sides_c,
            sides_r,
        } = self.reach(obb);
        if near_c + near_r <= 0.0 {
            return 0.0; // wholly behind the near plane
        }
        if (sides_c + sides_r).cmplt(Vec4::ZERO).any() {
            return 0.0; // wholly outside one side of the view
        }
        if near_c - near_r < 0.0 {
            return (self.straddling_area(obb) * f64::from(self.ndc_to_pixels)) as f32;
        }

        // The eye in the box's frame, against the faces: the 1999 method.
        let e = self.eye;
        let local = obb.axes.transpose() * (e.xyz() - obb.center * e.w);
        let bound = obb.half_extents * e.w;
        const SPREAD: [u8; 8] = [0, 1, 4, 5, 16, 17, 20, 21];
        let below = SPREAD[local.cmplt(-bound).bitmask() as usize];
        let above = SPREAD[local.cmpgt(bound).bitmask() as usize];
        let outline = silhouette(below | (above << 1));
        if (sides_c - sides_r).cmpge(Vec4::ZERO).all() {
            // Wholly inside the viewport (give or take the f32 rounding of the test): no
            // clipping, and the outline is measured around the centre's projection.
            if let Some(area) = scalar::outline_area(c, &a, outline) {
                return area * self.ndc_to_pixels;
            }
        }

        // The box in clip space again, in f64, for clipped outlines and thin ones. In f32 the
        // corners (centre ± half axes) round to the centre's magnitude, most of the outline's
        // size for a small box far away, and the clipped sliver of a box at the viewport's edge
        // moves with every rounding of its position.
        let (c, a) = self.clip_box_f64(obb);
        let area = scalar::clipped_outline_area(c, &a, outline);
        (area * f64::from(self.ndc_to_pixels)) as f32
    }

    /// Whether some of `obb` may be in view: false when it lies wholly behind the near plane
    /// or wholly outside a side of the view, where [`projected_area`](Self::projected_area)
    /// is 0 (the first tests it makes, five dot products). True does not promise a positive
    /// area: a flat box seen edge-on has none.
    ///
    /// ```
    /// use bevy_aslod::budget::{Obb, ProjectedAreaCamera};
    /// use glam::{Mat3, Mat4, Vec2, Vec3};
    ///
    /// let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y);
    /// let projection = Mat4::perspective_infinite_reverse_rh(1.0, 1.0, 0.1);
    /// let camera = ProjectedAreaCamera::new(view, projection, Vec2::splat(512.0)).unwrap();
    /// let ahead = Obb::new(Vec3::ZERO, Mat3::IDENTITY, Vec3::splat(1.0));
    /// let behind = Obb::new(Vec3::new(0.0, 0.0, 20.0), Mat3::IDENTITY, Vec3::splat(1.0));
    /// assert!(camera.may_see(&ahead) && !camera.may_see(&behind));
    /// assert_eq!(camera.projected_area(&behind), 0.0);
    /// ```
    #[must_use]
    pub fn may_see(&self, obb: &Obb) -> bool {
        let r = self.reach(obb);
        r.near_c + r.near_r > 0.0 && (r.sides_c + r.sides_r).cmpge(Vec4::ZERO).all()
    }

    /// The box in clip space (centre and half axes), and the ranges over it of the near
    /// plane and of the four side planes `w ± x`, `w ± y`: a linear function's range over a
    /// box is its value at the centre ± Σ |value at the half axes|.
    #[inline]
    fn reach(&self, obb: &Obb) -> Reach {
        let m = self.clip_from_world;
        let h = obb.half_extents;
        let c = m * (obb.center - self.origin).extend(0.0) + self.origin_clip;
        let a = [
            m * (obb.axes.x_axis * h.x).extend(0.0),
            m * (obb.axes.y_axis * h.y).extend(0.0),
            m * (obb.axes.z_axis * h.z).extend(0.0),
        ];
        let n = self.near.xyz();
        let near_c = n.dot(obb.center - self.origin) + self.near.w;
        let near_a = [
            n.dot(obb.axes.x_axis * h.x),
            n.dot(obb.axes.y_axis * h.y),
            n.dot(obb.axes.z_axis * h.z),
        ];
        let near_r = near_a[0].abs() + near_a[1].abs() + near_a[2].abs();
        let sides = |v: Vec4| Vec4::splat(v.w) + Vec4::new(v.x, -v.x, v.y, -v.y);
        Reach {
            c,
            a,
            near_c,
            near_r,
            sides_c: sides(c),
            sides_r: sides(a[0]).abs() + sides(a[1]).abs() + sides(a[2]).abs(),
        }
    }

    /// The box's centre and half axes in clip space, in `f64`.
    #[inline]
    fn clip_box_f64(&self, obb: &Obb) -> (DVec4, [DVec4; 3]) {
        let m = self.clip_from_world_f64;
        let h = obb.half_extents.as_dvec3();
        let offset = obb.center.as_dvec3() - self.origin.as_dvec3();
        let c = m * offset.extend(0.0) + self.origin_clip_f64;
        let a = [
            m * (obb.axes.x_axis.as_dvec3() * h.x).extend(0.0),
            m * (obb.axes.y_axis.as_dvec3() * h.y).extend(0.0),
            m * (obb.axes.z_axis.as_dvec3() * h.z).extend(0.0),
        ];
        (c, a)
    }

    /// The NDC area of a box that straddles the near plane ([`clip::front_area`]). All in
    /// `f64`: the cut can run close to the eye, where `f32` loses the digits that matter.
    #[cold]
    fn straddling_area(&self, obb: &Obb) -> f64 {
        let (c, a) = self.clip_box_f64(obb);
        let h = obb.half_extents.as_dvec3();
        let offset = obb.center.as_dvec3() - self.origin.as_dvec3();
        let axes = [
            obb.axes.x_axis.as_dvec3() * h.x,
            obb.axes.y_axis.as_dvec3() * h.y,
            obb.axes.z_axis.as_dvec3() * h.z,
        ];
        let n = self.near_f64.xyz();
        let near_c = n.dot(offset) + self.near_f64.w;
        let near_a = axes.map(|v| n.dot(v));
        clip::front_area(c, &a, near_c, &near_a)
    }
}

/// A box against a camera's view ([`ProjectedAreaCamera::reach`]).
struct Reach {
    /// Centre and half axes in clip space.
    c: Vec4,
    a: [Vec4; 3],
    /// The near plane at the centre, and its range over the box.
    near_c: f32,
    near_r: f32,
    /// The side planes `w + x`, `w − x`, `w + y`, `w − y` at the centre, and their ranges.
    sides_c: Vec4,
    sides_r: Vec4,
}

/// The null vector of three 4-vectors (the generalised cross product): orthogonal to all three.
fn null_vector(a: DVec4, b: DVec4, c: DVec4) -> DVec4 {
    let det3 = |p: DVec3, q: DVec3, r: DVec3| p.dot(q.cross(r));
    DVec4::new(
        det3(a.yzw(), b.yzw(), c.yzw()),
        -det3(a.xzw(), b.xzw(), c.xzw()),
        det3(a.xyw(), b.xyw(), c.xyw()),
        -det3(a.xyz(), b.xyz(), c.xyz()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_recognise_their_projection() {
        let view = Mat4::look_at_rh(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y);
        let size = Vec2::new(800.0, 600.0);
        let eye = Vec3::new(1.0, 2.0, 3.0);
        let forward = -eye.normalize();
        for (projection, ortho) in [
            (Mat4::perspective_rh(1.0, 1.3, 0.1, 100.0), false),
            (Mat4::perspective_infinite_reverse_rh(1.0, 1.3, 0.1), false),
            (Mat4::orthographic_rh(-2.0, 2.0, -1.0, 1.0, 0.1, 50.0), true),
            (Mat4::orthographic_rh(-2.0, 2.0, -1.0, 1.0, 50.0, 0.1), true),
        ] {
            let camera = ProjectedAreaCamera::new(view, projection, size).unwrap();
            assert_eq!(camera.is_orthographic(), ortho);
            // The near plane is 0.1 in front of the eye, facing forward.
            let depth = |p: Vec3| camera.near.xyz().dot(p - camera.origin) + camera.near.w;
            assert!(depth(eye + forward * 0.09) < 0.0 && depth(eye + forward * 0.11) > 0.0);
            assert!(camera.near.xyz().normalize().distance(forward) < 1e-5);
            if ortho {
                let toward_viewer = Vec3::new(1.0, 2.0, 3.0).normalize();
                assert!(camera.eye.xyz().distance(toward_viewer) < 1e-6);
            } else {
                assert!(camera.eye.distance(Vec4::new(1.0, 2.0, 3.0, 1.0)) < 1e-5);
            }
        }
        assert!(ProjectedAreaCamera::new(view, Mat4::ZERO, size).is_err());
        assert!(ProjectedAreaCamera::new(view, Mat4::IDENTITY, Vec2::new(0.0, 1.0)).is_err());
        assert!(ProjectedAreaCamera::new(Mat4::ZERO, Mat4::IDENTITY, size).is_err());
        assert!(
            ProjectedAreaCamera::new(view, Mat4::from_cols_array(&[f32::NAN; 16]), size).is_err()
        );
    }

    #[test]
    fn oblique_near_plane_is_honoured() {
        // Bevy's mirror cameras replace the z row so that reverse-Z's near plane w − z = 0 is
        // an arbitrary view-space plane C (Lengyel 2005): row z = row w − C.
        let mut projection = Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1);
        let plane = Vec4::new(0.4, 0.1, -1.0, -2.0); // C · (x, 1) ≥ 0 is visible
        let rows = [0, 1, 2, 3].map(|r| projection.row(r));
        let z_row = rows[3] - plane;
        projection = Mat4::from_cols(rows[0], rows[1], z_row, rows[3]).transpose();
        let camera = ProjectedAreaCamera::new(Mat4::IDENTITY, projection, Vec2::ONE).unwrap();
        for p in [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(3.0, 0.0, -3.0),
            Vec3::new(-3.0, 1.0, -1.0),
            Vec3::new(0.5, -2.0, -2.5),
        ] {
            let ours = camera.near.xyz().dot(p - camera.origin) + camera.near.w;
            let theirs = plane.dot(p.extend(1.0));
            assert_eq!(ours >= 0.0, theirs >= 0.0, "{p}: {ours} vs {theirs}");
            assert!((ours - theirs).abs() < 1e-5 * theirs.abs().max(1.0));
        }
    }
}
