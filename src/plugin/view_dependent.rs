//! View-dependent models: a [`MultiresModel`](super::MultiresModel) refined every frame as one
//! variable-resolution mesh (the [`refine`](crate::refine) module) instead of by regions.
//! [`ViewDependent`] asks for it; the plugin keeps the model's [`ViewDependentState`] (its
//! refined level, the level shown under geomorphs, and the child that draws it) and gives
//! it its part in each step: [`aim_view_dependent`] (what it refines for) in `Allocate`, the
//! refinement and the grant of its geomorphs in `SelectLod`, its index buffer and moving
//! vertices in `Upload`.

use super::cameras::{CameraView, FrameCameras};
use super::components::FullDetail;
use super::geomorph::{Clock, LevelMorphs, MorphChange, MorphOutput};
use super::instance::{LevelSummary, MultiresInstance, Refinement, StagedIndices};
use super::render::{UploadTarget, swap_staged};
use super::tasks::par_chunks;
use crate::bounds::Obb;
use crate::budget::{ProjectedAreaCamera, RegionInput};
use crate::refine::{
    Criteria, LevelCut, ScreenSpaceError, ToleranceSearch, VariableCache, VariableGeomorphs,
    VariableMesh, View,
};
use bevy::asset::AssetId;
use bevy::camera::visibility::RenderLayers;
use bevy::ecs::system::NonSendMarker;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use std::sync::Arc;

/// Makes a [`MultiresModel`](super::MultiresModel) refine per frame as one variable-resolution
/// mesh: Güdükbay et al.'s view-dependent refinement over MOM's extraction, from the camera
/// (see [`RefineCamera`](super::RefineCamera)), so the near, lit or silhouette parts of one mesh keep the detail
/// the rest gives up. Its asset must carry the refinement data
/// ([`MultiresMesh::with_refinement`](super::MultiresMesh::with_refinement)); skinned models
/// keep their regions (with a warning).
///
/// While it is on, the model draws one child ([`ViewDependentLevel`](super::ViewDependentLevel)) and hides its region
/// children; removing it shows the regions again and frees the child's mesh.
///
/// How many triangles:
///
/// | `budgeted` | `tolerance_px` | the model shows |
/// |---|---|---|
/// | `true` | `None` | the most detail within the count the α allocation gives it (it takes part like one region, weighted by its bounds' projected area): the smallest screen-space tolerance τ that fits ([`ToleranceSearch`]) |
/// | `true` | `Some(τ₀)` | the same with τ ≥ τ₀: no more detail than τ₀ pixels of error asks for, and no more than its count (the budget caps the tolerance's count) |
/// | `false` | `Some(τ₀)` | τ₀ pixels of error, whatever the count (like Godot's `mesh_lod_threshold`); its triangles count against the budget as fixed cost, like [`CountInBudget`](super::CountInBudget) |
/// | `false` | `None` | full detail where `criteria` keep it |
///
/// `criteria` are the other reasons to drop detail (by default Hoppe's: out of the frustum,
/// facing away); their screen-space tolerance is ignored (τ comes from the table above).
/// Spheres of interest and lights are in the model's own space.
///
/// ```
/// use bevy_aslod::plugin::ViewDependent;
/// // Within its share of the budget, never finer than half a pixel of error.
/// let settings = ViewDependent::default().with_tolerance_px(Some(0.5));
/// assert!(settings.budgeted);
/// ```
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Default)]
#[non_exhaustive]
pub struct ViewDependent {
    /// The screen-space tolerance in pixels (see the table). A NaN, infinite or negative
    /// value is ignored, with a warning. Default: `None`.
    pub tolerance_px: Option<f32>,
    /// Whether the model takes part in the budget allocation. Default: `true`.
    pub budgeted: bool,
    /// The criteria besides the screen-space error. Default: frustum and back faces. (Not
    /// reflected: an inspector shows the two fields above.)
    #[reflect(ignore)]
    pub criteria: Criteria,
}

impl Default for ViewDependent {
    fn default() -> Self {
        Self {
            tolerance_px: None,
            budgeted: true,
            criteria: Criteria::default()
                .with_frustum(true)
                .with_back_facing(true),
        }
    }
}

with_setters!(ViewDependent {
    tolerance_px: Option<f32> => with_tolerance_px,
    budgeted: bool => with_budgeted,
    criteria: Criteria => with_criteria,
});

