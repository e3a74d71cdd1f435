//! Vertex partitions: which region each vertex belongs to.

use super::RegionError;
use super::util::{find, unite};
use crate::mesh::{IndexedMesh, weld_positions};
use glam::Vec3;

/// The plane a [`Partition::grid`] is laid over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "bevy", derive(bevy::reflect::Reflect))]
pub enum GridPlane {
    /// The ground plane (Y up): terrain.
    #[default]
    XZ,
    /// The front plane.
    XY,
    /// The side plane.
    YZ,
}

impl GridPlane {
    #[inline]
    fn project(self, p: Vec3) -> (f32, f32) {
        match self {
            Self::XZ => (p.x, p.z),
            Self::XY => (p.x, p.y),
            Self::YZ => (p.y, p.z),
        }
    }
}

/// A division of a mesh's vertices into disjoint, non-empty regions `0..region_count()`.
///
/// Vertices at the same position (attribute seams) always share a region, so a region border
/// never runs through a seam. Triangles are not partitioned: see
/// [`triangle_owner`](super::triangle_owner).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Partition {
    region_of: Vec<u32>,
    region_count: usize,
}

impl Partition {
    /// The region of every vertex.
    #[inline]
    #[must_use]
    pub fn region_of(&self) -> &[u32] {
        &self.region_of
    }

    /// Number of regions; every one holds at least one vertex.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.region_count
    }

    /// Vertices per region.
    #[must_use]
    pub fn region_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.region_count];
        for &r in &self.region_of {
            sizes[r as usize] += 1;
        }
        sizes
    }

    /// A partition from caller-supplied region ids (for example painted by an artist).
    ///
    /// Ids need not be contiguous: they are renumbered `0..k` in increasing order, so empty
    /// ids disappear. Where vertices at one position carry different ids, all of them take the
    /// id of the first such vertex (a seam must not split); the number of vertices changed
    /// this way is returned alongside, and logged as a warning when non-zero.
    ///
    /// # Errors
    /// [`RegionError::LengthMismatch`] when `ids` does not have one entry per vertex, and
    /// [`RegionError::EmptyMesh`] for a mesh without vertices.
    pub fn from_ids(mesh: &IndexedMesh, ids: &[u32]) -> Result<(Self, usize), RegionError> {
        if ids.len() != mesh.vertex_count() {
            return Err(RegionError::LengthMismatch {
                expected: mesh.vertex_count(),
                found: ids.len(),
            });
        }
        if ids.is_empty() {
            return Err(RegionError::EmptyMesh);
        }
        let weld = weld_positions(&mesh.positions);
        let mut changed = 0;
        let ids: Vec<u32> = (0..ids.len())
            .map(|v| {
                let id = ids[weld.remap[v] as usize];
                changed += usize::from(id != ids[v]);
                id
            })
            .collect();
        if changed > 0 {
            log::warn!(
                "{changed} vertices at a shared position had a different region id; \
                 they now follow the first vertex at that position"
            );
        }
        Ok((Self::compact(ids), changed))
    }

    /// A grid of `nx` by `ny` cells over the mesh's bounding rectangle in `plane`.
    ///
    /// Cells without vertices are dropped, so there may be fewer than `nx * ny` regions.
    /// Regions are numbered row by row (along the plane's second axis, then its first).
    ///
    /// # Errors
    /// [`RegionError::ZeroRegions`] when `nx` or `ny` is zero, [`RegionError::EmptyMesh`] for
    /// a mesh without vertices.
    pub fn grid(
        mesh: &IndexedMesh,
        plane: GridPlane,
        nx: usize,
        ny: usize,
    ) -> Result<Self, RegionError> {
        if nx == 0 || ny == 0 {
            return Err(RegionError::ZeroRegions);
        }
        let (lo, hi) = mesh.bounds().ok_or(RegionError::EmptyMesh)?;
        let (lo, hi) = (plane.project(lo), plane.project(hi));
        let cell = |v: f32, lo: f32, hi: f32, n: usize| {
            let extent = hi - lo;
            if extent <= 0.0 {
                return 0;
            }
            (((v - lo) / extent * n as f32) as usize).min(n - 1)
        };
        let ids = mesh
            .positions
            .iter()
            .map(|&p| {
                let (a, b) = plane.project(p);
                (cell(b, lo.1, hi.1, ny) * nx + cell(a, lo.0, hi.0, nx)) as u32
            })
            .collect();
        Ok(Self::compact(ids))
    }

    /// About `target` spatially compact, connected regions of similar vertex counts.
    ///
    /// Recursive bisection: the vertex set is split across the longest side of its bounding
    /// box at the point that gives each half its share of regions, until every part is one
    /// region. A region that falls apart into several connected pieces keeps its largest
    /// piece and hands the others to the neighbour they share most edges with.
    ///
    /// # Errors
    /// [`RegionError::ZeroRegions`] when `target` is zero, [`RegionError::EmptyMesh`] for a
    /// mesh without vertices.
    pub fn clusters(mesh: &IndexedMesh, target: usize) -> Result<Self, RegionError> {
        if target == 0 {
            return Err(RegionError::ZeroRegions);
        }
        if mesh.vertex_count() == 0 {
            return Err(RegionError::EmptyMesh);
        }
        let weld = weld_positions(&mesh.positions);
        // Bisect the distinct positions; seam copies follow their representative.
        let mut points: Vec<u32> = (0..mesh.vertex_count() as u32)
            .filter(|&v| weld.remap[v as usize] == v)
            .collect();
        let mut ids = vec![0u32; mesh.vertex_count()];
        let mut next = 0u32;
        bisect(&mesh.positions, &mut points, target, &mut ids, &mut next);
        for v in 0..ids.len() {
            ids[v] = ids[weld.remap[v] as usize];
        }
        make_connected(mesh, &weld.remap, &mut ids);
        Ok(Self::compact(ids))
    }

    /// A partition whose ids are already `0..region_count`, every one used.
    pub(crate) fn from_region_of(region_of: Vec<u32>, region_count: usize) -> Self {
        Self {
            region_of,
            region_count,
        }
    }

    /// Renumbers ids to `0..k` in increasing order of the original id.
    fn compact(ids: Vec<u32>) -> Self {
        let mut distinct = ids.clone();
        distinct.sort_unstable();
        distinct.dedup();
        let region_of = ids
            .iter()
            .map(|id| distinct.binary_search(id).expect("id is in the list") as u32)
            .collect();
        Self {
            region_of,
            region_count: distinct.len(),
        }
    }
}

