//! Per-instance state of a [`RegionMesh`]: one polygon cache per region.

use super::RegionMesh;
use crate::multires::records::Walk;
use crate::multires::{CacheIndex, PolygonCache, ProgressiveMesh, steady_targets};

/// One instance's levels of every region of a [`RegionMesh`].
///
/// Each region has its own [`PolygonCache`] (16-bit where its vertices fit, see
/// [`Region::fits_u16`](super::Region::fits_u16)) and triangle count. Changing a region's level
/// marks it dirty, and also the neighbours whose border corners held a vertex that the
/// crossed steps removed or brought back: those corners get their new representatives
/// there and then. [`write_indices`](Self::write_indices) writes a dirty region's index
/// buffer, ready to render by itself.
#[derive(Clone, Debug)]
pub struct RegionCaches {
    caches: Vec<Cache>,
    /// Per region, its count and the targets that leave it where it is: the per-frame pass
    /// over every region reads these few bytes instead of the region's cache.
    steady: Vec<Steady>,
    dirty: Vec<bool>,
    scratch: Scratch,
}

/// A region's triangle count, and the targets `from..below` that
/// [`RegionCaches::set_triangle_count`] answers without moving it.
#[derive(Clone, Copy, Debug)]
struct Steady {
    count: usize,
    from: usize,
    below: usize,
}

impl Steady {
    #[inline]
    fn of(cache: &Cache, mesh: &ProgressiveMesh) -> Self {
        let (from, below) = match cache {
            Cache::Narrow(c) => c.steady_targets(mesh),
            Cache::Wide(c) => c.steady_targets(mesh),
            Cache::Levels(walk) => steady_targets(walk, mesh),
        };
        Self {
            count: cache.triangle_count(),
            from,
            below,
        }
    }
}

/// Equal when every region is at the same level with the same buffer and dirty flag (scratch
/// space does not count).
impl PartialEq for RegionCaches {
    fn eq(&self, other: &Self) -> bool {
        self.caches == other.caches && self.dirty == other.dirty
    }
}

impl Eq for RegionCaches {}

/// One region's cache, in the narrowest index type that fits.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Cache {
    Narrow(PolygonCache<u16>),
    Wide(PolygonCache<u32>),
    /// The level alone, no indices ([`RegionCaches::levels_only`]).
    Levels(Walk),
}

impl Cache {
    fn new(mesh: &ProgressiveMesh) -> Self {
        match PolygonCache::with_index_type(mesh) {
            Some(narrow) => Self::Narrow(narrow),
            None => Self::Wide(PolygonCache::new(mesh)),
        }
    }

    /// A region's level alone, at full detail.
    fn levels(mesh: &ProgressiveMesh) -> Self {
        Self::Levels(Walk {
            count: mesh.max_triangles(),
            ..Walk::default()
        })
    }

    #[inline]
    fn triangle_count(&self) -> usize {
        match self {
            Self::Narrow(c) => c.triangle_count(),
            Self::Wide(c) => c.triangle_count(),
            Self::Levels(walk) => walk.count,
        }
    }

    #[inline]
    fn level(&self) -> usize {
        match self {
            Self::Narrow(c) => c.level(),
            Self::Wide(c) => c.level(),
            Self::Levels(walk) => walk.level,
        }
    }

    #[inline]
    fn set_triangle_count(&mut self, mesh: &ProgressiveMesh, triangles: usize) -> usize {
        match self {
            Self::Narrow(c) => c.set_triangle_count(mesh, triangles),
            Self::Wide(c) => c.set_triangle_count(mesh, triangles),
            Self::Levels(walk) => {
                mesh.records.walk_levels(walk, triangles);
                walk.count
            }
        }
    }

    #[inline]
    fn set_level(&mut self, mesh: &ProgressiveMesh, level: usize) {
        match self {
            Self::Narrow(c) => _ = c.set_level(mesh, level),
            Self::Wide(c) => _ = c.set_level(mesh, level),
            Self::Levels(walk) => mesh.records.walk_to_level(walk, level),
        }
    }

