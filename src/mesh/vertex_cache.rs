//! Triangle order for the GPU's post-transform vertex cache: Tipsify (Sander, Nehab and
//! Barczak, "Fast triangle reordering for vertex locality and reduced overdraw", 2007).
//!
//! A progressive mesh writes a level's triangles in the order its collapses leave them, which
//! scatters neighbours across the buffer: about 2.2 vertex shader runs per triangle against
//! the 0.9–1.3 of an exporter's order. Reordering a level once it is made brings it back.

/// The cache size Tipsify plans for; GPUs reuse at least this many recent vertices.
const CACHE: u32 = 16;

/// Reorders the triangles of `indices` (a triangle list over `vertex_count` vertices) so that
/// consecutive triangles share vertices: the same triangles, each with its corners in the same
/// cyclic order (so facing is kept). Linear in the triangles; allocates about 12 bytes per
/// corner.
///
/// Indices at or above `vertex_count`, and a trailing partial triangle, are left as they are.
///
/// ```
/// use bevy_aslod::mesh::{optimize_vertex_cache, vertex_cache_misses};
///
/// // A strip of 200 triangles, listed in a scattered order.
/// let mut indices = Vec::new();
/// for k in (0..200u32).map(|k| (k * 73) % 200) {
///     indices.extend([k, k + 1, k + 2]);
/// }
/// let before = vertex_cache_misses(&indices, 16);
/// optimize_vertex_cache(&mut indices, 202);
/// assert!(vertex_cache_misses(&indices, 16) < before / 2.0);
/// ```
pub fn optimize_vertex_cache(indices: &mut [u32], vertex_count: usize) {
    let corners = indices.len() / 3 * 3;
    if corners == 0
        || indices[..corners]
            .iter()
            .any(|&v| v as usize >= vertex_count)
    {
        return;
    }
    let list = &mut indices[..corners];
    let triangles = corners / 3;
    // Each vertex's triangles (compressed rows).
    let mut offsets = vec![0u32; vertex_count + 1];
    for &v in list.iter() {
        offsets[v as usize + 1] += 1;
    }
    for v in 0..vertex_count {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets.clone();
    let mut adjacent = vec![0u32; corners];
    for (t, triangle) in list.chunks_exact(3).enumerate() {
        for &v in triangle {
            adjacent[fill[v as usize] as usize] = t as u32;
            fill[v as usize] += 1;
        }
    }
    drop(fill);
    // Unemitted triangles per vertex, and when each vertex last entered the cache.
    let mut live: Vec<u32> = offsets.windows(2).map(|w| w[1] - w[0]).collect();
    let mut stamp = vec![0u32; vertex_count];
    let mut time = CACHE + 1;
    let mut emitted = vec![false; triangles];
    let mut out = Vec::with_capacity(corners);
    let (mut dead_end, mut candidates) = (Vec::new(), Vec::new());
    let mut cursor = 0usize;
    let mut fan = Some(list[0]);
    while let Some(f) = fan {
        candidates.clear();
        let f = f as usize;
        for &t in &adjacent[offsets[f] as usize..offsets[f + 1] as usize] {
            let t = t as usize;
            if std::mem::replace(&mut emitted[t], true) {
                continue;
            }
            for &v in &list[3 * t..3 * t + 3] {
                out.push(v);
                dead_end.push(v);
                candidates.push(v);
                let v = v as usize;
                live[v] -= 1;
                if time - stamp[v] > CACHE {
                    stamp[v] = time;
                    time += 1;
                }
            }
        }
        // The next fan: the candidate still used by triangles that stays longest in the cache
        // while they are emitted, else one from the dead-end stack, else the next live vertex.
        let mut best: Option<(u32, u32)> = None;
        for &v in &candidates {
            let vi = v as usize;
            if live[vi] == 0 {
                continue;
            }
            let age = time - stamp[vi];
            let priority = if age + 2 * live[vi] <= CACHE { age } else { 0 };
            if best.is_none_or(|(p, _)| priority > p) {
                best = Some((priority, v));
            }
        }
        fan = best.map(|(_, v)| v).or_else(|| {
            while let Some(v) = dead_end.pop() {
                if live[v as usize] > 0 {
                    return Some(v);
                }
            }
            while cursor < vertex_count {
                if live[cursor] > 0 {
                    return Some(cursor as u32);
                }
                cursor += 1;
            }
            None
        });
    }
    list.copy_from_slice(&out);
}

/// Vertex shader runs a triangle list costs through a first-in first-out cache of `cache`
/// vertices, per triangle (the average cache miss ratio: 0.5 is the best a regular grid
/// allows, 3 the worst).
#[must_use]
pub fn vertex_cache_misses(indices: &[u32], cache: usize) -> f64 {
    let mut fifo = std::collections::VecDeque::with_capacity(cache + 1);
    let mut misses = 0usize;
    for &v in indices {
        if !fifo.contains(&v) {
            misses += 1;
            fifo.push_back(v);
            if fifo.len() > cache {
                fifo.pop_front();
            }
        }
    }
    misses as f64 / (indices.len() / 3).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_grid;

    /// Each triangle with its corners rotated so that the smallest comes first, sorted.
    fn triangles(indices: &[u32]) -> Vec<[u32; 3]> {
        let mut out: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| {
                let k = (0..3).min_by_key(|&k| t[k]).unwrap();
                [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
            })
            .collect();
        out.sort_unstable();
        out
    }

    #[test]
    fn reordering_keeps_every_triangle_and_its_facing_and_cuts_misses() {
        let grid = test_grid(40, |_, _| 0.0);
        // The grid's triangles in a scattered order, as a progressive mesh writes them.
        let n = grid.indices.len() / 3;
        let mut scattered = Vec::with_capacity(grid.indices.len());
        for k in (0..n).map(|k| (k * 7_919) % n) {
            scattered.extend_from_slice(&grid.indices[3 * k..3 * k + 3]);
        }
        let before = vertex_cache_misses(&scattered, 16);
        let mut indices = scattered.clone();
        optimize_vertex_cache(&mut indices, grid.vertex_count());
        assert_eq!(triangles(&indices), triangles(&scattered));
        let after = vertex_cache_misses(&indices, 16);
        assert!(before > 2.0, "{before}");
        assert!(after < 0.8, "{before} -> {after}");
    }

    #[test]
    fn bad_input_is_left_alone() {
        let mut out_of_range = vec![0, 1, 9];
        optimize_vertex_cache(&mut out_of_range, 3);
        assert_eq!(out_of_range, [0, 1, 9]);
        let mut partial = vec![0, 1, 2, 2, 1];
        optimize_vertex_cache(&mut partial, 3);
        assert_eq!(partial, [0, 1, 2, 2, 1]);
        optimize_vertex_cache(&mut [], 0);
    }
}
