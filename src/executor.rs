//! Who runs the crate's parallel work: an [`Executor`] is handed the items and a function,
//! and calls it on every item, on whatever threads it has. The allocator's passes and the
//! region build take one, so an engine can give them its own thread pool (the Bevy plugin
//! gives its compute task pool) instead of the crate starting threads of its own.

/// Runs a parallel pass over items: [`Sequential`] one after another on the calling thread,
/// [`Threads`] on scoped OS threads, or an engine's thread pool (the Bevy plugin uses its
/// compute task pool). The allocator's passes take one
/// ([`Allocator::allocate_with`](crate::budget::Allocator::allocate_with)), and so do the
/// region build's rounds ([`RegionMesh::build_with`](crate::regions::RegionMesh::build_with)).
///
/// Neither result depends on the executor or on the number of threads: the allocator's
/// chunks are the same whoever runs them and their sums are combined in chunk order, and
/// the regions of one build round are independent of each other.
///
/// ```
/// use bevy_aslod::budget::{AllocationParams, Allocator, RegionInput};
/// use bevy_aslod::executor::{Executor, Sequential};
///
/// /// Runs the chunks on scoped threads, two at a time.
/// struct Threads;
///
/// impl Executor for Threads {
///     fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync)) {
///         std::thread::scope(|scope| {
///             for pair in items.chunks_mut(2) {
///                 scope.spawn(move || pair.iter_mut().for_each(f));
///             }
///         });
///     }
/// }
///
/// let regions: Vec<RegionInput> = (0..10_000)
///     .map(|i| RegionInput::from_area((i % 97) as f32, 1.0, 2, 500, 0))
///     .collect();
/// let params = AllocationParams::with_budget(1_000_000);
/// let (mut on_threads, mut in_order) = (Vec::new(), Vec::new());
/// Allocator::new().allocate_with(&params, &regions, &mut on_threads, &Threads)?;
/// Allocator::new().allocate_with(&params, &regions, &mut in_order, &Sequential)?;
/// assert_eq!(on_threads, in_order);
/// # Ok::<(), bevy_aslod::budget::BudgetError>(())
/// ```
pub trait Executor: Sync {
    /// Calls `f` once on every item of `items`, in any order and on any threads, and returns
    /// when every call has returned.
    fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync));
}

/// The [`Executor`] that runs every chunk in order on the calling thread
/// ([`Allocator::allocate`](crate::budget::Allocator::allocate) uses it).
#[derive(Clone, Copy, Debug, Default)]
pub struct Sequential;

impl Executor for Sequential {
    #[inline]
    fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync)) {
        items.iter_mut().for_each(f);
    }
}

/// The [`Executor`] that splits the items among scoped OS threads, one run of items per
/// available core ([`RegionMesh::build`](crate::regions::RegionMesh::build) uses it). Inside
/// an engine with a thread pool, pass an executor over that pool instead.
#[derive(Clone, Copy, Debug, Default)]
pub struct Threads;

impl Executor for Threads {
    fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync)) {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        if threads < 2 || items.len() < 2 {
            items.iter_mut().for_each(f);
            return;
        }
        let chunk = items.len().div_ceil(threads);
        std::thread::scope(|scope| {
            for run in items.chunks_mut(chunk) {
                scope.spawn(move || run.iter_mut().for_each(f));
            }
        });
    }
}
