//! The camera a refinement is made for, in the mesh's own space.

use super::RefineError;
use glam::{DVec3, DVec4, Mat4, Vec3, Vec4};

/// A perspective camera in the mesh's local space: its eye, its frustum planes and how many
/// pixels a length covers at a given distance. It need not be the camera that draws the
/// mesh: a second ("phantom") camera may drive the refinement while another one looks at the
/// result, as in Güdükbay et al.'s Visualizer.
///
/// ```
/// use bevy_aslod::refine::View;
/// use glam::Vec3;
///
/// // 60° vertical field of view, 800×600 pixels, looking down -Z from z = 5.
/// let view = View::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, Vec3::Y,
///     60f32.to_radians(), 800.0 / 600.0, 0.1, 600.0)?;
/// // A length of 0.01 at distance 5 covers about 1 pixel.
/// assert!((view.pixels_at(0.01, 5.0) - 1.04).abs() < 0.01);
/// # Ok::<(), bevy_aslod::refine::RefineError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    eye: DVec3,
    /// Inward-facing planes, normalised: a point is inside when `dot(plane, (p, 1)) >= 0`.
    planes: [DVec4; 6],
    plane_count: usize,
    /// Pixels covered by a unit length at unit distance.
    pixels: f64,
}

impl View {
    /// A perspective camera at `eye` looking along `forward` (`up` gives the roll), with a
    /// vertical field of view `fov_y` (radians), an aspect ratio (width / height), a near
    /// plane distance and no far plane, drawn `viewport_height` pixels high.
    ///
    /// # Errors
    /// [`RefineError::InvalidCamera`] when a value is not finite, the field of view is not
    /// in `(0, π)`, the aspect ratio, near distance or viewport height is not positive, or
    /// `forward` and `up` are zero or parallel.
    pub fn perspective(
        eye: Vec3,
        forward: Vec3,
        up: Vec3,
        fov_y: f32,
        aspect: f32,
        near: f32,
        viewport_height: f32,
    ) -> Result<Self, RefineError> {
        if !(eye.is_finite() && forward.is_finite() && up.is_finite()) {
            return Err(RefineError::InvalidCamera(
                "the eye, forward or up vector is not finite",
            ));
        }
        if !(fov_y > 0.0 && fov_y < std::f32::consts::PI) {
            return Err(RefineError::InvalidCamera(
                "the field of view must be between 0 and π radians",
            ));
        }
        if !(aspect > 0.0 && aspect.is_finite() && near > 0.0 && near.is_finite()) {
            return Err(RefineError::InvalidCamera(
                "the aspect ratio and the near distance must be positive and finite",
            ));
        }
        let (Some(f), Some(u)) = (forward.try_normalize(), up.try_normalize()) else {
            return Err(RefineError::InvalidCamera("forward or up is a zero vector"));
        };
        if f.cross(u).length() < 1e-6 {
            return Err(RefineError::InvalidCamera("forward and up are parallel"));
        }
        let clip_from_view = Mat4::perspective_infinite_reverse_rh(fov_y, aspect, near);
        let view_from_local = Mat4::look_to_rh(eye, f, u);
        Self::from_clip_from_local(clip_from_view * view_from_local, viewport_height)
    }

    /// The camera of a perspective projection matrix from the mesh's local space to clip
    /// space (`clip_from_view * view_from_world * world_from_local`, depth in `0..=1` either
    /// way round, as Bevy and wgpu use), drawn `viewport_height` pixels high. The eye is the
    /// matrix's centre of projection. Scales in the matrix are fine: a uniformly scaled
    /// model refines as it looks.
    ///
    /// # Errors
    /// [`RefineError::InvalidCamera`] when the matrix is not finite, is orthographic or
    /// singular, or the viewport height is not positive and finite.
    pub fn from_clip_from_local(
        clip_from_local: Mat4,
        viewport_height: f32,
    ) -> Result<Self, RefineError> {
        if !clip_from_local.is_finite() {
            return Err(RefineError::InvalidCamera("the matrix is not finite"));
        }
        if !(viewport_height > 0.0 && viewport_height.is_finite()) {
            return Err(RefineError::InvalidCamera(
                "the viewport height must be positive and finite",
            ));
        }
        let m = clip_from_local.as_dmat4();
        let row = |i: usize| DVec4::new(m.x_axis[i], m.y_axis[i], m.z_axis[i], m.w_axis[i]);
        let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
        if r3.truncate().length() < 1e-12 {
            return Err(RefineError::InvalidCamera(
                "orthographic projections are not supported",
            ));
        }
        // The eye projects to x = y = w = 0.
        let a = glam::DMat3::from_cols(r0.truncate(), r1.truncate(), r3.truncate()).transpose();
        if a.determinant().abs() < 1e-300 {
            return Err(RefineError::InvalidCamera("the matrix is singular"));
        }
        let eye = a.inverse() * -DVec3::new(r0.w, r1.w, r3.w);
        let pixels =
            0.5 * f64::from(viewport_height) * r1.truncate().length() / r3.truncate().length();
        let mut planes = [DVec4::ZERO; 6];
        let mut plane_count = 0;
        for p in [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2] {
            let len = p.truncate().length();
            // An infinite far plane is a plane at infinity (no normal): skip it.
            if len > 1e-12 * p.w.abs().max(1.0) {
                planes[plane_count] = p / len;
                plane_count += 1;
            }
        }
        if !(eye.is_finite() && pixels.is_finite() && pixels > 0.0) {
            return Err(RefineError::InvalidCamera("the matrix is degenerate"));
        }
        Ok(Self {
            eye,
            planes,
            plane_count,
            pixels,
        })
    }

