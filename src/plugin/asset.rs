//! The [`MultiresMesh`] asset: a partitioned multiresolution mesh shared by its instances.

use super::error::MultiresError;
use super::skin::binding::SkinBinding;
use crate::bevy_mesh::from_bevy_mesh;
use crate::bounds::{Obb, fit_aabb};
use crate::mesh::IndexedMesh;
use crate::mrm::BakedMesh;
use crate::multires::{BuildOptions, ProgressiveMesh};
use crate::refine::VariableMesh;
use crate::regions::{ErrorCurves, GridPlane, Partition, Region, RegionError, RegionMesh};
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, TaskPool};
use glam::{Mat4, Vec3};
use std::sync::Arc;

/// How to cut a mesh into regions for [`MultiresMesh::from_bevy_mesh`].
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PartitionSpec {
    /// One region: the whole mesh changes detail as one.
    Single,
    /// A grid of `nx` by `ny` cells in `plane` ([`Partition::grid`]); for terrain.
    Grid {
        /// The plane the grid lies in.
        plane: GridPlane,
        /// Cells along the plane's first axis.
        nx: usize,
        /// Cells along the plane's second axis.
        ny: usize,
    },
    /// About this many compact, connected regions ([`Partition::clusters`]); for objects.
    Clusters(usize),
}

impl PartitionSpec {
    /// The partition of `mesh` this spec describes.
    ///
    /// # Errors
    /// As [`Partition::grid`] and [`Partition::clusters`].
    pub fn partition(&self, mesh: &IndexedMesh) -> Result<Partition, RegionError> {
        match *self {
            Self::Single => Partition::grid(mesh, GridPlane::XZ, 1, 1),
            Self::Grid { plane, nx, ny } => Partition::grid(mesh, plane, nx, ny),
            Self::Clusters(target) => Partition::clusters(mesh, target),
        }
    }
}

/// A multiresolution mesh: regions with their progressive sequences, and one bounding box
/// per region in the mesh's own space. Built once, shared by every [`MultiresModel`](super::MultiresModel)
/// that uses it; each instance keeps its own levels of detail.
#[derive(Asset, TypePath, Clone, Debug)]
pub struct MultiresMesh {
    regions: Arc<RegionMesh>,
    obbs: Arc<[Obb]>,
    /// The axis-aligned box around every region box.
    bounds: Obb,
    /// Every region's triangles against its error, for [`RegionSplit::ScreenError`](super::RegionSplit).
    curves: Arc<ErrorCurves>,
    skin: Option<Arc<SkinBinding>>,
    /// The whole mesh as one variable-resolution mesh, for [`ViewDependent`](super::ViewDependent).
    variable: Option<Arc<VariableMesh>>,
}

impl MultiresMesh {
    /// Wraps already built regions and fits one box per region (on its own vertices).
    #[must_use]
    pub fn from_regions(regions: RegionMesh) -> Self {
        let obbs = regions.regions().iter().map(Region::obb).collect();
        Self::from_parts(regions, obbs, None, None)
    }

    /// The asset of its parts; the bounds are the axis-aligned box around the region boxes.
    fn from_parts(
        regions: RegionMesh,
        obbs: Arc<[Obb]>,
        skin: Option<SkinBinding>,
        variable: Option<VariableMesh>,
    ) -> Self {
        let corners: Vec<Vec3> = obbs.iter().flat_map(Obb::corners).collect();
        let bounds = fit_aabb(&corners).unwrap_or(Obb::from_aabb(Vec3::ZERO, Vec3::ZERO));
        let curves = Arc::new(ErrorCurves::new(&regions, &obbs));
        Self {
            regions: Arc::new(regions),
            obbs,
            bounds,
            curves,
            skin: skin.map(Arc::new),
            variable: variable.map(Arc::new),
        }
    }

