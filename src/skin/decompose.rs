//! Decomposition of a skin into rigid and deformable regions by influence (section 5.2).

use super::{DEFAULT_RIGID_DELTA, Influences, SkinRegionKind};
use crate::mesh::weld_positions;
use glam::Vec3;

/// The region decomposition of a skin by influence (ASLOD section 5.2).
///
/// Every vertex is in exactly one region; every region is either rigid (one bone) or
/// deformable (two bones). See [`decompose`].
#[derive(Clone, Debug, PartialEq)]
pub struct SkinDecomposition {
    /// Per vertex, its region: dense ids `0..kinds.len()`.
    pub region_of: Vec<u32>,
    /// Per region, rigid on one bone or deformable between two. Sorted: every rigid region
    /// before every deformable one, then by bone indices.
    pub kinds: Vec<SkinRegionKind>,
    /// Per vertex, true when it is in a rigid region, and so is placed by its dominant bone
    /// alone (see [`blend_with_rigid`](super::blend_with_rigid)).
    pub rigid: Vec<bool>,
    /// Vertices with more than two non-zero influences. They join the region of their two
    /// largest but blend with all of them.
    pub more_than_two: usize,
}

impl SkinDecomposition {
    /// Number of regions.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.kinds.len()
    }

    /// Number of vertices in each region, indexed by region id.
    #[must_use]
    pub fn region_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.kinds.len()];
        for &r in &self.region_of {
            if let Some(s) = sizes.get_mut(r as usize) {
                *s += 1;
            }
        }
        sizes
    }
}

/// The region kind one vertex asks for, from its own (sorted) influences.
#[inline]
fn kind_of(joints: [u16; 4], weights: [f32; 4], delta: f32) -> SkinRegionKind {
    let (a, b) = (joints[0], joints[1]);
    // The NaN test covers hand-built influences that break the invariants.
    if weights[0] >= 1.0 - delta || weights[1] <= 0.0 || weights[1].is_nan() || a == b {
        SkinRegionKind::Rigid { bone: a }
    } else {
        SkinRegionKind::Deformable {
            bones: [a.min(b), a.max(b)],
        }
    }
}

/// Decomposes a skin into rigid and deformable regions by its influences (section 5.2).
///
/// - A vertex whose largest weight is at least `1 - delta` is rigid: it goes to the rigid region
///   of that bone. There is one rigid region per bone, even when its vertices are not
///   connected (two hands on one bone are one region).
/// - Any other vertex goes to the deformable region of its two largest influences' bones
///   (the sorted pair). A vertex with three or four influences is counted in
///   [`more_than_two`](SkinDecomposition::more_than_two).
/// - `delta` is clamped to `[0, 0.5]`, so a rigid vertex's bone always carries at least half
///   of its weight; NaN means [`DEFAULT_RIGID_DELTA`].
/// - Vertices at the same position (attribute-seam copies, bit-for-bit equal positions, as
///   [`weld_positions`] groups them) get the region of the first vertex at that position, so
///   a seam never separates two regions. `positions` may be shorter than `influences` (the
///   vertices without a position are not welded); extra positions are ignored.
/// - Region ids are dense and deterministic: the distinct kinds sorted, rigid regions first,
///   then by bone indices.
///
/// Empty input gives zero regions.
///
/// # Example
/// ```
/// use bevy_aslod::skin::{DEFAULT_RIGID_DELTA, Influences, SkinRegionKind, decompose};
/// use glam::Vec3;
///
/// let positions = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
/// let joints = [[0, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]];
/// let weights = [[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]];
/// let (influences, _) = Influences::new(&joints, &weights, 2)?;
/// let skin = decompose(&positions, &influences, DEFAULT_RIGID_DELTA);
/// assert_eq!(
///     skin.kinds,
///     [
///         SkinRegionKind::Rigid { bone: 0 },
///         SkinRegionKind::Rigid { bone: 1 },
///         SkinRegionKind::Deformable { bones: [0, 1] },
///     ]
/// );
/// assert_eq!(skin.region_of, [0, 2, 1]);
/// assert_eq!(skin.rigid, [true, false, true]);
/// # Ok::<(), bevy_aslod::skin::SkinError>(())
/// ```
#[must_use]
pub fn decompose(positions: &[Vec3], influences: &Influences, delta: f32) -> SkinDecomposition {
    let delta = if delta.is_nan() {
        DEFAULT_RIGID_DELTA
    } else {
        delta.clamp(0.0, 0.5)
    };
    let n = influences.len();
    let own: Vec<SkinRegionKind> = influences
        .joints
        .iter()
        .zip(&influences.weights)
        .map(|(&j, &w)| kind_of(j, w, delta))
        .collect();
    let weld = weld_positions(&positions[..positions.len().min(n)]);
    let kind_at = |v: usize| own[weld.remap.get(v).map_or(v, |&r| r as usize)];

    let mut kinds = own.clone();
    kinds.sort_unstable();
    kinds.dedup();

    let mut region_of = Vec::with_capacity(n);
    let mut rigid = Vec::with_capacity(n);
    for v in 0..n {
        let kind = kind_at(v);
        // `kinds` holds every kind in `own`, so the search always succeeds.
        region_of.push(kinds.binary_search(&kind).unwrap_or(0) as u32);
        rigid.push(matches!(kind, SkinRegionKind::Rigid { .. }));
    }
    let more_than_two = influences
        .weights
        .iter()
        .take(n)
        .filter(|w| w[2] > 0.0)
        .count();
    SkinDecomposition {
        region_of,
        kinds,
        rigid,
        more_than_two,
    }
}
