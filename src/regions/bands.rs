//! The bands between two regions: cutting those that close on themselves.

use super::util::{find, unite};
use crate::mesh::IndexedMesh;

/// Vertices to pin so that no band between two regions closes on itself.
///
/// The band between regions A and B is the set of triangles with corners in both and in no
/// third region. Where it ends (at a junction with a third region, or at the mesh's border),
/// it is a strip between two polylines, and each side collapsing only along its own polyline
/// merges runs of consecutive vertices: no edge of the band can appear twice. Where it closes
/// on itself (a region that is an island in another, or a slice of a sphere from pole to
/// pole), each side's front is a loop, and runs can wrap round it: B may merge an arc of its
/// loop into one vertex `b` that, once A has merged the rest of its loop into the two ends of
/// that arc, sees every vertex of A's loop, while A's vertex `a` sees every vertex of B's
/// loop; the band then uses the edge `a-b` twice (two closed halves pinched along one edge).
/// Each side's own build keeps its surface manifold, so the fold needs both sides' merges to
/// wrap. Pinning both ends of one edge across each closed band (a pinned vertex is neither
/// removed nor a collapse target) cuts both loops at the same place, so the band is a strip
/// again.
///
/// Returns, per vertex of `mesh`, whether it is pinned as a cut (seam copies alike).
pub(super) fn closed_band_cuts(mesh: &IndexedMesh, region_of: &[u32], at: &[u32]) -> Vec<bool> {
    use std::collections::HashMap;
    /// An edge across two regions: its two-region triangles, and whether the band ends there
    /// (a triangle with three regions on it, or other than two two-region triangles).
    #[derive(Clone, Copy)]
    struct Crossing {
        tris: [u32; 2],
        end: bool,
    }
    // By position.
    let mut edges: HashMap<(u32, u32), Crossing> = HashMap::new();
    let tris: Vec<[u32; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]].map(|v| at[v as usize]))
        .collect();
    for (t, tri) in tris.iter().enumerate() {
        let regions = tri.map(|p| region_of[p as usize]);
        let three =
            regions[0] != regions[1] && regions[1] != regions[2] && regions[0] != regions[2];
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if region_of[a as usize] == region_of[b as usize] || a == b {
                continue;
            }
            let e = edges.entry((a.min(b), a.max(b))).or_insert(Crossing {
                tris: [u32::MAX; 2],
                end: false,
            });
            if three {
                e.end = true;
            } else if e.tris[0] == u32::MAX {
                e.tris[0] = t as u32;
            } else if e.tris[1] == u32::MAX {
                e.tris[1] = t as u32;
            } else {
                e.end = true;
            }
        }
    }
    // Components of two-region triangles joined across such edges.
    let mut parent: Vec<u32> = (0..tris.len() as u32).collect();
    let mut sorted: Vec<((u32, u32), Crossing)> = edges.into_iter().collect();
    sorted.sort_unstable_by_key(|e| e.0);
    for &(_, Crossing { tris: [t0, t1], .. }) in &sorted {
        if t0 != u32::MAX && t1 != u32::MAX {
            unite(&mut parent, t0, t1);
        }
    }
    // A component is open when one of its edges ends the band; otherwise cut it at its
    // first edge.
    let mut open = vec![false; tris.len()];
    for &(
        _,
        Crossing {
            tris: [t0, t1],
            end,
        },
    ) in &sorted
    {
        let ends = end || t0 == u32::MAX || t1 == u32::MAX;
        for t in [t0, t1] {
            if t != u32::MAX && ends {
                let root = find(&mut parent, t);
                open[root as usize] = true;
            }
        }
    }
    let mut cut_positions = vec![false; region_of.len()];
    let mut done = vec![false; tris.len()];
    for &((a, b), Crossing { tris: [t0, _], .. }) in &sorted {
        if t0 == u32::MAX {
            continue;
        }
        let root = find(&mut parent, t0) as usize;
        if !open[root] && !done[root] {
            done[root] = true;
            cut_positions[a as usize] = true;
            cut_positions[b as usize] = true;
        }
    }
    (0..region_of.len())
        .map(|v| cut_positions[at[v] as usize])
        .collect()
}
