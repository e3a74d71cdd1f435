//! The screen area of an oriented box; the method is on [`ProjectedAreaCamera`].

use super::{BudgetError, Obb};
use glam::{
    Affine3A, BVec4A, DMat4, DVec2, DVec3, DVec4, Mat4, Vec2, Vec3, Vec3A, Vec3Swizzles, Vec4,
    Vec4Swizzles,
};

/// The face planes, one bit each, in the order of the [`silhouette`] code: bit `2k` is set
/// when the eye is below the box on axis `k` (it sees the `−k` face), bit `2k + 1` when it is
/// above (it sees the `+k` face).
const fn face_loop(axis: usize, positive: bool) -> [u8; 4] {
    // With u = k+1, v = k+2 (cyclic), e_u × e_v = e_k, so (u, v) = (0,0) (1,0) (1,1) (0,1) runs
    // counter-clockwise seen from +k, and the reverse from −k.
    let u = (axis + 1) % 3;
    let v = (axis + 2) % 3;
    let base = if positive { 1u8 << axis } else { 0 };
    let uv: [(u8, u8); 4] = if positive {
        [(0, 0), (1, 0), (1, 1), (0, 1)]
    } else {
        [(0, 0), (0, 1), (1, 1), (1, 0)]
    };
    let mut out = [0u8; 4];
    let mut i = 0;
    while i < 4 {
        out[i] = base | (uv[i].0 << u) | (uv[i].1 << v);
        i += 1;
    }
    out
}

/// The outline for one code: `[len, c0, c1, …]`, `len` 0 for the 38 codes that cannot occur
/// with the eye outside the box.
const fn silhouette_row(code: usize) -> [u8; 7] {
    let mut row = [0u8; 7];
    if code == 0 {
        return row; // the eye is inside the box
    }
    let mut axis = 0;
    while axis < 3 {
        if (code >> (2 * axis)) & 3 == 3 {
            return row; // below and above the same axis at once
        }
        axis += 1;
    }
    // The directed boundary edges of every visible face, each face counter-clockwise from
    // outside. An edge shared by two visible faces appears once in each direction.
    let mut from = [0u8; 12];
    let mut to = [0u8; 12];
    let mut n = 0;
    axis = 0;
    while axis < 3 {
        let mut side = 0;
        while side < 2 {
            if (code >> (2 * axis + side)) & 1 == 1 {
                let face = face_loop(axis, side == 1);
                let mut e = 0;
                while e < 4 {
                    from[n] = face[e];
                    to[n] = face[(e + 1) % 4];
                    n += 1;
                    e += 1;
                }
            }
            side += 1;
        }
        axis += 1;
    }
    // The outline is what is left after the shared edges cancel.
    let mut keep = [false; 12];
    let mut start = u8::MAX;
    let mut i = 0;
    while i < n {
        keep[i] = true;
        let mut j = 0;
        while j < n {
            if from[j] == to[i] && to[j] == from[i] {
                keep[i] = false;
            }
            j += 1;
        }
        if keep[i] && from[i] < start {
            start = from[i];
        }
        i += 1;
    }
    // Chain the kept edges into a loop, starting from the lowest corner.
    let mut len = 0;
    let mut current = start;
    loop {
        row[1 + len] = current;
        len += 1;
        let mut next = u8::MAX;
        let mut k = 0;
        while k < n {
            if keep[k] && from[k] == current {
                next = to[k];
            }
            k += 1;
        }
        current = next;
        if current == start || len == 6 {
            break;
        }
    }
    row[0] = len as u8;
    row
}

const fn build_silhouette_table() -> [[u8; 7]; 64] {
    let mut table = [[0u8; 7]; 64];
    let mut code = 0;
    while code < 64 {
        table[code] = silhouette_row(code);
        code += 1;
    }
    table
}

/// Generated at compile time from the face geometry above; checked against projected corner
/// hulls in the tests.
static SILHOUETTE: [[u8; 7]; 64] = build_silhouette_table();

