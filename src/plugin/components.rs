//! The plugin's public components and resources: what an app sets ([`PolygonBudget`],
//! [`MultiresModel`], [`LodPriority`], [`Geomorph`], ...) and what it reads ([`AslodStats`]).

use super::asset::MultiresMesh;
use crate::budget::{AllocationParams, ControllerState, DEFAULT_ALPHA, DEFAULT_BUDGET};
use bevy::prelude::*;

/// The global polygon budget and how it is split (the paper's allocator node).
#[derive(Resource, Reflect, Clone, Debug, PartialEq)]
#[reflect(Resource, Default)]
pub struct PolygonBudget {
    /// `P`: the most triangles all multiresolution regions and the [`CountInBudget`] meshes
    /// may show together. Must be positive; `0` is warned about and skipped.
    ///
    /// Default: `100_000` ([`DEFAULT_BUDGET`], as the core allocator's).
    pub total: u32,
    /// α: `pᵢ ∝ wᵢ^(1/α)`; `1` proportional to screen area, larger flattens towards an equal
    /// split (per region under [`RegionSplit::Area`]; under the default
    /// [`RegionSplit::ScreenError`] it sets each model's total, which its regions then share
    /// by error). Must be positive.
    ///
    /// Default: `3` ([`DEFAULT_ALPHA`], the paper's).
    pub alpha: f32,
    /// Hysteresis ε: a region keeps its level while its new target stays within this many
    /// triangles of its current count.
    ///
    /// Default: `0`.
    pub hysteresis: u32,
    /// A frame time to aim at: with it, the plugin sets `total` every frame (see
    /// [`FrameTarget`]). Default: `None` (`total` is the user's).
    pub frame_target: Option<FrameTarget>,
    /// How a model's triangles are shared among its regions.
    ///
    /// Default: [`RegionSplit::ScreenError`].
    pub split: RegionSplit,
    /// The smallest a model may look and still be drawn, in pixels: a model whose regions'
    /// projected areas add up to less than `min_pixels²` shows nothing (its region entities
    /// are hidden) and counts nothing against the budget, as a LOD group's last "culled"
    /// level does. So do models out of every camera's view, which Bevy does not draw either.
    /// A model that shows nothing keeps its last level, and takes its allocation again the
    /// frame it is large enough. Off with [`FullDetail`]`(true)` and for
    /// [`ViewDependent`](super::ViewDependent) models. Negative or non-finite values count
    /// as `0`.
    ///
    /// Default: `0.0` (off: every model shows at least its coarsest level, a triangle or a
    /// few for most meshes; see [`BuildOptions::permissive`](crate::multires::BuildOptions)).
    pub min_pixels: f32,
}

/// How a model's part of the budget is shared among its regions ([`PolygonBudget::split`]).
///
/// Either way the split over all regions of all models comes first (ASLOD's, by projected
/// area); a model then shows at most the total it made for the model, so the budget holds.
/// Under `ScreenError`, α weighs models against each other, and a region's pixels per unit
/// come from its projected area clipped to the view: a region partly off screen, seen edge
/// on, or around the camera counts as smaller than it is.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RegionSplit {
    /// As the allocation gave it: each region by its own projected area, `pᵢ ∝ (c·Aᵢ)^(1/α)`
    /// (ASLOD section 5), whatever its shape. A flat region gets as many triangles as a
    /// detailed one of the same size on screen.
    Area,
    /// Shared again so that every region of the model shows about the same geometric error
    /// in pixels (its error at its level, times the pixels a unit of the model covers at that
    /// region): triangles go where they remove the most error, as when simplifying the whole
    /// mesh at once, and regions nearer the camera still get more
    /// ([`ErrorCurves::split`](crate::regions::ErrorCurves::split)).
    #[default]
    ScreenError,
}

/// A budget in milliseconds: each frame, before the split, the plugin moves
/// [`PolygonBudget::total`] within `min..=max` so that frames take about `ms`
/// ([`FrameTimeController`](crate::budget::FrameTimeController)). The cost it measures is the
/// whole frame's wall time (`Time<Real>`'s delta; [`AslodStats::frame_ms`] smoothed), so
/// with vsync on, a target below the display's interval is what it can reach. The triangle
/// budget still holds every frame inside the `total` it chose.
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
pub struct FrameTarget {
    /// The frame time to aim at, in milliseconds. Must be positive and finite (else the
    /// target is ignored, with a warning).
    pub ms: f32,
    /// The smallest `total` it may set (at least `1`).
    pub min: u32,
    /// The largest `total` it may set.
    pub max: u32,
}

impl Default for PolygonBudget {
    fn default() -> Self {
        Self {
            total: DEFAULT_BUDGET,
            alpha: DEFAULT_ALPHA,
            hysteresis: 0,
            frame_target: None,
            split: RegionSplit::default(),
            min_pixels: 0.0,
        }
    }
}

