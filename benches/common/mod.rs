//! What the Bevy benches share: the task pool setting.

use bevy::prelude::*;

/// Bevy's task pools, or with `ASLOD_COMPUTE_THREADS=N` a compute pool of N threads. By default
/// Bevy gives I/O and async compute a thread each, so on a 2-core machine the compute pool (where
/// systems and the plugin's parallel loops run) has one.
pub fn task_pools() -> TaskPoolPlugin {
    let Some(threads) = std::env::var("ASLOD_COMPUTE_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    else {
        return TaskPoolPlugin::default();
    };
    let mut options = TaskPoolOptions::default();
    options.compute.min_threads = threads;
    options.compute.max_threads = threads;
    TaskPoolPlugin {
        task_pool_options: options,
    }
}

/// What `task_pools` made, for the table's title.
pub fn compute_threads() -> String {
    format!(
        "compute pool {} threads",
        bevy::tasks::ComputeTaskPool::get().thread_num()
    )
}
