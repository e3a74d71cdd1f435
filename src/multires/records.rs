//! The packed records of a progressive mesh: the full-detail index buffer, one header per
//! step, the corner rewrites and the `[old, new]` vertex pairs, in the narrowest layout the
//! mesh allows.
//!
//! A mesh of at most 65,535 vertices and fewer than 2²³ corners (2.8 million triangles), none
//! of whose steps rewrites more than 4,095 corners, is kept narrow: 16-bit indices and pairs,
//! 16-bit step headers and 3-byte corner records. Anything else is kept wide (32 bits each).

use super::index::CacheIndex;

/// A step's header packed into one integer: `corners << 4 | pairs << 2 | removed`. A step
/// removes at most two triangles and has at most two vertex pairs (one per edge triangle).
pub(crate) trait Header: Copy + Eq + std::fmt::Debug + Send + Sync + 'static {
    /// The most corner rewrites one header can count.
    const MAX_CORNERS: usize;

    /// Packs a header; the caller checked the ranges.
    fn pack(corners: usize, pairs: usize, removed: usize) -> Self;

    /// `(corners, pairs, removed)`.
    fn unpack(self) -> (usize, usize, usize);
}

impl Header for u16 {
    const MAX_CORNERS: usize = (1 << 12) - 1;

    #[inline]
    fn pack(corners: usize, pairs: usize, removed: usize) -> Self {
        (corners << 4 | pairs << 2 | removed) as u16
    }

    #[inline]
    fn unpack(self) -> (usize, usize, usize) {
        let h = usize::from(self);
        (h >> 4, (h >> 2) & 3, h & 3)
    }
}

impl Header for u32 {
    const MAX_CORNERS: usize = (1 << 28) - 1;

    #[inline]
    fn pack(corners: usize, pairs: usize, removed: usize) -> Self {
        (corners << 4 | pairs << 2 | removed) as u32
    }

    #[inline]
    fn unpack(self) -> (usize, usize, usize) {
        let h = self as usize;
        (h >> 4, (h >> 2) & 3, h & 3)
    }
}

/// One corner rewrite: `corner << 1 | pair`, the corner's index in the index buffer and
/// which of the step's pairs applies.
pub(crate) trait Corner: Copy + Eq + std::fmt::Debug + Send + Sync + 'static {
    /// One past the largest value it holds.
    const LIMIT: u64;

    /// Packs a value below [`LIMIT`](Self::LIMIT).
    fn pack(value: u32) -> Self;

    /// The packed value.
    fn get(self) -> u32;
}

impl Corner for [u8; 3] {
    const LIMIT: u64 = 1 << 24;

    #[inline]
    fn pack(value: u32) -> Self {
        let [a, b, c, _] = value.to_le_bytes();
        [a, b, c]
    }

    #[inline(always)]
    fn get(self) -> u32 {
        let [a, b, c] = self;
        u32::from_le_bytes([a, b, c, 0])
    }
}

impl Corner for u32 {
    const LIMIT: u64 = 1 << 32;

    #[inline]
    fn pack(value: u32) -> Self {
        value
    }

    #[inline(always)]
    fn get(self) -> u32 {
        self
    }
}

/// The side of an `[old, new]` pair a coarsening step writes.
pub(crate) const NEW: usize = 1;
/// The side of an `[old, new]` pair a refining step writes.
pub(crate) const OLD: usize = 0;

/// The records in one layout: vertices of type `V`, headers `H`, corner records `C`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Records<V, H, C> {
    /// The full-detail index buffer in slot order.
    pub(crate) indices: Vec<V>,
    /// One header per step.
    pub(crate) steps: Vec<H>,
    /// The corner rewrites, per step in order.
    pub(crate) corners: Vec<C>,
    /// `[old, new]` vertex pairs, per step in order.
    pub(crate) pairs: Vec<[V; 2]>,
}

/// The records of a build before packing: one `(corners, pairs, removed)` per step.
pub(crate) struct Unpacked {
    pub(crate) indices: Vec<u32>,
    pub(crate) steps: Vec<(usize, usize, usize)>,
    pub(crate) corners: Vec<u32>,
    pub(crate) pairs: Vec<[u32; 2]>,
}