/// The box corners on the outline seen from an eye with face code `code` (only the low six bits
/// count), in counter-clockwise order as seen from the eye, starting at the lowest corner.
/// Corners are numbered as in [`Obb::corner`].
///
/// Bit `2k` of the code is set when the eye is below the box on axis `k` (`x < min`), bit
/// `2k + 1` when it is above (`x > max`). Of the 64 codes, 26 can occur with the eye outside
/// the box: 6 see one face and give 4 corners, 12 see two faces and 8 see three, which give 6.
/// The others (the eye inside, or on both sides of an axis) give an empty slice.
///
/// ```
/// use bevy_aslod::budget::silhouette;
///
/// // Eye above the box on z only: the outline is the +z face.
/// assert_eq!(silhouette(0b10_0000), &[4, 5, 7, 6]);
/// assert_eq!((0..64).filter(|&c| !silhouette(c).is_empty()).count(), 26);
/// ```
#[inline]
#[must_use]
pub fn silhouette(code: u8) -> &'static [u8] {
    let row = &SILHOUETTE[usize::from(code & 63)];
    &row[1..1 + usize::from(row[0])]
}

/// A camera prepared for [`projected_area`](Self::projected_area): build one per camera per
/// frame, then query every box. Areas are in pixels² of the viewport it was made with.
///
/// # Method
///
/// Schmalstieg & Tobler, "Fast projected area computation for three-dimensional bounding
/// boxes" (1999), made exact for what the 1999 method leaves out. The eye, moved into the
/// box's frame, lies outside some of the six face planes. One bit per
/// plane gives a 6-bit code; the code picks a row of a 64-entry table that lists the corners of
/// the box's outline in order ([`silhouette`]). Only those 4 or 6 corners are projected, and the
/// shoelace formula gives the outline's area. Beyond the paper:
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
        let lanes = Lanes::new(self);
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
            if let Some(area) = outline_area(c, &a, outline) {
                return area * self.ndc_to_pixels;
            }
        }

        // The box in clip space again, in f64, for clipped outlines and thin ones. In f32 the
        // corners (centre ± half axes) round to the centre's magnitude, most of the outline's
        // size for a small box far away, and the clipped sliver of a box at the viewport's edge
        // moves with every rounding of its position.
        let (c, a) = self.clip_box_f64(obb);
        let sides = |v: DVec4| DVec4::splat(v.w) + DVec4::new(v.x, -v.x, v.y, -v.y);
        let sides_r = sides(a[0]).abs() + sides(a[1]).abs() + sides(a[2]).abs();
        let inside = (sides(c) - sides_r).cmpge(DVec4::ZERO);
        let mut corners = [DVec2::ZERO; 6];
        for (slot, &corner) in corners.iter_mut().zip(outline) {
            let v = corner_clip(c, &a, corner);
            *slot = v.xy() / v.w;
        }
        let corners = &corners[..outline.len()];
        let area = if inside.all() {
            shoelace(corners)
        } else {
            let mut polygon = Polygon::new();
            for &p in corners {
                polygon.push(p);
            }
            polygon.clip_to_viewport(inside.bitmask());
            polygon.area()
        };
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

    /// The NDC area of a box that straddles the near plane: the hull of the projected corners
    /// in front of it and of the points where its edges cross it. All in `f64`: the cut can
    /// run close to the eye, where `f32` loses the digits that matter.
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
        let corners: [DVec4; 8] = std::array::from_fn(|i| corner_clip(c, &a, i as u8));
        let depth: [f64; 8] = std::array::from_fn(|i| corner_clip(near_c, &near_a, i as u8));
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

