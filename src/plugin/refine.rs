//! View-dependent models: a [`MultiresModel`](super::MultiresModel) refined every frame as one
//! variable-resolution mesh (the [`refine`](crate::refine) module) instead of by regions.

use super::{StagedIndices, VertexRun};
use crate::refine::{
    Criteria, LevelCut, ScreenSpaceError, ToleranceSearch, VariableCache, VariableGeomorphs,
    VariableMesh, View,
};
use bevy::asset::AssetId;
use bevy::mesh::Indices;
use bevy::prelude::*;
use std::sync::Arc;

/// Makes a [`MultiresModel`](super::MultiresModel) refine per frame as one variable-resolution
/// mesh: Güdükbay et al.'s view-dependent refinement over MOM's extraction, from the camera
/// (see [`RefineCamera`]), so the near, lit or silhouette parts of one mesh keep the detail
/// the rest gives up. Its asset must carry the refinement data
/// ([`MultiresMesh::with_refinement`](super::MultiresMesh::with_refinement)); skinned models
/// keep their regions (with a warning).
///
/// While it is on, the model draws one child ([`VariableLevel`]) and hides its region
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
/// let fine = ViewDependent::default().with_tolerance_px(Some(0.5));
/// assert!(fine.budgeted);
/// ```
#[derive(Component, Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct ViewDependent {
    /// The screen-space tolerance in pixels (see the table). A NaN, infinite or negative
    /// value is ignored, with a warning. Default: `None`.
    pub tolerance_px: Option<f32>,
    /// Whether the model takes part in the budget allocation. Default: `true`.
    pub budgeted: bool,
    /// The criteria besides the screen-space error. Default: frustum and back faces.
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

/// Marks the camera that view-dependent models refine for, active or not (Güdükbay et al.'s
/// phantom camera: it may drive the refinement while another camera looks at the result).
/// The first one found is used. Without a render target of its own (an inactive camera) it
/// takes the viewport height of [`AslodViewport`](super::AslodViewport) when there is one,
/// else of the first active camera; its projection is its own, so set its aspect ratio. Without one, each model refines for the active 3D camera
/// that sees its bounds largest, so in split screen every model is as fine as its nearest
/// view needs; a view that sees it smaller gets the same mesh.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineCamera;

/// The child that draws a [`ViewDependent`] model (the plugin spawns it).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VariableLevel;

/// What a view-dependent model did in the last `SelectLod`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct Refinement {
    /// Triangles of the level it refined to (under [`Geomorph`](super::Geomorph), the level
    /// shown reaches it within the morph time: [`MultiresInstance::triangle_count`](super::MultiresInstance::triangle_count)
    /// is what is shown).
    pub triangles: usize,
    /// The count the allocation gave it this frame (budgeted models), else `None`.
    pub allocated: Option<u32>,
    /// The screen-space tolerance of the level, in pixels: `0` at full detail, infinite at
    /// the coarsest-level fallback, `NaN` when the level was not refined from a view (out of
    /// view, an orthographic camera).
    pub tolerance_px: f32,
    /// The camera it refined for.
    pub camera: Option<Entity>,
    /// Incremental updates run this frame.
    pub updates: u32,
}

/// What `Allocate` decided a view-dependent model shows this frame.
// One per view-dependent model, replaced every frame: the size does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, Default)]
pub(super) enum Goal {
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

/// A view-dependent model's state, kept in its [`MultiresInstance`](super::MultiresInstance).
#[derive(Debug)]
pub(super) struct FineState {
    pub(super) mesh: Arc<VariableMesh>,
    cache: VariableCache,
    search: ToleranceSearch,
    pub(super) entity: Entity,
    pub(super) handle: Handle<Mesh>,
    pub(super) id: AssetId<Mesh>,
    pub(super) staged: StagedIndices,
    pub(super) settings: ViewDependent,
    pub(super) goal: Goal,
    /// The count the allocation gave it, for `SelectLod` (budgeted models).
    pub(super) target: Option<u32>,
    /// The count of the last level that ended at the tolerance floor, when it did: what the
    /// model would use of a larger allocation.
    pub(super) floor_count: Option<usize>,
    /// This frame's allocation was capped at [`max_useful`](Self::max_useful).
    pub(super) capped: bool,
    pub(super) report: Refinement,
    /// Any view: the criteria that ignore it still take one.
    any_view: View,
    warned_tolerance: bool,
    /// Under [`Geomorph`](super::Geomorph): the level shown, following `cache`.
    pub(super) morph: Option<FineMorph>,
}

/// A view-dependent model's geomorphs: the level shown follows the refined one.
#[derive(Debug)]
pub(super) struct FineMorph {
    pub(super) morphs: VariableGeomorphs,
    /// The material interpolates on the GPU: a vertex is written when a morph starts on it.
    pub(super) gpu: bool,
    /// The mesh has the morph attributes (added once, by `Upload`).
    pub(super) attributes: bool,
    /// On the CPU: the vertices moved last frame (written once more at rest); on the GPU:
    /// every vertex must be written again.
    pub(super) moved: bool,
    /// `SelectLod`'s first pass: the triangles the level shown would add to reach the target.
    pub(super) wanted: u32,
    /// The runs of vertices `Upload` writes (one, at rest, on the CPU path).
    pub(super) runs: Vec<VertexRun>,
}

impl FineState {
    pub(super) fn new(
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
            staged: StagedIndices {
                ready: false,
                indices: super::systems::empty_indices(narrow),
            },
            settings,
            goal: Goal::Keep,
            target: None,
            floor_count: None,
            capped: false,
            report: Refinement::default(),
            any_view,
            warned_tolerance: false,
            morph: None,
        }
    }