    /// Sets one corner (a local vertex of the region, which fits the cache's type); a cache
    /// of levels alone has none.
    #[inline]
    fn set_corner(&mut self, corner: usize, vertex: u32) {
        match self {
            Self::Narrow(c) => c.indices_mut()[corner] = u16::from_u32(vertex),
            Self::Wide(c) => c.indices_mut()[corner] = vertex,
            Self::Levels(_) => {}
        }
    }

    /// Bytes of the index buffer held.
    fn index_bytes(&self) -> usize {
        match self {
            Self::Narrow(c) => c.index_bytes(),
            Self::Wide(c) => c.index_bytes(),
            Self::Levels(_) => 0,
        }
    }
}

/// Buffers `write_indices` reuses.
#[derive(Clone, Debug, Default)]
struct Scratch {
    /// Fin-prone triangles not to emit, by position in the active part of
    /// `Region::fin_prone`.
    skip: Vec<bool>,
    /// The active fin-prone triangles by oriented key: sorted positions, winding, position
    /// in the active part of `Region::fin_prone`.
    group: Vec<([u32; 3], bool, u32)>,
}

/// Appends `src` to `out`, converted (a plain copy when the types agree; the caller checked
/// that narrowing fits).
#[inline]
fn extend<I: CacheIndex, J: CacheIndex>(out: &mut Vec<I>, src: &[J]) {
    out.extend(src.iter().map(|&v| I::from_u32(v.into())));
}

/// The triangle's positions sorted, and whether the sort kept its winding; `None` when
/// degenerate.
fn oriented_key([a, b, c]: [u32; 3]) -> Option<([u32; 3], bool)> {
    if a == b || b == c || a == c {
        return None;
    }
    // Rotate the smallest first; the winding is then told by the order of the other two.
    let (x, y, z) = if a < b && a < c {
        (a, b, c)
    } else if b < c {
        (b, c, a)
    } else {
        (c, a, b)
    };
    Some(if y < z {
        ([x, y, z], true)
    } else {
        ([x, z, y], false)
    })
}

/// The active entries of `triangles` (increasing triangle indices).
fn active(triangles: &[u32], active_triangles: usize) -> &[u32] {
    let n = triangles.partition_point(|&t| (t as usize) < active_triangles);
    &triangles[..n]
}

/// [`oriented_key`] of triangle `t` of `indices`, by position.
#[inline(always)]
fn oriented_triangle<J: CacheIndex>(
    data: &super::Region,
    indices: &[J],
    t: u32,
) -> Option<([u32; 3], bool)> {
    let t = 3 * t as usize;
    let corners = &indices[t..t + 3];
    oriented_key([
        data.position_of(corners[0].into()),
        data.position_of(corners[1].into()),
        data.position_of(corners[2].into()),
    ])
}

/// Marks fins in `skip`: among border triangles with the same positions (`group`: oriented
/// key, winding, position in the active `Region::fin_prone`; sorted here), opposite pairs
/// cancel, and of what is left one copy stays.
fn cancel_fins(group: &mut [([u32; 3], bool, u32)], skip: &mut [bool]) {
    group.sort_unstable();
    for same in group.chunk_by(|a, b| a.0 == b.0) {
        if same.len() < 2 {
            continue;
        }
        let forward = same.iter().filter(|k| k.1).count();
        let pairs = forward.min(same.len() - forward);
        let mut kept_one = false;
        let (mut f, mut b) = (0, 0);
        for &(_, is_forward, i) in same {
            let cancelled = if is_forward {
                f += 1;
                f <= pairs
            } else {
                b += 1;
                b <= pairs
            };
            if cancelled || std::mem::replace(&mut kept_one, true) {
                skip[i as usize] = true;
            }
        }
    }
}