/// A camera's constants, each splat across the four lanes of a [`Vec4`], for measuring four
/// boxes at once (one per lane): the common case of [`ProjectedAreaCamera::projected_area`].
struct Lanes {
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
    #[inline]
    fn new(camera: &ProjectedAreaCamera) -> Self {
        let m = camera.clip_from_world;
        let columns = [m.x_axis, m.y_axis, m.z_axis];
        let row = |pick: fn(Vec4) -> f32| columns.map(|c| Vec4::splat(pick(c)));
        let o = camera.origin_clip;
        Self {
            m: [row(|c| c.x), row(|c| c.y), row(|c| c.w)],
            origin_clip: [o.x, o.y, o.w].map(Vec4::splat),
            origin: camera.origin.to_array().map(Vec4::splat),
            near: camera.near.to_array().map(Vec4::splat),
            ndc_to_pixels: Vec4::splat(camera.ndc_to_pixels),
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
    /// those boxes need [`ProjectedAreaCamera::projected_area`].
    ///
    /// No silhouette here: the outline of a convex body in front of the eye is covered
    /// twice by the projections of its six faces (once by the faces turned to the eye, once
    /// by those turned away), so the area is half the sum of the faces' unsigned projected
    /// areas, whichever are which. A projected face is a quadrilateral, whose area is half the
    /// cross product of its diagonals. The corners are measured relative to the projection of
    /// the box's centre, as in [`outline_area`], and the same two precision checks apply.
    #[inline(always)]
    fn areas(&self, boxes: [&Obb; 4]) -> (Vec4, u32) {
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

/// The NDC area of the outline `outline` (corner numbers, as [`silhouette`] gives them) of
/// a box with clip-space centre `c` and half axes `a`, wholly in front of the near plane.
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
fn outline_area(c: Vec4, a: &[Vec4; 3], outline: &[u8]) -> Option<f32> {
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

/// Corner `i` of a box with centre `c` and half axes `a` (in whatever space, or any linear
/// function of them): bit `k` of `i` picks `+a[k]`.
#[inline]
fn corner_clip<T>(c: T, a: &[T; 3], i: u8) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T>,
{
    let mut v = c;
    for (k, &ak) in a.iter().enumerate() {
        v = if (i >> k) & 1 == 1 { v + ak } else { v - ak };
    }
    v
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

/// The area of a simple polygon by the shoelace formula. The sum runs on offsets from the
/// first vertex, so a small polygon far from the origin keeps its digits.
#[inline]
fn shoelace(p: &[DVec2]) -> f64 {
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
struct Polygon {
    len: usize,
    points: [DVec2; Self::CAPACITY],
}

impl Polygon {
    const CAPACITY: usize = 24;

    #[inline]
    fn new() -> Self {
        Self {
            len: 0,
            points: [DVec2::ZERO; Self::CAPACITY],
        }
    }

    #[inline]
    fn push(&mut self, p: DVec2) {
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
    fn area(&self) -> f64 {
        shoelace(self.as_slice())
    }

    /// Sutherland–Hodgman against `x ≥ −1`, `x ≤ 1`, `y ≥ −1`, `y ≤ 1`, skipping the sides
    /// whose bit is set in `inside` (known not to cut the polygon).
    fn clip_to_viewport(&mut self, inside: u32) {
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

    /// The convex hull of the points (Andrew's monotone chain), counter-clockwise.
    fn convex_hull(&self) -> Polygon {
        let mut sorted = *self;
        let pts = &mut sorted.points[..sorted.len];
        // Insertion sort: at most 14 points.
        for i in 1..pts.len() {
            let mut j = i;
            while j > 0 && (pts[j - 1].x, pts[j - 1].y) > (pts[j].x, pts[j].y) {
                pts.swap(j - 1, j);
                j -= 1;
            }
        }
        let mut hull = Polygon::new();
        if pts.len() < 3 {
            for &p in pts.iter() {
                hull.push(p);
            }
            return hull;
        }
        let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
        let mut k = 0;
        let mut out = [DVec2::ZERO; Self::CAPACITY + 1];
        for &p in pts.iter() {
            while k >= 2 && cross(out[k - 2], out[k - 1], p) <= 0.0 {
                k -= 1;
            }
            out[k] = p;
            k += 1;
        }
        let lower = k + 1;
        for &p in pts.iter().rev().skip(1) {
            while k >= lower && cross(out[k - 2], out[k - 1], p) <= 0.0 {
                k -= 1;
            }
            out[k] = p;
            k += 1;
        }
        for &p in &out[..k.saturating_sub(1)] {
            hull.push(p);
        }
        hull
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_26_valid_codes() {
        let lens: Vec<usize> = (0..64u8).map(|c| silhouette(c).len()).collect();
        assert_eq!(lens.iter().filter(|&&l| l == 4).count(), 6);
        assert_eq!(lens.iter().filter(|&&l| l == 6).count(), 20);
        assert_eq!(lens.iter().filter(|&&l| l == 0).count(), 38);
        for code in 0..64u8 {
            let s = silhouette(code);
            let mut sorted = s.to_vec();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), s.len(), "code {code:06b} repeats a corner");
        }
    }

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