impl<V: CacheIndex, H: Header, C: Corner> Records<V, H, C> {
    /// Packs `records` for a mesh of `vertices` vertices, or `None` when something does not
    /// fit this layout.
    fn pack(records: &Unpacked, vertices: usize) -> Option<Self> {
        let fits = vertices as u64 <= V::MAX_VERTICES
            && (records.indices.len() as u64) << 1 < C::LIMIT
            && records.steps.iter().all(|s| s.0 <= H::MAX_CORNERS);
        fits.then(|| Self {
            indices: records.indices.iter().map(|&v| V::from_u32(v)).collect(),
            steps: records
                .steps
                .iter()
                .map(|&(c, p, r)| H::pack(c, p, r))
                .collect(),
            corners: records.corners.iter().map(|&c| C::pack(c)).collect(),
            pairs: records.pairs.iter().map(|p| p.map(V::from_u32)).collect(),
        })
    }

    /// Bytes held.
    fn bytes(&self) -> usize {
        self.indices.len() * size_of::<V>()
            + self.steps.len() * size_of::<H>()
            + self.corners.len() * size_of::<C>()
            + self.pairs.len() * size_of::<[V; 2]>()
    }

    /// Moves `indices` (a cache at `state`) to the finest level with at most `triangles`
    /// triangles, or the base level.
    #[inline]
    pub(crate) fn walk<I: CacheIndex>(
        &self,
        indices: &mut [I],
        state: &mut Walk,
        triangles: usize,
    ) {
        let steps = &self.steps[..];
        let Walk {
            mut level,
            mut count,
            mut corner,
            mut pair,
        } = *state;
        while count > triangles && level < steps.len() {
            let (nc, np, removed) = steps[level].unpack();
            self.rewrite(indices, corner..corner + nc, pair..pair + np, NEW);
            (corner, pair) = (corner + nc, pair + np);
            count -= removed;
            level += 1;
        }
        while level > 0 {
            let (nc, np, removed) = steps[level - 1].unpack();
            if count + removed > triangles {
                break;
            }
            (corner, pair) = (corner - nc, pair - np);
            self.rewrite(indices, corner..corner + nc, pair..pair + np, OLD);
            count += removed;
            level -= 1;
        }
        *state = Walk {
            level,
            count,
            corner,
            pair,
        };
    }

    /// Points one step's corner records (`corners`, into its `pairs`) at side `side` of
    /// their pair: [`NEW`] coarsening, [`OLD`] refining.
    #[inline(always)]
    fn rewrite<I: CacheIndex>(
        &self,
        indices: &mut [I],
        corners: std::ops::Range<usize>,
        pairs: std::ops::Range<usize>,
        side: usize,
    ) {
        let pairs = &self.pairs[pairs];
        for c in &self.corners[corners] {
            let c = c.get();
            indices[(c >> 1) as usize] = I::from_u32(pairs[(c & 1) as usize][side].into());
        }
    }

    /// One step coarser; false at the base level.
    #[inline]
    pub(crate) fn coarsen<I: CacheIndex>(&self, indices: &mut [I], state: &mut Walk) -> bool {
        let Some(&header) = self.steps.get(state.level) else {
            return false;
        };
        let (nc, np, removed) = header.unpack();
        let (corner, pair) = (state.corner, state.pair);
        self.rewrite(indices, corner..corner + nc, pair..pair + np, NEW);
        state.corner += nc;
        state.pair += np;
        state.count -= removed;
        state.level += 1;
        true
    }

    /// One step finer; false at full detail.
    #[inline]
    pub(crate) fn refine<I: CacheIndex>(&self, indices: &mut [I], state: &mut Walk) -> bool {
        if state.level == 0 {
            return false;
        }
        let (nc, np, removed) = self.steps[state.level - 1].unpack();
        state.corner -= nc;
        state.pair -= np;
        let (corner, pair) = (state.corner, state.pair);
        self.rewrite(indices, corner..corner + nc, pair..pair + np, OLD);
        state.count += removed;
        state.level -= 1;
        true
    }
}