    /// The asset of already built (or read) data: nothing is built, the skin binding and
    /// the refinement graph are derived (linear in the vertices).
    ///
    /// ```
    /// use bevy_aslod::mrm::{self, BakedMesh};
    /// use bevy_aslod::plugin::{MultiresMesh, PartitionSpec};
    /// use bevy_aslod::prelude::*;
    ///
    /// let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
    /// let partition = PartitionSpec::Clusters(8).partition(&mesh)?;
    /// let baked = BakedMesh::build(&mesh, &partition, &BuildOptions::default())?;
    /// let cow = MultiresMesh::from_baked(baked)?;
    /// assert_eq!(cow.max_triangles(), mesh.triangle_count());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`MultiresError::Baked`] when the boxes or skin kinds do not match the regions, and
    /// [`MultiresError::Skin`] or [`MultiresError::Refine`] when the skin's influences or
    /// the refinement data are unusable.
    pub fn from_baked(baked: BakedMesh) -> Result<Self, MultiresError> {
        let BakedMesh {
            regions,
            obbs,
            skin,
            variable,
        } = baked;
        if obbs.len() != regions.regions().len() {
            return Err(MultiresError::Baked("one box per region is needed"));
        }
        let skin = skin
            .map(|s| SkinBinding::from_baked(&regions, s))
            .transpose()?;
        let variable = variable.map(VariableMesh::new).transpose()?;
        Ok(Self::from_parts(regions, obbs.into(), skin, variable))
    }

    /// Adds the refinement data a [`ViewDependent`](super::ViewDependent) model needs: the
    /// whole of `mesh` (the mesh the regions were built from) as one progressive mesh with
    /// the view-dependent bounds ([`BuildOptions::view_dependent`] is turned on), about
    /// 7 bytes per triangle more than a plain one, plus the dependency graph.
    ///
    /// ```
    /// use bevy_aslod::plugin::{MultiresMesh, PartitionSpec};
    /// use bevy_aslod::prelude::*;
    ///
    /// let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
    /// let partition = PartitionSpec::Clusters(8).partition(&mesh)?;
    /// let cow = MultiresMesh::from_indexed(&mesh, &partition)?
    ///     .with_refinement(&mesh, &BuildOptions::default())?;
    /// assert!(cow.variable().is_some());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`MultiresError::Mesh`] when `mesh` is invalid or too large to build.
    pub fn with_refinement(
        mut self,
        mesh: &IndexedMesh,
        options: &BuildOptions,
    ) -> Result<Self, MultiresError> {
        let options = options.clone().with_view_dependent(true);
        let pm = ProgressiveMesh::build(mesh, &options)?;
        self.variable = Some(Arc::new(VariableMesh::new(pm)?));
        Ok(self)
    }

    /// The refinement data, when [`with_refinement`](Self::with_refinement) added it.
    #[inline]
    #[must_use]
    pub fn variable(&self) -> Option<&Arc<VariableMesh>> {
        self.variable.as_ref()
    }

    /// Builds a skinned multiresolution mesh: regions by influence (a vertex whose dominant
    /// weight is at least `1 − rigid_delta` goes to its bone's rigid region, any other to
    /// the deformable region of its two largest influences), one progressive sequence per
    /// region, and the binding the plugin needs to animate it.
    ///
    /// `mesh` must carry joints and weights (glTF `JOINTS_0`/`WEIGHTS_0`) in bind space;
    /// `inverse_bindposes` has one matrix per joint. Weights that do not sum to one are
    /// normalised, with a warning.
    ///
    /// # Errors
    /// [`MultiresError::NotSkinned`] for a mesh without joints or weights,
    /// [`MultiresError::Skin`] for bad influences (negative, NaN, all zero, a joint out of
    /// range, no joints), and the errors of [`from_indexed`](Self::from_indexed).
    pub fn from_skinned(
        mesh: &IndexedMesh,
        inverse_bindposes: &[Mat4],
        rigid_delta: f32,
    ) -> Result<Self, MultiresError> {
        let baked = BakedMesh::build_skinned(mesh, inverse_bindposes, Vec::new(), rigid_delta)?;
        Self::from_baked(baked)
    }

