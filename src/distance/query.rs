//! The parallel query driver: fixed-size chunks of closest-point queries on worker threads.

use super::bvh::Bvh;
use glam::Vec3A;
use std::sync::{Mutex, PoisonError};

/// Points per work unit. Fixed, so that each point's query (which starts from the answer for the
/// point before it in the same chunk) does not depend on the number of threads.
const CHUNK: usize = 2048;

/// Squared distance of every point to `bvh`, on up to `threads` threads (`0`: all cores).
pub(super) fn query_all(points: &[Vec3A], bvh: &Bvh, threads: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; points.len()];
    let chunks = points.len().div_ceil(CHUNK);
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .min(chunks);
    if threads <= 1 {
        for (p, o) in points.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            query_chunk(p, bvh, o);
        }
    } else {
        let work = Mutex::new(points.chunks(CHUNK).zip(out.chunks_mut(CHUNK)));
        std::thread::scope(|scope| {
            for _ in 0..threads {
                scope.spawn(|| {
                    loop {
                        let next = work.lock().unwrap_or_else(PoisonError::into_inner).next();
                        let Some((p, o)) = next else { break };
                        query_chunk(p, bvh, o);
                    }
                });
            }
        });
    }
    out
}

/// Squared distance of each point of `points` to `bvh` (infinite if `bvh` is empty), each chunk
/// seeding a query with the previous point's closest triangle.
fn query_chunk(points: &[Vec3A], bvh: &Bvh, out: &mut [f32]) {
    let mut hint = None;
    for (&p, d2) in points.iter().zip(out) {
        *d2 = match bvh.closest_impl(p, hint) {
            Some((d2, slot)) => {
                hint = Some(slot);
                d2
            }
            None => f32::INFINITY,
        };
    }
}
