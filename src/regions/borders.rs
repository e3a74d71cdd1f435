//! The borders between regions: foreign corners, their representatives, and fin-prone
//! triangles.

use super::{FrontEvent, Region};
use crate::mesh::{IndexedMesh, weld_positions};

/// The border triangles of region `r` that may ever need `write_indices`'s fin check.
///
/// A border triangle never loses its area: it is owned by `r`, so it has two corners in `r`
/// or corners in three regions, and corners in different regions never meet (a foreign
/// corner's representatives stay in their own region, and seam copies share one), while two
/// corners in `r` meet only through a collapse of `r` along their edge, which removes the
/// triangle. Two border triangles can still come to sit on the same three positions, a fin,
/// when a neighbour merges their foreign corners (say the two apexes across an edge of `r`
/// that has the same neighbour on both sides). That takes, at some level of `r`, the same
/// representatives in `r` and, for each foreign corner, a corner of the same region whose
/// chain of representatives ends at the same place (chains that meet share their end). This
/// walks `r`'s levels as events (a border triangle leaves the active prefix, or one of its
/// corners in `r` moves on to its next representative) and marks every border triangle that
/// meets another on that key at some level; the neighbours' levels are covered by comparing
/// chain ends. `O(e log e)` for the border triangles' `e` events.
///
/// `moves[v]`: the step of its own region that removes source vertex `v`, and the vertex that
/// represents it from then on (`u32::MAX` when never removed); `at[v]`: the position of `v`;
/// `root_at[v]`: the position of its last representative.
pub(super) fn fin_prone(
    region: &Region,
    r: u32,
    region_of: &[u32],
    moves: &[(u32, u32)],
    at: &[u32],
    root_at: &[u32],
) -> Vec<u32> {
    use std::collections::HashMap;
    let border = &region.border;
    if border.len() < 2 {
        return Vec::new();
    }
    let full = region.mesh.full_indices();
    // The key of each corner: its region and, in `r`, its current representative's position,
    // elsewhere its chain's last one. A triangle's key is its three corner keys, sorted.
    let owner = |g: u32| region_of[g as usize];
    let corner_key = |g: u32| {
        let p = if owner(g) == r {
            at[g as usize]
        } else {
            root_at[g as usize]
        };
        u64::from(owner(g)) << 32 | u64::from(p)
    };
    let mut corners: Vec<[u32; 3]> = border
        .iter()
        .map(|&t| {
            let t = 3 * t as usize;
            [0, 1, 2].map(|k| region.global[full[t + k] as usize])
        })
        .collect();
    let key = |tri: &[u32; 3]| {
        let mut k = tri.map(corner_key);
        k.sort_unstable();
        k
    };
    // What happens at each level of `r`: a border triangle leaves the active prefix, or one of
    // its own corners moves on to its next representative (`moves` holds every vertex's step
    // and parent in its own region).
    enum Event {
        Leave(usize),
        Move(usize, usize, u32),
    }
    let counts = region.mesh.level_triangle_counts();
    let mut events: Vec<(usize, Event)> = Vec::new();
    for (i, &t) in border.iter().enumerate() {
        // The first level whose prefix no longer holds t (counts decrease).
        let leaves = counts.partition_point(|&c| c > t as usize);
        if leaves < counts.len() {
            events.push((leaves, Event::Leave(i)));
        }
        for (k, &g) in corners[i].iter().enumerate() {
            if owner(g) != r {
                continue;
            }
            let mut v = g;
            while moves[v as usize].0 != u32::MAX {
                let (step, parent) = moves[v as usize];
                let level = step as usize + 1;
                if level >= leaves {
                    break;
                }
                events.push((level, Event::Move(i, k, parent)));
                v = parent;
            }
        }
    }
    // Leaves before moves at one level, then the moved triangles meet the others.
    events.sort_by_key(|(level, e)| (*level, matches!(e, Event::Move(..))));
    let mut prone = vec![false; border.len()];
    let mut by_key: HashMap<[u64; 3], Vec<usize>> = HashMap::with_capacity(border.len());
    let mark = |by_key: &HashMap<[u64; 3], Vec<usize>>, k: &[u64; 3], prone: &mut [bool]| {
        if let Some(same) = by_key.get(k)
            && same.len() > 1
        {
            for &j in same {
                prone[j] = true;
            }
        }
    };
    let mut keys: Vec<[u64; 3]> = corners.iter().map(key).collect();
    for (i, k) in keys.iter().enumerate() {
        by_key.entry(*k).or_default().push(i);
    }
    for k in &keys {
        mark(&by_key, k, &mut prone);
    }
    let mut moved = Vec::new();
    for same_level in events.chunk_by(|a, b| a.0 == b.0) {
        moved.clear();
        for (_, event) in same_level {
            let i = match *event {
                Event::Leave(i) => i,
                Event::Move(i, k, parent) => {
                    corners[i][k] = parent;
                    moved.push(i);
                    i
                }
            };
            if let Some(same) = by_key.get_mut(&keys[i]) {
                same.retain(|&j| j != i);
            }
        }
        moved.sort_unstable();
        moved.dedup();
        for &i in &moved {
            keys[i] = key(&corners[i]);
            by_key.entry(keys[i]).or_default().push(i);
        }
        for &i in &moved {
            mark(&by_key, &keys[i], &mut prone);
        }
    }
    border
        .iter()
        .zip(&prone)
        .filter_map(|(&t, &p)| p.then_some(t))
        .collect()
}

