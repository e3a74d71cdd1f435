//! What decides whether a collapse is performed: the [`Criterion`] trait and the built-ins.

use super::{RefineError, View};
use glam::{DVec3, Vec3};

/// The bounds of one collapse and of every collapse below it (those it depends on), in the
/// mesh's local space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// The collapse's index in the sequence (its level is `step + 1`).
    pub step: u32,
    /// Centre of the bounding sphere (near the vertex the collapse moves onto).
    pub center: Vec3,
    /// Radius of a sphere holding every triangle these collapses change, before and after.
    pub radius: f32,
    /// The largest geometric error of these collapses (the quadric and local error the
    /// builder ranked them by), in the mesh's units.
    pub error: f32,
    /// Axis of a cone holding the normals of those triangles.
    pub axis: Vec3,
    /// Half-angle of that cone, radians (`π`: any direction).
    pub cone_angle: f32,
    pub(crate) cone_cos: f32,
    pub(crate) cone_sin: f32,
}

impl Node {
    #[inline]
    fn centre(&self) -> DVec3 {
        self.center.as_dvec3()
    }

    /// Least and largest `n · (p - eye)` over the sphere and the cone.
    #[inline]
    fn facing(&self, view: &View) -> (f64, f64) {
        view.facing(
            self.centre(),
            f64::from(self.radius),
            self.axis.as_dvec3(),
            f64::from(self.cone_cos),
            f64::from(self.cone_sin),
        )
    }
}

/// Decides, collapse by collapse, whether a variable-resolution level performs it.
///
/// A criterion answers one question per collapse: may it be performed, because nothing it
/// looks at needs the detail the collapse removes? Each built-in answers from the collapse's
/// [`Node`] (a sphere, a cone of normals and an error bounding the collapse and every
/// collapse below it) and the [`View`]:
///
/// | criterion | performs a collapse when | units |
/// |---|---|---|
/// | [`Frustum`] | its sphere lies wholly outside the view frustum (Hoppe, Güdükbay) | — |
/// | [`BackFacing`] | every normal of its cone faces away from the eye from every point of its sphere (Hoppe's surface orientation) | — |
/// | [`ScreenSpaceError`] | its error, seen from the nearest point of its sphere, covers fewer than τ pixels | pixels |
/// | [`SphereOfInterest`] | its sphere does not meet a sphere of interest (MOM's experiment) | the mesh's units |
/// | [`Silhouette`] | it is wholly front-facing or wholly back-facing, so not on the silhouette (MOM) | — |
/// | [`Illumination`] | every normal of its cone faces away from a directional light: unlit (MOM) | — |
/// | [`LevelCut`] | it comes before a given level: a uniform level, for comparisons | collapses |
///
/// Criteria combine by [`Criteria`] (the built-ins, each on or off) or by tuples: a collapse
/// is performed when **any** criterion allows it, so every criterion is a reason to drop
/// detail and one with nothing to say keeps it (with no criterion at all, nothing
/// collapses). Each built-in is monotone: when it allows a collapse it allows every collapse
/// below it, whose bounds lie inside. The incremental extraction relies on that to match a
/// fresh one; a custom criterion that is not monotone still gives a crack-free mesh, but
/// [`VariableCache::update`](super::VariableCache::update) may then keep detail a fresh
/// extraction would drop.
pub trait Criterion {
    /// True when the collapse `node` may be performed (its detail is not needed), seen from
    /// `view`.
    fn coarsen(&self, node: &Node, view: &View) -> bool;

    /// Checks the criterion's settings before an extraction.
    ///
    /// # Errors
    /// A [`RefineError`] naming the setting that cannot be used. The default accepts
    /// everything.
    fn validate(&self) -> Result<(), RefineError> {
        Ok(())
    }
}

impl<C: Criterion + ?Sized> Criterion for &C {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        (**self).coarsen(node, view)
    }

    fn validate(&self) -> Result<(), RefineError> {
        (**self).validate()
    }
}

impl<C: Criterion + ?Sized> Criterion for Box<C> {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        (**self).coarsen(node, view)
    }

    fn validate(&self) -> Result<(), RefineError> {
        (**self).validate()
    }
}

