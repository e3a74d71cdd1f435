//! A model's state once its asset is loaded: [`MultiresInstance`], the public read-only part
//! every kind of model has, and the internal parts that only some kinds have.
//!
//! | component | on | written by | read by |
//! |---|---|---|---|
//! | [`MultiresInstance`] | every model | `Spawn`, `Allocate` (skinned boxes), `SelectLod`, `Deform` | everyone |
//! | [`AllocationSlot`] | every model | `Allocate` | `SelectLod` |
//! | [`RegionStaging`] | unskinned models | `SelectLod` | `Upload` |
//! | `SkinState` ([`skin`](super::skin)) | skinned models | `Allocate`, `Deform` | `Upload` |
//! | `RegionGeomorphs` ([`geomorph`](super::geomorph)) | models with a [`Geomorph`](super::Geomorph) | `SelectLod` | `Deform`, `Upload` |
//! | `ViewDependentState` ([`view_dependent`](super::view_dependent)) | unskinned [`ViewDependent`](super::ViewDependent) models | `Spawn`, `Allocate`, `SelectLod` | `Upload` |
//! | [`Rebuild`] | models whose asset changed | `Spawn` | `Spawn` |

use crate::bounds::Obb;
use crate::regions::{ErrorCurves, RegionCaches, RegionMesh};
use bevy::asset::AssetId;
use bevy::mesh::Indices;
use bevy::prelude::*;
use std::sync::Arc;

/// The per-instance state of a [`MultiresModel`](super::MultiresModel), added by the plugin:
/// one polygon cache per region, the allocated counts and the region meshes. Read-only: the
/// plugin's systems change it.
#[derive(Component, Debug)]
pub struct MultiresInstance {
    /// The asset it was built from (a [`MultiresModel`](super::MultiresModel) given another
    /// handle is rebuilt).
    pub(super) asset: AssetId<super::asset::MultiresMesh>,
    pub(super) regions: Arc<RegionMesh>,
    pub(super) obbs: Arc<[Obb]>,
    /// Every region's triangles against its error (the asset's).
    pub(super) curves: Arc<ErrorCurves>,
    /// A box around every region's box, in the model's space: a model whose box is out of
    /// every view skips its regions' projections (unskinned models only).
    pub(super) bounds: Obb,
    pub(super) caches: RegionCaches,
    pub(super) targets: Vec<u32>,
    pub(super) meshes: Vec<Handle<Mesh>>,
    /// `meshes`' ids, for `Upload`: reading one from its handle follows the handle's pointer,
    /// a cache miss per region mesh.
    pub(super) mesh_ids: Vec<AssetId<Mesh>>,
    /// Every region entity, by region (a skinned model's rigid regions live under their
    /// joints, the others under the model).
    pub(super) region_entities: Vec<Entity>,
    /// Skinned models: every region's box in world space this frame, moved with its bones
    /// (empty until the first `Allocate`).
    pub(super) skinned_boxes: Option<Vec<Obb>>,
    /// A [`ViewDependent`](super::ViewDependent) model: the level it draws instead of its
    /// regions (which are hidden and keep their levels).
    pub(super) level: Option<LevelSummary>,
}

/// What a view-dependent model draws, as the last system that changed it left it.
#[derive(Clone, Copy, Debug)]
pub(super) struct LevelSummary {
    /// The child drawing the level.
    pub(super) entity: Entity,
    /// Triangles drawn.
    pub(super) shown: usize,
    pub(super) report: Refinement,
}

/// What a view-dependent model did in the last `SelectLod`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct Refinement {
    /// Triangles of the level it refined to (under [`Geomorph`](super::Geomorph), the level
    /// shown reaches it within the morph time: [`MultiresInstance::triangle_count`]
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

impl MultiresInstance {
    /// The instance's polygon caches (read-only). A [`SharedLevels`](super::SharedLevels)
    /// model's keep its regions' levels alone, no index buffers
    /// ([`RegionCaches::levels_only`]): its level meshes are made once per asset.
    #[inline]
    #[must_use]
    pub fn caches(&self) -> &RegionCaches {
        &self.caches
    }

    /// The regions this instance shows.
    #[inline]
    #[must_use]
    pub fn regions(&self) -> &RegionMesh {
        &self.regions
    }

    /// Per region, the triangle count the last allocation gave it (taken over in
    /// [`AslodSystems::SelectLod`](super::AslodSystems::SelectLod): between `Allocate` and
    /// `SelectLod` it still holds the previous frame's).
    #[inline]
    #[must_use]
    pub fn targets(&self) -> &[u32] {
        &self.targets
    }

    /// Per region, the Bevy mesh the plugin writes.
    #[inline]
    #[must_use]
    pub fn meshes(&self) -> &[Handle<Mesh>] {
        &self.meshes
    }

    /// Whether the instance is skinned and animated by joints.
    #[inline]
    #[must_use]
    pub fn is_skinned(&self) -> bool {
        self.skinned_boxes.is_some()
    }

    /// The world-space box of every region as the last `Allocate` saw it (skinned models:
    /// moved with their bones), else `None`.
    #[must_use]
    pub fn skinned_world_boxes(&self) -> Option<&[Obb]> {
        self.skinned_boxes.as_deref()
    }

