//! The packed records of a progressive mesh: the full-detail index buffer, one header per
//! step, the corner rewrites and the `[old, new]` vertex pairs, in the narrowest layout the
//! mesh allows.
//!
//! The widths of a header's pair and removed-triangle counts and of a corner record's pair
//! selector are the mesh's [`Fields`]: the narrowest that hold every step's counts, and never
//! below [`Fields::CLASSIC`] (two pairs and three removed triangles a step, the widths of
//! every mesh written before format version 4).
//!
//! A mesh of at most 65,535 vertices whose corner records fit 24 bits (fewer than 2²³
//! corners, 2.8 million triangles, with the classic widths) and whose step headers fit 16
//! bits (none of its steps rewrites more than 4,095 corners with the classic widths) is kept
//! narrow: 16-bit indices and pairs, 16-bit step headers and 3-byte corner records. Anything
//! else is kept wide (32 bits each).

use super::index::CacheIndex;

/// Bit widths of the variable fields of a mesh's records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Fields {
    /// Bits of a corner record's pair selector (`corner << pair_bits | pair`); the header's
    /// pair count field is `pair_bits + 1` bits wide.
    pub(crate) pair_bits: u8,
    /// Bits of the header's removed-triangle count.
    pub(crate) removed_bits: u8,
}

impl Fields {
    /// The widths of every mesh written before format version 4: a 1-bit selector, a 2-bit
    /// pair count and a 2-bit removed count (`corners << 4 | pairs << 2 | removed`, and
    /// `corner << 1 | pair`).
    pub(crate) const CLASSIC: Self = Self {
        pair_bits: 1,
        removed_bits: 2,
    };

    /// The widest either field may be (what a file may declare).
    pub(crate) const MAX_BITS: u8 = 8;

    /// The narrowest widths (never below [`CLASSIC`](Self::CLASSIC)) that hold every step's
    /// pairs and removed count; `steps` are `(corners, pairs, removed)`.
    pub(crate) fn for_steps(steps: &[(usize, usize, usize)]) -> Self {
        let (pairs, removed) = steps
            .iter()
            .fold((0, 0), |(p, r), &(_, np, nr)| (p.max(np), r.max(nr)));
        // Bits that hold `n`.
        let bits = |n: usize| (usize::BITS - n.leading_zeros()) as u8;
        Self {
            // A selector names pairs 0 to `pairs - 1`.
            pair_bits: bits(pairs.saturating_sub(1)).max(Self::CLASSIC.pair_bits),
            removed_bits: bits(removed).max(Self::CLASSIC.removed_bits),
        }
    }

    /// Whether the widths are ones a file may declare: a selector of 1 to 8 bits and a
    /// removed count of 2 to 8 bits.
    pub(crate) fn is_valid(self) -> bool {
        (Self::CLASSIC.pair_bits..=Self::MAX_BITS).contains(&self.pair_bits)
            && (Self::CLASSIC.removed_bits..=Self::MAX_BITS).contains(&self.removed_bits)
    }

    /// Bits of a header below its corner count: the pair and removed counts.
    #[inline(always)]
    pub(crate) fn count_bits(self) -> u32 {
        u32::from(self.pair_bits) + 1 + u32::from(self.removed_bits)
    }

    /// The most pairs a step may have: as many as a selector names.
    #[inline]
    pub(crate) fn max_pairs(self) -> usize {
        1 << self.pair_bits
    }
}

/// A step's header packed into one integer:
/// `corners << (pair_bits + 1 + removed_bits) | pairs << removed_bits | removed`, with the
/// mesh's [`Fields`].
pub(crate) trait Header:
    Copy + Eq + Into<u32> + std::fmt::Debug + Send + Sync + 'static
{
    /// Bits of the type.
    const BITS: u32;

    /// Whether a header of this type has room for the counts of `f` and at least one bit of
    /// corner count.
    #[inline]
    fn fits(f: Fields) -> bool {
        f.count_bits() < Self::BITS
    }

    /// The most corner rewrites one header with the widths `f` can count (0 when the widths
    /// do not [fit](Self::fits)).
    #[inline]
    fn max_corners(f: Fields) -> usize {
        match Self::BITS.checked_sub(f.count_bits()) {
            Some(bits) if bits > 0 => (1 << bits) - 1,
            _ => 0,
        }
    }

    /// Packs a header; the caller checked the ranges.
    fn pack(f: Fields, corners: usize, pairs: usize, removed: usize) -> Self;

    /// `(corners, pairs, removed)`.
    fn unpack(self, f: Fields) -> (usize, usize, usize);
}