/// Any of the criteria in a slice: a collapse is performed when one of them allows it.
impl<C: Criterion> Criterion for [C] {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        self.iter().any(|c| c.coarsen(node, view))
    }

    fn validate(&self) -> Result<(), RefineError> {
        self.iter().try_for_each(Criterion::validate)
    }
}

macro_rules! any_of_tuple {
    ($($name:ident $index:tt),+) => {
        /// Any of the criteria: a collapse is performed when one of them allows it.
        impl<$($name: Criterion),+> Criterion for ($($name,)+) {
            #[inline]
            fn coarsen(&self, node: &Node, view: &View) -> bool {
                $(self.$index.coarsen(node, view))||+
            }

            fn validate(&self) -> Result<(), RefineError> {
                $(self.$index.validate()?;)+
                Ok(())
            }
        }
    };
}

any_of_tuple!(A 0, B 1);
any_of_tuple!(A 0, B 1, C 2);
any_of_tuple!(A 0, B 1, C 2, D 3);

/// Performs collapses whose sphere lies wholly outside the view frustum: what the camera
/// cannot see keeps no detail.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Frustum;

impl Criterion for Frustum {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        view.sphere_outside(node.centre(), f64::from(node.radius))
    }
}

/// Performs collapses whose every normal faces away from the eye wherever in their sphere
/// the surface is: back faces keep no detail (Hoppe's surface orientation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BackFacing;

impl Criterion for BackFacing {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        node.facing(view).0 > 0.0
    }
}

/// Performs collapses whose error, projected from the nearest point of their sphere, covers
/// fewer than `tolerance` pixels. With a tolerance of 0 it performs none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenSpaceError {
    tolerance: f32,
}

impl ScreenSpaceError {
    /// The criterion with a tolerance of `tolerance_px` pixels.
    ///
    /// # Errors
    /// [`RefineError::InvalidTolerance`] when `tolerance_px` is NaN, infinite or negative.
    pub fn new(tolerance_px: f32) -> Result<Self, RefineError> {
        if tolerance_px.is_finite() && tolerance_px >= 0.0 {
            Ok(Self {
                tolerance: tolerance_px,
            })
        } else {
            Err(RefineError::InvalidTolerance(tolerance_px))
        }
    }

    /// The tolerance, in pixels.
    #[inline]
    #[must_use]
    pub fn tolerance(&self) -> f32 {
        self.tolerance
    }
}

impl Criterion for ScreenSpaceError {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        view.max_pixels(f64::from(node.error), node.centre(), f64::from(node.radius))
            < f64::from(self.tolerance)
    }

    fn validate(&self) -> Result<(), RefineError> {
        Self::new(self.tolerance).map(|_| ())
    }
}

/// Performs collapses whose sphere does not meet the sphere of interest: detail stays inside
/// it only (MOM's interactive selection, and its Figure 7 experiment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereOfInterest {
    center: Vec3,
    radius: f32,
}

impl SphereOfInterest {
    /// A sphere of interest in the mesh's local space.
    ///
    /// # Errors
    /// [`RefineError::InvalidCriterion`] when the centre is not finite or the radius is NaN
    /// or negative (an infinite radius keeps every detail).
    pub fn new(center: Vec3, radius: f32) -> Result<Self, RefineError> {
        if !center.is_finite() {
            return Err(RefineError::InvalidCriterion(
                "the sphere of interest's centre is not finite",
            ));
        }
        if radius.is_nan() || radius < 0.0 {
            return Err(RefineError::InvalidCriterion(
                "the sphere of interest's radius is NaN or negative",
            ));
        }
        Ok(Self { center, radius })
    }
}

impl Criterion for SphereOfInterest {
    #[inline]
    fn coarsen(&self, node: &Node, _view: &View) -> bool {
        node.centre().distance(self.center.as_dvec3())
            > f64::from(node.radius) + f64::from(self.radius)
    }

    fn validate(&self) -> Result<(), RefineError> {
        Self::new(self.center, self.radius).map(|_| ())
    }
}

/// Performs collapses that are wholly front-facing or wholly back-facing: detail stays only
/// where the surface turns from the eye, on the silhouette (MOM's silhouette criterion).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Silhouette;