    /// The eye, in the mesh's local space.
    #[inline]
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.eye.as_vec3()
    }

    /// The frustum's planes (normalised, facing inwards: `dot(plane, (p, 1)) >= 0` inside),
    /// without the far plane when there is none.
    #[must_use]
    pub fn planes(&self) -> Vec<Vec4> {
        self.planes[..self.plane_count]
            .iter()
            .map(|p| p.as_vec4())
            .collect()
    }

    /// Pixels covered by a length `length` seen face-on at distance `distance`.
    #[inline]
    #[must_use]
    pub fn pixels_at(&self, length: f32, distance: f32) -> f64 {
        f64::from(length) * self.pixels / f64::from(distance)
    }

    /// Whether the sphere lies wholly outside one of the frustum's planes.
    #[inline]
    pub(crate) fn sphere_outside(&self, centre: DVec3, radius: f64) -> bool {
        self.planes[..self.plane_count]
            .iter()
            .any(|p| p.truncate().dot(centre) + p.w < -radius)
    }

    /// The most pixels a length `length` covers anywhere in the sphere: infinite when the eye
    /// is inside it.
    #[inline]
    pub(crate) fn max_pixels(&self, length: f64, centre: DVec3, radius: f64) -> f64 {
        let distance = centre.distance(self.eye) - radius;
        if length <= 0.0 {
            0.0
        } else if distance <= 0.0 {
            f64::INFINITY
        } else {
            length * self.pixels / distance
        }
    }

    /// The least and the largest `n · (p - eye)` over the points `p` of a sphere and the unit
    /// normals `n` of a cone (axis, cosine and sine of its half-angle): both positive when
    /// everything faces away from the eye, both negative when everything faces it.
    #[inline]
    pub(crate) fn facing(
        &self,
        centre: DVec3,
        radius: f64,
        axis: DVec3,
        cos: f64,
        sin: f64,
    ) -> (f64, f64) {
        let d = centre - self.eye;
        let (lo, hi) = cone_dot_range(d, axis, cos, sin);
        (lo - radius, hi + radius)
    }
}

/// The least and largest `n · d` over the unit vectors `n` of a cone (axis, cosine and sine of
/// the half-angle).
#[inline]
pub(crate) fn cone_dot_range(d: DVec3, axis: DVec3, cos: f64, sin: f64) -> (f64, f64) {
    let len = d.length();
    if len == 0.0 {
        return (0.0, 0.0);
    }
    let c = (axis.dot(d) / len).clamp(-1.0, 1.0);
    let s = (1.0 - c * c).max(0.0).sqrt();
    // The angle φ between the axis and d against the half-angle θ: the least is cos(φ + θ)
    // (or -1 past π), the largest cos(φ - θ) (or 1 when d is inside the cone).
    let lo = if c <= -cos { -1.0 } else { c * cos - s * sin };
    let hi = if c >= cos { 1.0 } else { c * cos + s * sin };
    (len * lo, len * hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_cameras_are_errors() {
        let eye = Vec3::new(0.0, 0.0, 5.0);
        let ok = |fov: f32, near: f32, h: f32| {
            View::perspective(eye, Vec3::NEG_Z, Vec3::Y, fov, 1.0, near, h)
        };
        assert!(ok(1.0, 0.1, 600.0).is_ok());
        assert!(ok(0.0, 0.1, 600.0).is_err());
        assert!(ok(f32::NAN, 0.1, 600.0).is_err());
        assert!(ok(1.0, 0.0, 600.0).is_err());
        assert!(ok(1.0, 0.1, 0.0).is_err());
        assert!(View::perspective(Vec3::NAN, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 600.0).is_err());
        assert!(View::perspective(eye, Vec3::Y, Vec3::Y, 1.0, 1.0, 0.1, 600.0).is_err());
        assert!(View::perspective(eye, Vec3::ZERO, Vec3::Y, 1.0, 1.0, 0.1, 600.0).is_err());
        let ortho = Mat4::orthographic_rh(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0);
        assert!(View::from_clip_from_local(ortho, 600.0).is_err());
    }

    #[test]
    fn the_eye_and_the_planes_come_from_the_matrix() {
        let eye = Vec3::new(1.0, 2.0, 3.0);
        let view = View::perspective(
            eye,
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::Y,
            1.0,
            1.5,
            0.1,
            600.0,
        )
        .unwrap();
        assert!(view.eye().distance(eye) < 1e-4);
        // Four sides and the near plane; the far plane is at infinity.
        assert_eq!(view.planes().len(), 5);
        assert!(!view.sphere_outside(DVec3::new(1.0, 2.0, -5.0), 0.1));
        assert!(view.sphere_outside(DVec3::new(1.0, 2.0, 10.0), 0.1));
        assert!(view.sphere_outside(DVec3::new(100.0, 2.0, -5.0), 1.0));
        // A sphere reaching into the frustum is not outside.
        assert!(!view.sphere_outside(DVec3::new(1.0, 2.0, 4.0), 2.0));
        // 1 / tan(0.5) * 300 pixels per unit at unit distance.
        let expected = 300.0 / 0.5f64.tan();
        assert!((view.pixels_at(1.0, 1.0) - expected).abs() < 1e-3 * expected);
    }

    #[test]
    fn cone_ranges_bound_every_normal() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let axis = DVec3::new(next(), next(), next()).normalize();
            let theta = (next() + 1.0) * 1.5;
            let d = DVec3::new(next(), next(), next()) * 3.0;
            let (lo, hi) = cone_dot_range(d, axis, theta.cos(), theta.sin());
            for _ in 0..50 {
                let n = DVec3::new(next(), next(), next()).normalize();
                if n.dot(axis).acos() <= theta {
                    let v = n.dot(d);
                    assert!(v >= lo - 1e-9 && v <= hi + 1e-9);
                }
            }
        }
    }
}