    /// The skeleton binding, for a mesh built by [`from_skinned`](Self::from_skinned).
    #[inline]
    #[must_use]
    pub fn skin(&self) -> Option<&Arc<SkinBinding>> {
        self.skin.as_ref()
    }

    /// Builds the regions of `mesh` cut by `partition`, with default [`BuildOptions`].
    ///
    /// # Errors
    /// Any [`RegionError`] of [`RegionMesh::build`]: a partition made for another mesh, an
    /// invalid mesh.
    pub fn from_indexed(mesh: &IndexedMesh, partition: &Partition) -> Result<Self, MultiresError> {
        Self::from_indexed_with(mesh, partition, &BuildOptions::default())
    }

    /// [`from_indexed`](Self::from_indexed) with explicit build options.
    ///
    /// # Errors
    /// As [`from_indexed`](Self::from_indexed).
    pub fn from_indexed_with(
        mesh: &IndexedMesh,
        partition: &Partition,
        options: &BuildOptions,
    ) -> Result<Self, MultiresError> {
        // Scoped threads of their own: a scope on Bevy's compute pool, opened from the async
        // compute pool where the plugin builds its assets, never ran (the build hung).
        Ok(Self::from_regions(RegionMesh::build(
            mesh, partition, options,
        )?))
    }

    /// Builds from a Bevy triangle-list mesh (positions, normals, UVs, joints and weights),
    /// cut into regions as `spec` says.
    ///
    /// # Errors
    /// [`MultiresError::Mesh`] when the mesh cannot be read (see
    /// [`from_bevy_mesh`](crate::bevy_mesh::from_bevy_mesh)); [`MultiresError::Region`] when
    /// it cannot be partitioned or built.
    pub fn from_bevy_mesh(mesh: &Mesh, spec: PartitionSpec) -> Result<Self, MultiresError> {
        let indexed = from_bevy_mesh(mesh)?;
        let partition = spec.partition(&indexed)?;
        Self::from_indexed(&indexed, &partition)
    }

    /// Starts [`from_indexed`](Self::from_indexed) on Bevy's [`AsyncComputeTaskPool`], for
    /// meshes large enough to stall a frame. Poll the task (e.g. with
    /// `bevy::tasks::futures::check_ready`) and add the result to `Assets<MultiresMesh>`.
    /// The pool is created with default settings when no `TaskPoolPlugin` has made it.
    pub fn build_async(
        mesh: IndexedMesh,
        partition: Partition,
    ) -> Task<Result<Self, MultiresError>> {
        AsyncComputeTaskPool::get_or_init(TaskPool::default)
            .spawn(async move { Self::from_indexed(&mesh, &partition) })
    }

    /// The regions and their progressive sequences.
    #[inline]
    #[must_use]
    pub fn regions(&self) -> &Arc<RegionMesh> {
        &self.regions
    }

    /// One box per region, in the mesh's space, in region order.
    #[inline]
    #[must_use]
    pub fn obbs(&self) -> &Arc<[Obb]> {
        &self.obbs
    }

    /// The axis-aligned box around every region's box, in the mesh's space.
    #[inline]
    #[must_use]
    pub fn bounds(&self) -> Obb {
        self.bounds
    }

    /// Every region's triangle count against its geometric error, with which
    /// [`RegionSplit::ScreenError`](super::RegionSplit::ScreenError) shares a model's
    /// triangles among its regions.
    #[inline]
    #[must_use]
    pub fn error_curves(&self) -> &Arc<ErrorCurves> {
        &self.curves
    }

    /// Number of regions.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.regions.regions().len()
    }

    /// Triangles at full detail, all regions together.
    #[must_use]
    pub fn max_triangles(&self) -> usize {
        self.regions
            .regions()
            .iter()
            .map(|r| r.max_triangles())
            .sum()
    }

    /// Triangles at the coarsest level, all regions together.
    #[must_use]
    pub fn min_triangles(&self) -> usize {
        self.regions
            .regions()
            .iter()
            .map(|r| r.min_triangles())
            .sum()
    }
}