impl Criterion for Silhouette {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        let (lo, hi) = node.facing(view);
        lo > 0.0 || hi < 0.0
    }
}

/// Performs collapses whose every normal faces away from a directional light: detail stays
/// where the surface is lit (MOM's illumination criterion, its Figure 6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Illumination {
    to_light: Vec3,
}

impl Illumination {
    /// A directional light, `to_light` pointing from the surface towards it (any length).
    ///
    /// # Errors
    /// [`RefineError::InvalidCriterion`] when `to_light` is zero or not finite.
    pub fn new(to_light: Vec3) -> Result<Self, RefineError> {
        match to_light.try_normalize() {
            Some(to_light) => Ok(Self { to_light }),
            None => Err(RefineError::InvalidCriterion(
                "the light direction is zero or not finite",
            )),
        }
    }
}

impl Criterion for Illumination {
    #[inline]
    fn coarsen(&self, node: &Node, _view: &View) -> bool {
        let (_, hi) = super::view::cone_dot_range(
            self.to_light.as_dvec3(),
            node.axis.as_dvec3(),
            f64::from(node.cone_cos),
            f64::from(node.cone_sin),
        );
        hi < 0.0
    }

    fn validate(&self) -> Result<(), RefineError> {
        Self::new(self.to_light).map(|_| ())
    }
}

/// Performs every collapse before level `.0` and none after: the uniform level a
/// [`PolygonCache`](crate::multires::PolygonCache) would show, as a criterion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LevelCut(pub usize);

impl Criterion for LevelCut {
    #[inline]
    fn coarsen(&self, node: &Node, _view: &View) -> bool {
        (node.step as usize) < self.0
    }
}

/// The built-in criteria, each on or off: a collapse is performed when any one that is on
/// allows it. The default has every criterion off (the full-detail mesh).
///
/// ```
/// use bevy_aslod::refine::{Criteria, ScreenSpaceError};
/// // Hoppe's three criteria: out of view, facing away, or under one pixel of error.
/// let hoppe = Criteria::default()
///     .with_frustum(true)
///     .with_back_facing(true)
///     .with_screen_space(Some(ScreenSpaceError::new(1.0)?));
/// assert!(hoppe.frustum);
/// # Ok::<(), bevy_aslod::refine::RefineError>(())
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct Criteria {
    /// [`Frustum`]. Default: off.
    pub frustum: bool,
    /// [`BackFacing`]. Default: off.
    pub back_facing: bool,
    /// [`ScreenSpaceError`] with its tolerance. Default: off.
    pub screen_space: Option<ScreenSpaceError>,
    /// [`SphereOfInterest`]. Default: off.
    pub sphere_of_interest: Option<SphereOfInterest>,
    /// [`Silhouette`]. Default: off.
    pub silhouette: bool,
    /// [`Illumination`] with its light. Default: off.
    pub illumination: Option<Illumination>,
}

with_setters!(Criteria {
    frustum: bool => with_frustum,
    back_facing: bool => with_back_facing,
    screen_space: Option<ScreenSpaceError> => with_screen_space,
    sphere_of_interest: Option<SphereOfInterest> => with_sphere_of_interest,
    silhouette: bool => with_silhouette,
    illumination: Option<Illumination> => with_illumination,
});

impl Criterion for Criteria {
    #[inline]
    fn coarsen(&self, node: &Node, view: &View) -> bool {
        (self.frustum && Frustum.coarsen(node, view))
            || self.screen_space.is_some_and(|c| c.coarsen(node, view))
            || (self.back_facing && BackFacing.coarsen(node, view))
            || self
                .sphere_of_interest
                .is_some_and(|c| c.coarsen(node, view))
            || (self.silhouette && Silhouette.coarsen(node, view))
            || self.illumination.is_some_and(|c| c.coarsen(node, view))
    }

