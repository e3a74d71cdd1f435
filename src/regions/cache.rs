//! Per-instance state of a [`RegionMesh`]: one polygon cache per region.

use super::RegionMesh;
use crate::multires::PolygonCache;

/// One instance's levels of every region of a [`RegionMesh`].
///
/// Each region has its own [`PolygonCache`] and triangle count. Changing a region's level
/// marks it and every region that borders on it dirty, because their border triangles must
/// look up new representatives; [`write_indices`](Self::write_indices) resolves them and
/// writes a region's index buffer, ready to render by itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RegionCaches {
    caches: Vec<PolygonCache>,
    dirty: Vec<bool>,
    /// Scratch: triangles not to emit.
    skip: Vec<u32>,
    /// Scratch: border triangles by oriented position key.
    keys: Vec<([u32; 3], bool, u32)>,
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

/// The active triangles with a foreign corner, each once, in increasing order (`border` is
/// sorted by corner).
fn border_triangles(data: &super::Region, active: usize) -> impl Iterator<Item = u32> + '_ {
    let mut last = u32::MAX;
    data.border
        .iter()
        .take_while(move |bc| (bc.corner as usize) < active)
        .map(|bc| bc.corner / 3)
        .filter(move |&t| std::mem::replace(&mut last, t) != t)
}

/// Every triangle without a foreign corner has three corners at distinct positions (checked
/// in debug builds: `write_indices` copies such triangles without looking).
fn own_triangles_have_area(data: &super::Region, indices: &[u32]) -> bool {
    let border: std::collections::HashSet<u32> = border_triangles(data, indices.len()).collect();
    indices.chunks_exact(3).enumerate().all(|(t, tri)| {
        let [a, b, c] = [0, 1, 2].map(|k| data.position_of[tri[k] as usize]);
        border.contains(&(t as u32)) || (a != b && b != c && a != c)
    })
}

impl RegionCaches {
    /// Every region at full detail, every region dirty.
    #[must_use]
    pub fn new(mesh: &RegionMesh) -> Self {
        Self {
            caches: mesh
                .regions()
                .iter()
                .map(|r| PolygonCache::new(&r.mesh))
                .collect(),
            dirty: vec![true; mesh.regions().len()],
            skip: Vec::new(),
            keys: Vec::new(),
        }
    }

    /// Number of regions.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.caches.len()
    }

    /// A region's cache.
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[must_use]
    pub fn cache(&self, region: usize) -> &PolygonCache {
        &self.caches[region]
    }

    /// Triangles of a region at its current level (border triangles that became degenerate
    /// are counted here but not written).
    ///
    /// # Panics
    /// Panics when `region` is out of range.
    #[inline]
    #[must_use]
    pub fn triangle_count(&self, region: usize) -> usize {
        self.caches[region].triangle_count()
    }

    /// Sum of [`triangle_count`](Self::triangle_count) over all regions.
    #[must_use]
    pub fn total_triangles(&self) -> usize {
        self.caches.iter().map(PolygonCache::triangle_count).sum()
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

    /// Moves a region to the finest level with at most `triangles` triangles (never below
    /// its base) and returns the count reached. A change marks the region and the regions
    /// that border on it dirty.
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
        let data = &mesh.regions()[region];
        let cache = &mut self.caches[region];
        let before = cache.level();
        let reached = cache.set_triangle_count(&data.mesh, triangles);
        if cache.level() != before {
            self.dirty[region] = true;
            for &d in &data.dependents {
                self.dirty[d as usize] = true;
            }
        }
        reached
    }

    /// Writes a region's triangles into `out` (cleared first), as indices into the region's
    /// local vertex table ([`Region::progressive_mesh`](super::Region::progressive_mesh)),
    /// and clears its dirty flag. Foreign corners are replaced by their current
    /// representatives; border triangles that became degenerate are skipped. Returns the
    /// number of triangles written.
    ///
    /// # Panics
    /// Panics when `region` is out of range or `mesh` is not the mesh the caches were made
    /// for.
    pub fn write_indices(&mut self, mesh: &RegionMesh, region: usize, out: &mut Vec<u32>) -> usize {
        let data = &mesh.regions()[region];
        let active = 3 * self.caches[region].triangle_count();
        // Resolve foreign corners in place: the region's own steps never touch them.
        for bc in &data.border {
            if bc.corner as usize >= active {
                break;
            }
            let level = self.caches[bc.owner as usize].level() as u32;
            let chain = &data.chain[bc.chain_start as usize..][..bc.chain_len as usize];
            // A vertex removed at step s is present at every level <= s.
            let local = chain
                .iter()
                .find(|&&(step, _)| step >= level)
                .map_or(chain[chain.len() - 1].1, |&(_, l)| l);
            self.caches[region].indices_mut()[bc.corner as usize] = local;
        }
        // Border triangles whose representatives merged: degenerate ones, and "fins" (the
        // same three vertices twice, once each way round) are not emitted. Only border
        // triangles can become either: a region's own steps never create them.
        let indices = self.caches[region].indices();
        let mut skip = std::mem::take(&mut self.skip);
        skip.clear();
        let mut keys = std::mem::take(&mut self.keys);
        keys.clear();
        for t in border_triangles(data, active) {
            let at = |k: usize| data.position_of[indices[3 * t as usize + k] as usize];
            match oriented_key([at(0), at(1), at(2)]) {
                Some(key) => keys.push((key.0, key.1, t)),
                // Two corners at one position (seam copies count as one) make no area.
                None => skip.push(t),
            }
        }
        keys.sort_unstable();
        for group in keys.chunk_by(|a, b| a.0 == b.0) {
            if group.len() < 2 {
                continue;
            }
            let forward: Vec<u32> = group.iter().filter(|k| k.1).map(|k| k.2).collect();
            let backward: Vec<u32> = group.iter().filter(|k| !k.1).map(|k| k.2).collect();
            // Opposite pairs cancel; of what is left, one copy stays.
            let pairs = forward.len().min(backward.len());
            skip.extend_from_slice(&forward[..pairs]);
            skip.extend_from_slice(&backward[..pairs]);
            let rest = if forward.len() > pairs {
                &forward[pairs..]
            } else {
                &backward[pairs..]
            };
            skip.extend(rest.iter().skip(1));
        }
        skip.sort_unstable();
        // Own triangles are copied in runs; only border triangles (those with a foreign
        // corner, listed in `data.border` in corner order) are checked.
        out.clear();
        out.reserve(indices.len());
        let mut next = 0; // first triangle not yet copied or checked
        for t in border_triangles(data, active) {
            let t = t as usize;
            out.extend_from_slice(&indices[3 * next..3 * t]);
            if skip.binary_search(&(t as u32)).is_err() {
                out.extend_from_slice(&indices[3 * t..3 * t + 3]);
            }
            next = t + 1;
        }
        out.extend_from_slice(&indices[3 * next..]);
        debug_assert!(
            own_triangles_have_area(data, indices),
            "a region's own collapses never leave a triangle without area"
        );
        self.skip = skip;
        self.keys = keys;
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
