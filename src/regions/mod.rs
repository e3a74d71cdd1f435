//! Regions: parts of one mesh that change detail independently, without cracks.
//!
//! ASLOD section 4 (coarse view-dependence): a large mesh is cut into regions so that its
//! near side can be finer than its far side. The cut goes through the vertices, not the
//! triangles:
//!
//! - every vertex belongs to exactly one region ([`Partition`]);
//! - a triangle belongs to the region that holds at least two of its corners; a triangle
//!   whose three corners lie in three regions belongs to the one with the smallest id
//!   ([`triangle_owner`]; the paper leaves this case open);
//! - a region's progressive sequence only collapses edges between two of its own vertices,
//!   so an edge across a border is never collapsed; edges of border triangles that lie inside
//!   one region may be;
//! - a border triangle's corners in other regions ("foreign" corners) are looked up at draw
//!   time: each one is replaced by the vertex that represents it in its own region at that
//!   region's current level. Both triangles on any edge see the same representatives, so the
//!   border stays watertight whatever levels the neighbours have. No triangle ever loses its
//!   area this way (corners in different regions never meet); border triangles that could
//!   come onto the same three positions as another ("fins") are found when the regions are
//!   built, and only those are checked when a region is written.
//!
//! Each region's sequence is built on the triangles it owns plus, as context, the
//! neighbours' triangles around its vertices, so the validity checks (link condition, flips)
//! see the whole surface around every collapse.
//!
//! ```
//! use bevy_aslod::mesh::IndexedMesh;
//! use bevy_aslod::multires::BuildOptions;
//! use bevy_aslod::regions::{GridPlane, Partition, RegionCaches, RegionMesh};
//! use glam::Vec3;
//!
//! // A 9x9-vertex terrain patch cut into 2x2 regions.
//! let mut positions = Vec::new();
//! for z in 0..9 {
//!     for x in 0..9 {
//!         positions.push(Vec3::new(x as f32, ((x * 7 + z * 3) % 5) as f32 * 0.2, z as f32));
//!     }
//! }
//! let mut indices = Vec::new();
//! for z in 0..8u32 {
//!     for x in 0..8u32 {
//!         let i = z * 9 + x;
//!         indices.extend_from_slice(&[i, i + 9, i + 1, i + 1, i + 9, i + 10]);
//!     }
//! }
//! let mesh = IndexedMesh::new(positions, indices);
//! let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2)?;
//! let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default())?;
//! let mut caches = RegionCaches::new(&regions);
//! caches.set_triangle_count(&regions, 0, 4); // the first region coarse, the rest full
//! let mut out = Vec::new();
//! caches.write_indices(&regions, 0, &mut out);
//! assert!(out.len() / 3 <= 4);
//! # Ok::<(), bevy_aslod::regions::RegionError>(())
//! ```

mod bands;
mod borders;
mod build;
mod cache;
mod error_split;
mod merge;
mod morph;
mod partition;
mod util;

pub use cache::RegionCaches;
pub use error_split::ErrorCurves;
pub use merge::MergedRoot;
pub use morph::{Geomorphs, MorphGroup, MorphKind, VertexMorph};
pub use partition::{GridPlane, Partition};

use crate::mesh::MeshError;
use crate::multires::ProgressiveMesh;
use glam::Vec3;
use thiserror::Error;

/// What can go wrong when partitioning or building regions.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RegionError {
    /// The per-vertex ids do not match the vertex count.
    #[error("region ids: expected one per vertex ({expected}), found {found}")]
    LengthMismatch {
        /// Vertex count.
        expected: usize,
        /// Ids given.
        found: usize,
    },
    /// A grid with zero cells or a clustering into zero regions was asked for.
    #[error("a partition needs at least one region (got zero cells or a zero target)")]
    ZeroRegions,
    /// The mesh has no vertices.
    #[error("cannot partition an empty mesh")]
    EmptyMesh,
    /// The partition was made for another mesh.
    #[error("the partition has {found} vertices but the mesh has {expected}")]
    PartitionMismatch {
        /// Vertex count of the mesh.
        expected: usize,
        /// Vertex count of the partition.
        found: usize,
    },
    /// The mesh itself is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// The region that owns a triangle whose corners lie in `regions`: the one holding at least
/// two corners, or, when all three differ, the smallest id.
///
/// ```
/// use bevy_aslod::regions::triangle_owner;
/// assert_eq!(triangle_owner([4, 2, 4]), 4);
/// assert_eq!(triangle_owner([5, 3, 7]), 3);
/// ```
#[inline]
#[must_use]
pub fn triangle_owner(regions: [u32; 3]) -> u32 {
    let [a, b, c] = regions;
    if a == b || a == c {
        a
    } else if b == c {
        b
    } else {
        a.min(b).min(c)
    }
}