/// Finds the region's foreign corners and the chain of representatives of each, adding the
/// representatives to the local vertex table where they are missing.
pub(super) fn link_border(
    region: &mut Region,
    r: u32,
    region_of: &[u32],
    moves: &[(u32, u32)],
    mesh: &IndexedMesh,
    events: &mut [Vec<FrontEvent>],
) {
    let mut local: std::collections::HashMap<u32, u32> = region
        .global
        .iter()
        .enumerate()
        .map(|(i, &v)| (v, i as u32))
        .collect();
    let mut extra = Vec::new();
    let indices = region.mesh.full_indices();
    let mut neighbors = Vec::new();
    for (corner, &lv) in indices.iter().enumerate() {
        let v = region.global[lv as usize];
        let owner = region_of[v as usize];
        if owner == r {
            continue;
        }
        neighbors.push(owner);
        let t = (corner / 3) as u32;
        if region.border.last() != Some(&t) {
            region.border.push(t);
        }
        // The vertex and its representatives in turn, each removed by a step of the owner
        // (the owner's collapses stay inside it); the last one is never removed.
        let mut g = v;
        let mut before = lv;
        loop {
            let (step, parent) = moves[g as usize];
            if step == u32::MAX {
                break;
            }
            let after = *local.entry(parent).or_insert_with(|| {
                extra.push(parent);
                (region.global.len() + extra.len() - 1) as u32
            });
            events[owner as usize].push(FrontEvent {
                step,
                region: r,
                corner: corner as u32,
                before,
                after,
            });
            (g, before) = (parent, after);
        }
    }
    if !extra.is_empty() {
        let added = mesh.subset(&extra);
        region.mesh.append_vertices(&added);
        region.global.extend_from_slice(&extra);
    }
    neighbors.sort_unstable();
    neighbors.dedup();
    region.neighbors = neighbors;
    let weld = weld_positions(&region.mesh.vertices().positions);
    region.position_of = if weld.unique == weld.remap.len() {
        Vec::new()
    } else {
        weld.remap
    };
}

#[cfg(test)]
mod tests {
    use super::fin_prone;
    use crate::mesh::test_grid;
    use crate::multires::BuildOptions;
    use crate::regions::{GridPlane, Partition, Region, RegionMesh};

    /// `fin_prone` marks the border triangles that could meet: here the two triangles on
    /// region 0's edge 5-6, whose apexes 2 and 9 are both in region 1. With region 1 free
    /// to merge everything (every chain ending at one place) they could become a fin;
    /// with chains that never meet, and with the chains the build made, nothing is marked.
    ///
    /// ```text
    ///  0 -- 1 -- 2 -- 3      region 1: every vertex but 5 and 6
    ///  |    |    |    |
    ///  4 -- 5 == 6 -- 7      region 0: 5 and 6
    ///  |    |    |    |
    ///  8 -- 9 -- 10-- 11
    /// ```
    #[test]
    fn fin_prone_marks_triangles_whose_foreign_corners_can_merge() {
        let mut mesh = test_grid(4, |_, _| 0.0);
        mesh.positions.truncate(12);
        mesh.indices = Vec::new();
        for z in 0..2u32 {
            for x in 0..3u32 {
                let i = z * 4 + x;
                mesh.indices
                    .extend_from_slice(&[i, i + 4, i + 1, i + 1, i + 4, i + 5]);
            }
        }
        let ids: Vec<u32> = (0..12).map(|v| u32::from(v != 5 && v != 6)).collect();
        let (partition, _) = Partition::from_ids(&mesh, &ids).unwrap();
        let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
        let r0 = partition.region_of()[5];
        let region = &regions.regions()[r0 as usize];
        let at: Vec<u32> = (0..12).collect();
        let full = region.mesh.full_indices();
        let on_edge: Vec<u32> = region
            .border
            .iter()
            .copied()
            .filter(|&t| {
                let tri = &full[3 * t as usize..3 * t as usize + 3];
                let global: Vec<u32> = tri.iter().map(|&v| region.global[v as usize]).collect();
                global.contains(&5) && global.contains(&6)
            })
            .collect();
        assert_eq!(on_edge.len(), 2, "two border triangles on edge 5-6");
        // Every chain of region 1 ends at vertex 0.
        let one_root: Vec<u32> = (0..12)
            .map(|v| if ids[v] == 1 { 0 } else { v as u32 })
            .collect();
        let none = vec![(u32::MAX, u32::MAX); 12];
        let marked = fin_prone(region, r0, partition.region_of(), &none, &at, &one_root);
        for t in &on_edge {
            assert!(marked.contains(t), "{on_edge:?} not in {marked:?}");
        }
        // Chains that never meet: nothing.
        assert!(fin_prone(region, r0, partition.region_of(), &none, &at, &at).is_empty());
        assert_eq!(region.fin_prone, Vec::<u32>::new());
    }

