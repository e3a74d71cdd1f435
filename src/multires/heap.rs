//! A binary min-heap over vertex ids with change-key, so each vertex has at most one entry.
//!
//! A plain `BinaryHeap` with lazy deletion keeps every stale entry: several per collapse,
//! most of them cache misses when popped. With one entry per vertex the heap stays small.

/// Min-heap of `(key, id)`, at most one entry per id, ordered by key then id.
pub(crate) struct IndexedHeap {
    heap: Vec<u32>,
    /// Position of each id in `heap`, or `u32::MAX` when absent.
    slot: Vec<u32>,
    key: Vec<u64>,
}

impl IndexedHeap {
    pub(crate) fn new(ids: usize) -> Self {
        Self {
            heap: Vec::new(),
            slot: vec![u32::MAX; ids],
            key: vec![0; ids],
        }
    }

    #[inline]
    fn less(&self, a: u32, b: u32) -> bool {
        (self.key[a as usize], a) < (self.key[b as usize], b)
    }

    /// Inserts `id` or changes its key.
    pub(crate) fn set(&mut self, id: u32, key: u64) {
        self.key[id as usize] = key;
        let slot = self.slot[id as usize];
        if slot == u32::MAX {
            self.heap.push(id);
            let i = self.heap.len() - 1;
            self.slot[id as usize] = i as u32;
            self.sift_up(i);
        } else {
            let i = self.sift_up(slot as usize);
            self.sift_down(i);
        }
    }

    /// Removes `id` if present.
    pub(crate) fn remove(&mut self, id: u32) {
        let slot = self.slot[id as usize];
        if slot == u32::MAX {
            return;
        }
        let i = slot as usize;
        let last = self.heap.pop().expect("present id means non-empty heap");
        self.slot[id as usize] = u32::MAX;
        if i < self.heap.len() {
            self.heap[i] = last;
            self.slot[last as usize] = i as u32;
            let i = self.sift_up(i);
            self.sift_down(i);
        }
    }

    /// Whether `id` is queued.
    #[inline]
    pub(crate) fn contains(&self, id: u32) -> bool {
        self.slot[id as usize] != u32::MAX
    }

    /// The key of `id`, meaningful while it is queued.
    #[inline]
    pub(crate) fn key(&self, id: u32) -> u64 {
        self.key[id as usize]
    }

    /// Removes and returns the smallest `(key, id)`.
    pub(crate) fn pop(&mut self) -> Option<(u64, u32)> {
        let &top = self.heap.first()?;
        self.remove(top);
        Some((self.key[top as usize], top))
    }

    fn sift_up(&mut self, mut i: usize) -> usize {
        while i > 0 {
            let parent = (i - 1) / 2;
            if !self.less(self.heap[i], self.heap[parent]) {
                break;
            }
            self.swap(i, parent);
            i = parent;
        }
        i
    }

    fn sift_down(&mut self, mut i: usize) {
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut best = i;
            if l < self.heap.len() && self.less(self.heap[l], self.heap[best]) {
                best = l;
            }
            if r < self.heap.len() && self.less(self.heap[r], self.heap[best]) {
                best = r;
            }
            if best == i {
                return;
            }
            self.swap(i, best);
            i = best;
        }
    }

    #[inline]
    fn swap(&mut self, a: usize, b: usize) {
        self.heap.swap(a, b);
        self.slot[self.heap[a] as usize] = a as u32;
        self.slot[self.heap[b] as usize] = b as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::IndexedHeap;

    #[test]
    fn pops_in_key_order_after_changes_and_removals() {
        let mut heap = IndexedHeap::new(8);
        for (id, key) in [(0, 50), (1, 10), (2, 30), (3, 20), (4, 40), (5, 30)] {
            heap.set(id, key);
        }
        heap.set(4, 5); // decrease
        heap.set(1, 60); // increase
        heap.remove(3);
        let order: Vec<u32> = std::iter::from_fn(|| heap.pop().map(|(_, id)| id)).collect();
        // Equal keys (2 and 5 at 30) go by id.
        assert_eq!(order, vec![4, 2, 5, 0, 1]);
    }
}
