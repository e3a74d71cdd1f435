//! Union-find, which the partition, the bands and the build share.

/// Union-find over `parent` (each entry its parent, roots their own): the root of `x`, with
/// path halving.
pub(super) fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// Union-find: joins the sets of `a` and `b` under the smaller root.
pub(super) fn unite(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    parent[ra.max(rb) as usize] = ra.min(rb);
}
