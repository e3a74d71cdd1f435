//! Shortest-path weights for a painted skin without weights (section 5.5).

use super::{Influences, SkinError, SkinRegionKind};
use crate::mesh::{IndexedMesh, weld_positions};
use crate::util::{Buckets, buckets};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Computes two-bone skin weights from a region painting by shortest paths (ASLOD section 5.5).
///
/// For a mesh that has a region painting (`region_of[v]` is vertex `v`'s region, `kinds[r]` the
/// region's kind) and a skeleton but no weights, such as one whose regions were painted by
/// vertex colour, as the paper's animators did in 3D Studio MAX.
///
/// - A vertex of a rigid region follows its bone alone: joints `[bone, 0, 0, 0]`, weights
///   `[1, 0, 0, 0]`.
/// - For each deformable region D with bones `[a, b]`, a multi-source Dijkstra runs over the
///   mesh edges (Euclidean lengths) restricted to D's vertices, once from D's border with
///   bone `a` and once from its border with bone `b`. The border with bone `a` is the set of
///   vertices of `a`'s rigid region(s) that share an edge with D; they start at distance 0.
///   With `|PA|` and `|PB|` the two path lengths of vertex P, P's weight for bone `b` is
///   `s = |PA| / (|PA| + |PB|)` and its weight for `a` is `1 - s`: the weight shifts
///   gradually from `a` to `b` across the region.
/// - The joints of a deformable vertex are `[a, b, 0, 0]` with weights `[1 - s, s, 0, 0]`,
///   then sorted largest first (ties by joint) as [`Influences`] requires; a zero weight's slot
///   is cleared.
///
/// How this reads the paper. Section 5.5 writes `s = |PA| / (|PA| + |PB|)` without saying which
/// bone `s` belongs to, and section 5.3's `P_d = s P_A + (1 - s) P_B T` would, read literally,
/// give a vertex on A's border (`|PA| = 0`) entirely to bone B. Both contradict the paper's
/// own requirement that "vertices that are closer to one bone should be influenced more by
/// that bone", so `s` is taken as the weight of the *far* bone B: a vertex at A's border
/// follows A fully, one at B's border follows B fully. The paper's "border vertices, contained
/// in both the deformable and one of the bordering regions" are, in this crate's vertex
/// partition, the rigid vertices next to D; they have weight exactly 0 or 1 by being rigid.
///
/// Vertices at the same position (seam copies, as [`weld_positions`] groups them) are one node
/// of the graph, so a UV seam does not cut the paths.
///
/// Fallbacks:
/// - a vertex of D that reaches only one border (D touches only one of its bones' regions,
///   or the vertex lies on a part of D cut off from the other border) follows the reachable
///   bone fully;
/// - a deformable region with bones `[a, a]` follows `a` fully;
/// - a region with no vertices is skipped.
///
/// # Errors
/// - [`SkinError::LengthMismatch`] when `region_of` does not have one entry per vertex;
/// - [`SkinError::RegionOutOfRange`] for a region id `>= kinds.len()`;
/// - [`SkinError::IndexOutOfRange`] for a triangle corner that is not a vertex;
/// - [`SkinError::NoRegionBorder`] for a vertex of a deformable region that reaches neither
///   border (naming the region and the first such vertex).
///
/// # Example
/// ```
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::skin::{SkinRegionKind, shortest_path_weights};
/// use glam::Vec3;
///
/// // A polyline of five vertices along X, drawn as thin triangles: A A D D B.
/// let positions: Vec<Vec3> = (0..5)
///     .flat_map(|i| [Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32, 0.1, 0.0)])
///     .collect();
/// let mut indices = Vec::new();
/// for i in 0..4u32 {
///     let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
///     indices.extend_from_slice(&[a, c, b, b, c, d]);
/// }
/// let mesh = IndexedMesh::new(positions, indices);
/// let kinds = [
///     SkinRegionKind::Rigid { bone: 0 },
///     SkinRegionKind::Rigid { bone: 1 },
///     SkinRegionKind::Deformable { bones: [0, 1] },
/// ];
/// let region_of = [0, 0, 0, 0, 2, 2, 2, 2, 1, 1];
/// let influences = shortest_path_weights(&mesh, &region_of, &kinds)?;
/// // x = 2 is one edge from A and two from B: one third of the way.
/// assert_eq!(influences.joints[4], [0, 1, 0, 0]);
/// assert!((influences.weights[4][1] - 1.0 / 3.0).abs() < 1e-6);
/// assert_eq!(influences.weights[0], [1.0, 0.0, 0.0, 0.0]);
/// # Ok::<(), bevy_aslod::skin::SkinError>(())
/// ```
pub fn shortest_path_weights(
    mesh: &IndexedMesh,
    region_of: &[u32],
    kinds: &[SkinRegionKind],
) -> Result<Influences, SkinError> {
    let n = mesh.positions.len();
    validate(mesh, region_of, kinds)?;
    let graph = Graph::new(mesh);

    // Per vertex, the bone of its rigid region, if it is in one.
    let rigid_bone: Vec<Option<u16>> = region_of
        .iter()
        .map(|&r| match kinds[r as usize] {
            SkinRegionKind::Rigid { bone } => Some(bone),
            SkinRegionKind::Deformable { .. } => None,
        })
        .collect();
    let has_copy_on = |x: usize, bone: u16| {
        graph
            .copies(x)
            .iter()
            .any(|&v| rigid_bone[v as usize] == Some(bone))
    };

    let mut out = Influences {
        joints: vec![[0; 4]; n],
        weights: vec![[0.0; 4]; n],
    };
    for (v, bone) in rigid_bone.iter().enumerate() {
        if let Some(bone) = *bone {
            out.joints[v] = [bone, 0, 0, 0];
            out.weights[v] = [1.0, 0.0, 0.0, 0.0];
        }
    }

    let members = buckets(region_of, kinds.len());
    let mut in_region = vec![u32::MAX; n];
    let mut dist = [vec![f64::INFINITY; n], vec![f64::INFINITY; n]];
    let mut touched = Vec::new();
    let mut heap = BinaryHeap::new();
    for (r, kind) in kinds.iter().enumerate() {
        let SkinRegionKind::Deformable { bones: [a, b] } = *kind else {
            continue;
        };
        let verts = members.get(r);
        if a == b {
            for &v in verts {
                out.joints[v as usize] = [a, 0, 0, 0];
                out.weights[v as usize] = [1.0, 0.0, 0.0, 0.0];
            }
            continue;
        }
        for &v in verts {
            in_region[graph.node(v)] = r as u32;
        }
        for (side, bone) in [a, b].into_iter().enumerate() {
            let dist = &mut dist[side];
            // Sources: rigid nodes of `bone` next to the region (or in it, through a seam copy
            // painted differently).
            for &v in verts {
                let x = graph.node(v);
                for &y in std::iter::once(&(x as u32)).chain(graph.neighbours(x)) {
                    let y = y as usize;
                    if dist[y] != 0.0 && has_copy_on(y, bone) {
                        dist[y] = 0.0;
                        touched.push(y);
                        heap.push(Entry(0.0, y));
                    }
                }
            }
            while let Some(Entry(d, x)) = heap.pop() {
                if d > dist[x] {
                    continue;
                }
                for &y in graph.neighbours(x) {
                    let y = y as usize;
                    if in_region[y] != r as u32 {
                        continue;
                    }
                    let nd = d + graph.length(mesh, x, y);
                    if nd < dist[y] {
                        dist[y] = nd;
                        touched.push(y);
                        heap.push(Entry(nd, y));
                    }
                }
            }
        }
        for &v in verts {
            let x = graph.node(v);
            let (da, db) = (dist[0][x], dist[1][x]);
            let s = match (da.is_finite(), db.is_finite()) {
                (true, true) if da + db > 0.0 => (da / (da + db)) as f32,
                (true, true) => 0.5,
                (true, false) => 0.0,
                (false, true) => 1.0,
                (false, false) => {
                    return Err(SkinError::NoRegionBorder {
                        region: r as u32,
                        vertex: v as usize,
                    });
                }
            };
            let (j, w) = two_bones(a, b, s);
            out.joints[v as usize] = j;
            out.weights[v as usize] = w;
        }
        for &x in &touched {
            dist[0][x] = f64::INFINITY;
            dist[1][x] = f64::INFINITY;
        }
        touched.clear();
    }
    Ok(out)
}

