//! The polygon cache: one instance's current level of a [`ProgressiveMesh`].

use super::ProgressiveMesh;
use super::index::CacheIndex;
use super::records::{Layout, Walk};

/// One instance's index buffer at its current level (ASLOD's polygonal cache).
///
/// The cache owns a copy of the full index buffer; the active triangles are always its
/// prefix. Moving one level rewrites the few corners that the step records (O(valence)), in
/// either direction, with no search. The cache does not borrow the mesh, so many caches can
/// share one [`ProgressiveMesh`] (for example behind an `Arc`); pass the same mesh to every
/// call.
///
/// The index type `I` is `u32` by default; [`with_index_type`](Self::with_index_type) makes a
/// `u16` cache for meshes of at most 65,535 vertices, which keeps half the bytes per instance
/// and moves and copies half as much memory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PolygonCache<I: CacheIndex = u32> {
    indices: Vec<I>,
    walk: Walk,
    changed: bool,
}

impl PolygonCache {
    /// A cache at full detail.
    #[must_use]
    pub fn new(mesh: &ProgressiveMesh) -> Self {
        Self::full(mesh)
    }
}

impl<I: CacheIndex> PolygonCache<I> {
    /// A cache at full detail holding indices of type `I`, or `None` when the mesh has more
    /// vertices than `I` can address.
    ///
    /// ```
    /// use bevy_aslod::mesh::IndexedMesh;
    /// use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
    /// use glam::Vec3;
    ///
    /// let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    /// let mesh = IndexedMesh::new(positions, vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]);
    /// let pm = ProgressiveMesh::build(&mesh, &BuildOptions::default()).unwrap();
    /// let mut narrow = PolygonCache::<u16>::with_index_type(&pm).expect("4 vertices fit");
    /// let mut wide = PolygonCache::new(&pm);
    /// narrow.set_triangle_count(&pm, 2);
    /// wide.set_triangle_count(&pm, 2);
    /// assert!(narrow.indices().iter().map(|&i| u32::from(i)).eq(wide.indices().iter().copied()));
    /// ```
    #[must_use]
    pub fn with_index_type(mesh: &ProgressiveMesh) -> Option<Self> {
        (mesh.vertices().vertex_count() as u64 <= I::MAX_VERTICES).then(|| Self::full(mesh))
    }

    fn full(mesh: &ProgressiveMesh) -> Self {
        Self {
            indices: mesh.records.indices_as(),
            walk: Walk {
                count: mesh.max_triangles(),
                ..Walk::default()
            },
            changed: true,
        }
    }

    /// The active triangles, ready to render: `3 * triangle_count()` indices into the mesh's
    /// vertex table.
    #[inline]
    #[must_use]
    pub fn indices(&self) -> &[I] {
        &self.indices[..3 * self.walk.count]
    }

    /// Bytes of the index buffer held.
    pub(crate) fn index_bytes(&self) -> usize {
        self.indices.capacity() * size_of::<I>()
    }

    /// The whole index buffer, for regions to resolve their foreign corners in place.
    #[inline]
    pub(crate) fn indices_mut(&mut self) -> &mut [I] {
        &mut self.indices
    }

    /// Number of active triangles.
    #[inline]
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.walk.count
    }

    /// Current level: `0` is full detail, each level one collapse coarser.
    #[inline]
    #[must_use]
    pub fn level(&self) -> usize {
        self.walk.level
    }

    /// True when the index buffer changed since the last [`clear_changed`](Self::clear_changed)
    /// (a new cache starts changed, so it is uploaded once).
    #[inline]
    #[must_use]
    pub fn is_changed(&self) -> bool {
        self.changed
    }

    /// Marks the current index buffer as seen (uploaded).
    #[inline]
    pub fn clear_changed(&mut self) {
        self.changed = false;
    }

    /// One collapse coarser. Returns false at the base level.
    #[inline]
    pub fn coarsen(&mut self, mesh: &ProgressiveMesh) -> bool {
        let moved = match &mesh.records {
            Layout::Narrow(r) => r.coarsen(&mut self.indices, &mut self.walk),
            Layout::Wide(r) => r.coarsen(&mut self.indices, &mut self.walk),
        };
        self.changed |= moved;
        moved
    }

    /// One vertex split finer. Returns false at full detail.
    #[inline]
    pub fn refine(&mut self, mesh: &ProgressiveMesh) -> bool {
        let moved = match &mesh.records {
            Layout::Narrow(r) => r.refine(&mut self.indices, &mut self.walk),
            Layout::Wide(r) => r.refine(&mut self.indices, &mut self.walk),
        };
        self.changed |= moved;
        moved
    }

    /// Moves to the finest level with at most `triangles` triangles (never below the base
    /// mesh) and returns the triangle count reached.
    ///
    /// The cost is proportional to the number of levels crossed.
    ///
    /// # Panics
    /// May panic when `mesh` is not the mesh the cache was made for (debug builds also check
    /// that a 16-bit cache's indices fit).
    pub fn set_triangle_count(&mut self, mesh: &ProgressiveMesh, triangles: usize) -> usize {
        let level = self.walk.level;
        match &mesh.records {
            Layout::Narrow(r) => r.walk(&mut self.indices, &mut self.walk, triangles),
            Layout::Wide(r) => r.walk(&mut self.indices, &mut self.walk, triangles),
        }
        self.changed |= level != self.walk.level;
        self.walk.count
    }

    /// The targets that [`set_triangle_count`](Self::set_triangle_count) answers without
    /// moving: every count in `from..below`.
    #[inline]
    pub(crate) fn steady_targets(&self, mesh: &ProgressiveMesh) -> (usize, usize) {
        steady_targets(&self.walk, mesh)
    }

    /// Moves to `level` (clamped to the base level) and returns the triangle count reached.
    pub fn set_level(&mut self, mesh: &ProgressiveMesh, level: usize) -> usize {
        let level = level.min(mesh.level_count() - 1);
        while self.walk.level < level && self.coarsen(mesh) {}
        while self.walk.level > level && self.refine(mesh) {}
        self.walk.count
    }

    /// Moves to the coarsest level whose error (relative to the bounding-box diagonal) is at
    /// most `error`, and returns the triangle count reached.
    pub fn set_max_error(&mut self, mesh: &ProgressiveMesh, error: f32) -> usize {
        self.set_level(mesh, mesh.level_for_error(error))
    }
}

/// The targets a cache at `walk` answers without moving: every count in `from..below`.
#[inline]
pub(crate) fn steady_targets(walk: &Walk, mesh: &ProgressiveMesh) -> (usize, usize) {
    let Walk { level, count, .. } = *walk;
    // Coarser while the count is above the target, down to the base level; finer while
    // the next level's count is within it, up to full detail.
    let from = if level + 1 >= mesh.level_count() {
        0
    } else {
        count
    };
    let below = match level.checked_sub(1) {
        Some(step) => count + mesh.records.removed_by(step),
        None => usize::MAX,
    };
    (from, below)
}