impl Scratch {
    /// The region's active triangles `indices` into `out`, less fins.
    ///
    /// No triangle of a region ever loses its area, and only the region's fin-prone border
    /// triangles (usually none, see `regions::borders::fin_prone`) can come to sit on the
    /// same three positions as another: every other triangle is copied without a look.
    fn write<I: CacheIndex, J: CacheIndex>(
        &mut self,
        data: &super::Region,
        built: bool,
        indices: &[J],
        out: &mut Vec<I>,
    ) {
        debug_assert!(
            !built || only_fin_prone_triangles_meet(data, indices),
            "a triangle lost its area, or border triangles met outside the fin-prone ones"
        );
        let prone = active(&data.fin_prone, indices.len() / 3);
        out.clear();
        if out.capacity() < indices.len() {
            // A fresh buffer (growing this one would copy its stale contents), with room for
            // twice what is needed now but never more than the region's full detail: buffers
            // that follow a region as it grows reallocate rarely, and never outgrow it.
            let full = 3 * data.mesh.max_triangles();
            *out = Vec::with_capacity(full.min(2 * indices.len().max(out.capacity())));
        }
        if prone.len() < 2 {
            // The common case: every active triangle, in one copy.
            extend(out, indices);
            return;
        }
        // Fin-prone triangles whose positions are now the same as another's: "fins" (the
        // same three positions twice, once each way round) cancel in pairs, and of what is
        // left one copy stays.
        let skip = &mut self.skip;
        skip.clear();
        skip.resize(prone.len(), false);
        self.group.clear();
        for (i, &t) in prone.iter().enumerate() {
            match oriented_triangle(data, indices, t) {
                Some((key, forward)) => self.group.push((key, forward, i as u32)),
                None => skip[i] = true, // no area (never happens, see above; checked in debug builds)
            }
        }
        cancel_fins(&mut self.group, skip);
        // Triangles are copied in runs; skipped fin-prone triangles are left out.
        out.reserve(indices.len());
        let mut next = 0; // first triangle not yet copied or checked
        for (&t, &left_out) in prone.iter().zip(skip.iter()) {
            let t = t as usize;
            extend(out, &indices[3 * next..3 * t]);
            if !left_out {
                extend(out, &indices[3 * t..3 * t + 3]);
            }
            next = t + 1;
        }
        extend(out, &indices[3 * next..]);
    }
}

/// Every active triangle has three corners at distinct positions, and two border triangles
/// on the same three positions are both fin-prone (checked in debug builds: `write_indices`
/// relies on it to copy the others without a look).
fn only_fin_prone_triangles_meet<J: CacheIndex>(data: &super::Region, indices: &[J]) -> bool {
    let active_triangles = indices.len() / 3;
    if (0..active_triangles as u32).any(|t| oriented_triangle(data, indices, t).is_none()) {
        return false;
    }
    let prone = active(&data.fin_prone, active_triangles);
    let mut keys: Vec<([u32; 3], bool)> = active(&data.border, active_triangles)
        .iter()
        .map(|&t| {
            let (key, _) = oriented_triangle(data, indices, t).expect("checked above");
            (key, prone.binary_search(&t).is_ok())
        })
        .collect();
    keys.sort_unstable();
    keys.chunk_by(|a, b| a.0 == b.0)
        .all(|same| same.len() == 1 || same.iter().all(|k| k.1))
}

impl RegionCaches {
    /// Every region at full detail, every region dirty.
    #[must_use]
    pub fn new(mesh: &RegionMesh) -> Self {
        Self::of(mesh, Cache::new)
    }

    /// Every region's cache made by `cache`, at full detail, every region dirty.
    fn of(mesh: &RegionMesh, cache: fn(&ProgressiveMesh) -> Cache) -> Self {
        let caches: Vec<_> = mesh.regions().iter().map(|r| cache(&r.mesh)).collect();
        let steady = caches
            .iter()
            .zip(mesh.regions())
            .map(|(cache, r)| Steady::of(cache, &r.mesh))
            .collect();
        Self {
            caches,
            steady,
            dirty: vec![true; mesh.regions().len()],
            scratch: Scratch::default(),
        }
    }

