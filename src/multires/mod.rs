//! Progressive meshes: one mesh that moves to any triangle count, cheaply and exactly.
//!
//! [`ProgressiveMesh::build`] runs QEM-ranked half-edge collapses (each removes one vertex by
//! moving it onto a neighbour; its cost is the quadric error, see
//! [`BuildOptions::weight_exponent`], plus a local error, see
//! [`BuildOptions::local_weight`]) from the full mesh down to a base mesh, and records them. The
//! triangles are stored in removal order (Hoxha's MR-model; MOM's incremental sequence), so
//! the triangles of any level are a prefix of one index buffer, and every level uses a subset
//! of the original vertices, which is what ASLOD's shared vertex table and precomputed skin
//! weights need (ASLOD section 5.4).
//!
//! A [`PolygonCache`] is one instance's view of the sequence (the paper's polygonal cache):
//! a copy of the index buffer that [`PolygonCache::set_triangle_count`] walks back and forth,
//! rewriting only the corners each step records, O(valence) per step with no search.
//!
//! ```
//! use bevy_aslod::mesh::IndexedMesh;
//! use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
//! use glam::Vec3;
//!
//! // A 4x4-vertex grid: 18 triangles.
//! let mut positions = Vec::new();
//! for y in 0..4 {
//!     for x in 0..4 {
//!         positions.push(Vec3::new(x as f32, ((x * y) % 3) as f32 * 0.1, y as f32));
//!     }
//! }
//! let mut indices = Vec::new();
//! for y in 0..3u32 {
//!     for x in 0..3u32 {
//!         let i = y * 4 + x;
//!         indices.extend_from_slice(&[i, i + 4, i + 1, i + 1, i + 4, i + 5]);
//!     }
//! }
//! let mesh = IndexedMesh::new(positions, indices);
//! let pm = ProgressiveMesh::build(&mesh, &BuildOptions::default())?;
//! let mut cache = PolygonCache::new(&pm);
//! assert_eq!(cache.triangle_count(), 18);
//! let reached = cache.set_triangle_count(&pm, 6);
//! assert!(reached <= 6);
//! assert_eq!(cache.indices().len(), 3 * reached);
//! cache.set_triangle_count(&pm, usize::MAX);
//! assert_eq!(cache.indices(), pm.full_indices());
//! # Ok::<(), bevy_aslod::mesh::MeshError>(())
//! ```

pub(crate) mod build;
mod cache;
mod heap;
pub(crate) mod hierarchy;
mod index;
pub(crate) mod morph;
mod quadric;
pub(crate) mod records;

pub use build::{BuildOptions, CollapseOperator};
pub use cache::PolygonCache;
pub(crate) use cache::steady_targets;
pub use index::CacheIndex;

use crate::mesh::{IndexedMesh, MeshError};
use records::Layout;

/// A mesh that can be moved to any triangle count between its base and full detail.
///
/// Built once (offline, or at load on a background task) and shared by every instance;
/// each instance keeps its own [`PolygonCache`].
#[derive(Clone, Debug, PartialEq)]
pub struct ProgressiveMesh {
    /// The vertex table, unchanged from the source; its `indices` are empty (the triangles
    /// are in `records`).
    pub(crate) vertices: IndexedMesh,
    pub(crate) base_triangles: u32,
    /// The full-detail triangles in slot order (base triangles first, then the triangles of
    /// the last collapse, ..., the first) and the step records, packed.
    pub(crate) records: Layout,
    /// `errors[i]`: the geometric error after `i + 1` collapses, relative to the bounding-box
    /// diagonal, rounded up to 16 bits (`records::error_to_u16`); monotone.
    pub(crate) errors: Vec<u16>,
    /// The view-dependent data ([`BuildOptions::view_dependent`]), for `refine`.
    pub(crate) view: Option<hierarchy::ViewData>,
}

impl ProgressiveMesh {
    /// Builds the progressive sequence of `mesh`.
    ///
    /// The mesh is validated first (a copy is; the input is not changed), so degenerate
    /// triangles are dropped and bad input is reported rather than built.
    ///
    /// # Errors
    /// Any [`MeshError`] from [`IndexedMesh::validate`], and [`MeshError::TooLarge`] for a mesh
    /// too large to index (over 715 million triangles).
    pub fn build(mesh: &IndexedMesh, options: &BuildOptions) -> Result<Self, MeshError> {
        Self::build_with(mesh, options, None, &mut |_, _| {})
    }