/// A header's bits.
#[inline(always)]
fn pack_header(f: Fields, corners: usize, pairs: usize, removed: usize) -> usize {
    debug_assert!(pairs < 2 << f.pair_bits && removed < 1 << f.removed_bits);
    corners << f.count_bits() | pairs << f.removed_bits | removed
}

/// `(corners, pairs, removed)` of a header's bits.
#[inline(always)]
fn unpack_header(f: Fields, h: usize) -> (usize, usize, usize) {
    let pair_mask = (2 << f.pair_bits) - 1;
    let removed_mask = (1 << f.removed_bits) - 1;
    (
        h >> f.count_bits(),
        (h >> f.removed_bits) & pair_mask,
        h & removed_mask,
    )
}

impl Header for u16 {
    const BITS: u32 = 16;

    #[inline]
    fn pack(f: Fields, corners: usize, pairs: usize, removed: usize) -> Self {
        pack_header(f, corners, pairs, removed) as u16
    }

    #[inline]
    fn unpack(self, f: Fields) -> (usize, usize, usize) {
        unpack_header(f, usize::from(self))
    }
}

impl Header for u32 {
    const BITS: u32 = 32;

    #[inline]
    fn pack(f: Fields, corners: usize, pairs: usize, removed: usize) -> Self {
        pack_header(f, corners, pairs, removed) as u32
    }

    #[inline]
    fn unpack(self, f: Fields) -> (usize, usize, usize) {
        unpack_header(f, self as usize)
    }
}

/// One corner rewrite: `corner << pair_bits | pair` (the mesh's [`Fields`]), the corner's
/// index in the index buffer and which of the step's pairs applies
/// ([`Records::corner_slot`] and [`Records::corner_pair`]).
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
    /// The widths of the headers' counts and the corner records' pair selectors.
    pub(crate) fields: Fields,
}

/// The records of a build before packing.
pub(crate) struct Unpacked {
    /// The full-detail index buffer in slot order.
    pub(crate) indices: Vec<u32>,
    /// One `(corners, pairs, removed)` per step.
    pub(crate) steps: Vec<(usize, usize, usize)>,
    /// The corner rewrites, per step in order: the corner's index in the index buffer and
    /// the index of its pair among the step's pairs.
    pub(crate) corners: Vec<(u32, u32)>,
    /// `[old, new]` vertex pairs, per step in order.
    pub(crate) pairs: Vec<[u32; 2]>,
}

impl<V, H: Header, C: Corner> Records<V, H, C> {
    /// A corner record's corner: its index in the index buffer (its triangle's slot is a
    /// third of it).
    #[inline(always)]
    pub(crate) fn corner_slot(&self, c: C) -> usize {
        (c.get() >> self.fields.pair_bits) as usize
    }

    /// A corner record's pair: its index among its step's pairs.
    #[inline(always)]
    pub(crate) fn corner_pair(&self, c: C) -> usize {
        (c.get() & ((1 << self.fields.pair_bits) - 1)) as usize
    }

    /// Step `step`'s `(corners, pairs, removed)`.
    #[inline(always)]
    pub(crate) fn step(&self, step: usize) -> (usize, usize, usize) {
        self.steps[step].unpack(self.fields)
    }

    /// Every step's `(corners, pairs, removed)`, in order.
    #[inline]
    pub(crate) fn headers(&self) -> impl ExactSizeIterator<Item = (usize, usize, usize)> + '_ {
        let f = self.fields;
        self.steps.iter().map(move |h| h.unpack(f))
    }
}