    /// Every region at full detail, every region dirty, keeping each region's level alone
    /// and no index buffer: for an instance whose triangles are written elsewhere (the
    /// plugin's shared level meshes, made from one full set of caches per asset). Levels,
    /// counts and dirty flags move exactly as [`new`](Self::new)'s do; the `write_*`
    /// methods panic.
    #[must_use]
    pub fn levels_only(mesh: &RegionMesh) -> Self {
        Self::of(mesh, Cache::levels)
    }

    /// Whether the caches hold index buffers (made by [`new`](Self::new), not
    /// [`levels_only`](Self::levels_only)).
    #[must_use]
    pub fn holds_indices(&self) -> bool {
        !matches!(self.caches.first(), Some(Cache::Levels(_)))
    }

    /// Bytes of index buffers held, over all regions (`0` for
    /// [`levels_only`](Self::levels_only) caches).
    #[must_use]
    pub fn index_bytes(&self) -> usize {
        self.caches.iter().map(Cache::index_bytes).sum()
    }

    /// Number of regions.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.caches.len()
    }

    /// A region's level, as in [`PolygonCache::level`]: `0` is full detail, each level one
    /// collapse coarser.
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[must_use]
    pub fn level(&self, region: usize) -> usize {
        self.caches[region].level()
    }

    /// Triangles of a region at its current level (fins, which only fin-prone regions can
    /// have, are counted here but not written).
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[must_use]
    pub fn triangle_count(&self, region: usize) -> usize {
        self.steady[region].count
    }

    /// Sum of [`triangle_count`](Self::triangle_count) over all regions.
    #[must_use]
    pub fn total_triangles(&self) -> usize {
        self.steady.iter().map(|s| s.count).sum()
    }

    /// True when the region's index buffer must be written again.
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[must_use]
    pub fn is_dirty(&self, region: usize) -> bool {
        self.dirty[region]
    }

    /// Clears a region's dirty flag without writing it: for a caller that keys the region's
    /// buffer by its levels and wrote that buffer before.
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[cfg_attr(not(feature = "bevy"), allow(dead_code))]
    pub(crate) fn mark_written(&mut self, region: usize) {
        self.dirty[region] = false;
    }

    /// Moves a region to the finest level with at most `triangles` triangles (never below
    /// its base) and returns the count reached. A change marks the region dirty, and the
    /// regions whose border corners it moves to other representatives: their corners are
    /// rewritten here, by the steps crossed (no search).
    ///
    /// # Panics
    /// Panics when `region` is out of range or `mesh` is not the mesh the caches were made
    /// for.
    pub fn set_triangle_count(
        &mut self,
        mesh: &RegionMesh,
        region: usize,
        triangles: usize,
    ) -> usize {
        let steady = self.steady[region];
        if (steady.from..steady.below).contains(&triangles) {
            return steady.count;
        }
        let data = &mesh.regions()[region];
        let before = self.caches[region].level();
        let reached = self.caches[region].set_triangle_count(&data.mesh, triangles);
        self.moved(mesh, region, before);
        reached
    }

    /// Moves a region to `level` (clamped to its base level), as
    /// [`set_triangle_count`](Self::set_triangle_count) moves it, and returns the triangle
    /// count reached: to put these caches where another instance's are.
    ///
    /// # Panics
    /// Panics when `region` is out of range or `mesh` is not the mesh the caches were made
    /// for.
    pub fn set_level(&mut self, mesh: &RegionMesh, region: usize, level: usize) -> usize {
        let data = &mesh.regions()[region];
        let before = self.caches[region].level();
        self.caches[region].set_level(&data.mesh, level);
        self.moved(mesh, region, before);
        self.steady[region].count
    }

    /// After region `region` moved from level `before`: its steady targets, its dirty flag,
    /// and the corners its front events move in other regions.
    fn moved(&mut self, mesh: &RegionMesh, region: usize, before: usize) {
        let data = &mesh.regions()[region];
        let cache = &self.caches[region];
        let after = cache.level();
        if after == before {
            return;
        }
        self.steady[region] = Steady::of(cache, &data.mesh);
        self.dirty[region] = true;
        let events = &data.front_events;
        let first = |level: usize| events.partition_point(|e| (e.step as usize) < level);
        if after > before {
            // Coarser: each corner ends at the `after` of the last step it passes.
            for e in &events[first(before)..first(after)] {
                self.caches[e.region as usize].set_corner(e.corner as usize, e.after);
                self.dirty[e.region as usize] = true;
            }
        } else {
            // Finer: each corner ends at the `before` of the first step it passes back.
            for e in events[first(after)..first(before)].iter().rev() {
                self.caches[e.region as usize].set_corner(e.corner as usize, e.before);
                self.dirty[e.region as usize] = true;
            }
        }
    }

    /// Writes a region's triangles into `out` (cleared first), as indices into the region's
    /// local vertex table ([`Region::progressive_mesh`](super::Region::progressive_mesh)),
    /// and clears its dirty flag. Foreign corners hold their current representatives (kept
    /// up to date by [`set_triangle_count`](Self::set_triangle_count)); border triangles that
    /// became "fins" (two on the same three positions, which only regions with fin-prone border
    /// triangles can have: none in practice) are cancelled, and no triangle ever loses its
    /// area. Returns the number of triangles written.
    ///
    /// # Panics
    /// Panics when `region` is out of range, `mesh` is not the mesh the caches were made
    /// for, or the caches are [`levels_only`](Self::levels_only).
    pub fn write_indices(&mut self, mesh: &RegionMesh, region: usize, out: &mut Vec<u32>) -> usize {
        self.write(mesh, region, out)
    }

    /// [`write_indices`](Self::write_indices) with 16-bit indices: half the bytes to copy,
    /// keep and upload, for regions whose local vertex table
    /// ([`Region::progressive_mesh`](super::Region::progressive_mesh)) has at most 65,535
    /// vertices ([`Region::fits_u16`](super::Region::fits_u16)).
    ///
    /// ```
    /// use bevy_aslod::mesh::IndexedMesh;
    /// use bevy_aslod::multires::BuildOptions;
    /// use bevy_aslod::regions::{Partition, RegionCaches, RegionMesh};
    /// use glam::Vec3;
    ///
    /// let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)];
    /// let mesh = IndexedMesh::new(positions, vec![0, 2, 1, 1, 2, 3]);
    /// let (partition, _) = Partition::from_ids(&mesh, &[0, 0, 1, 1]).unwrap();
    /// let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
    /// let mut caches = RegionCaches::new(&regions);
    /// let (mut wide, mut narrow) = (Vec::new(), Vec::new());
    /// assert!(regions.regions()[0].fits_u16());
    /// caches.write_indices(&regions, 0, &mut wide);
    /// caches.write_indices_u16(&regions, 0, &mut narrow);
    /// assert_eq!(wide, narrow.iter().map(|&i| u32::from(i)).collect::<Vec<_>>());
    /// ```
    ///
    /// # Panics
    /// As [`write_indices`](Self::write_indices), and when the region has more than 65,535
    /// vertices.
    pub fn write_indices_u16(
        &mut self,
        mesh: &RegionMesh,
        region: usize,
        out: &mut Vec<u16>,
    ) -> usize {
        assert!(
            mesh.regions()[region].fits_u16(),
            "region {region} has more than 65,535 vertices: 16-bit indices cannot address them"
        );
        self.write(mesh, region, out)
    }

    fn write<I: CacheIndex>(
        &mut self,
        mesh: &RegionMesh,
        region: usize,
        out: &mut Vec<I>,
    ) -> usize {
        let data = &mesh.regions()[region];
        let scratch = &mut self.scratch;
        match &self.caches[region] {
            Cache::Narrow(cache) => scratch.write(data, mesh.built, cache.indices(), out),
            Cache::Wide(cache) => scratch.write(data, mesh.built, cache.indices(), out),
            Cache::Levels(_) => panic!("levels-only caches hold no indices to write"),
        }
        self.dirty[region] = false;
        out.len() / 3
    }

    /// [`write_indices`](Self::write_indices), then maps the indices to the source mesh's
    /// vertices.
    ///
    /// # Panics
    /// As [`write_indices`](Self::write_indices).
    pub fn write_global_indices(
        &mut self,
        mesh: &RegionMesh,
        region: usize,
        out: &mut Vec<u32>,
    ) -> usize {
        let n = self.write_indices(mesh, region, out);
        let global = &mesh.regions()[region].global;
        for i in out.iter_mut() {
            *i = global[*i as usize];
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::{Cache, RegionCaches, cancel_fins};
    use crate::mesh::test_grid;
    use crate::multires::{BuildOptions, PolygonCache};
    use crate::regions::{GridPlane, Partition, RegionMesh};

    /// A bumpy 17×17-vertex grid cut into `n`×`n` regions.
    fn bumpy_grid_regions(n: usize) -> RegionMesh {
        let mesh = test_grid(17, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1);
        let partition = Partition::grid(&mesh, GridPlane::XZ, n, n).unwrap();
        RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap()
    }

    /// The shortcut for targets that leave a region where it is agrees with a walk of the
    /// region's own cache, at every level boundary (targets one off the counts, 0, past the
    /// full count).
    #[test]
    fn steady_targets_are_exactly_those_that_do_not_move() {
        let regions = bumpy_grid_regions(3);
        let mut caches = RegionCaches::new(&regions);
        let mut plain: Vec<PolygonCache<u32>> = regions
            .regions()
            .iter()
            .map(|r| PolygonCache::new(&r.mesh))
            .collect();
        let mut seed = 0x9e37_79b9_u64;
        for _ in 0..4000 {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let r = (seed >> 33) as usize % regions.regions().len();
            let count = caches.triangle_count(r);
            let max = regions.regions()[r].max_triangles();
            let target = match (seed >> 20) % 8 {
                0 => 0,
                1 => max + 1,
                2 => (seed >> 40) as usize % (max + 1),
                k => (count + k as usize).saturating_sub(5),
            };
            let reached = caches.set_triangle_count(&regions, r, target);
            let mesh = &regions.regions()[r].mesh;
            assert_eq!(
                reached,
                plain[r].set_triangle_count(mesh, target),
                "{target}"
            );
            assert_eq!(caches.level(r), plain[r].level());
            assert_eq!(caches.triangle_count(r), reached);
        }
    }

    /// A buffer that follows a region up to its full detail grows to at most the full size.
    #[test]
    fn levels_only_caches_move_as_full_ones_and_set_level_reaches_their_buffers() {
        let regions = bumpy_grid_regions(3);
        let mut full = RegionCaches::new(&regions);
        let mut lean = RegionCaches::levels_only(&regions);
        assert!(full.holds_indices() && !lean.holds_indices());
        assert_eq!(lean.index_bytes(), 0);
        assert!(full.index_bytes() > 0);
        let n = regions.regions().len();
        let mut seed = 0x2545_f491_u64;
        for _ in 0..3000 {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let r = (seed >> 33) as usize % n;
            let max = regions.regions()[r].max_triangles();
            let target = (seed >> 40) as usize % (max + 2);
            if (seed >> 20).is_multiple_of(4) {
                let level = target % regions.regions()[r].mesh.level_count();
                assert_eq!(
                    full.set_level(&regions, r, level),
                    lean.set_level(&regions, r, level)
                );
            } else {
                assert_eq!(
                    full.set_triangle_count(&regions, r, target),
                    lean.set_triangle_count(&regions, r, target)
                );
            }
            for q in 0..n {
                assert_eq!(full.level(q), lean.level(q));
                assert_eq!(full.triangle_count(q), lean.triangle_count(q));
                assert_eq!(full.is_dirty(q), lean.is_dirty(q));
            }
            if (seed >> 24).is_multiple_of(16) {
                // Another full set of caches, put at the same levels by `set_level` from
                // wherever it was, writes the same buffers.
                let mut other = RegionCaches::new(&regions);
                for q in (0..n).rev() {
                    other.set_level(&regions, q, (q * 7) % 5);
                }
                for q in 0..n {
                    other.set_level(&regions, q, lean.level(q));
                }
                let (mut a, mut b) = (Vec::new(), Vec::new());
                for q in 0..n {
                    full.write_indices(&regions, q, &mut a);
                    other.write_indices(&regions, q, &mut b);
                    assert_eq!(a, b, "region {q}");
                }
                for q in 0..n {
                    lean.mark_written(q);
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "levels-only caches hold no indices")]
    fn levels_only_caches_write_nothing() {
        let regions = bumpy_grid_regions(2);
        let mut lean = RegionCaches::levels_only(&regions);
        lean.write_indices(&regions, 0, &mut Vec::new());
    }

    #[test]
    fn written_buffers_never_outgrow_the_full_detail() {
        let regions = bumpy_grid_regions(2);
        let mut caches = RegionCaches::new(&regions);
        let max = regions.regions()[0].max_triangles();
        let full = 3 * max;
        let mut out: Vec<u16> = Vec::new();
        // Grown by `Vec`'s doubling this sequence would end at 4/3 of the full size.
        for target in [max / 3, max / 2 + 1, max] {
            caches.set_triangle_count(&regions, 0, target);
            caches.write_indices_u16(&regions, 0, &mut out);
            assert!(out.capacity() <= full, "{} > {full}", out.capacity());
        }
        assert_eq!(out.len(), full);
    }

    /// 32-bit and 16-bit caches move and write alike (regions of more than 65,535 vertices
    /// get 32-bit ones; here they are forced on a small mesh).
    #[test]
    fn wide_and_narrow_caches_agree() {
        let regions = bumpy_grid_regions(3);
        let mut narrow = RegionCaches::new(&regions);
        assert!(narrow.caches.iter().all(|c| matches!(c, Cache::Narrow(_))));
        let mut wide = narrow.clone();
        wide.caches = regions
            .regions()
            .iter()
            .map(|r| Cache::Wide(PolygonCache::new(&r.mesh)))
            .collect();
        let mut seed = 0x2545_f491_u64;
        for _ in 0..400 {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let r = (seed >> 33) as usize % regions.regions().len();
            let target = (seed >> 20) as usize % (regions.regions()[r].max_triangles() + 1);
            assert_eq!(
                narrow.set_triangle_count(&regions, r, target),
                wide.set_triangle_count(&regions, r, target)
            );
            for r in 0..regions.regions().len() {
                assert_eq!(narrow.is_dirty(r), wide.is_dirty(r));
                let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
                narrow.write_indices(&regions, r, &mut a);
                wide.write_indices(&regions, r, &mut b);
                wide.write_indices_u16(&regions, r, &mut c);
                assert_eq!(a, b, "region {r}");
                assert!(a.iter().copied().eq(c.iter().map(|&i| u32::from(i))));
            }
        }
    }

    #[test]
    fn fins_cancel_in_pairs_and_copies_keep_one() {
        let (a, b) = ([1, 2, 3], [4, 5, 6]);
        // a: forward, backward, forward -> one pair cancels, one stays. b: forward twice ->
        // one copy stays. [7, 8, 9] alone stays.
        let mut group = vec![
            (a, true, 0),
            (b, true, 1),
            (a, false, 2),
            ([7, 8, 9], true, 3),
            (a, true, 4),
            (b, true, 5),
        ];
        let mut skip = vec![false; 6];
        cancel_fins(&mut group, &mut skip);
        assert_eq!(skip.iter().filter(|&&s| s).count(), 3);
        assert!(skip[2], "the backward copy of a pairs with a forward one");
        assert!(!skip[0] || !skip[4], "one forward copy of a stays");
        assert!(skip[1] ^ skip[5], "one copy of b stays");
        assert!(!skip[3]);
    }
}