impl ViewDependent {
    /// A pixel tolerance and no budget (the table's third row).
    #[must_use]
    pub fn tolerance(px: f32) -> Self {
        Self {
            tolerance_px: Some(px),
            budgeted: false,
            ..Self::default()
        }
    }
}

/// What a view-dependent model shows this frame, as [`aim_view_dependent`] decided it.
// One per view-dependent model, replaced every frame: the size does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, Default)]
enum Goal {
    /// No allocation this frame: keep the level.
    #[default]
    Keep,
    /// `FullDetail(true)`: everything.
    Full,
    /// No camera sees it: the coarsest level.
    Coarsest,
    /// An orthographic camera (no screen-space error): the uniform level within the count
    /// (full detail without one).
    Uniform,
    /// Refine for this view (in the model's space), from this camera.
    Refine(View, Entity),
}

/// A view-dependent model's state, beside its [`MultiresInstance`] (whose regions it hides
/// and leaves at their levels). Never on a skinned model.
#[derive(Component, Debug)]
pub(crate) struct ViewDependentState {
    mesh: Arc<VariableMesh>,
    /// The refined level.
    cache: VariableCache,
    search: ToleranceSearch,
    /// The child drawing the level, and its mesh.
    pub(crate) entity: Entity,
    pub(crate) handle: Handle<Mesh>,
    id: AssetId<Mesh>,
    /// The index buffer `SelectLod` wrote for `Upload`.
    staged: StagedIndices,
    settings: ViewDependent,
    goal: Goal,
    /// The largest projected area of its bounds in the cameras that count this frame.
    seen_area: f32,
    /// The count the allocation gave it, for `SelectLod` (budgeted models).
    target: Option<u32>,
    /// The count of the last level that ended at the tolerance floor, when it did: what the
    /// model would use of a larger allocation.
    floor_count: Option<usize>,
    report: Refinement,
    /// Any view: the criteria that ignore it still take one.
    any_view: View,
    warned_tolerance: bool,
    /// Under [`Geomorph`](super::Geomorph): the level shown, following `cache`.
    morph: Option<LevelMorph>,
}

/// A view-dependent model's geomorphs: the level shown follows the refined one.
#[derive(Debug)]
struct LevelMorph {
    morphs: VariableGeomorphs,
    /// `SelectLod`'s first pass: the triangles the level shown would add to reach the
    /// target; after the grant, what it was granted.
    wanted: u32,
    /// Its moving vertices, for `Upload`.
    output: MorphOutput,
}

/// Finds what every view-dependent model refines for this frame (`Allocate`, after the
/// cameras, before the budget split): the first [`RefineCamera`](super::RefineCamera), else
/// the active camera that sees its bounds largest; nothing seen, the coarsest level;
/// `FullDetail(true)`, full detail. A model with only a pixel tolerance is refined now: its
/// count is fixed cost for the split. Nothing happens without an active camera (nor is
/// there an allocation).
pub(crate) fn aim_view_dependent(
    mut cameras: ResMut<FrameCameras>,
    full_detail: Res<FullDetail>,
    mut models: Query<(
        &mut ViewDependentState,
        &MultiresInstance,
        &GlobalTransform,
        Option<&RenderLayers>,
    )>,
    _main_thread: NonSendMarker,
) {
    if cameras.active.is_empty() || models.is_empty() {
        return;
    }
    let start = Instant::now();
    let mut items: Vec<_> = models.iter_mut().collect();
    let views = &cameras.views;
    par_chunks(&mut items, |chunk| {
        for (state, instance, transform, layers) in chunk {
            state.aim(&instance.bounds, transform, *layers, views, full_detail.0);
            if !state.settings.budgeted {
                state.select();
            }
        }
    });
    cameras.ms += start.elapsed().as_secs_f64() * 1e3;
}

impl ViewDependentState {
    pub(crate) fn new(
        mesh: Arc<VariableMesh>,
        entity: Entity,
        handle: Handle<Mesh>,
        narrow: bool,
        settings: ViewDependent,
    ) -> Self {
        let any_view = View::perspective(Vec3::Z, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 1.0)
            .expect("a valid constant camera");
        // Coarsest until the first allocation reaches it, like a region.
        let mut cache = VariableCache::new(&mesh);
        if let Err(e) = cache.update(&mesh, &LevelCut(usize::MAX), &any_view) {
            warn!("a view-dependent model starts at full detail: {e}");
        }
        Self {
            cache,
            mesh,
            search: ToleranceSearch::default(),
            entity,
            id: handle.id(),
            handle,
            staged: StagedIndices::new(narrow),
            settings,
            goal: Goal::Keep,
            seen_area: 0.0,
            target: None,
            floor_count: None,
            report: Refinement::default(),
            any_view,
            warned_tolerance: false,
            morph: None,
        }
    }

