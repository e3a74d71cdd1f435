//! Building a region mesh: the regions' sequences, in rounds of non-neighbours.

use super::bands::closed_band_cuts;
use super::borders::{fin_prone, link_border};
use super::util::find;
use super::{FrontEvent, Partition, Region, RegionError, RegionMesh, triangle_owner};
use crate::executor::{Executor, Threads};
use crate::mesh::{IndexedMesh, weld_positions};
use crate::multires::{BuildOptions, build};
use glam::Vec3;

impl RegionMesh {
    /// Partitions `mesh` by `partition` and builds every region's sequence, on scoped threads
    /// (one per core; [`Threads`]).
    ///
    /// # Errors
    /// [`RegionError::PartitionMismatch`] when the partition has another vertex count, and
    /// any [`MeshError`](crate::mesh::MeshError) from validating the mesh.
    pub fn build(
        mesh: &IndexedMesh,
        partition: &Partition,
        options: &BuildOptions,
    ) -> Result<Self, RegionError> {
        Self::build_with(mesh, partition, options, &Threads)
    }

    /// [`build`](Self::build) with the regions of each round built by `executor` (an engine's
    /// thread pool, or [`Sequential`](crate::executor::Sequential)); the result is the same
    /// whichever runs them.
    ///
    /// # Errors
    /// As [`build`](Self::build).
    pub fn build_with(
        mesh: &IndexedMesh,
        partition: &Partition,
        options: &BuildOptions,
        executor: &impl Executor,
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
            let (mesh, region_of, owned, context, cuts, moves_so_far) =
                (&mesh, &region_of, &owned, &context, &cuts, &moves);
            let mut jobs: Vec<(usize, Option<Result<BuiltRegion, RegionError>>)> =
                work.iter().map(|&r| (r, None)).collect();
            executor.for_each(&mut jobs, &|(r, out)| {
                *out = Some(build_region(
                    mesh,
                    region_of,
                    *r as u32,
                    &owned[*r],
                    &context[*r],
                    cuts,
                    moves_so_far,
                    options,
                ));
            });
            let results = jobs
                .into_iter()
                .map(|(_, built)| built.expect("the executor ran every region"));
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
        let mut built = Self {
            partition: Partition::from_region_of(region_of, count),
            regions,
            vertex_count: mesh.vertex_count(),
            root: None,
            built: true,
            morph_tables: std::sync::OnceLock::new(),
        };
        let ratio = options.root_ratio;
        if !(ratio.is_finite() && (0.0..=1.0).contains(&ratio)) {
            log::warn!("BuildOptions::root_ratio = {ratio} is outside 0..=1: no root is built");
        } else if ratio > 0.0 && count > 1 {
            built.root = Some(super::merge::build_root(&mesh, &built, ratio, options)?);
        }
        Ok(built)
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
    let mut sub = mesh.subset(&global);
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
