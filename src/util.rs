//! Small helpers shared across the crate's layers, below every module that uses them (so that,
//! say, [`multires`](crate::multires) need not reach up into [`skin`](crate::skin) for them).

/// Vertex ids grouped by a dense key (compressed rows).
#[derive(Debug)]
pub(crate) struct Buckets {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Buckets {
    /// The ids with key `k`.
    pub(crate) fn get(&self, k: usize) -> &[u32] {
        &self.items[self.start[k] as usize..self.start[k + 1] as usize]
    }

    /// Every row's ids, row after row (rows in key order, each in input order), to rewrite in
    /// place: a caller that grouped pairs by their first element stores the second here.
    pub(crate) fn items_mut(&mut self) -> &mut [u32] {
        &mut self.items
    }
}

/// Groups `0..keys.len()` by `keys[i] < count`.
pub(crate) fn buckets(keys: &[u32], count: usize) -> Buckets {
    let mut start = vec![0u32; count + 1];
    for &k in keys {
        start[k as usize + 1] += 1;
    }
    for k in 0..count {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut items = vec![0; keys.len()];
    for (i, &k) in keys.iter().enumerate() {
        items[fill[k as usize] as usize] = i as u32;
        fill[k as usize] += 1;
    }
    Buckets { start, items }
}
