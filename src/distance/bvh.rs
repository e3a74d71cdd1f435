//! The BVH: a binned-SAH hierarchy over a triangle mesh for exact closest-point queries.

use super::kernel::Tri;
use super::{MeshRef, valid_triangles};
use glam::{Vec3, Vec3A};

/// Most triangles in a leaf when splitting still pays. Larger leaves only appear when the
/// triangles' centroids coincide or the depth limit is reached.
const MAX_LEAF: usize = 4;
/// Depth limit, which bounds the traversal stack.
const MAX_DEPTH: usize = 60;
/// Bins per axis for the SAH split search.
const BINS: usize = 16;

/// A bounding-volume hierarchy over a triangle mesh, for exact closest-point queries.
///
/// Built top-down with a binned surface-area heuristic over the triangle centroids, stored as a
/// flat node array, and traversed iteratively, nearer child first, pruning every box farther than
/// the best triangle found so far. Triangles with an out-of-range index or a non-finite corner
/// are left out.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
    /// Mesh triangle index of each entry of `tris`.
    ids: Vec<u32>,
    /// Entry of `tris` of each mesh triangle (`u32::MAX` for an invalid one).
    slots: Vec<u32>,
}

/// A node of the flat BVH: an inner node's children are `first` and `first + 1`; a leaf holds
/// triangles `first .. first + count` of [`Bvh::tris`].
#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3A,
    max: Vec3A,
    first: u32,
    count: u32,
}

impl Node {
    /// Squared distance from `p` to the node's box (`0` inside).
    #[inline]
    fn d2(&self, p: Vec3A) -> f32 {
        let d = (self.min - p).max(p - self.max).max(Vec3A::ZERO);
        d.length_squared()
    }
}

