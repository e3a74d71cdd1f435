//! One instance's variable-resolution level, kept from frame to frame.

use super::extract::{Bits, drawn, first_stage};
use super::{Criterion, RefineError, RefineStats, VariableMesh, View, with_records};
use crate::multires::CacheIndex;
use crate::multires::records::{Corner, Header, NEW, OLD, Records};

/// No triangle of the output.
const NONE: u32 = u32::MAX;

/// One instance's variable-resolution level of a [`VariableMesh`], ready to render, kept
/// from frame to frame.
///
/// [`extract`](Self::extract) computes a level from scratch (MOM's algorithm).
/// [`update`](Self::update) moves from the current level to the one a fresh extraction
/// would give for the new view, looking only at the collapses on the level's front: those
/// performed with nothing performed above them (each may be undone), and those not
/// performed whose dependencies all are (each may be performed). Everything behind the front
/// keeps its decision; the criteria being monotone (see [`Criterion`]), no decision behind it
/// can change without one on it changing first. The index buffer is edited in place: a
/// performed collapse rewrites its corners where its triangles lie and swaps its removed
/// triangles out, an undone one appends them again.
///
/// Memory per instance: the index buffer ([`indices`](Self::indices)), a copy of every
/// triangle slot's current version (the full-detail size), the output position of every
/// slot and the slot of every output triangle (4 bytes each), a bit per collapse (performed)
/// and the front (4 bytes per entry, a bit per collapse). A fresh [`extract`](super::extract)
/// without a cache needs one bit per triangle beyond its index buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VariableCache<I: CacheIndex = u32> {
    /// Every slot's current version.
    slots: Vec<I>,
    pub(super) performed: Bits,
    performed_count: usize,
    /// The drawn triangles, and for each its slot; for each slot, its triangle or [`NONE`].
    out: Vec<I>,
    out_slot: Vec<u32>,
    out_pos: Vec<u32>,
    /// Collapses that may change: performed with no dependent performed, or not performed
    /// with every dependency performed (and some stale entries, dropped as they are met).
    front: Vec<u32>,
    in_front: Bits,
    /// Scratch of a fresh extraction (a bit per slot).
    frozen: Bits,
    /// Collapses of the mesh the cache was made for.
    collapses: usize,
    pub(super) changed: bool,
}

impl VariableCache {
    /// A cache at full detail.
    #[must_use]
    pub fn new(mesh: &VariableMesh) -> Self {
        Self::full(mesh)
    }
}

impl<I: CacheIndex> VariableCache<I> {
    /// A cache at full detail holding indices of type `I`, or `None` when the mesh has more
    /// vertices than `I` can address.
    #[must_use]
    pub fn with_index_type(mesh: &VariableMesh) -> Option<Self> {
        (mesh.mesh.vertices().vertex_count() as u64 <= I::MAX_VERTICES).then(|| Self::full(mesh))
    }

    fn full(mesh: &VariableMesh) -> Self {
        let slots: Vec<I> = mesh.mesh.records.indices_as();
        let n = slots.len() / 3;
        let steps = mesh.collapse_count();
        let mut cache = Self {
            out: slots.clone(),
            slots,
            performed: Bits::new(steps),
            performed_count: 0,
            out_slot: (0..n as u32).collect(),
            out_pos: (0..n as u32).collect(),
            front: Vec::new(),
            in_front: Bits::new(steps),
            frozen: Bits::default(),
            collapses: steps,
            changed: true,
        };
        cache.rebuild_front(mesh);
        cache
    }

    /// The drawn triangles, ready to render: `3 * triangle_count()` indices into the mesh's
    /// vertex table, in no particular order.
    #[inline]
    #[must_use]
    pub fn indices(&self) -> &[I] {
        &self.out
    }

    /// For each drawn triangle of [`indices`](Self::indices), its slot: its triangle's index
    /// in [`ProgressiveMesh::full_indices`](crate::multires::ProgressiveMesh::full_indices),
    /// the full-detail triangle it is a version of.
    #[inline]
    #[must_use]
    pub fn triangle_slots(&self) -> &[u32] {
        &self.out_slot
    }