/// Length and range checks, so that the rest never indexes out of bounds.
fn validate(
    mesh: &IndexedMesh,
    region_of: &[u32],
    kinds: &[SkinRegionKind],
) -> Result<(), SkinError> {
    let n = mesh.positions.len();
    if region_of.len() != n {
        return Err(SkinError::LengthMismatch {
            what: "region_of",
            expected: n,
            found: region_of.len(),
        });
    }
    if let Some((vertex, &region)) = region_of
        .iter()
        .enumerate()
        .find(|&(_, &r)| r as usize >= kinds.len())
    {
        return Err(SkinError::RegionOutOfRange {
            vertex,
            region,
            region_count: kinds.len(),
        });
    }
    if let Some((corner, &index)) = mesh
        .indices
        .iter()
        .enumerate()
        .find(|&(_, &i)| i as usize >= n)
    {
        return Err(SkinError::IndexOutOfRange {
            corner,
            index,
            vertex_count: n,
        });
    }
    Ok(())
}

/// Joints and weights of a vertex between bones `a` (weight `1 - s`) and `b` (weight `s`),
/// sorted largest first, ties by joint, zero slots cleared.
fn two_bones(a: u16, b: u16, s: f32) -> ([u16; 4], [f32; 4]) {
    let (wa, wb) = (1.0 - s, s);
    if wb <= 0.0 {
        ([a, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
    } else if wa <= 0.0 {
        ([b, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
    } else if wb > wa || (wb == wa && b < a) {
        ([b, a, 0, 0], [wb, wa, 0.0, 0.0])
    } else {
        ([a, b, 0, 0], [wa, wb, 0.0, 0.0])
    }
}

/// Edges between welded vertices: node ids are the representative vertex of each position.
struct Graph {
    remap: Vec<u32>,
    adjacency: Buckets,
    copies: Buckets,
}

impl Graph {
    fn new(mesh: &IndexedMesh) -> Self {
        let n = mesh.positions.len();
        let remap = weld_positions(&mesh.positions).remap;
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.indices.len() * 2);
        for t in mesh.indices.chunks_exact(3) {
            for k in 0..3 {
                let a = remap[t[k] as usize];
                let b = remap[t[(k + 1) % 3] as usize];
                if a != b {
                    edges.push((a, b));
                    edges.push((b, a));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let keys: Vec<u32> = edges.iter().map(|e| e.0).collect();
        let mut adjacency = buckets(&keys, n);
        // `buckets` keeps the input order, so row `a` lists the `b` of the edges `(a, b)`.
        for (item, e) in adjacency.items_mut().iter_mut().zip(&edges) {
            *item = e.1;
        }
        let copies = buckets(&remap, n);
        Self {
            remap,
            adjacency,
            copies,
        }
    }

    #[inline]
    fn node(&self, v: u32) -> usize {
        self.remap[v as usize] as usize
    }

    #[inline]
    fn neighbours(&self, x: usize) -> &[u32] {
        self.adjacency.get(x)
    }

    #[inline]
    fn copies(&self, x: usize) -> &[u32] {
        self.copies.get(x)
    }

    #[inline]
    fn length(&self, mesh: &IndexedMesh, x: usize, y: usize) -> f64 {
        f64::from(mesh.positions[x].distance(mesh.positions[y]))
    }
}

/// A heap entry ordered by smallest distance first.
struct Entry(f64, usize);

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}
