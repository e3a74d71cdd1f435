//! MOM's two-stage extraction (Ribelles et al., Figure 5) on the crate's sequence, and the
//! bit sets it keeps.

use super::{Criterion, Node, View};
use crate::multires::CacheIndex;
use crate::multires::records::{Corner, Header, NEW, Records};

/// A fixed-size set of bits.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Bits(Vec<u64>);

impl Bits {
    /// `len` bits, all clear.
    pub(crate) fn new(len: usize) -> Self {
        Self(vec![0; len.div_ceil(64)])
    }

    /// Clears every bit and makes room for `len`.
    pub(crate) fn reset(&mut self, len: usize) {
        self.0.clear();
        self.0.resize(len.div_ceil(64), 0);
    }

    #[inline(always)]
    pub(crate) fn get(&self, i: usize) -> bool {
        self.0[i >> 6] >> (i & 63) & 1 != 0
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize) {
        self.0[i >> 6] |= 1 << (i & 63);
    }

    #[inline(always)]
    pub(crate) fn clear(&mut self, i: usize) {
        self.0[i >> 6] &= !(1 << (i & 63));
    }

    /// The bits, 64 to a word, the first in the lowest bit of the first word.
    pub(crate) fn words(&self) -> &[u64] {
        &self.0
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.0.len() * 8
    }
}

/// What one extraction did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineStats {
    /// Triangles of the extracted mesh.
    pub triangles: usize,
    /// Collapses performed in the extracted mesh.
    pub performed: usize,
    /// Criterion evaluations.
    pub evaluated: usize,
    /// Collapses performed or undone by this call (an incremental update's work; a fresh
    /// extraction counts the collapses it performed).
    pub changed: usize,
}

/// The first stage, over the collapses in order: a collapse is performed when the criterion
/// allows it and no triangle slot it removes or changes is frozen; a collapse that is not
/// performed freezes the slots it would have removed or changed (MOM's `NO_DRAWABLE`: the
/// versions it would have made cannot appear). The second stage is the caller's: a slot is
/// drawn when it is a base triangle or frozen (see [`drawn`]).
///
/// MOM states its dependency on the faces a simplification removes or changes (section
/// 3.1; the condition in 3.2 names the faces it creates, which are the same slots here):
/// with the crate's in-place records a slot's version is its content, so the rule is kept
/// per slot. An ear collapse, which changes no corner, records an identity rewrite of its
/// neighbour (see the builder), so skipping it freezes what it leans on.
///
/// MOM evaluates its criterion only for the simplifications that hold a face of the
/// full-detail mesh, which saves work for a criterion that either keeps full detail or drops
/// everything (its sphere of interest) but would perform every coarser collapse unasked; a
/// screen-space tolerance has to judge every collapse, so here every collapse whose slots are
/// free is evaluated.
///
/// `slots` starts as the full-detail index buffer and ends with every slot's last version;
/// `frozen` starts clear. Returns the criterion evaluations and the collapses performed.
pub(crate) fn first_stage<V, H, C, I, K>(
    records: &Records<V, H, C>,
    nodes: &[Node],
    criterion: &K,
    view: &View,
    slots: &mut [I],
    frozen: &mut Bits,
    mut performed: Option<&mut Bits>,
) -> (usize, usize)
where
    V: CacheIndex,
    H: Header,
    C: Corner,
    I: CacheIndex,
    K: Criterion + ?Sized,
{
    let mut count = slots.len() / 3;
    let (mut corner, mut pair) = (0, 0);
    let (mut evaluated, mut done) = (0, 0);
    for (step, (nc, np, removed)) in records.headers().enumerate() {
        let first = count - removed;
        let corners = &records.corners[corner..corner + nc];
        let blocked = (first..count).any(|s| frozen.get(s))
            || corners
                .iter()
                .any(|&c| frozen.get(records.corner_slot(c) / 3));
        let perform = !blocked && {
            evaluated += 1;
            criterion.coarsen(&nodes[step], view)
        };
        if perform {
            let pairs = &records.pairs[pair..pair + np];
            for &c in corners {
                slots[records.corner_slot(c)] =
                    I::from_u32(pairs[records.corner_pair(c)][NEW].into());
            }
            if let Some(p) = performed.as_deref_mut() {
                p.set(step);
            }
            done += 1;
        } else {
            for s in first..count {
                frozen.set(s);
            }
            for &c in corners {
                frozen.set(records.corner_slot(c) / 3);
            }
        }
        count = first;
        corner += nc;
        pair += np;
    }
    (evaluated, done)
}

/// The second stage's rule: slot `slot` is drawn when it is a base triangle (`base` of
/// them) or a collapse that would have removed it was not performed (it is frozen).
#[inline(always)]
pub(crate) fn drawn(slot: usize, base: usize, frozen: &Bits) -> bool {
    slot < base || frozen.get(slot)
}
