//! The first step of `Allocate`: the frame's cameras, as the allocation and the
//! view-dependent models see them ([`FrameCameras`]).

use super::components::{AslodStats, AslodViewport, PolygonBudget};
use crate::budget::ProjectedAreaCamera;
use bevy::camera::visibility::RenderLayers;
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// Marks the camera that view-dependent models refine for, active or not (Güdükbay et al.'s
/// phantom camera: it may drive the refinement while another camera looks at the result).
/// The first one found is used. Without a render target of its own (an inactive camera) it
/// takes the viewport height of [`AslodViewport`](super::AslodViewport) when there is one,
/// else of the first active camera; its projection is its own, so set its aspect ratio. Without one, each model refines for the active 3D camera
/// that sees its bounds largest, so in split screen every model is as fine as its nearest
/// view needs; a view that sees it smaller gets the same mesh.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct RefineCamera;

/// A camera marked with this takes no part in the budget split: a minimap, a
/// render-to-texture or a debug camera draws the levels the other cameras chose. (With
/// [`RefineCamera`] too, view-dependent models still refine for it.)
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct NoLodAllocation;

/// The weight of a camera's view in the budget split (default `1`): each region weighs the
/// largest of `weight × its projected area` over the cameras. A picture-in-picture view
/// might take `0.25`. A negative or non-finite weight counts as `0` (the camera then asks
/// for nothing), with a warning.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct LodCameraWeight(pub f32);

impl Default for LodCameraWeight {
    fn default() -> Self {
        Self(1.0)
    }
}

/// What the split needs to know of an active camera besides its projection.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct CameraShare {
    /// Its render layers: it weighs only the models on a layer it renders.
    pub(crate) layers: RenderLayers,
    /// Its [`LodCameraWeight`].
    pub(crate) weight: f32,
}

impl CameraShare {
    /// Whether a model on `layers` (none: the default layer) is drawn by this camera.
    pub(crate) fn sees(&self, layers: Option<&RenderLayers>) -> bool {
        self.layers
            .intersects(layers.unwrap_or(&RenderLayers::default()))
    }
}

/// This frame's cameras, gathered at the start of `Allocate`.
#[derive(Resource, Default)]
pub(crate) struct FrameCameras {
    /// Milliseconds `Allocate`'s systems took so far this frame (for
    /// [`AslodStats::allocation_ms`]).
    pub(crate) ms: f64,
    /// The active cameras' projected areas: the allocation weighs regions by what these see.
    pub(crate) active: Vec<ProjectedAreaCamera>,
    /// Each active camera's layers and weight, by `active`'s index.
    pub(crate) shares: Vec<CameraShare>,
    /// Each active camera's weight, by `active`'s index (the shares' weights as one slice,
    /// for the models every camera draws).
    pub(crate) weights: Vec<f32>,
    /// Whether every active camera renders the default layer and nothing else, at weight 1
    /// (then a model without layers is weighed by all of them as they are).
    pub(crate) plain: bool,
    /// The cameras view-dependent models may refine for.
    pub(crate) views: Vec<CameraView>,
}

/// A camera a view-dependent model may refine for.
#[derive(Clone, Debug)]
pub(crate) struct CameraView {
    pub(crate) entity: Entity,
    pub(crate) clip_from_world: Mat4,
    /// Viewport height in pixels.
    pub(crate) height: f32,
    /// Its projected areas (`None` for a camera they cannot use).
    pub(crate) projector: Option<ProjectedAreaCamera>,
    /// Active: it renders, and the allocation weighs regions by what it sees.
    pub(crate) active: bool,
    /// Marked [`RefineCamera`].
    pub(crate) marked: bool,
    /// Its layers and weight (weight `0` for one that is not active).
    pub(crate) share: CameraShare,
}

/// The viewport of a camera in pixels: its own, else [`AslodViewport`].
fn viewport_size(camera: &Camera, fallback: Option<&AslodViewport>) -> Option<Vec2> {
    camera
        .physical_viewport_size()
        .map(|s| s.as_vec2())
        .filter(|s| s.x > 0.0 && s.y > 0.0)
        .or(fallback.map(|v| v.0))
}

/// A camera as [`gather_cameras`] reads it.
type CameraItem = (
    Entity,
    &'static Camera,
    &'static GlobalTransform,
    &'static Projection,
    Has<RefineCamera>,
    Has<NoLodAllocation>,
    Option<&'static LodCameraWeight>,
    Option<&'static RenderLayers>,
);

/// Gathers the frame's cameras: every active 3D camera with a viewport that is not marked
/// [`NoLodAllocation`], and the [`RefineCamera`]s, active or not.
pub(crate) fn gather_cameras(
    budget: Res<PolygonBudget>,
    viewport: Option<Res<AslodViewport>>,
    cameras: Query<CameraItem, With<Camera3d>>,
    mut frame: ResMut<FrameCameras>,
    mut stats: ResMut<AslodStats>,
    mut warned: Local<bool>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    stats.allocated = false;
    stats.budget = budget.total;
    frame.active.clear();
    frame.shares.clear();
    frame.weights.clear();
    frame.views.clear();
    frame.plain = true;
    // A phantom `RefineCamera` with no render target of its own refines for the viewport of
    // the first active camera.
    let active_size = cameras
        .iter()
        .filter(|c| c.1.is_active)
        .find_map(|c| viewport_size(c.1, viewport.as_deref()));
    for (entity, camera, transform, projection, marked, opted_out, weight, layers) in &cameras {
        // Counts in the split: renders, and not opted out.
        let counts = camera.is_active && !opted_out;
        if !counts && !marked {
            continue;
        }
        let weight = weight.map_or(1.0, |w| w.0);
        let weight = if weight.is_finite() && weight >= 0.0 {
            weight
        } else {
            if !std::mem::replace(&mut *warned, true) {
                warn!(
                    "LodCameraWeight {weight} of camera {entity} is not a finite weight ≥ 0: it counts as 0"
                );
            }
            0.0
        };
        let share = CameraShare {
            layers: layers.cloned().unwrap_or_default(),
            weight: if counts { weight } else { 0.0 },
        };
        let size = viewport_size(camera, viewport.as_deref())
            .or(active_size.filter(|_| marked && !camera.is_active));
        let Some(size) = size else {
            continue;
        };
        // `camera_system` fills `clip_from_view`; before it has run (or without a renderer)
        // it is the default identity, and the projection gives the right matrix.
        let mut clip_from_view = camera.clip_from_view();
        if clip_from_view == Mat4::IDENTITY || clip_from_view == Mat4::ZERO {
            clip_from_view = projection.get_clip_from_view();
        }
        let projector = match ProjectedAreaCamera::from_world_from_view(
            transform.to_matrix(),
            clip_from_view,
            size,
        ) {
            Ok(c) => Some(c),
            Err(e) => {
                debug!("skipping a camera for LOD allocation: {e}");
                None
            }
        };
        if counts && let Some(c) = projector {
            frame.plain &= share.weight == 1.0 && share.layers == RenderLayers::default();
            frame.active.push(c);
            frame.weights.push(share.weight);
            frame.shares.push(share.clone());
        }
        frame.views.push(CameraView {
            entity,
            clip_from_world: clip_from_view * transform.to_matrix().inverse(),
            height: size.y,
            projector,
            active: counts,
            marked,
            share,
        });
    }
    stats.cameras = frame.active.len();
    frame.ms = start.elapsed().as_secs_f64() * 1e3;
}