    /// Per region, the entity that draws it.
    #[inline]
    #[must_use]
    pub fn region_entities(&self) -> &[Entity] {
        &self.region_entities
    }

    /// Triangles the instance shows now: all regions together, or its variable-resolution
    /// level while it is [`ViewDependent`](super::ViewDependent).
    #[inline]
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        match &self.level {
            Some(level) => level.shown,
            None => self.caches.total_triangles(),
        }
    }

    /// What the model's view-dependent refinement did last frame, while it is
    /// [`ViewDependent`](super::ViewDependent) (and not skinned).
    #[inline]
    #[must_use]
    pub fn refinement(&self) -> Option<&Refinement> {
        self.level.as_ref().map(|l| &l.report)
    }

    /// The entity drawing the model's variable-resolution level, while it is
    /// [`ViewDependent`](super::ViewDependent).
    #[inline]
    #[must_use]
    pub fn variable_level_entity(&self) -> Option<Entity> {
        self.level.as_ref().map(|l| l.entity)
    }

    /// Every entity that draws the model: the regions, and the variable-resolution level.
    pub(super) fn drawn_entities(&self) -> impl Iterator<Item = Entity> + '_ {
        self.region_entities
            .iter()
            .copied()
            .chain(self.level.as_ref().map(|l| l.entity))
    }
}

/// Where a model's inputs sat in the last allocation that included it.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub(super) struct AllocationSlot {
    /// That allocation's serial number ([`FrameAllocation::serial`](super::allocate::FrameAllocation)).
    pub(super) allocation: u64,
    /// The model's first input in that allocation's inputs and counts.
    pub(super) first: usize,
    /// The tolerance its last split by error found (`NaN`: none yet), where the next one
    /// starts ([`ErrorCurves::split_from`]).
    pub(super) tolerance: f32,
    /// That allocation found the model smaller than [`PolygonBudget::min_pixels`] (or out
    /// of view under it): it shows nothing.
    ///
    /// [`PolygonBudget::min_pixels`]: super::PolygonBudget::min_pixels
    pub(super) too_small: bool,
    /// Whether its region entities are hidden for being too small now.
    pub(super) hidden: bool,
}

impl Default for AllocationSlot {
    fn default() -> Self {
        Self {
            allocation: 0,
            first: 0,
            tolerance: f32::NAN,
            too_small: false,
            hidden: false,
        }
    }
}

/// An unskinned model's index buffers between `SelectLod` and `Upload` (skinned models
/// stage theirs in `SkinState`, written in `Deform`).
#[derive(Component, Debug)]
pub(super) struct RegionStaging {
    /// Per region, the index buffer `SelectLod` wrote for `Upload`.
    pub(super) staged: Vec<StagedIndices>,
    /// The regions whose `staged` flag `SelectLod` raised since the last `Upload`, each once.
    pub(super) ready: Vec<u32>,
    /// `SelectLod` left every region at its target and wrote every dirty one, so the same
    /// targets again leave nothing to do (only `SelectLod` moves the caches).
    pub(super) settled: bool,
    /// The triangles `SelectLod` left the instance showing, all regions together.
    pub(super) shown: u64,
}

impl RegionStaging {
    /// Empty staging for `regions`, unsettled.
    pub(super) fn new(regions: &RegionMesh) -> Self {
        Self {
            staged: regions
                .regions()
                .iter()
                .map(|region| StagedIndices::new(region.fits_u16()))
                .collect(),
            ready: Vec::new(),
            settled: false,
            shown: 0,
        }
    }
}

/// One index buffer between `SelectLod` and `Upload`.
#[derive(Debug)]
pub(super) struct StagedIndices {
    /// `SelectLod` wrote a new level into `indices` that `Upload` has not swapped in yet.
    pub(super) ready: bool,
    /// The new level, for `Upload` to swap into the mesh; after the swap, the mesh's old
    /// buffer, so steady state allocates nothing. 16-bit wherever the mesh's vertices fit
    /// (half the bytes to write, keep and upload).
    pub(super) indices: Indices,
}

impl StagedIndices {
    /// Nothing staged, in 16-bit indices when `narrow`.
    pub(super) fn new(narrow: bool) -> Self {
        Self {
            ready: false,
            indices: empty_indices(narrow),
        }
    }

    /// `indices` staged in this buffer's index type, ready for `Upload`.
    pub(super) fn stage(&mut self, indices: &[u32]) {
        match &mut self.indices {
            Indices::U16(buffer) => {
                buffer.clear();
                buffer.extend(indices.iter().map(|&i| i as u16));
            }
            Indices::U32(buffer) => {
                buffer.clear();
                buffer.extend_from_slice(indices);
            }
        }
        self.ready = true;
    }
}

/// An empty index buffer, 16-bit when `narrow`.
pub(super) fn empty_indices(narrow: bool) -> Indices {
    if narrow {
        Indices::U16(Vec::new())
    } else {
        Indices::U32(Vec::new())
    }
}

/// Hot reload: the model's asset changed, so `Spawn` builds its state anew.
#[derive(Component, Clone, Copy, Debug, Default)]
pub(super) struct Rebuild;