/// Where a cache stands in the records: its level, triangle count and the cursors into the
/// corner and pair records (the first record of step `level`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Walk {
    pub(crate) level: usize,
    pub(crate) count: usize,
    pub(crate) corner: usize,
    pub(crate) pair: usize,
}

/// The records in the narrowest layout that holds them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Layout {
    /// 16-bit vertices and headers, 3-byte corner records.
    Narrow(Records<u16, u16, [u8; 3]>),
    /// 32 bits each.
    Wide(Records<u32, u32, u32>),
}

impl Layout {
    /// Packs `records` of a mesh of `vertices` vertices; `None` when not even the wide
    /// layout holds them (a step that rewrites more than 268 million corners, or 2³¹ corners
    /// in all; the builder refuses such meshes first).
    ///
    /// Vertices appended to the mesh later (a region's neighbours' representatives) are
    /// never recorded, so the layout stays as it is when the vertex table grows.
    pub(crate) fn new(records: &Unpacked, vertices: usize) -> Option<Self> {
        match Records::pack(records, vertices) {
            Some(narrow) => Some(Self::Narrow(narrow)),
            None => Records::pack(records, vertices).map(Self::Wide),
        }
    }

    /// Number of steps.
    #[inline]
    pub(crate) fn step_count(&self) -> usize {
        match self {
            Self::Narrow(r) => r.steps.len(),
            Self::Wide(r) => r.steps.len(),
        }
    }

    /// Triangles removed by step `step`.
    #[inline]
    pub(crate) fn removed_by(&self, step: usize) -> usize {
        match self {
            Self::Narrow(r) => r.steps[step].unpack().2,
            Self::Wide(r) => r.steps[step].unpack().2,
        }
    }

    /// Every step's vertex pairs `(step, old, new)`: the attribute vertices the step moves
    /// and where (one pair, or one per side of a seam).
    pub(crate) fn step_pairs(&self) -> Vec<(usize, u32, u32)> {
        fn walk<V: Copy + Into<u32>, H: Header, C: Corner>(
            r: &Records<V, H, C>,
        ) -> Vec<(usize, u32, u32)> {
            let mut out = Vec::with_capacity(r.pairs.len());
            let mut p = 0;
            for (s, h) in r.steps.iter().enumerate() {
                let (_, np, _) = h.unpack();
                for pair in r.pairs.get(p..p + np).unwrap_or_default() {
                    out.push((s, pair[0].into(), pair[1].into()));
                }
                p += np;
            }
            out
        }
        match self {
            Self::Narrow(r) => walk(r),
            Self::Wide(r) => walk(r),
        }
    }

    /// Triangles removed by each step, in order.
    pub(crate) fn removed(&self) -> Vec<usize> {
        (0..self.step_count()).map(|s| self.removed_by(s)).collect()
    }

    /// The full-detail index buffer as `I` (which the caller checked can hold every vertex).
    pub(crate) fn indices_as<I: CacheIndex>(&self) -> Vec<I> {
        match self {
            Self::Narrow(r) => r.indices.iter().map(|&v| I::from_u32(v.into())).collect(),
            Self::Wide(r) => r.indices.iter().map(|&v| I::from_u32(v)).collect(),
        }
    }

    /// Length of the full-detail index buffer.
    #[inline]
    pub(crate) fn index_count(&self) -> usize {
        match self {
            Self::Narrow(r) => r.indices.len(),
            Self::Wide(r) => r.indices.len(),
        }
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        match self {
            Self::Narrow(r) => r.bytes(),
            Self::Wide(r) => r.bytes(),
        }
    }
}

/// An error bound rounded up to 16 bits (the top half of the `f32`: 7 bits of mantissa, < 0.8 %
/// above), so that a stored bound never understates the error. Rounding up keeps a monotone
/// table monotone.
#[inline]
pub(crate) fn error_to_u16(error: f32) -> u16 {
    let error = error.max(0.0);
    let bits = error.to_bits();
    let high = (bits >> 16) as u16;
    if bits & 0xFFFF != 0 && error.is_finite() {
        high + 1 // the largest finite f32 rounds to +inf: still an upper bound
    } else {
        high
    }
}