    /// [`fin_prone`] the slow way, for comparison: every level of the region through a
    /// polygon cache, every border triangle's key at each.
    fn fin_prone_by_levels(
        region: &Region,
        r: u32,
        region_of: &[u32],
        at: &[u32],
        root_at: &[u32],
    ) -> Vec<u32> {
        if region.border.len() < 2 {
            return Vec::new();
        }
        let key_of = |v: u32| -> u64 {
            let g = region.global[v as usize] as usize;
            let owner = region_of[g];
            let p = if owner == r { at[g] } else { root_at[g] };
            u64::from(owner) << 32 | u64::from(p)
        };
        let mut cache = crate::multires::PolygonCache::new(&region.mesh);
        let mut prone = vec![false; region.border.len()];
        let mut last = vec![[u32::MAX; 3]; region.border.len()];
        let mut keyed: Vec<([u64; 3], usize)> = Vec::new();
        loop {
            let indices = cache.indices();
            let active = region
                .border
                .partition_point(|&t| 3 * (t as usize) < indices.len());
            // A triangle leaving the prefix meets no new one: only rewrites matter.
            let mut changed = false;
            for (slot, &t) in last.iter_mut().zip(&region.border[..active]) {
                let t = 3 * t as usize;
                let tri = [indices[t], indices[t + 1], indices[t + 2]];
                changed |= *slot != tri;
                *slot = tri;
            }
            if changed {
                keyed.clear();
                keyed.extend(last[..active].iter().enumerate().map(|(i, tri)| {
                    let mut key = tri.map(key_of);
                    key.sort_unstable();
                    (key, i)
                }));
                keyed.sort_unstable();
                for same in keyed.chunk_by(|a, b| a.0 == b.0) {
                    if same.len() > 1 {
                        for &(_, i) in same {
                            prone[i] = true;
                        }
                    }
                }
            }
            if !cache.coarsen(&region.mesh) {
                break;
            }
        }
        region
            .border
            .iter()
            .zip(&prone)
            .filter_map(|(&t, &p)| p.then_some(t))
            .collect()
    }

    /// The event walk of `fin_prone` marks what walking every level marks, on partitions
    /// where keys are made to meet (five positions in all, every chain of a region ending at
    /// one place).
    #[test]
    fn fin_prone_events_match_a_walk_over_every_level() {
        let mesh = test_grid(17, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1);
        let mut compared = 0;
        for partition in [
            Partition::grid(&mesh, GridPlane::XZ, 3, 3).unwrap(),
            Partition::clusters(&mesh, 7).unwrap(),
        ] {
            let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
            let region_of = partition.region_of();
            // Few positions, so that keys meet often.
            let at: Vec<u32> = (0..mesh.vertex_count() as u32).map(|v| v % 5).collect();
            // The real moves, rebuilt from the regions' own records.
            let mut moves = vec![(u32::MAX, u32::MAX); mesh.vertex_count()];
            for region in regions.regions() {
                let mut cache = crate::multires::PolygonCache::new(&region.mesh);
                let mut level = 0u32;
                loop {
                    let before: Vec<u32> = cache.indices().to_vec();
                    if !cache.coarsen(&region.mesh) {
                        break;
                    }
                    for (&b, &a) in before.iter().zip(cache.indices()) {
                        if a != b {
                            moves[region.global[b as usize] as usize] =
                                (level, region.global[a as usize]);
                        }
                    }
                    level += 1;
                }
            }
            let one_root: Vec<u32> = region_of.iter().map(|&g| u32::MAX - g).collect();
            for (r, region) in regions.regions().iter().enumerate() {
                let r = r as u32;
                let events = fin_prone(region, r, region_of, &moves, &at, &one_root);
                let levels = fin_prone_by_levels(region, r, region_of, &at, &one_root);
                assert_eq!(events, levels, "region {r}");
                compared += events.len();
            }
        }
        assert!(compared > 0, "the fake chains make some triangles meet");
    }
}