fn bisect(positions: &[Vec3], points: &mut [u32], parts: usize, ids: &mut [u32], next: &mut u32) {
    if parts <= 1 || points.len() <= 1 {
        for &v in points.iter() {
            ids[v as usize] = *next;
        }
        *next += 1;
        return;
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for &v in points.iter() {
        lo = lo.min(positions[v as usize]);
        hi = hi.max(positions[v as usize]);
    }
    let axis = (hi - lo).max_position();
    let left_parts = parts / 2;
    let split = (points.len() * left_parts / parts).clamp(1, points.len() - 1);
    // Ties broken by index keep the result deterministic.
    points.select_nth_unstable_by(split, |&a, &b| {
        positions[a as usize][axis]
            .total_cmp(&positions[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (left, right) = points.split_at_mut(split);
    bisect(positions, left, left_parts, ids, next);
    bisect(positions, right, parts - left_parts, ids, next);
}

/// Reassigns every connected piece of a region but its largest to the neighbouring region it
/// shares most edges with, until each region is one piece (or nothing moves).
fn make_connected(mesh: &IndexedMesh, remap: &[u32], ids: &mut [u32]) {
    let n = mesh.vertex_count();
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.indices.len());
    for t in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (remap[t[k] as usize], remap[t[(k + 1) % 3] as usize]);
            edges.push((a.min(b), a.max(b)));
        }
    }
    edges.sort_unstable();
    edges.dedup();
    for _round in 0..8 {
        // Union-find over edges inside one region.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        for &(a, b) in &edges {
            if ids[a as usize] == ids[b as usize] {
                unite(&mut parent, a, b);
            }
        }
        let mut size = vec![0usize; n];
        for v in 0..n as u32 {
            if remap[v as usize] == v {
                let root = find(&mut parent, v);
                size[root as usize] += 1;
            }
        }
        // The largest piece of each region (ties: smallest root).
        let regions = ids.iter().copied().max().map_or(0, |m| m as usize + 1);
        let mut largest = vec![(0usize, u32::MAX); regions];
        for v in 0..n as u32 {
            if remap[v as usize] == v && find(&mut parent, v) == v {
                let best = &mut largest[ids[v as usize] as usize];
                if size[v as usize] > best.0 || (size[v as usize] == best.0 && v < best.1) {
                    *best = (size[v as usize], v);
                }
            }
        }
        // Votes of stray pieces for a neighbouring region.
        let mut votes: std::collections::BTreeMap<(u32, u32), usize> = Default::default();
        for &(a, b) in &edges {
            if ids[a as usize] == ids[b as usize] {
                continue;
            }
            for (x, y) in [(a, b), (b, a)] {
                let root = find(&mut parent, x);
                if largest[ids[x as usize] as usize].1 != root {
                    *votes.entry((root, ids[y as usize])).or_default() += 1;
                }
            }
        }
        if votes.is_empty() {
            return;
        }
        let mut target: std::collections::BTreeMap<u32, (usize, u32)> = Default::default();
        for (&(root, region), &count) in &votes {
            let best = target.entry(root).or_insert((0, u32::MAX));
            if count > best.0 {
                *best = (count, region);
            }
        }
        for v in 0..n as u32 {
            let root = find(&mut parent, remap[v as usize]);
            if let Some(&(_, region)) = target.get(&root) {
                ids[v as usize] = region;
            }
        }
    }
}