/// A foreign corner whose representative changes when the region owning its vertex passes
/// one step: moving past `step` (to a level above it) writes `after` into the corner, moving
/// back writes `before`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FrontEvent {
    /// The owner's step, as in [`PolygonCache::level`](crate::multires::PolygonCache::level):
    /// the vertex `before` is present at every level `<= step`.
    pub(crate) step: u32,
    /// The region whose triangle holds the corner.
    pub(crate) region: u32,
    /// Index into that region's full-detail index buffer.
    pub(crate) corner: u32,
    /// Local vertices of `region`.
    pub(crate) before: u32,
    pub(crate) after: u32,
}

/// One region of a [`RegionMesh`].
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    /// The region's progressive sequence, over a local vertex table.
    pub(crate) mesh: ProgressiveMesh,
    /// Local vertex -> vertex of the source mesh.
    pub(crate) global: Vec<u32>,
    /// Triangles with a foreign corner, increasing.
    pub(crate) border: Vec<u32>,
    /// The border triangles that may, at some mix of levels, sit on the same three positions
    /// as another border triangle (a fin, or a copy), increasing: the only ones
    /// `write_indices` has to look at (see [`fin_prone`](borders::fin_prone)). Usually empty.
    pub(crate) fin_prone: Vec<u32>,
    /// Where this region's steps move other regions' foreign corners, sorted by step.
    pub(crate) front_events: Vec<FrontEvent>,
    /// Regions whose vertices appear in this region's triangles.
    pub(crate) neighbors: Vec<u32>,
    pub(crate) own_vertices: usize,
    pub(crate) bounds: (Vec3, Vec3),
    /// Local vertex -> the first local vertex at the same position (seams weld); empty when
    /// no two vertices share a position.
    pub(crate) position_of: Vec<u32>,
}

impl Region {
    /// The first local vertex at the same position as local vertex `v`.
    #[inline]
    pub(crate) fn position_of(&self, v: u32) -> u32 {
        if self.position_of.is_empty() {
            v
        } else {
            self.position_of[v as usize]
        }
    }

    /// True when 16-bit indices can address the region's local vertex table (at most 65,535
    /// vertices: index `0xFFFF` stays unused, Metal and WebGL read it as a primitive restart):
    /// see [`RegionCaches::write_indices_u16`].
    #[inline]
    #[must_use]
    pub fn fits_u16(&self) -> bool {
        self.mesh.vertices().vertex_count() as u64
            <= <u16 as crate::multires::CacheIndex>::MAX_VERTICES
    }

    /// The region's progressive sequence. Its vertex table is local: see
    /// [`global_vertices`](Self::global_vertices).
    #[inline]
    #[must_use]
    pub fn progressive_mesh(&self) -> &ProgressiveMesh {
        &self.mesh
    }

    /// Local vertex index -> vertex index in the source mesh.
    #[inline]
    #[must_use]
    pub fn global_vertices(&self) -> &[u32] {
        &self.global
    }

    /// Fewest triangles the region can show (its base mesh).
    #[inline]
    #[must_use]
    pub fn min_triangles(&self) -> usize {
        self.mesh.min_triangles()
    }

    /// Triangles at full detail.
    #[inline]
    #[must_use]
    pub fn max_triangles(&self) -> usize {
        self.mesh.max_triangles()
    }

    /// Axis-aligned bounds of the region's own vertices, in the mesh's space.
    #[inline]
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// The tight box around the region's own vertices ([`fit_obb`](crate::bounds::fit_obb);
    /// an axis-aligned one when that fails, the bounds when no point is usable): the box the
    /// budget projects.
    #[must_use]
    pub fn obb(&self) -> crate::bounds::Obb {
        use crate::bounds::{Obb, fit_aabb, fit_obb};
        let points = &self.mesh.vertices().positions[..self.own_vertices];
        fit_obb(points)
            .or_else(|| fit_aabb(points))
            .unwrap_or_else(|| Obb::from_aabb(self.bounds.0, self.bounds.1))
    }

    /// Positions of the region's own vertices (for fitting a bounding box).
    pub fn own_positions(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.mesh.vertices().positions[..self.own_vertices]
            .iter()
            .copied()
    }

    /// Regions whose vertices appear in this region's border triangles.
    #[inline]
    #[must_use]
    pub fn neighbors(&self) -> &[u32] {
        &self.neighbors
    }
}