impl PolygonBudget {
    /// A budget in milliseconds: frames of about `ms`, with `total` kept within `range`
    /// (starting at its lower end).
    ///
    /// ```
    /// use bevy_aslod::plugin::PolygonBudget;
    /// // About 60 frames a second, between 20,000 and 2 million triangles.
    /// let budget = PolygonBudget::target_ms(16.0, 20_000..=2_000_000);
    /// assert_eq!(budget.total, 20_000);
    /// ```
    #[must_use]
    pub fn target_ms(ms: f32, range: std::ops::RangeInclusive<u32>) -> Self {
        Self {
            total: (*range.start()).max(1),
            frame_target: Some(FrameTarget {
                ms,
                min: *range.start(),
                max: *range.end(),
            }),
            ..Self::default()
        }
    }

    /// The projected area in pixels² below which a model shows nothing
    /// ([`min_pixels`](Self::min_pixels) squared); `0` when that is off, or at
    /// `full_detail`.
    pub(crate) fn min_area(&self, full_detail: bool) -> f32 {
        let m = self.min_pixels;
        if full_detail || !(m.is_finite() && m > 0.0) {
            0.0
        } else {
            m * m
        }
    }

    /// The allocator's parameters for a fixed cost.
    #[must_use]
    pub fn params(&self, fixed_cost: u32) -> AllocationParams {
        AllocationParams {
            budget: self.total,
            fixed_cost,
            alpha: self.alpha,
            hysteresis: self.hysteresis,
        }
    }
}

/// The "no LOD" switch: while it is `true`, every region of every model is kept at its full
/// detail, whatever the budget and wherever the camera looks (regions out of view too), so an
/// app can compare the same scene with and without LOD. Like the budget, it is applied in
/// `Allocate`, which needs an active 3D camera. Skinned regions still blend only when their
/// bones move. Default `false`.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Default)]
pub struct FullDetail(pub bool);

/// The user priority `c` of a model: its regions weigh `c · A`. Without it `c = 1`; `0`
/// keeps the model at its coarsest level. Negative or non-finite values count as `0`.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct LodPriority(pub f32);

impl Default for LodPriority {
    fn default() -> Self {
        Self(1.0)
    }
}

/// A multiresolution model: the plugin gives this entity one child per region of the mesh.
/// Put it next to a `MeshMaterial3d<StandardMaterial>` (or of another material with a
/// [`MultiresMaterialPlugin`](super::MultiresMaterialPlugin)) and a `Transform`.
///
/// The children are made when the asset is loaded, with the material the model has then.
/// Giving it another handle rebuilds them from the new asset once that is loaded (as a
/// `Mesh3d` given another mesh draws it); so does a hot-reloaded asset.
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
#[require(Transform, Visibility)]
pub struct MultiresModel(pub Handle<MultiresMesh>);

/// Geomorphs on a [`MultiresModel`]: its level changes take this many seconds instead of
/// a frame (`regions::Geomorphs`). A refining region changes its triangles at once and its
/// new vertices grow out of their representatives; a coarsening region keeps its triangles,
/// and counts them, until its vanishing vertices have reached their representatives. The
/// allocation is the view's, whatever is morphing; the budget holds because refinements only
/// take the triangles that are free, so one that needs a coarsening's triangles waits for
/// them (a lower [`PolygonBudget`] is met once the coarsening regions arrive, after the
/// morph time). Borders stay closed: a vertex moves the same way in every region that draws
/// it. `0` (or no component) changes levels at once; [`Default`] is
/// [`DEFAULT_SECONDS`](Self::DEFAULT_SECONDS). A model's first levels (when it is new, or
/// gets the component) are taken at once. A [`MultiresScene`](super::MultiresScene) with one gives it to every
/// model it makes.
///
/// Unskinned models with a [`GeomorphMaterial`](super::GeomorphMaterial) (or another material with [`GpuGeomorph`](super::GpuGeomorph))
/// are interpolated by the vertex shaders: a vertex is written once, when a morph starts
/// on it. With any other material their moving regions' positions and normals are written
/// from the CPU each frame they move. Skinned models blend their moving vertices in
/// `Deform`, from where the morphs show them in the bind pose.
///
/// [`ViewDependent`](super::ViewDependent) models morph between their variable-resolution levels
/// (`refine::VariableGeomorphs`) the same way, collapse by collapse.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct Geomorph(pub f32);

impl Geomorph {
    /// The default morph time: a quarter second.
    pub const DEFAULT_SECONDS: f32 = 0.25;
}

