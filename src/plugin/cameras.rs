//! The first step of `Allocate`: the frame's cameras, as the allocation and the
//! view-dependent models see them ([`FrameCameras`]).

use super::components::{AslodStats, AslodViewport, PolygonBudget};
use crate::budget::ProjectedAreaCamera;
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// Marks the camera that view-dependent models refine for, active or not (Güdükbay et al.'s
/// phantom camera: it may drive the refinement while another camera looks at the result).
/// The first one found is used. Without a render target of its own (an inactive camera) it
/// takes the viewport height of [`AslodViewport`](super::AslodViewport) when there is one,
/// else of the first active camera; its projection is its own, so set its aspect ratio. Without one, each model refines for the active 3D camera
/// that sees its bounds largest, so in split screen every model is as fine as its nearest
/// view needs; a view that sees it smaller gets the same mesh.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineCamera;

/// This frame's cameras, gathered at the start of `Allocate`.
#[derive(Resource, Default)]
pub(crate) struct FrameCameras {
    /// Milliseconds `Allocate`'s systems took so far this frame (for
    /// [`AslodStats::allocation_ms`]).
    pub(crate) ms: f64,
    /// The active cameras' projected areas: the allocation weighs regions by what these see.
    pub(crate) active: Vec<ProjectedAreaCamera>,
    /// The cameras view-dependent models may refine for.
    pub(crate) views: Vec<CameraView>,
}

/// A camera a view-dependent model may refine for.
#[derive(Clone, Copy, Debug)]
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
}

/// The viewport of a camera in pixels: its own, else [`AslodViewport`].
fn viewport_size(camera: &Camera, fallback: Option<&AslodViewport>) -> Option<Vec2> {
    camera
        .physical_viewport_size()
        .map(|s| s.as_vec2())
        .filter(|s| s.x > 0.0 && s.y > 0.0)
        .or(fallback.map(|v| v.0))
}

/// Gathers the frame's cameras: every active 3D camera with a viewport, and the
/// [`RefineCamera`]s, active or not.
#[allow(clippy::type_complexity)]
pub(crate) fn gather_cameras(
    budget: Res<PolygonBudget>,
    viewport: Option<Res<AslodViewport>>,
    cameras: Query<
        (
            Entity,
            &Camera,
            &GlobalTransform,
            &Projection,
            Has<RefineCamera>,
        ),
        With<Camera3d>,
    >,
    mut frame: ResMut<FrameCameras>,
    mut stats: ResMut<AslodStats>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    stats.allocated = false;
    stats.budget = budget.total;
    frame.active.clear();
    frame.views.clear();
    // A phantom `RefineCamera` with no render target of its own refines for the viewport of
    // the first active camera.
    let active_size = cameras
        .iter()
        .filter(|c| c.1.is_active)
        .find_map(|c| viewport_size(c.1, viewport.as_deref()));
    for (entity, camera, transform, projection, marked) in &cameras {
        if !camera.is_active && !marked {
            continue;
        }
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
        if camera.is_active
            && let Some(c) = projector
        {
            frame.active.push(c);
        }
        frame.views.push(CameraView {
            entity,
            clip_from_world: clip_from_view * transform.to_matrix().inverse(),
            height: size.y,
            projector,
            active: camera.is_active,
            marked,
        });
    }
    stats.cameras = frame.active.len();
    frame.ms = start.elapsed().as_secs_f64() * 1e3;
}