/// A partitioned multiresolution mesh: one progressive sequence per region, sharing the
/// source mesh's vertices.
#[derive(Clone, Debug)]
pub struct RegionMesh {
    partition: Partition,
    regions: Vec<Region>,
    vertex_count: usize,
    /// The whole model as one mesh below its regions' kept levels
    /// ([`BuildOptions::root_ratio`](crate::multires::BuildOptions::root_ratio)).
    pub(crate) root: Option<MergedRoot>,
    /// Built here, not read from a file: the fin-prone lists are the builder's, so debug
    /// builds check that no other border triangles meet. A file's are only range-checked.
    pub(crate) built: bool,
    /// The geomorph tables, made by the first [`Geomorphs`] of the mesh and shared by all.
    pub(crate) morph_tables:
        std::sync::OnceLock<std::sync::Arc<crate::multires::morph::MorphTables>>,
}

/// Equal regions, however they were made.
impl PartialEq for RegionMesh {
    fn eq(&self, other: &Self) -> bool {
        self.partition == other.partition
            && self.regions == other.regions
            && self.vertex_count == other.vertex_count
            && self.root == other.root
    }
}

impl RegionMesh {
    /// Regions read from a baked file (checked by its reader).
    pub(crate) fn from_parts(
        partition: Partition,
        regions: Vec<Region>,
        vertex_count: usize,
        root: Option<MergedRoot>,
    ) -> Self {
        Self {
            partition,
            regions,
            vertex_count,
            root,
            built: false,
            morph_tables: std::sync::OnceLock::new(),
        }
    }

    /// The source mesh's vertex table (every attribute, no indices), put back together from
    /// the regions' local tables. A vertex no region's triangles use is left at zero.
    #[must_use]
    pub fn source_vertices(&self) -> crate::mesh::IndexedMesh {
        fn scatter<T: Copy + Default>(
            regions: &[Region],
            n: usize,
            field: impl Fn(&crate::mesh::IndexedMesh) -> Option<&Vec<T>>,
        ) -> Option<Vec<T>> {
            // Every region has the same attributes: the first one says which.
            field(regions.first()?.mesh.vertices())?;
            let mut out = vec![T::default(); n];
            for r in regions {
                let local = field(r.mesh.vertices())?;
                for (&g, &x) in r.global.iter().zip(local) {
                    if let Some(slot) = out.get_mut(g as usize) {
                        *slot = x;
                    }
                }
            }
            Some(out)
        }
        let n = self.vertex_count;
        let r = &self.regions;
        let attributes = r.first().map_or_else(Vec::new, |first| {
            first
                .mesh
                .vertices()
                .attributes
                .iter()
                .enumerate()
                .map(|(k, a)| {
                    let size = a.format.size();
                    let mut data = vec![0u8; n * size];
                    for region in r {
                        let local = &region.mesh.vertices().attributes[k];
                        for (i, &g) in region.global.iter().enumerate() {
                            if let Some(slot) =
                                data.get_mut(g as usize * size..(g as usize + 1) * size)
                            {
                                slot.copy_from_slice(local.record(i));
                            }
                        }
                    }
                    crate::mesh::VertexAttribute {
                        data,
                        ..a.without_data()
                    }
                })
                .collect()
        });
        crate::mesh::IndexedMesh {
            positions: scatter(r, n, |m| Some(&m.positions)).unwrap_or_default(),
            normals: scatter(r, n, |m| m.normals.as_ref()),
            uvs: scatter(r, n, |m| m.uvs.as_ref()),
            joints: scatter(r, n, |m| m.joints.as_ref()),
            weights: scatter(r, n, |m| m.weights.as_ref()),
            tangents: scatter(r, n, |m| m.tangents.as_ref()),
            attributes,
            indices: Vec::new(),
        }
    }

    /// The regions, indexed by region id.
    #[inline]
    #[must_use]
    pub fn regions(&self) -> &[Region] {
        &self.regions
    }

    /// The partition the mesh was built with (seam copies follow their position).
    #[inline]
    #[must_use]
    pub fn partition(&self) -> &Partition {
        &self.partition
    }

    /// Vertices of the source mesh.
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The merged root: the whole model as one progressive mesh, from every region at its
    /// kept level down, its borders free to collapse ([`MergedRoot`]); `None` when the build
    /// asked for none ([`BuildOptions::root_ratio`](crate::multires::BuildOptions::root_ratio))
    /// or there is one region.
    #[inline]
    #[must_use]
    pub fn root(&self) -> Option<&MergedRoot> {
        self.root.as_ref()
    }

    /// Bytes of the shared data of every region, and of the root.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.root.as_ref().map_or(0, MergedRoot::memory_bytes)
            + self
                .regions
                .iter()
                .map(|r| {
                    r.mesh.memory_bytes()
                        + r.global.len() * 4
                        + r.border.len() * 4
                        + r.fin_prone.len() * 4
                        + r.front_events.len() * size_of::<FrontEvent>()
                })
                .sum::<usize>()
    }
}
