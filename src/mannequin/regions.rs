//! Cutting the skin into rigid and deformable regions by distance to the bones and joints
//! (the automatic decomposition ASLOD section 5.2 mentions, "using distance to a joint as
//! criterion"), then repairing it on the mesh so every deformable region is a band that
//! separates its two rigid regions.

use super::skeleton::BoneDef;
use super::surface::Adjacency;
use glam::Vec3;
use std::collections::VecDeque;

/// The extent of a joint's deformable band, measured from the joint's pivot along the child
/// bone: from `before` on the parent's side to `after` on the child's, and at most `radius`
/// from the pivot; or else within the ball `extra` (centre, radius), which lets a band follow
/// a crease that is not square to the bone, such as the groin.
#[derive(Clone, Copy, Debug)]
pub(super) struct Band {
    pub before: f32,
    pub after: f32,
    pub radius: f32,
    pub extra: Option<(Vec3, f32)>,
}

impl Band {
    fn contains(&self, bone: &BoneDef, p: Vec3) -> bool {
        let offset = p - bone.pivot;
        let s = offset.dot(bone.direction());
        (-self.before < s && s < self.after && offset.length() < self.radius)
            || self.extra.is_some_and(|(c, r)| p.distance(c) < r)
    }
}

/// Rigid vertices of a joint's two bones closer than this many edges to each other are moved
/// into the joint's band: the band is then at least this wide everywhere, so the shortest-path
/// weights have room to blend.
const MIN_BAND_EDGES: usize = 3;

/// Region ids: the rigid region of bone `b` is `b`; the deformable region of the joint whose
/// child bone is `c` is `bones.len() - 1 + c`.
pub(super) fn deformable_region(bone_count: usize, child: usize) -> u32 {
    (bone_count - 1 + child) as u32
}

/// A region id per vertex. `bands[c]` is the band of the joint between bone `c` and its parent
/// (ignored for the root).
pub(super) fn assign(
    positions: &[Vec3],
    adjacency: &Adjacency,
    bones: &[BoneDef],
    bands: &[Band],
) -> Vec<u32> {
    let n = bones.len();
    // The nearest bone (by distance to its segment less its radius), then the band of one of
    // that bone's joints that holds the vertex, if any.
    let mut region: Vec<u32> = positions
        .iter()
        .map(|&p| {
            let nearest = (0..n)
                .min_by(|&a, &b| {
                    bones[a]
                        .surface_distance(p)
                        .total_cmp(&bones[b].surface_distance(p))
                })
                .expect("bones");
            // Where bands overlap (the two groins meet at the crotch), the nearest pivot wins.
            (1..n)
                .filter(|&c| {
                    let parent = bones[c].parent.expect("only the root has no parent");
                    (nearest == c || nearest == parent) && bands[c].contains(&bones[c], p)
                })
                .min_by(|&a, &b| {
                    p.distance(bones[a].pivot)
                        .total_cmp(&p.distance(bones[b].pivot))
                })
                .map_or(nearest as u32, |c| deformable_region(n, c))
        })
        .collect();

    // Widen every band where its rigid sides come too close (or touch).
    for (c, bone) in bones.iter().enumerate().skip(1) {
        let parent = bone.parent.expect("only the root has no parent");
        let (pr, cr) = (parent as u32, c as u32);
        let near_child = within_edges(adjacency, &region, cr, MIN_BAND_EDGES);
        let near_parent = within_edges(adjacency, &region, pr, MIN_BAND_EDGES);
        for v in 0..region.len() {
            if (region[v] == pr && near_child[v]) || (region[v] == cr && near_parent[v]) {
                region[v] = deformable_region(n, c);
            }
        }
    }

    keep_largest_components(adjacency, &mut region);
    region
}

/// Marks the vertices at most `hops` edges from a vertex of region `from`.
fn within_edges(adjacency: &Adjacency, region: &[u32], from: u32, hops: usize) -> Vec<bool> {
    let mut depth = vec![usize::MAX; region.len()];
    let mut queue = VecDeque::new();
    for (v, &r) in region.iter().enumerate() {
        if r == from {
            depth[v] = 0;
            queue.push_back(v);
        }
    }
    while let Some(v) = queue.pop_front() {
        if depth[v] == hops {
            continue;
        }
        for &w in adjacency.of(v) {
            let w = w as usize;
            if depth[w] == usize::MAX {
                depth[w] = depth[v] + 1;
                queue.push_back(w);
            }
        }
    }
    depth.into_iter().map(|d| d <= hops).collect()
}

/// Connected components of equal region id, as a component number per vertex and the size of
/// each component.
fn components(adjacency: &Adjacency, region: &[u32]) -> (Vec<u32>, Vec<usize>) {
    let mut component = vec![u32::MAX; region.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..region.len() {
        if component[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        component[start] = id;
        stack.push(start);
        let mut size = 0;
        while let Some(v) = stack.pop() {
            size += 1;
            for &w in adjacency.of(v) {
                let w = w as usize;
                if component[w] == u32::MAX && region[w] == region[start] {
                    component[w] = id;
                    stack.push(w);
                }
            }
        }
        sizes.push(size);
    }
    (component, sizes)
}

/// Gives every region a single connected piece: each smaller piece of a region joins the
/// region that most of its outside neighbours belong to.
fn keep_largest_components(adjacency: &Adjacency, region: &mut [u32]) {
    for _ in 0..8 {
        let (component, sizes) = components(adjacency, region);
        let regions = region.iter().max().map_or(0, |&r| r as usize + 1);
        let mut largest = vec![u32::MAX; regions];
        for (c, &size) in sizes.iter().enumerate() {
            let v = component
                .iter()
                .position(|&x| x == c as u32)
                .expect("member");
            let r = region[v] as usize;
            if largest[r] == u32::MAX || size > sizes[largest[r] as usize] {
                largest[r] = c as u32;
            }
        }
        let mut changed = false;
        let mut votes = vec![0usize; regions];
        for (c, _) in sizes.iter().enumerate() {
            let members: Vec<usize> = (0..region.len())
                .filter(|&v| component[v] == c as u32)
                .collect();
            let r = region[members[0]];
            if largest[r as usize] == c as u32 {
                continue;
            }
            votes.fill(0);
            for &v in &members {
                for &w in adjacency.of(v) {
                    if component[w as usize] != c as u32 {
                        votes[region[w as usize] as usize] += 1;
                    }
                }
            }
            // The most common neighbour; the lowest id on a tie.
            let best = (0..regions)
                .rev()
                .max_by_key(|&r| votes[r])
                .expect("regions");
            for &v in &members {
                region[v] = best as u32;
            }
            changed = true;
        }
        if !changed {
            break;
        }
    }
}
