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