    /// Number of drawn triangles.
    #[inline]
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.out_slot.len()
    }

    /// Whether collapse `step` is performed in the current level (false past the last one).
    #[inline]
    #[must_use]
    pub fn is_performed(&self, step: usize) -> bool {
        step < self.collapses && self.performed.get(step)
    }

    /// True when the index buffer changed since the last
    /// [`clear_changed`](Self::clear_changed) (a new cache starts changed).
    #[inline]
    #[must_use]
    pub fn is_changed(&self) -> bool {
        self.changed
    }

    /// Marks the current index buffer as seen (uploaded).
    #[inline]
    pub fn clear_changed(&mut self) {
        self.changed = false;
    }

    /// Bytes this instance holds (see the type's docs).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        (self.slots.capacity() + self.out.capacity()) * size_of::<I>()
            + 4 * (self.out_slot.capacity() + self.out_pos.capacity() + self.front.capacity())
            + self.performed.bytes()
            + self.in_front.bytes()
            + self.frozen.bytes()
    }

    /// Computes the level for `view` from scratch (MOM's two-stage algorithm, see
    /// [`extract`](super::extract)) and makes it the cache's current level.
    ///
    /// # Errors
    /// [`RefineError::MeshMismatch`] when the cache was made for another mesh, and any error
    /// of the criterion's [`validate`](Criterion::validate).
    pub fn extract<K: Criterion + ?Sized>(
        &mut self,
        mesh: &VariableMesh,
        criterion: &K,
        view: &View,
    ) -> Result<RefineStats, RefineError> {
        self.check(mesh)?;
        criterion.validate()?;
        let pm = &mesh.mesh;
        let n = self.out_pos.len();
        with_records!(&pm.records, r => fill(&mut self.slots, r));
        self.frozen.reset(n);
        self.performed.reset(mesh.collapse_count());
        let (evaluated, performed) = with_records!(&pm.records, r => first_stage(
            r,
            &mesh.nodes,
            criterion,
            view,
            &mut self.slots,
            &mut self.frozen,
            Some(&mut self.performed),
        ));
        let base = pm.min_triangles();
        self.out.clear();
        self.out_slot.clear();
        for s in 0..n {
            if drawn(s, base, &self.frozen) {
                self.out_pos[s] = self.out_slot.len() as u32;
                self.out_slot.push(s as u32);
                self.out.extend_from_slice(&self.slots[3 * s..3 * s + 3]);
            } else {
                self.out_pos[s] = NONE;
            }
        }
        self.performed_count = performed;
        self.rebuild_front(mesh);
        self.changed = true;
        Ok(RefineStats {
            triangles: self.triangle_count(),
            performed,
            evaluated,
            changed: performed,
        })
    }

    /// Moves the current level to the one [`extract`](Self::extract) would give for `view`,
    /// performing or undoing only collapses on the front (see the type's docs). The time it
    /// takes grows with the front (about the drawn triangles) and with what changed, not with
    /// the mesh.
    ///
    /// # Errors
    /// As [`extract`](Self::extract).
    pub fn update<K: Criterion + ?Sized>(
        &mut self,
        mesh: &VariableMesh,
        criterion: &K,
        view: &View,
    ) -> Result<RefineStats, RefineError> {
        self.check(mesh)?;
        criterion.validate()?;
        let (mut evaluated, mut changed) = (0, 0);
        let mut k = 0;
        while k < self.front.len() {
            let step = self.front[k] as usize;
            let keep = if self.performed.get(step) {
                if !self.is_maximal(mesh, step) {
                    false
                } else {
                    evaluated += 1;
                    if !criterion.coarsen(&mesh.nodes[step], view) {
                        self.undo(mesh, step);
                        changed += 1;
                        for &d in mesh.dependencies(step) {
                            let d = d as usize;
                            if !self.in_front.get(d) && self.is_maximal(mesh, d) {
                                self.push_front(d);
                            }
                        }
                    }
                    true
                }
            } else if !self.is_candidate(mesh, step) {
                false
            } else {
                evaluated += 1;
                if criterion.coarsen(&mesh.nodes[step], view) {
                    self.perform(mesh, step);
                    changed += 1;
                    for &c in mesh.dependents(step) {
                        let c = c as usize;
                        if !self.in_front.get(c) && self.is_candidate(mesh, c) {
                            self.push_front(c);
                        }
                    }
                }
                true
            };
            if keep {
                k += 1;
            } else {
                self.in_front.clear(step);
                self.front.swap_remove(k);
            }
        }
        self.changed |= changed > 0;
        Ok(RefineStats {
            triangles: self.triangle_count(),
            performed: self.performed_count,
            evaluated,
            changed,
        })
    }

    pub(super) fn check(&self, mesh: &VariableMesh) -> Result<(), RefineError> {
        let slots = mesh.mesh.max_triangles();
        if self.out_pos.len() != slots || self.collapses != mesh.collapse_count() {
            return Err(RefineError::MeshMismatch {
                cache: self.out_pos.len(),
                mesh: slots,
            });
        }
        Ok(())
    }

    #[inline]
    fn push_front(&mut self, step: usize) {
        self.in_front.set(step);
        self.front.push(step as u32);
    }

    /// Performed, and no collapse that depends on it is.
    #[inline]
    pub(super) fn is_maximal(&self, mesh: &VariableMesh, step: usize) -> bool {
        self.performed.get(step)
            && mesh
                .dependents(step)
                .iter()
                .all(|&c| !self.performed.get(c as usize))
    }

    /// Not performed, and every collapse it depends on is.
    #[inline]
    pub(super) fn is_candidate(&self, mesh: &VariableMesh, step: usize) -> bool {
        !self.performed.get(step)
            && mesh
                .dependencies(step)
                .iter()
                .all(|&d| self.performed.get(d as usize))
    }

    /// Every collapse that may change, from scratch.
    fn rebuild_front(&mut self, mesh: &VariableMesh) {
        self.front.clear();
        self.in_front.reset(mesh.collapse_count());
        for step in 0..mesh.collapse_count() {
            if self.is_maximal(mesh, step) || self.is_candidate(mesh, step) {
                self.push_front(step);
            }
        }
    }

    /// Performs `step`, a candidate: rewrites its corners (they lie in drawn triangles) and
    /// swaps its removed triangles out of the index buffer.
    pub(super) fn perform(&mut self, mesh: &VariableMesh, step: usize) {
        with_records!(&mesh.mesh.records, r => self.rewrite(mesh, r, step, NEW));
        let (first, removed) = removed_slots(mesh, step);
        for s in first..first + removed {
            self.remove_out(s);
        }
        self.performed.set(step);
        self.performed_count += 1;
        self.changed = true;
    }

    /// Undoes `step`, a performed collapse nothing performed depends on.
    pub(super) fn undo(&mut self, mesh: &VariableMesh, step: usize) {
        let (first, removed) = removed_slots(mesh, step);
        for s in first..first + removed {
            self.push_out(s);
        }
        with_records!(&mesh.mesh.records, r => self.rewrite(mesh, r, step, OLD));
        self.performed.clear(step);
        self.performed_count -= 1;
        self.changed = true;
    }

    fn rewrite<V: CacheIndex, H: Header, C: Corner>(
        &mut self,
        mesh: &VariableMesh,
        records: &Records<V, H, C>,
        step: usize,
        side: usize,
    ) {
        let (nc, np, _) = records.step(step);
        let corner = mesh.graph.corner_start[step] as usize;
        let pair = mesh.graph.pair_start[step] as usize;
        let pairs = &records.pairs[pair..pair + np];
        for &c in &records.corners[corner..corner + nc] {
            let index = records.corner_slot(c);
            let v = I::from_u32(pairs[records.corner_pair(c)][side].into());
            self.slots[index] = v;
            let at = self.out_pos[index / 3];
            debug_assert_ne!(at, NONE, "a collapse changes only drawn triangles");
            self.out[3 * at as usize + index % 3] = v;
        }
    }

    /// Takes slot `s`'s triangle out of the index buffer; the last one takes its place.
    fn remove_out(&mut self, s: usize) {
        let at = self.out_pos[s] as usize;
        debug_assert_ne!(at as u32, NONE, "a removed triangle was drawn");
        let last = self.out_slot.len() - 1;
        if at != last {
            let moved = self.out_slot[last];
            self.out_slot[at] = moved;
            self.out_pos[moved as usize] = at as u32;
            self.out.copy_within(3 * last..3 * last + 3, 3 * at);
        }
        self.out_slot.pop();
        self.out.truncate(3 * last);
        self.out_pos[s] = NONE;
    }

    /// Appends slot `s`'s triangle to the index buffer.
    fn push_out(&mut self, s: usize) {
        self.out_pos[s] = self.out_slot.len() as u32;
        self.out_slot.push(s as u32);
        self.out.extend_from_slice(&self.slots[3 * s..3 * s + 3]);
    }
}

/// The first slot `step` removes and how many.
#[inline]
fn removed_slots(mesh: &VariableMesh, step: usize) -> (usize, usize) {
    let removed = mesh.mesh.records.removed_by(step);
    (mesh.graph.first_removed[step] as usize, removed)
}

/// `slots` set to the full-detail index buffer.
fn fill<V: CacheIndex, H, C, I: CacheIndex>(slots: &mut [I], records: &Records<V, H, C>) {
    for (s, &v) in slots.iter_mut().zip(&records.indices) {
        *s = I::from_u32(v.into());
    }
}