    fn validate(&self) -> Result<(), RefineError> {
        self.screen_space
            .as_ref()
            .map_or(Ok(()), Criterion::validate)?;
        self.sphere_of_interest
            .as_ref()
            .map_or(Ok(()), Criterion::validate)?;
        self.illumination
            .as_ref()
            .map_or(Ok(()), Criterion::validate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(center: Vec3, radius: f32, error: f32, axis: Vec3, angle: f32) -> Node {
        Node {
            step: 0,
            center,
            radius,
            error,
            axis,
            cone_angle: angle,
            cone_cos: angle.cos(),
            cone_sin: angle.sin(),
        }
    }

    fn view() -> View {
        View::perspective(
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::NEG_Z,
            Vec3::Y,
            1.0,
            1.0,
            0.1,
            600.0,
        )
        .unwrap()
    }

    #[test]
    fn each_criterion_decides_as_documented() {
        let v = view();
        let facing_eye = node(Vec3::ZERO, 0.1, 0.001, Vec3::Z, 0.2);
        let facing_away = node(Vec3::ZERO, 0.1, 0.001, Vec3::NEG_Z, 0.2);
        let edge_on = node(Vec3::ZERO, 0.1, 0.001, Vec3::X, 0.2);
        assert!(!Frustum.coarsen(&facing_eye, &v));
        assert!(Frustum.coarsen(&node(Vec3::new(0.0, 0.0, 20.0), 1.0, 0.0, Vec3::Z, 0.1), &v));
        assert!(!BackFacing.coarsen(&facing_eye, &v));
        assert!(BackFacing.coarsen(&facing_away, &v));
        assert!(!BackFacing.coarsen(&edge_on, &v));
        assert!(Silhouette.coarsen(&facing_eye, &v));
        assert!(Silhouette.coarsen(&facing_away, &v));
        assert!(!Silhouette.coarsen(&edge_on, &v));
        let light = Illumination::new(Vec3::Z).unwrap();
        assert!(!light.coarsen(&facing_eye, &v));
        assert!(light.coarsen(&facing_away, &v));
        // 0.001 at distance 9.9 covers about 0.055 pixels.
        assert!(ScreenSpaceError::new(0.1).unwrap().coarsen(&facing_eye, &v));
        assert!(
            !ScreenSpaceError::new(0.01)
                .unwrap()
                .coarsen(&facing_eye, &v)
        );
        assert!(!ScreenSpaceError::new(0.0).unwrap().coarsen(&facing_eye, &v));
        let sphere = SphereOfInterest::new(Vec3::new(3.0, 0.0, 0.0), 1.0).unwrap();
        assert!(sphere.coarsen(&facing_eye, &v));
        assert!(!sphere.coarsen(&node(Vec3::new(1.95, 0.0, 0.0), 0.1, 0.0, Vec3::Z, 0.1), &v));
        assert!(!Criteria::default().coarsen(&facing_away, &v));
        assert!(
            Criteria::default()
                .with_back_facing(true)
                .coarsen(&facing_away, &v)
        );
        assert!((Frustum, BackFacing).coarsen(&facing_away, &v));
        assert!(LevelCut(1).coarsen(&facing_eye, &v));
        assert!(!LevelCut(0).coarsen(&facing_eye, &v));
    }

    #[test]
    fn bad_settings_are_errors() {
        for t in [f32::NAN, f32::INFINITY, -1.0] {
            assert!(matches!(
                ScreenSpaceError::new(t),
                Err(RefineError::InvalidTolerance(_))
            ));
        }
        assert!(SphereOfInterest::new(Vec3::NAN, 1.0).is_err());
        assert!(SphereOfInterest::new(Vec3::ZERO, -1.0).is_err());
        assert!(SphereOfInterest::new(Vec3::ZERO, f32::INFINITY).is_ok());
        assert!(Illumination::new(Vec3::ZERO).is_err());
        assert!(Illumination::new(Vec3::INFINITY).is_err());
    }

    #[test]
    fn the_eye_inside_a_sphere_keeps_its_detail() {
        let v = view();
        let around_eye = node(Vec3::new(0.0, 0.0, 9.5), 1.0, 1e-6, Vec3::NEG_Z, 0.1);
        assert!(
            !ScreenSpaceError::new(1000.0)
                .unwrap()
                .coarsen(&around_eye, &v)
        );
        assert!(!BackFacing.coarsen(&around_eye, &v));
    }
}
