//! Welding by position: the topology the simplifier sees.
//!
//! Attribute seams (UV or normal discontinuities) are stored as several vertices at one
//! position. The simplifier must treat them as one point, or the seams tear; but the
//! attribute vertices themselves must survive, so welding produces a map, not a new mesh.

use glam::Vec3;
use std::collections::HashMap;

/// Vertex -> representative vertex with the same position.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WeldMap {
    /// `remap[v]` is the smallest vertex index with exactly the same position as `v`.
    pub remap: Vec<u32>,
    /// Number of distinct positions.
    pub unique: usize,
}

impl WeldMap {
    /// True when vertex `v` is the representative of its position.
    #[inline]
    #[must_use]
    pub fn is_representative(&self, v: u32) -> bool {
        self.remap[v as usize] == v
    }
}

/// Groups vertices whose positions are bit-for-bit equal (`-0.0` equals `0.0`).
///
/// Exact equality is deliberate: importers write the same float for the same point, and a
/// tolerance would merge distinct close vertices of fine scans.
///
/// # Example
/// ```
/// use bevy_aslod::mesh::weld_positions;
/// use glam::Vec3;
///
/// let weld = weld_positions(&[Vec3::X, Vec3::Y, Vec3::X]);
/// assert_eq!(weld.remap, vec![0, 1, 0]);
/// assert_eq!(weld.unique, 2);
/// ```
#[must_use]
pub fn weld_positions(positions: &[Vec3]) -> WeldMap {
    let key = |p: Vec3| {
        let f = |x: f32| if x == 0.0 { 0u32 } else { x.to_bits() };
        (f(p.x), f(p.y), f(p.z))
    };
    let mut first: HashMap<(u32, u32, u32), u32> = HashMap::with_capacity(positions.len());
    let mut remap = Vec::with_capacity(positions.len());
    for (i, &p) in positions.iter().enumerate() {
        remap.push(*first.entry(key(p)).or_insert(i as u32));
    }
    let unique = first.len();
    WeldMap { remap, unique }
}

/// Groups vertices whose positions are within `distance` of each other, as
/// [`weld_positions`] does for equal ones, except that two vertices of one triangle never
/// share a group (a triangle stays a triangle to the topology).
///
/// Exported meshes often place the two sides of a seam a few ulps apart (a transform applied
/// per part, a format round trip); exact equality then sees an open border where the surface
/// is closed. Groups are chained: a vertex joins a group when it is within `distance` of one
/// of its members, so a run of points each within `distance` of the next can span more.
/// `distance <= 0` (or not finite) is [`weld_positions`].
///
/// # Example
/// ```
/// use bevy_aslod::mesh::weld_positions_within;
/// use glam::Vec3;
///
/// let noisy = [Vec3::X, Vec3::Y, Vec3::new(1.0, 1e-7, 0.0), Vec3::Z];
/// let weld = weld_positions_within(&noisy, &[0, 1, 3, 2, 3, 1], 1e-5);
/// assert_eq!(weld.remap, vec![0, 1, 0, 3]);
/// // Two corners of one triangle stay apart however close they are.
/// let sliver = weld_positions_within(&noisy, &[0, 1, 2], 1e-5);
/// assert_eq!(sliver.remap, vec![0, 1, 2, 3]);
/// ```
#[must_use]
pub fn weld_positions_within(positions: &[Vec3], indices: &[u32], distance: f32) -> WeldMap {
    let exact = weld_positions(positions);
    if !(distance.is_finite() && distance > 0.0) || positions.is_empty() {
        return exact;
    }
    let n = positions.len();
    // Union-find over the exact groups' representatives, smallest index as the root.
    let mut parent: Vec<u32> = exact.remap.clone();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    // Per representative, the representatives it shares a triangle with: they never join it.
    let mut shares: HashMap<u32, Vec<u32>> = HashMap::new();
    for tri in indices.chunks_exact(3) {
        let r = [0, 1, 2].map(|k| exact.remap[tri[k] as usize]);
        for k in 0..3 {
            for j in 0..3 {
                if j != k {
                    let list = shares.entry(r[k]).or_default();
                    if !list.contains(&r[j]) {
                        list.push(r[j]);
                    }
                }
            }
        }
    }
    // Members of each group, to test the triangle rule when two groups join.
    let mut members: HashMap<u32, Vec<u32>> = HashMap::new();
    let cell_of = |p: Vec3| (p / distance).floor().as_i64vec3();
    let mut grid: HashMap<glam::I64Vec3, Vec<u32>> = HashMap::new();
    for v in 0..n as u32 {
        if exact.remap[v as usize] == v {
            grid.entry(cell_of(positions[v as usize]))
                .or_default()
                .push(v);
            members.insert(v, vec![v]);
        }
    }
    let limit = distance * distance;
    for v in 0..n as u32 {
        if exact.remap[v as usize] != v {
            continue;
        }
        let p = positions[v as usize];
        for q in cells_around(&grid, cell_of(p)) {
            if q <= v || positions[q as usize].distance_squared(p) > limit {
                continue;
            }
            let (a, b) = (root(&mut parent, v), root(&mut parent, q));
            if a == b {
                continue;
            }
            let apart = members[&a].iter().any(|m| {
                shares
                    .get(m)
                    .is_some_and(|s| s.iter().any(|x| members[&b].contains(x)))
            });
            if apart {
                continue;
            }
            let (keep, gone) = (a.min(b), a.max(b));
            parent[gone as usize] = keep;
            let moved = members.remove(&gone).unwrap_or_default();
            members.entry(keep).or_default().extend(moved);
        }
    }
    let remap: Vec<u32> = (0..n as u32)
        .map(|v| root(&mut parent, exact.remap[v as usize]))
        .collect();
    let unique = members.len();
    WeldMap { remap, unique }
}

/// The items of a hash grid's 27 cells around (and at) cell `c`.
pub(crate) fn cells_around(
    grid: &HashMap<glam::I64Vec3, Vec<u32>>,
    c: glam::I64Vec3,
) -> impl Iterator<Item = u32> + '_ {
    (-1..=1)
        .flat_map(|dz| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| (dx, dy, dz))))
        .filter_map(move |(dx, dy, dz)| grid.get(&(c + glam::I64Vec3::new(dx, dy, dz))))
        .flatten()
        .copied()
}