    /// Starts, changes or ends the model's geomorphs (`seconds`, `0`: none): a new or
    /// changed morph shows the refined level as it is; an ended one writes every vertex once
    /// more at rest before it goes (`Upload`).
    pub(super) fn sync_morph(&mut self, seconds: f32, gpu: bool) {
        // (NaN and negative times are off, as `VariableGeomorphs` takes them.)
        let seconds = if seconds > 0.0 { seconds } else { 0.0 };
        let fresh = |duration: f32| VariableGeomorphs::new(&self.mesh, &self.cache, duration);
        match &mut self.morph {
            None if seconds > 0.0 => {
                self.morph = Some(FineMorph {
                    morphs: fresh(seconds),
                    gpu,
                    attributes: false,
                    moved: gpu,
                    wanted: 0,
                    runs: Vec::new(),
                });
            }
            Some(m) if m.morphs.duration() != seconds || (seconds > 0.0 && m.gpu != gpu) => {
                m.morphs = fresh(seconds);
                m.gpu = gpu && seconds > 0.0;
                m.moved = true;
            }
            _ => {}
        }
    }

    /// `SelectLod`'s first pass, after [`select`](Self::select) (or `Allocate`, for a model
    /// with only a pixel tolerance) moved the refined level: under geomorphs, lands what
    /// arrived and starts what the level changed (its refinements wait for
    /// [`finish_morph`](Self::finish_morph)); without, stages the level. Returns the
    /// triangles shown.
    pub(super) fn begin_morph(&mut self, now: f32) -> usize {
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

    /// `SelectLod`'s second pass under geomorphs: refines the level shown by at most
    /// `granted` triangles and stages it. Returns the triangles shown.
    pub(super) fn finish_morph(&mut self, granted: u32, now: f32) -> usize {
        if let Some(m) = &mut self.morph
            && let Err(e) = m
                .morphs
                .grant(&self.mesh, &self.cache, granted as usize, now)
        {
            warn_once!("a view-dependent model keeps its level: {e}");
        }
        self.stage_indices();
        self.shown_count()
    }

    /// Triangles drawn: the level shown under geomorphs, else the refined one.
    pub(super) fn shown_count(&self) -> usize {
        self.morph
            .as_ref()
            .map_or(self.cache.triangle_count(), |m| {
                m.morphs.shown().triangle_count()
            })
    }

    /// Copies the level drawn into `staged` when it changed.
    fn stage_indices(&mut self) {
        let shown = match &mut self.morph {
            Some(m) if m.morphs.shown().is_changed() => {
                let shown = m.morphs.shown().indices();
                stage(&mut self.staged, shown);
                m.morphs.clear_changed();
                return;
            }
            Some(_) => return,
            None => &mut self.cache,
        };
        if shown.is_changed() {
            stage(&mut self.staged, shown.indices());
            shown.clear_changed();
        }
    }

    /// New settings: the search and what it knew start over.
    pub(super) fn set_settings(&mut self, settings: ViewDependent) {
        self.settings = settings;
        self.search = ToleranceSearch::default();
        self.floor_count = None;
        self.warned_tolerance = false;
    }

    /// Triangles of the refined level.
    pub(super) fn triangle_count(&self) -> usize {
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
    pub(super) fn max_useful(&self) -> usize {
        let full = self.mesh.mesh().max_triangles();
        match (self.settings.tolerance_px, self.floor_count) {
            (Some(_), Some(n)) => (n + n / 4 + 16).clamp(self.mesh.mesh().min_triangles(), full),
            _ => full,
        }
    }

    /// Moves the refined level to this frame's goal. Returns its triangles.
    pub(super) fn select(&mut self) -> usize {
        let floor = self.floor();
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
                                Some(_) if self.capped => Some(target as usize),
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

/// `indices` into `staged`, in its index type, ready for `Upload`.
fn stage(staged: &mut StagedIndices, indices: &[u32]) {
    match &mut staged.indices {
        Indices::U16(buffer) => {
            buffer.clear();
            buffer.extend(indices.iter().map(|&i| i as u16));
        }
        Indices::U32(buffer) => {
            buffer.clear();
            buffer.extend_from_slice(indices);
        }
    }
    staged.ready = true;
}
