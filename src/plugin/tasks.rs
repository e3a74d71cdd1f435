//! Running the plugin's per-frame work on Bevy's compute task pool, with the calling thread.

use crate::budget::Executor;
use bevy::tasks::{ComputeTaskPool, ParallelSliceMut, TaskPool};

/// Runs `f` over `items` in chunks on the compute task pool and returns its results, one per
/// chunk. There are enough chunks for every compute thread and for the calling thread too:
/// the plugin's heavy systems run on the main thread (they take a
/// [`NonSendMarker`](bevy::ecs::system::NonSendMarker)), which
/// otherwise only waits for the schedule, and a task-pool scope opened there works through
/// the chunks alongside the compute threads. Bevy gives the compute pool one thread on a
/// 2-core machine, so without this the work would use one core of two.
pub(super) fn par_chunks<T: Send, R: Send + 'static>(
    items: &mut [T],
    f: impl Fn(&mut [T]) -> R + Send + Sync,
) -> Vec<R> {
    let mut items = items;
    if items.len() < 2 {
        return vec![f(items)];
    }
    let pool = ComputeTaskPool::get_or_init(TaskPool::default);
    let size = items.len().div_ceil(4 * (pool.thread_num() + 1)).max(1);
    items.par_chunk_map_mut(pool, size, |_, chunk| f(chunk))
}

/// The allocator's passes on the compute task pool, with the calling thread (see
/// [`par_chunks`]).
pub(super) struct ComputePool;

impl Executor for ComputePool {
    fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync)) {
        par_chunks(items, |chunk| chunk.iter_mut().for_each(f));
    }
}
