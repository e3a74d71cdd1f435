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
mod cache;
mod partition;
mod util;

pub use cache::RegionCaches;
pub use partition::{GridPlane, Partition};

use crate::mesh::{IndexedMesh, MeshError, weld_positions};
use crate::multires::{BuildOptions, ProgressiveMesh, build};
use bands::closed_band_cuts;
use borders::{fin_prone, link_border};
use glam::Vec3;
use thiserror::Error;
use util::{find, subset};

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

    /// The tight box around the region's own vertices ([`fit_obb`](crate::budget::fit_obb);
    /// an axis-aligned one when that fails, the bounds when no point is usable): the box the
    /// budget projects.
    #[must_use]
    pub fn obb(&self) -> crate::budget::Obb {
        use crate::budget::{Obb, fit_aabb, fit_obb};
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
#[derive(Clone, Debug, PartialEq)]
pub struct RegionMesh {
    partition: Partition,
    regions: Vec<Region>,
    vertex_count: usize,
}

impl RegionMesh {
    /// Partitions `mesh` by `partition` and builds every region's sequence.
    ///
    /// # Errors
    /// [`RegionError::PartitionMismatch`] when the partition has another vertex count, and
    /// any [`MeshError`] from validating the mesh.
    pub fn build(
        mesh: &IndexedMesh,
        partition: &Partition,
        options: &BuildOptions,
    ) -> Result<Self, RegionError> {
        if partition.region_of().len() != mesh.vertex_count() {
            return Err(RegionError::PartitionMismatch {
                expected: mesh.vertex_count(),
                found: partition.region_of().len(),
            });
        }
        let mut mesh = mesh.clone();
        mesh.validate()?;
        // Seam copies must share their region, or the border would split a position.
        let weld = weld_positions(&mesh.positions);
        let region_of: Vec<u32> = (0..mesh.vertex_count())
            .map(|v| partition.region_of()[weld.remap[v] as usize])
            .collect();
        let count = partition.region_count();
        let owner: Vec<u32> = mesh
            .indices
            .chunks_exact(3)
            .map(|t| triangle_owner([t[0], t[1], t[2]].map(|v| region_of[v as usize])))
            .collect();

        // Owned and context triangles per region.
        let mut owned: Vec<Vec<u32>> = vec![Vec::new(); count];
        let mut context: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
            let o = owner[t];
            owned[o as usize].push(t as u32);
            // Each other region with a corner here sees the triangle as context, once.
            let mut seen = [o; 3];
            let mut n = 1;
            for &v in tri {
                let r = region_of[v as usize];
                if !seen[..n].contains(&r) {
                    seen[n] = r;
                    n += 1;
                    context[r as usize].push(t as u32);
                }
            }
        }

        let cuts = closed_band_cuts(&mesh, &region_of, &weld.remap);

        // Build the regions in rounds, no two neighbours in one round, each round in
        // parallel where there are cores. A region sees the chains of its neighbours built in
        // earlier rounds, and checks its moves of band triangles against every level of
        // theirs (see `build_region`).
        let colour = colour_regions(&mesh, &region_of, count);
        let rounds = colour.iter().max().map_or(0, |&c| c + 1);
        let mut built: Vec<Option<Region>> = (0..count).map(|_| None).collect();
        // moves[v] = (step, parent) in v's own region, for the regions built so far.
        let mut moves = vec![(u32::MAX, u32::MAX); mesh.vertex_count()];
        for round in 0..rounds {
            let work: Vec<usize> = (0..count).filter(|&r| colour[r] == round).collect();
            let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
            let chunk = work.len().div_ceil(threads.max(1)).max(1);
            let (mesh, region_of, owned, context, cuts, moves_so_far) =
                (&mesh, &region_of, &owned, &context, &cuts, &moves);
            let results: Vec<Result<BuiltRegion, RegionError>> = std::thread::scope(|scope| {
                let handles: Vec<_> = work
                    .chunks(chunk)
                    .map(|regions| {
                        scope.spawn(move || {
                            regions
                                .iter()
                                .map(|&r| {
                                    build_region(
                                        mesh,
                                        region_of,
                                        r as u32,
                                        &owned[r],
                                        &context[r],
                                        cuts,
                                        moves_so_far,
                                        options,
                                    )
                                })
                                .collect::<Vec<_>>()
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .flat_map(|h| h.join().expect("region build does not panic"))
                    .collect()
            });
            for (&r, result) in work.iter().zip(results) {
                let (region, region_moves) = result?;
                for (step, old, new) in region_moves {
                    moves[region.global[old as usize] as usize] =
                        (step, region.global[new as usize]);
                }
                built[r] = Some(region);
            }
        }
        let mut regions: Vec<Region> = built
            .into_iter()
            .map(|r| r.expect("every region has a round"))
            .collect();
        let mut events = vec![Vec::new(); regions.len()];
        for (r, region) in regions.iter_mut().enumerate() {
            link_border(region, r as u32, &region_of, &moves, &mesh, &mut events);
        }
        for (region, mut events) in regions.iter_mut().zip(events) {
            events.sort_unstable_by_key(|e: &FrontEvent| (e.step, e.region, e.corner));
            region.front_events = events;
        }
        // Each vertex's last representative (its chain's root), by position: the chains are
        // a forest whose roots were never removed, so union-find's `find` walks them.
        let mut parent: Vec<u32> = moves
            .iter()
            .enumerate()
            .map(|(v, &(step, p))| if step == u32::MAX { v as u32 } else { p })
            .collect();
        let root_at: Vec<u32> = (0..parent.len() as u32)
            .map(|v| weld.remap[find(&mut parent, v) as usize])
            .collect();
        for (r, region) in regions.iter_mut().enumerate() {
            region.fin_prone =
                fin_prone(region, r as u32, &region_of, &moves, &weld.remap, &root_at);
        }
        Ok(Self {
            partition: Partition::from_region_of(region_of, count),
            regions,
            vertex_count: mesh.vertex_count(),
        })
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

    /// Bytes of the shared data of every region.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.regions
            .iter()
            .map(|r| {
                r.mesh.memory_bytes()
                    + r.global.len() * 4
                    + r.border.len() * 4
                    + r.fin_prone.len() * 4
                    + r.front_events.len() * size_of::<FrontEvent>()
            })
            .sum()
    }
}

/// A built region, and its vertex moves `(step, old, new)` in local indices.
type BuiltRegion = (Region, Vec<(u32, u32, u32)>);

/// A greedy colouring of the regions' adjacency (two regions are adjacent when a triangle has
/// corners in both): no two neighbours share a colour. Clustered and grid partitions need a
/// handful of colours; a fragmented partition (random ids) can need nearly one per region,
/// and its regions are then built one after another.
fn colour_regions(mesh: &IndexedMesh, region_of: &[u32], count: usize) -> Vec<u32> {
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); count];
    for t in mesh.indices.chunks_exact(3) {
        for &a in t {
            for &b in t {
                let (ra, rb) = (region_of[a as usize], region_of[b as usize]);
                if ra != rb {
                    neighbours[ra as usize].push(rb);
                }
            }
        }
    }
    let mut colour = vec![u32::MAX; count];
    let mut taken = Vec::new();
    for r in 0..count {
        neighbours[r].sort_unstable();
        neighbours[r].dedup();
        taken.clear();
        taken.extend(
            neighbours[r]
                .iter()
                .map(|&n| colour[n as usize])
                .filter(|&c| c != u32::MAX),
        );
        taken.sort_unstable();
        taken.dedup();
        // The smallest colour not taken: the first gap in the sorted list.
        colour[r] = taken
            .iter()
            .enumerate()
            .find(|&(i, &c)| c != i as u32)
            .map_or(taken.len() as u32, |(i, _)| i as u32);
    }
    colour
}

/// Builds one region's sequence over its owned triangles, with context triangles around its
/// vertices, and returns the vertex moves in local indices.
/// `moves` holds the vertex moves `(step, parent)` of the regions built before this one (the
/// rest are `u32::MAX`): the band triangles this region moves are checked against every
/// position their foreign corners take in those regions, not only at full detail.
#[allow(clippy::too_many_arguments)]
fn build_region(
    mesh: &IndexedMesh,
    region_of: &[u32],
    r: u32,
    owned: &[u32],
    context: &[u32],
    cuts: &[bool],
    moves: &[(u32, u32)],
    options: &BuildOptions,
) -> Result<BuiltRegion, RegionError> {
    // Local vertex table: own vertices first (by global id), then foreign ones.
    let mut global: Vec<u32> = owned
        .iter()
        .chain(context)
        .flat_map(|&t| {
            mesh.indices[3 * t as usize..3 * t as usize + 3]
                .iter()
                .copied()
        })
        .collect();
    global.sort_unstable_by_key(|&v| (region_of[v as usize] != r, v));
    global.dedup();
    let own_vertices = global
        .iter()
        .take_while(|&&v| region_of[v as usize] == r)
        .count();
    let mut local = std::collections::HashMap::with_capacity(global.len());
    for (i, &v) in global.iter().enumerate() {
        local.insert(v, i as u32);
    }
    let mut sub = subset(mesh, &global);
    sub.indices = owned
        .iter()
        .chain(context)
        .flat_map(|&t| mesh.indices[3 * t as usize..3 * t as usize + 3].iter())
        .map(|v| local[v])
        .collect();
    // Foreign vertices are pinned. So are junctions: own vertices next to vertices of two or
    // more other regions, where the fronts of three regions meet and no single front order
    // exists to collapse along.
    // And so are the cuts of closed bands (see `bands::closed_band_cuts`).
    let mut pinned: Vec<bool> = (0..global.len())
        .map(|i| i >= own_vertices || cuts[global[i] as usize])
        .collect();
    let mut foreign_region: Vec<u32> = vec![u32::MAX; own_vertices];
    // Going round an own vertex, count where the ring passes from own to foreign vertices:
    // more than once means several separate runs of foreign neighbours, so there is no
    // single front to collapse along (random or fragmented partitions); pin those too.
    // Counted per position, so that the seam copies of a vertex share one ring.
    let at = weld_positions(&sub.positions).remap;
    let mut own_to_foreign = vec![0u32; own_vertices];
    for t in sub.indices.chunks_exact(3) {
        for k in 0..3 {
            let (u, a, b) = (
                t[k] as usize,
                t[(k + 1) % 3] as usize,
                t[(k + 2) % 3] as usize,
            );
            if u < own_vertices && a < own_vertices && b >= own_vertices {
                own_to_foreign[at[u] as usize] += 1;
            }
        }
    }
    for u in 0..own_vertices {
        pinned[u] |= own_to_foreign[at[u] as usize] > 1;
    }
    for t in sub.indices.chunks_exact(3) {
        for &a in t {
            for &b in t {
                let (a, b) = (a as usize, b as usize);
                if a < own_vertices && b >= own_vertices {
                    let region = region_of[global[b] as usize];
                    match foreign_region[a] {
                        u32::MAX => foreign_region[a] = region,
                        seen if seen != region => pinned[a] = true,
                        _ => {}
                    }
                }
            }
        }
    }
    // Fronts run along the foreign vertices only, not along the junctions (see
    // `Builder::touches_anchor`).
    let foreign: Vec<bool> = (0..global.len()).map(|i| i >= own_vertices).collect();
    // Each foreign vertex's representatives in its (built) region: from which level on each
    // stands in for it, and where.
    let chains: Vec<Vec<(u32, Vec3)>> = global
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let mut chain = Vec::new();
            if i >= own_vertices {
                chain.push((0, mesh.positions[v as usize]));
                let mut at = v;
                while let (step, parent) = moves[at as usize]
                    && step != u32::MAX
                {
                    chain.push((step + 1, mesh.positions[parent as usize]));
                    at = parent;
                }
            }
            chain
        })
        .collect();
    let built = build::build(
        &sub,
        options,
        &build::Constraints {
            pinned: Some(&pinned),
            anchors: Some(&foreign),
            chains: Some(&chains),
        },
        owned.len(),
        &mut |_, _| {},
    )?;
    let bounds = sub.positions[..own_vertices]
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let region = Region {
        mesh: built.mesh,
        global,
        border: Vec::new(),
        fin_prone: Vec::new(),
        front_events: Vec::new(),
        neighbors: Vec::new(),
        position_of: Vec::new(),
        own_vertices,
        bounds,
    };
    Ok((region, built.moves))
}