impl Default for Geomorph {
    fn default() -> Self {
        Self(Self::DEFAULT_SECONDS)
    }
}

/// A region child of a [`MultiresModel`]: which region of the mesh its `Mesh3d` shows.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct LodRegion {
    /// Index into the mesh's regions.
    pub region: usize,
}

/// A conventional (not multiresolution) `Mesh3d` whose triangles count against the budget
/// as fixed cost: `P' = P − Σ its triangles`.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct CountInBudget;

/// The child that draws a [`ViewDependent`](super::ViewDependent) model's variable-resolution
/// level (the plugin spawns it), as [`LodRegion`] marks the children that draw its regions.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct ViewDependentLevel;

/// The viewport size in pixels for cameras whose size is not known yet (no render target,
/// as in a headless test, or the first frame). A camera with a known viewport
/// (`Camera::physical_viewport_size`) uses its own. Without this resource such cameras are
/// skipped; with no usable camera, allocation does nothing that frame.
/// Its default is 1280×720.
#[derive(Resource, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Resource, Default)]
pub struct AslodViewport(pub Vec2);

impl Default for AslodViewport {
    fn default() -> Self {
        Self(Vec2::new(1280.0, 720.0))
    }
}

/// Whether the debug overlay is on (ASLOD Figure 10): each region's world box, coloured from
/// blue (coarsest) to red (full detail), and with the crate's `ui` feature its triangle count as a label ([`OverlayLabel`](super::OverlayLabel)
/// UI nodes, at most [`MAX_OVERLAY_LABELS`](super::MAX_OVERLAY_LABELS)). Needs `GizmoPlugin`, part of `DefaultPlugins`.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Default)]
pub struct AslodOverlay(pub bool);

/// What the plugin did in the last frame; also published as diagnostics ([`diagnostics`](super::diagnostics)).
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Resource, Default)]
pub struct AslodStats {
    /// Triangles of all region instances after `SelectLod`.
    pub triangles: u64,
    /// `P` of the frame.
    pub budget: u32,
    /// Triangles of the [`CountInBudget`] meshes.
    pub fixed_cost: u32,
    /// Models and regions seen.
    pub models: usize,
    /// Region instances seen.
    pub regions: usize,
    /// Cameras used.
    pub cameras: usize,
    /// Whether `Allocate` split the budget this frame (it needs a camera and a valid
    /// budget); when it did not, every model keeps its levels.
    pub allocated: bool,
    /// Milliseconds the plugin's systems took in `Allocate`.
    pub allocation_ms: f64,
    /// Milliseconds the plugin's systems took in `SelectLod` and `Upload`.
    pub update_ms: f64,
    /// Milliseconds in `Upload` alone (part of `update_ms`).
    pub upload_ms: f64,
    /// Milliseconds in `Deform` (skinned models; near `0` when no joint moved).
    pub deform_ms: f64,
    /// Vertices blended in `Deform`.
    pub vertices_blended: usize,
    /// Regions whose index buffer was rewritten.
    pub regions_changed: usize,
    /// Bytes of region mesh data handed to the renderer in `Upload`: the new index buffers
    /// and blended vertex runs ([`RegionUpload::IndicesOnly`](super::RegionUpload::IndicesOnly), `0` without a render sub-app),
    /// or every changed mesh's whole vertex and index data ([`RegionUpload::WholeMesh`](super::RegionUpload::WholeMesh)),
    /// and the level meshes [`SharedLevels`](super::SharedLevels) models made.
    pub upload_bytes: u64,
    /// Level meshes alive that [`SharedLevels`](super::SharedLevels) models share.
    pub shared_meshes: usize,
    /// The frame time [`PolygonBudget::frame_target`] aims at (`0` without one).
    pub target_ms: f32,
    /// The frame time the controller measured, smoothed over a few frames, from
    /// [`frame_source`](Self::frame_source) (`0` without a target).
    pub frame_ms: f32,
    /// What the frame-time controller is doing.
    pub controller: ControllerState,
    /// Where the frame time it measures comes from.
    pub frame_source: FrameSource,
}

/// Where the frame time the controller holds to its target comes from
/// ([`AslodStats::frame_source`]).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Default)]
pub enum FrameSource {
    /// No frame-time target.
    #[default]
    None,
    /// The frame's wall time, `Time<Real>`'s delta: everything the frame waited for, vsync
    /// included.
    FrameDelta,
    /// GPU timestamps: the larger of the GPU's time for a frame (the sum of Bevy's top-level
    /// render spans, `render/*/elapsed_gpu`, which `RenderDiagnosticsPlugin` reads back a few
    /// frames late) and the main world's CPU time for the last frame (`First` to `Last`).
    /// Waits for vsync are not in it; the render world's CPU time is not either.
    GpuTimestamps,
}