    /// What the model draws, for its [`MultiresInstance`].
    pub(crate) fn summary(&self) -> LevelSummary {
        LevelSummary {
            entity: self.entity,
            shown: self.shown_count(),
            report: self.report,
        }
    }

    /// The variable-resolution mesh.
    pub(crate) fn mesh(&self) -> &VariableMesh {
        &self.mesh
    }

    /// New settings: the search and what it knew start over.
    pub(crate) fn set_settings(&mut self, settings: ViewDependent) {
        self.settings = settings;
        self.search = ToleranceSearch::default();
        self.floor_count = None;
        self.warned_tolerance = false;
    }

    /// Whether the model takes part in the allocation (one input), or only has a pixel
    /// tolerance (none: its count is fixed cost).
    pub(crate) fn is_budgeted(&self) -> bool {
        self.settings.budgeted
    }

    /// Decides what the model refines for this frame (see [`aim_view_dependent`]), and the
    /// area its bounds (`bounds`, in its space) cover in the cameras that count: the active
    /// ones and the one it refines for.
    fn aim(
        &mut self,
        bounds: &Obb,
        transform: &GlobalTransform,
        layers: Option<&RenderLayers>,
        views: &[CameraView],
        full_detail: bool,
    ) {
        let bounds = bounds.transformed(&transform.affine());
        let area_of = |cam: &ProjectedAreaCamera| {
            let a = if cam.may_see(&bounds) {
                cam.projected_area(&bounds)
            } else {
                0.0
            };
            if a.is_finite() { a } else { 0.0 }
        };
        let marked = views.iter().find(|v| v.marked);
        // What each camera that counts sees of it, weighted: the active ones that draw its
        // layers, and the marked one.
        let seen = || {
            views
                .iter()
                .filter(|v| {
                    (v.active && v.share.sees(layers))
                        || marked.is_some_and(|m| m.entity == v.entity)
                })
                .filter_map(|v| {
                    let weight = if v.active { v.share.weight } else { 1.0 };
                    Some((v, area_of(v.projector.as_ref()?) * weight))
                })
        };
        self.seen_area = if full_detail || !self.settings.budgeted {
            0.0
        } else {
            seen().map(|(_, a)| a).fold(0.0, f32::max)
        };
        if full_detail {
            self.goal = Goal::Full;
            return;
        }
        // The marked camera, else the active one that sees the model largest.
        let chosen = marked.or_else(|| {
            seen()
                .filter(|(_, a)| *a > 0.0)
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(v, _)| v)
        });
        self.goal = match chosen {
            None => Goal::Coarsest,
            Some(v) => {
                let clip_from_local = v.clip_from_world * transform.to_matrix();
                match View::from_clip_from_local(clip_from_local, v.height) {
                    Ok(view) => Goal::Refine(view, v.entity),
                    Err(e) => {
                        warn_once!(
                            "a ViewDependent model refines uniformly: its camera cannot drive a refinement ({e})"
                        );
                        Goal::Uniform
                    }
                }
            }
        };
    }

    /// The model's allocation input (budgeted models): its bounds' largest projected area,
    /// between its coarsest level and the most it can use.
    pub(crate) fn allocation_input(&self, priority: f32, full_detail: bool) -> RegionInput {
        let pm = self.mesh.mesh();
        let (min, max) = if full_detail {
            (pm.max_triangles(), pm.max_triangles())
        } else {
            (pm.min_triangles(), self.max_useful())
        };
        RegionInput::from_area(
            self.seen_area,
            priority,
            min as u32,
            max as u32,
            self.triangle_count() as u32,
        )
    }

    /// Starts, changes or ends the model's geomorphs (`seconds`, `0`: none): a new or
    /// changed morph shows the refined level as it is; an ended one writes every vertex once
    /// more at rest before it goes (`Upload`).
    pub(crate) fn sync_morph(&mut self, seconds: f32, gpu: bool) {
        let current = self
            .morph
            .as_ref()
            .map(|m| (m.morphs.duration(), m.output.gpu));
        let change = MorphChange::of(current, seconds, gpu);
        let fresh = |duration: f32| VariableGeomorphs::new(&self.mesh, &self.cache, duration);
        match (change, &mut self.morph) {
            (MorphChange::Start, _) => {
                self.morph = Some(LevelMorph {
                    morphs: fresh(seconds),
                    wanted: 0,
                    output: MorphOutput::new(1, gpu),
                });
            }
            (MorphChange::Restart, Some(m)) => {
                m.morphs = fresh(seconds);
                m.output.restart(gpu);
            }
            (MorphChange::End, Some(m)) => {
                m.morphs = fresh(0.0);
                m.output.rewrite();
            }
            _ => {}
        }
    }

    /// `SelectLod`'s first pass: takes this frame's allocation (`count`, its input's, when
    /// `this_frame` the allocation included the model), refines (a model with only a pixel tolerance was
    /// refined in `Allocate`), and under geomorphs lands what arrived and starts what the
    /// level changed (its refinements wait for [`finish_morph`](Self::finish_morph)).
    /// Returns the triangles shown and refined to, and whether its refinements wait.
    pub(crate) fn take_allocation(
        &mut self,
        this_frame: bool,
        count: Option<u32>,
        now: f32,
    ) -> (u64, u64, bool) {
        if !this_frame {
            self.goal = Goal::Keep;
        }
        self.target = count.filter(|_| this_frame && self.settings.budgeted);
        if self.settings.budgeted {
            self.select();
        }
        let target = self.triangle_count() as u64;
        let shown = self.begin_morph(now) as u64;
        (shown, target, self.morph.is_some())
    }

    /// Under geomorphs, lands what arrived and starts what the refined level changed;
    /// without, stages the level. Returns the triangles shown.
    fn begin_morph(&mut self, now: f32) -> usize {
        let Some(m) = &mut self.morph else {
            self.stage_indices();
            return self.cache.triangle_count();
        };
        match m.morphs.begin(&self.mesh, &self.cache, now) {
            Ok(wanted) => m.wanted = u32::try_from(wanted).unwrap_or(u32::MAX),
            Err(e) => warn_once!("a view-dependent model keeps its level: {e}"),
        }
        m.morphs.shown().triangle_count()
    }

    /// The triangles the level shown would add under geomorphs to reach the refined level
    /// (`0`: none, or no geomorphs).
    pub(crate) fn wanted(&self) -> u32 {
        self.morph.as_ref().map_or(0, |m| m.wanted)
    }

    /// Notes what the grant gave the level's refinements.
    pub(crate) fn set_granted(&mut self, triangles: u32) {
        if let Some(m) = &mut self.morph {
            m.wanted = triangles;
        }
    }

    /// `SelectLod`'s second pass under geomorphs: refines the level shown by at most what
    /// was granted, and stages it and its moving vertices. Returns the triangles shown, or
    /// `None` without geomorphs (nothing waited for this pass).
    pub(crate) fn finish_morph(&mut self, clock: Clock) -> Option<u64> {
        let m = self.morph.as_mut()?;
        let granted = std::mem::take(&mut m.wanted);
        if let Err(e) = m
            .morphs
            .grant(&self.mesh, &self.cache, granted as usize, clock.now)
        {
            warn_once!("a view-dependent model keeps its level: {e}");
        }
        self.stage_indices();
        let shown = self.shown_count() as u64;
        let vertices = self.mesh.mesh().vertices().vertex_count();
        if let Some(m) = &mut self.morph {
            let mut source = LevelMorphs {
                morphs: &mut m.morphs,
                vertices,
            };
            m.output.stage(&mut source, clock);
        }
        Some(shown)
    }

    /// Triangles drawn: the level shown under geomorphs, else the refined one.
    pub(crate) fn shown_count(&self) -> usize {
        self.morph
            .as_ref()
            .map_or(self.cache.triangle_count(), |m| {
                m.morphs.shown().triangle_count()
            })
    }

    /// Copies the level drawn into `staged` when it changed.
    fn stage_indices(&mut self) {
        match &mut self.morph {
            Some(m) if m.morphs.shown().is_changed() => {
                self.staged.stage(m.morphs.shown().indices());
                m.morphs.clear_changed();
            }
            Some(_) => {}
            None if self.cache.is_changed() => {
                self.staged.stage(self.cache.indices());
                self.cache.clear_changed();
            }
            None => {}
        }
    }

    /// `Upload`: swaps the staged index buffer into the level's mesh and writes its moving
    /// vertices; the geomorphs go once they have ended and are at rest. Returns whether the
    /// index buffer changed.
    pub(crate) fn upload(&mut self, target: &mut UploadTarget) -> bool {
        let swapped = std::mem::take(&mut self.staged.ready)
            && target
                .mesh(self.id)
                .is_some_and(|mesh| swap_staged(mesh, &mut self.staged.indices));
        if swapped {
            target.indices_changed(self.id, self.entity);
        }
        if let Some(m) = &mut self.morph {
            m.output.upload(&[self.id], target, |_| swapped);
            if m.output.is_done(m.morphs.duration()) {
                self.morph = None;
            }
        }
        swapped
    }

    /// Triangles of the refined level.
    pub(crate) fn triangle_count(&self) -> usize {
        self.cache.triangle_count()
    }

    /// The tolerance floor of the settings, `None` (with a warning once) when it is unusable.
    fn floor(&mut self) -> Option<f32> {
        let t = self.settings.tolerance_px?;
        if ScreenSpaceError::new(t).is_ok() {
            return Some(t);
        }
        if !std::mem::replace(&mut self.warned_tolerance, true) {
            warn!(
                "ViewDependent::tolerance_px is {t} pixels: it must be finite and not negative; ignored"
            );
        }
        None
    }

    /// The most triangles the model can use this frame, for the allocator: its full detail,
    /// or about the count at its tolerance floor when the last level ended there.
    fn max_useful(&self) -> usize {
        let full = self.mesh.mesh().max_triangles();
        match (self.settings.tolerance_px, self.floor_count) {
            (Some(_), Some(n)) => (n + n / 4 + 16).clamp(self.mesh.mesh().min_triangles(), full),
            _ => full,
        }
    }

    /// Moves the refined level to this frame's goal. Returns its triangles.
    fn select(&mut self) -> usize {
        let floor = self.floor();
        // The allocation was capped at what the model can use (see `max_useful`).
        let capped = self.max_useful() < self.mesh.mesh().max_triangles();
        let mesh = &*self.mesh;
        let mut report = Refinement {
            allocated: self.target,
            tolerance_px: f32::NAN,
            ..Refinement::default()
        };
        let result = match std::mem::take(&mut self.goal) {
            Goal::Keep => {
                // No allocation this frame: the level, its tolerance and camera stay.
                report = Refinement {
                    updates: 0,
                    ..self.report
                };
                Ok(())
            }
            Goal::Full => {
                report.tolerance_px = 0.0;
                self.cache
                    .update(mesh, &Criteria::default(), &self.any_view)
                    .map(|_| report.updates = 1)
            }
            Goal::Coarsest => self
                .cache
                .update(mesh, &LevelCut(usize::MAX), &self.any_view)
                .map(|_| report.updates = 1),
            Goal::Uniform => {
                let target = self.target.map_or(usize::MAX, |t| t as usize);
                let counts = mesh.mesh().level_triangle_counts();
                let level = counts
                    .iter()
                    .position(|&n| n <= target)
                    .unwrap_or(counts.len().saturating_sub(1));
                self.cache
                    .update(mesh, &LevelCut(level), &self.any_view)
                    .map(|_| report.updates = 1)
            }
            Goal::Refine(view, camera) => {
                report.camera = Some(camera);
                let criteria = self.settings.criteria.with_screen_space(None);
                match self.target.filter(|_| self.settings.budgeted) {
                    Some(target) => self
                        .search
                        .fit(
                            &mut self.cache,
                            mesh,
                            &criteria,
                            &view,
                            target as usize,
                            floor.unwrap_or(0.0),
                        )
                        .map(|fit| {
                            report.updates = fit.updates;
                            report.tolerance_px = fit.tolerance_px;
                            // At the floor: what it needs. Above it under a capped
                            // allocation: the cap, so that the next one grows by a quarter
                            // (never back to uncapped and down again, a flicker).
                            self.floor_count = match floor {
                                Some(f) if fit.tolerance_px <= f => Some(fit.triangles),
                                Some(_) if capped => Some(target as usize),
                                _ => None,
                            };
                        }),
                    None => {
                        let criteria = criteria
                            .with_screen_space(floor.and_then(|t| ScreenSpaceError::new(t).ok()));
                        report.tolerance_px = floor.unwrap_or(0.0);
                        self.cache
                            .update(mesh, &criteria, &view)
                            .map(|_| report.updates = 1)
                    }
                }
            }
        };
        if let Err(e) = result {
            warn_once!("a view-dependent model keeps its level: {e}");
        }
        report.triangles = self.cache.triangle_count();
        self.report = report;
        report.triangles
    }
}