    /// [`build`](Self::build) with pinned vertices and a progress callback.
    ///
    /// `pinned[v]`, when given, keeps vertex `v` (and every vertex at its position) from being
    /// removed or used as a collapse target: regions pin their neighbours' vertices this way.
    /// `progress(removed, total)` is called every few thousand collapses with the triangles
    /// removed so far.
    ///
    /// # Errors
    /// As [`build`](Self::build); also [`MeshError::AttributeCountMismatch`] when `pinned`
    /// does not have one entry per vertex.
    pub fn build_with(
        mesh: &IndexedMesh,
        options: &BuildOptions,
        pinned: Option<&[bool]>,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Self, MeshError> {
        let mut mesh = mesh.clone();
        mesh.validate()?;
        if let Some(pinned) = pinned
            && pinned.len() != mesh.vertex_count()
        {
            return Err(MeshError::AttributeCountMismatch {
                attribute: "pinned",
                expected: mesh.vertex_count(),
                found: pinned.len(),
            });
        }
        let owned = mesh.triangle_count();
        let constraints = build::Constraints {
            pinned,
            ..build::Constraints::default()
        };
        Ok(build::build(&mesh, options, &constraints, owned, progress)?.mesh)
    }

    /// The vertex table: positions and the other attributes, unchanged from the source. Its
    /// `indices` are empty: the triangles are kept packed, see
    /// [`full_indices`](Self::full_indices) and [`to_indexed_mesh`](Self::to_indexed_mesh).
    #[inline]
    #[must_use]
    pub fn vertices(&self) -> &IndexedMesh {
        &self.vertices
    }

    /// The full-detail index buffer, in slot (reverse removal) order: a copy, widened to
    /// `u32` (the mesh keeps 16-bit indices when its vertices fit).
    #[must_use]
    pub fn full_indices(&self) -> Vec<u32> {
        self.records.indices_as()
    }

    /// The vertex table with the full-detail triangles: the source mesh, its triangles in
    /// slot order.
    #[must_use]
    pub fn to_indexed_mesh(&self) -> IndexedMesh {
        IndexedMesh {
            indices: self.full_indices(),
            ..self.vertices.clone()
        }
    }

    /// Triangles at full detail.
    #[inline]
    #[must_use]
    pub fn max_triangles(&self) -> usize {
        self.records.index_count() / 3
    }

    /// Triangles of the base mesh, the coarsest level.
    #[inline]
    #[must_use]
    pub fn min_triangles(&self) -> usize {
        self.base_triangles as usize
    }

    /// Number of levels, the collapses plus one: levels are numbered `0` (full detail) to
    /// `level_count() - 1` (base mesh).
    #[inline]
    #[must_use]
    pub fn level_count(&self) -> usize {
        self.records.step_count() + 1
    }

    /// Geometric error of `level` relative to the bounding-box diagonal (the simplification
    /// table): `0` at full detail, growing monotonically towards the base mesh. Levels past
    /// the end are clamped.
    #[must_use]
    pub fn level_error(&self, level: usize) -> f32 {
        match level.min(self.errors.len()) {
            0 => 0.0,
            l => records::error_from_u16(self.errors[l - 1]),
        }
    }

    /// Triangle count of every level, full detail first.
    #[must_use]
    pub fn level_triangle_counts(&self) -> Vec<usize> {
        let mut count = self.max_triangles();
        let mut out = Vec::with_capacity(self.level_count());
        out.push(count);
        for removed in self.records.removed() {
            count -= removed;
            out.push(count);
        }
        out
    }

    /// The coarsest level whose error is at most `error` (relative to the diagonal): the
    /// fewest triangles that keep the error below `error`.
    #[must_use]
    pub fn level_for_error(&self, error: f32) -> usize {
        // errors is monotone: count the collapses whose error stays within the bound.
        self.errors
            .partition_point(|&e| records::error_from_u16(e) <= error)
    }

    /// Appends vertices that no triangle uses yet (regions add their neighbours'
    /// representatives this way). `vertices` must have the same attributes as the table. The
    /// records never name them, so their layout does not change.
    pub(crate) fn append_vertices(&mut self, vertices: &IndexedMesh) {
        self.vertices.append_vertices(vertices);
    }

    /// Bytes of the shared data: the vertex table, the index buffer, the records, the error
    /// table and the view-dependent data when there is some.
    ///
    /// A mesh of at most 65,535 vertices keeps 16-bit indices, 16-bit step headers and
    /// 3-byte corner records; larger ones 32 bits each. Errors take 16 bits.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        indexed_mesh_bytes(&self.vertices)
            + self.records.bytes()
            + self.errors.len() * 2
            + self.view.as_ref().map_or(0, hierarchy::ViewData::bytes)
    }

    /// Whether the mesh keeps the data view-dependent refinement needs
    /// ([`BuildOptions::view_dependent`]).
    #[inline]
    #[must_use]
    pub fn has_view_data(&self) -> bool {
        self.view.is_some()
    }
}

/// Bytes of an indexed mesh's vertex attributes and index buffer.
#[must_use]
pub fn indexed_mesh_bytes(mesh: &IndexedMesh) -> usize {
    mesh.memory_bytes()
}