impl<V: CacheIndex, H: Header, C: Corner> Records<V, H, C> {
    /// Packs `records` for a mesh of `vertices` vertices with the narrowest [`Fields`] that
    /// hold them, or `None` when something does not fit this layout (or a step has over 256
    /// pairs or removes over 255 triangles, past what a file may declare).
    fn pack(records: &Unpacked, vertices: usize) -> Option<Self> {
        let f = Fields::for_steps(&records.steps);
        let fits = f.is_valid()
            && H::fits(f)
            && vertices as u64 <= V::MAX_VERTICES
            && (records.indices.len() as u64) << f.pair_bits < C::LIMIT
            && records.steps.iter().all(|s| s.0 <= H::max_corners(f));
        fits.then(|| Self {
            indices: records.indices.iter().map(|&v| V::from_u32(v)).collect(),
            steps: records
                .steps
                .iter()
                .map(|&(c, p, r)| H::pack(f, c, p, r))
                .collect(),
            corners: records
                .corners
                .iter()
                .map(|&(corner, pair)| {
                    debug_assert!((pair as usize) < f.max_pairs());
                    C::pack(corner << f.pair_bits | pair)
                })
                .collect(),
            pairs: records.pairs.iter().map(|p| p.map(V::from_u32)).collect(),
            fields: f,
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
            let (nc, np, removed) = steps[level].unpack(self.fields);
            self.rewrite(indices, corner..corner + nc, pair..pair + np, NEW);
            (corner, pair) = (corner + nc, pair + np);
            count -= removed;
            level += 1;
        }
        while level > 0 {
            let (nc, np, removed) = steps[level - 1].unpack(self.fields);
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
        for &c in &self.corners[corners] {
            indices[self.corner_slot(c)] = I::from_u32(pairs[self.corner_pair(c)][side].into());
        }
    }

    /// One step coarser; false at the base level.
    #[inline]
    pub(crate) fn coarsen<I: CacheIndex>(&self, indices: &mut [I], state: &mut Walk) -> bool {
        let Some(&header) = self.steps.get(state.level) else {
            return false;
        };
        let (nc, np, removed) = header.unpack(self.fields);
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
        let (nc, np, removed) = self.step(state.level - 1);
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
    /// in all, with the classic [`Fields`]; a step with over 256 pairs or 255 removed
    /// triangles; the builder refuses such meshes first).
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
        self.step(step).2
    }

    /// Step `step`'s `(corners, pairs, removed)`.
    #[inline]
    fn step(&self, step: usize) -> (usize, usize, usize) {
        match self {
            Self::Narrow(r) => r.step(step),
            Self::Wide(r) => r.step(step),
        }
    }

    /// Moves `state` where [`Records::walk`] would (the finest level with at most
    /// `triangles` triangles, or the base level), touching no indices: for a cache that
    /// keeps only its level.
    pub(crate) fn walk_levels(&self, state: &mut Walk, triangles: usize) {
        while state.count > triangles && state.level < self.step_count() {
            self.coarsen_levels(state);
        }
        while state.level > 0 && state.count + self.removed_by(state.level - 1) <= triangles {
            self.refine_levels(state);
        }
    }

    /// Moves `state` to `level` (clamped to the base level), touching no indices.
    pub(crate) fn walk_to_level(&self, state: &mut Walk, level: usize) {
        let level = level.min(self.step_count());
        while state.level < level {
            self.coarsen_levels(state);
        }
        while state.level > level {
            self.refine_levels(state);
        }
    }

    /// One step coarser, touching no indices.
    fn coarsen_levels(&self, state: &mut Walk) {
        let (corners, pairs, removed) = self.step(state.level);
        state.corner += corners;
        state.pair += pairs;
        state.count -= removed;
        state.level += 1;
    }

    /// One step finer, touching no indices.
    fn refine_levels(&self, state: &mut Walk) {
        let (corners, pairs, removed) = self.step(state.level - 1);
        state.corner -= corners;
        state.pair -= pairs;
        state.count += removed;
        state.level -= 1;
    }

    /// Every step's vertex pairs `(step, old, new)`: the attribute vertices the step moves
    /// and where (one pair, or one per side of a seam).
    pub(crate) fn step_pairs(&self) -> Vec<(usize, u32, u32)> {
        fn walk<V: Copy + Into<u32>, H: Header, C: Corner>(
            r: &Records<V, H, C>,
        ) -> Vec<(usize, u32, u32)> {
            let mut out = Vec::with_capacity(r.pairs.len());
            let mut p = 0;
            for (s, (_, np, _)) in r.headers().enumerate() {
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

    /// The widths of the headers' counts and the corner records' pair selectors.
    #[cfg(test)]
    pub(crate) fn fields(&self) -> Fields {
        match self {
            Self::Narrow(r) => r.fields,
            Self::Wide(r) => r.fields,
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

/// Records of ten triangles whose first step removes six and rewrites nine corners,
/// each with its own pair (two triangles' corners and three of a third's), and whose
/// second removes one more and rewrites two corners: three base triangles. Every corner
/// of the full-detail mesh has its own vertex (0 to 29); the first step moves them to
/// 40 to 48, the second moves 40 and 41 to 50 and 51. Its fields are 4 and 3 bits wide.
#[cfg(test)]
pub(crate) fn permissive() -> Unpacked {
    Unpacked {
        indices: (0..30).collect(),
        steps: vec![(9, 9, 6), (2, 2, 1)],
        corners: (0..9).map(|k| (k, k)).chain([(0, 0), (1, 1)]).collect(),
        pairs: (0..9)
            .map(|k| [k, 40 + k])
            .chain([[40, 50], [41, 51]])
            .collect(),
    }
}

/// [`permissive`]'s triangles with steps the classic widths hold: the first removes three
/// triangles and rewrites two corners, the second removes one and rewrites one (six base
/// triangles).
#[cfg(test)]
pub(crate) fn classic() -> Unpacked {
    Unpacked {
        steps: vec![(2, 2, 3), (1, 1, 1)],
        corners: vec![(4, 0), (5, 1), (6, 0)],
        pairs: vec![[4, 41], [5, 42], [6, 43]],
        ..permissive()
    }
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
                .headers()
                .map(|(c, p, removed)| <u32 as Header>::pack(r.fields, c, p, removed))
                .collect(),
            corners: r.corners.iter().map(|c| c.get()).collect(),
            pairs: r.pairs.iter().map(|p| p.map(u32::from)).collect(),
            fields: r.fields,
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
        let classic = Fields::CLASSIC;
        for (c, p, r) in [(0, 0, 0), (4095, 2, 2), (17, 1, 2), (3, 2, 0), (5, 3, 3)] {
            assert_eq!(
                <u16 as Header>::pack(classic, c, p, r).unpack(classic),
                (c, p, r)
            );
            assert_eq!(
                <u32 as Header>::pack(classic, c, p, r).unpack(classic),
                (c, p, r)
            );
        }
        // The classic widths are the bits of every mesh written before.
        assert_eq!(
            <u16 as Header>::pack(classic, 17, 1, 2),
            17 << 4 | 1 << 2 | 2
        );
        assert_eq!(<u16 as Header>::max_corners(classic), 4095);
        assert_eq!(<u32 as Header>::max_corners(classic), (1 << 28) - 1);
        let big = <u32 as Header>::max_corners(classic);
        assert_eq!(
            <u32 as Header>::pack(classic, big, 1, 1).unpack(classic),
            (big, 1, 1)
        );
        // Wider fields: 9 pairs need a 4-bit selector (a 5-bit count), 6 removed 3 bits.
        let f = Fields {
            pair_bits: 4,
            removed_bits: 3,
        };
        assert_eq!(<u16 as Header>::max_corners(f), 255);
        assert_eq!(<u32 as Header>::max_corners(f), (1 << 24) - 1);
        for (c, p, r) in [(0, 0, 0), (255, 16, 7), (9, 9, 6), (1, 31, 0)] {
            assert_eq!(<u16 as Header>::pack(f, c, p, r).unpack(f), (c, p, r));
            assert_eq!(<u32 as Header>::pack(f, c, p, r).unpack(f), (c, p, r));
        }
        let widest = Fields {
            pair_bits: Fields::MAX_BITS,
            removed_bits: Fields::MAX_BITS,
        };
        assert!(widest.is_valid() && !<u16 as Header>::fits(widest));
        assert!(<u32 as Header>::fits(widest));
        assert_eq!(<u16 as Header>::max_corners(widest), 0);
        let c = (1 << 15) - 1;
        assert_eq!(
            <u32 as Header>::pack(widest, c, 256, 255).unpack(widest),
            (c, 256, 255)
        );
        for v in [0, 1, 0xAB_CDEF, (1 << 24) - 1] {
            assert_eq!(<[u8; 3] as Corner>::pack(v).get(), v);
        }
    }

    #[test]
    fn fields_are_the_narrowest_that_hold_every_step() {
        let of = |steps: &[(usize, usize, usize)]| {
            let f = Fields::for_steps(steps);
            (f.pair_bits, f.removed_bits)
        };
        assert_eq!(Fields::for_steps(&[]), Fields::CLASSIC);
        assert_eq!(Fields::for_steps(&[(5, 2, 2), (9, 1, 3)]), Fields::CLASSIC);
        assert_eq!(of(&[(5, 3, 2)]), (2, 2));
        assert_eq!(of(&[(5, 2, 4)]), (1, 3));
        assert_eq!(of(&[(40, 9, 6), (3, 1, 1)]), (4, 3));
        assert_eq!(of(&[(40, 16, 7)]), (4, 3));
        assert_eq!(of(&[(40, 17, 8)]), (5, 4));
        assert_eq!(of(&[(40, 256, 255)]), (8, 8));
        assert!(Fields::for_steps(&[(40, 256, 255)]).is_valid());
        assert!(!Fields::for_steps(&[(40, 257, 2)]).is_valid());
        assert!(!Fields::for_steps(&[(40, 2, 256)]).is_valid());
    }

    /// The records `r` decoded back.
    fn unpacked<V: CacheIndex, H: Header, C: Corner>(r: &Records<V, H, C>) -> Unpacked {
        Unpacked {
            indices: r.indices.iter().map(|&v| v.into()).collect(),
            steps: r.headers().collect(),
            corners: r
                .corners
                .iter()
                .map(|&c| (r.corner_slot(c) as u32, r.corner_pair(c) as u32))
                .collect(),
            pairs: r.pairs.iter().map(|p| p.map(Into::into)).collect(),
        }
    }

    /// Walks `r` (the records of [`permissive`]) down and up, checking every level.
    fn walk_permissive<V: CacheIndex, H: Header, C: Corner>(r: &Records<V, H, C>) {
        let full: Vec<u32> = (0..30).collect();
        let mut level1 = full.clone();
        for (k, v) in level1[..9].iter_mut().enumerate() {
            *v = 40 + k as u32;
        }
        let mut level2 = level1.clone();
        level2[..2].copy_from_slice(&[50, 51]);
        let mut indices = full.clone();
        let mut state = Walk {
            count: 10,
            ..Walk::default()
        };
        r.walk(&mut indices, &mut state, 9);
        assert_eq!((state.level, state.count), (1, 4));
        assert_eq!(indices, level1);
        r.walk(&mut indices, &mut state, 0);
        assert_eq!((state.level, state.count), (2, 3));
        assert_eq!((state.corner, state.pair), (11, 11));
        assert_eq!(indices, level2);
        assert!(!r.coarsen(&mut indices, &mut state));
        assert!(r.refine(&mut indices, &mut state));
        assert_eq!((state.level, state.count), (1, 4));
        assert_eq!(indices, level1);
        assert!(r.coarsen(&mut indices, &mut state));
        assert_eq!(indices, level2);
        r.walk(&mut indices, &mut state, 10);
        assert_eq!(
            state,
            Walk {
                count: 10,
                ..Walk::default()
            }
        );
        assert_eq!(indices, full);
    }

    /// A step with nine pairs and six removed triangles (a permissive collapse) packs into
    /// wider fields, narrow and wide alike, unpacks to the same records and walks.
    #[test]
    fn many_pairs_and_removed_triangles_round_trip_and_walk() {
        let records = permissive();
        let wide_fields = Fields {
            pair_bits: 4,
            removed_bits: 3,
        };
        let layout = Layout::new(&records, 60).unwrap();
        let Layout::Narrow(narrow) = &layout else {
            panic!("a small mesh gets the narrow layout");
        };
        assert_eq!(layout.fields(), wide_fields);
        assert_eq!(layout.removed(), [6, 1]);
        assert_eq!(
            layout.step_pairs().iter().filter(|p| p.0 == 0).count(),
            9,
            "the first step's pairs"
        );
        let wide = Records::<u32, u32, u32>::pack(&records, 60).unwrap();
        assert_eq!(wide.fields, wide_fields);
        for r in [unpacked(narrow), unpacked(&wide)] {
            assert_eq!(r.indices, records.indices);
            assert_eq!(r.steps, records.steps);
            assert_eq!(r.corners, records.corners);
            assert_eq!(r.pairs, records.pairs);
        }
        // Corner 8 with pair 8: the selector takes four bits.
        assert_eq!(narrow.corners[8].get(), 8 << 4 | 8);
        assert_eq!(narrow.steps[0], 9 << 8 | 9 << 3 | 6);
        walk_permissive(narrow);
        walk_permissive(&wide);

        // The classic widths where they suffice: the same bits as before.
        let Some(Layout::Narrow(r)) = Layout::new(&classic(), 60) else {
            panic!("narrow");
        };
        assert_eq!(r.fields, Fields::CLASSIC);
        assert_eq!(r.corners[1].get(), 5 << 1 | 1);
        assert_eq!(r.steps[0], 2 << 4 | 2 << 2 | 3);
    }

    /// A step past the narrow headers' corner count with wide fields takes the wide layout;
    /// a step past what a file may declare is refused.
    #[test]
    fn wide_fields_fall_back_to_the_wide_layout() {
        let mut records = permissive();
        // 300 corners in the second step: over the 255 a 16-bit header counts with a 4-bit
        // selector and 3-bit removed count (the classic widths count 4,095).
        records.steps[1] = (300, 2, 1);
        records.corners.truncate(9);
        records.corners.extend((0..300).map(|k| (k % 9, k % 2)));
        let layout = Layout::new(&records, 60).unwrap();
        assert!(matches!(layout, Layout::Wide(_)), "{layout:?}");
        let mut too_many = permissive();
        too_many.steps[0].2 = 256;
        assert!(Layout::new(&too_many, 60).is_none());
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