/// The `f32` of [`error_to_u16`].
#[inline]
pub(crate) fn error_from_u16(error: u16) -> f32 {
    f32::from_bits(u32::from(error) << 16)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_grid;
    use crate::multires::{BuildOptions, PolygonCache, ProgressiveMesh};

    /// The same records in the wide layout.
    fn widen(records: &Layout) -> Records<u32, u32, u32> {
        let Layout::Narrow(r) = records else {
            panic!("a small mesh gets the narrow layout");
        };
        Records {
            indices: r.indices.iter().map(|&v| u32::from(v)).collect(),
            steps: r
                .steps
                .iter()
                .map(|h| {
                    let (c, p, removed) = h.unpack();
                    <u32 as Header>::pack(c, p, removed)
                })
                .collect(),
            corners: r.corners.iter().map(|c| c.get()).collect(),
            pairs: r.pairs.iter().map(|p| p.map(u32::from)).collect(),
        }
    }

    /// Caches walk the narrow and the wide layout alike (meshes past 65,535 vertices get the
    /// wide one; here it is forced on a small mesh), and the narrow one is smaller.
    #[test]
    fn narrow_and_wide_records_walk_alike() {
        let mesh = test_grid(14, |x, z| ((x * 7 + z * 3) % 5) as f32 * 0.1);
        let narrow = ProgressiveMesh::build(&mesh, &BuildOptions::default()).unwrap();
        let mut wide = narrow.clone();
        wide.records = Layout::Wide(widen(&narrow.records));
        assert!(narrow.memory_bytes() < wide.memory_bytes());
        let (mut a, mut b) = (PolygonCache::new(&narrow), PolygonCache::new(&wide));
        let mut seed = 0x9e37_79b9_u64;
        for _ in 0..200 {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let target = (seed >> 33) as usize % (narrow.max_triangles() + 1);
            assert_eq!(
                a.set_triangle_count(&narrow, target),
                b.set_triangle_count(&wide, target)
            );
            assert_eq!(a.indices(), b.indices());
            if seed & 1 == 1 {
                assert_eq!(a.coarsen(&narrow), b.coarsen(&wide));
            } else {
                assert_eq!(a.refine(&narrow), b.refine(&wide));
            }
            assert_eq!(a.indices(), b.indices());
            assert_eq!(a.level(), b.level());
        }
        assert_eq!(narrow.full_indices(), wide.full_indices());
    }

    #[test]
    fn headers_and_corners_round_trip() {
        for (c, p, r) in [(0, 0, 0), (4095, 2, 2), (17, 1, 2), (3, 2, 0)] {
            assert_eq!(<u16 as Header>::pack(c, p, r).unpack(), (c, p, r));
            assert_eq!(<u32 as Header>::pack(c, p, r).unpack(), (c, p, r));
        }
        let big = <u32 as Header>::MAX_CORNERS;
        assert_eq!(<u32 as Header>::pack(big, 1, 1).unpack(), (big, 1, 1));
        for v in [0, 1, 0xAB_CDEF, (1 << 24) - 1] {
            assert_eq!(<[u8; 3] as Corner>::pack(v).get(), v);
        }
    }

    #[test]
    fn errors_round_up_and_stay_monotone() {
        let mut last = 0.0f32;
        for e in [
            0.0,
            1e-9,
            1e-4,
            0.0123,
            0.0124,
            0.5,
            1.0,
            3.7,
            f32::MAX,
            f32::INFINITY,
        ] {
            let stored = error_from_u16(error_to_u16(e));
            assert!(stored >= e, "{e} stored as {stored}");
            assert!(e == 0.0 || stored <= e * 1.008 || !stored.is_finite() || e == f32::MAX);
            assert!(stored >= last);
            last = stored;
        }
        assert_eq!(error_from_u16(error_to_u16(0.25)), 0.25);
    }
}