impl Bvh {
    /// Builds the hierarchy over the triangles `indices` (three per triangle) into `positions`.
    #[must_use]
    pub fn new(positions: &[Vec3], indices: &[u32]) -> Self {
        let input = valid_triangles(MeshRef::new(positions, indices));
        if input.is_empty() {
            return Self::default();
        }
        let mut build: Vec<BuildTri> = input
            .iter()
            .map(|&(id, [i, j, k])| {
                let (a, b, c) = (
                    Vec3A::from(positions[i as usize]),
                    Vec3A::from(positions[j as usize]),
                    Vec3A::from(positions[k as usize]),
                );
                BuildTri {
                    min: a.min(b).min(c),
                    max: a.max(b).max(c),
                    centroid: (a + b + c) * (1.0 / 3.0),
                    id,
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * build.len() / MAX_LEAF + 1);
        nodes.push(Node {
            min: Vec3A::ZERO,
            max: Vec3A::ZERO,
            first: 0,
            count: 0,
        });
        build_node(&mut nodes, &mut build, 0, 0, 0);
        let mut slots = vec![u32::MAX; indices.len() / 3];
        for (slot, t) in build.iter().enumerate() {
            slots[t.id as usize] = slot as u32;
        }
        let tris = build
            .iter()
            .map(|t| {
                let c = &indices[3 * t.id as usize..][..3];
                let [a, b, c] = [0, 1, 2].map(|k| Vec3A::from(positions[c[k] as usize]));
                Tri::new(a, b, c)
            })
            .collect();
        Self {
            nodes,
            tris,
            ids: build.iter().map(|t| t.id).collect(),
            slots,
        }
    }

    /// Number of triangles in the hierarchy (the valid triangles of the mesh).
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether the hierarchy holds no triangle.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Bounding box `(min, max)` of all triangles, or `None` if empty.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let root = self.nodes.first()?;
        Some((root.min.into(), root.max.into()))
    }

    /// The closest triangle to `p`: `(squared distance, triangle index in the mesh)`, or `None`
    /// if the hierarchy is empty.
    ///
    /// The distance is exact (up to `f32` rounding). If several triangles are equally close, any
    /// one of them may be returned.
    #[must_use]
    pub fn closest_point(&self, p: Vec3) -> Option<(f32, u32)> {
        self.closest_impl(Vec3A::from(p), None)
            .map(|(d2, slot)| (d2, self.ids[slot as usize]))
    }

    /// Like [`closest_point`](Self::closest_point), but starts from a triangle expected to be close
    /// (typically the answer for a nearby point), which prunes the search sooner. The hint is a
    /// mesh triangle index; an invalid one is ignored. The returned distance is the same
    /// with or without a hint.
    #[must_use]
    pub fn closest_point_with_hint(&self, p: Vec3, hint: u32) -> Option<(f32, u32)> {
        let slot = self
            .slots
            .get(hint as usize)
            .copied()
            .filter(|&s| s != u32::MAX);
        self.closest_impl(Vec3A::from(p), slot)
            .map(|(d2, slot)| (d2, self.ids[slot as usize]))
    }

    /// Closest triangle as `(squared distance, slot in self.tris)`, starting from slot `hint`.
    pub(super) fn closest_impl(&self, p: Vec3A, hint: Option<u32>) -> Option<(f32, u32)> {
        if self.tris.is_empty() {
            return None;
        }
        let (mut best, mut best_slot) = (f32::INFINITY, 0u32);
        if let Some(h) = hint.filter(|&h| (h as usize) < self.tris.len()) {
            let t = &self.tris[h as usize];
            best = t.d2(p);
            best_slot = h;
        }
        let mut stack = [(0u32, 0f32); MAX_DEPTH + 4];
        let mut sp = 0usize;
        let root = &self.nodes[0];
        let mut node = 0u32;
        let mut node_d2 = root.d2(p);
        loop {
            if node_d2 < best {
                let n = &self.nodes[node as usize];
                if n.count > 0 {
                    let first = n.first as usize;
                    for (k, t) in self.tris[first..first + n.count as usize]
                        .iter()
                        .enumerate()
                    {
                        let d2 = t.d2(p);
                        if d2 < best {
                            best = d2;
                            best_slot = (first + k) as u32;
                        }
                    }
                } else {
                    let (l, r) = (n.first, n.first + 1);
                    let dl = self.nodes[l as usize].d2(p);
                    let dr = self.nodes[r as usize].d2(p);
                    let ((near, dn), (far, df)) = if dl <= dr {
                        ((l, dl), (r, dr))
                    } else {
                        ((r, dr), (l, dl))
                    };
                    if df < best && sp < stack.len() {
                        stack[sp] = (far, df);
                        sp += 1;
                    }
                    node = near;
                    node_d2 = dn;
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            (node, node_d2) = stack[sp];
        }
        Some((best, best_slot))
    }
}

/// A triangle during construction: its bounds and centroid, and its index in the mesh.
#[derive(Clone, Copy, Debug)]
struct BuildTri {
    min: Vec3A,
    max: Vec3A,
    centroid: Vec3A,
    id: u32,
}

/// Builds node `index` over `tris[start..]` (the slice handed in), recursively.
fn build_node(
    nodes: &mut Vec<Node>,
    tris: &mut [BuildTri],
    index: usize,
    start: usize,
    depth: usize,
) {
    let mut bounds = Aabb::EMPTY;
    let mut centroids = Aabb::EMPTY;
    for t in tris.iter() {
        bounds.grow(t.min, t.max);
        centroids.grow(t.centroid, t.centroid);
    }
    let leaf = Node {
        min: bounds.min,
        max: bounds.max,
        first: start as u32,
        count: tris.len() as u32,
    };
    let extent = centroids.max - centroids.min;
    let widest = extent.max_element();
    if tris.len() <= MAX_LEAF || depth >= MAX_DEPTH || widest.is_nan() || widest <= 0.0 {
        nodes[index] = leaf;
        return;
    }

    // Binned SAH over all three axes, binned in one pass.
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(BINS as f32) / extent,
        Vec3A::ZERO,
    );
    let bin_of = |c: Vec3A| {
        // `as usize` saturates (NaN to 0), so only the upper end needs clamping.
        let b = (c - centroids.min) * scale;
        [b.x, b.y, b.z].map(|x| (x as usize).min(BINS - 1))
    };
    let mut bins = [[(Aabb::EMPTY, 0usize); BINS]; 3];
    for t in tris.iter() {
        for (axis, b) in bin_of(t.centroid).into_iter().enumerate() {
            bins[axis][b].0.grow(t.min, t.max);
            bins[axis][b].1 += 1;
        }
    }
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, split bin)
    for (axis, bins) in bins.iter().enumerate() {
        if scale[axis] <= 0.0 {
            continue;
        }
        // Sweep from the right to get the cost of every right part, then from the left.
        let mut right = [0.0f32; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for b in (1..BINS).rev() {
            acc.grow(bins[b].0.min, bins[b].0.max);
            n += bins[b].1;
            right[b] = if n > 0 {
                acc.half_area() * n as f32
            } else {
                0.0
            };
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for b in 0..BINS - 1 {
            acc.grow(bins[b].0.min, bins[b].0.max);
            n += bins[b].1;
            if n == 0 || n == tris.len() {
                continue;
            }
            let cost = acc.half_area() * n as f32 + right[b + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }

    let mid = match best {
        Some((_, axis, split)) => {
            let mut mid = 0;
            for i in 0..tris.len() {
                if bin_of(tris[i].centroid)[axis] < split {
                    tris.swap(i, mid);
                    mid += 1;
                }
            }
            mid
        }
        None => 0,
    };
    let mid = if mid == 0 || mid == tris.len() {
        // No bin boundary separates the centroids: fall back to a median split on the widest axis.
        let axis = extent.max_position();
        let half = tris.len() / 2;
        tris.select_nth_unstable_by(half, |x, y| x.centroid[axis].total_cmp(&y.centroid[axis]));
        half
    } else {
        mid
    };

    let child = nodes.len();
    nodes[index] = Node {
        first: child as u32,
        count: 0,
        ..leaf
    };
    nodes.push(leaf);
    nodes.push(leaf);
    let (left, right) = tris.split_at_mut(mid);
    build_node(nodes, left, child, start, depth + 1);
    build_node(nodes, right, child + 1, start + mid, depth + 1);
}

/// Bounding box accumulator.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: Vec3A,
    max: Vec3A,
}

impl Aabb {
    const EMPTY: Self = Self {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
    }

    /// Half the surface area (enough for the SAH); `0` when empty.
    fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::kernel::point_triangle_distance_sq;
    use crate::distance::sample::{SplitMix64, tests::random_vec};

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = SplitMix64::new(11);
        let mut positions = Vec::new();
        for _ in 0..300 {
            let centre = random_vec(&mut rng, 5.0);
            for _ in 0..3 {
                positions.push(centre + random_vec(&mut rng, 0.5));
            }
        }
        let indices: Vec<u32> = (0..positions.len() as u32).collect();
        let bvh = Bvh::new(&positions, &indices);
        assert_eq!(bvh.len(), 300);
        for q in 0..1000 {
            let p = random_vec(&mut rng, 7.0);
            let brute = indices
                .chunks_exact(3)
                .map(|t| {
                    let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
                    point_triangle_distance_sq(p, a, b, c)
                })
                .fold(f32::INFINITY, f32::min);
            let (d2, tri) = bvh.closest_point(p).unwrap();
            assert_eq!(d2, brute, "query {q}");
            let t = &indices[3 * tri as usize..3 * tri as usize + 3];
            let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
            assert_eq!(point_triangle_distance_sq(p, a, b, c), d2);
            let (h2, _) = bvh.closest_point_with_hint(p, q % 300).unwrap();
            assert_eq!(h2, brute, "hinted query {q}");
        }
    }

    #[test]
    fn invalid_triangles_are_ignored() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NAN];
        let indices = [0, 1, 2, 0, 1, 3, 0, 1, 9, 2];
        let bvh = Bvh::new(&positions, &indices);
        assert_eq!(bvh.len(), 1);
        assert_eq!(bvh.closest_point(Vec3::Z), Some((1.0, 0)));
        assert!(Bvh::new(&[], &[]).closest_point(Vec3::ZERO).is_none());
    }
}
