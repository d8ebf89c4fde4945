//! Running a whole call on rayon's pool.
//!
//! A parallel region started from a thread outside the pool (the CLI's
//! main thread, the page's worker) is handed to the pool and the caller
//! sleeps until it is done: one cross-thread wake-up each way per region.
//! A frame runs many small regions (every tracking iteration at
//! every pyramid level is one), and in a browser a wake-up through
//! `Atomics.wait` / `notify` costs far more than a futex. Run from a pool
//! thread, a region is a job pushed on that thread's own queue, taken by
//! the other threads when they are free.

/// Runs `work` on a thread of rayon's pool and returns its result, the
/// caller waiting; directly when the caller is already a pool thread. The
/// work is the same either way: results do not change, only where they
/// are computed.
pub(crate) fn on_pool<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        return work();
    }
    rayon::scope(|_| work())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_from_outside_the_pool_runs_on_a_pool_thread() {
        // The test harness's threads are not rayon's.
        assert_eq!(rayon::current_thread_index(), None);
        assert!(on_pool(rayon::current_thread_index).is_some());
        assert_eq!(on_pool(|| 6 * 7), 42);
    }

    #[test]
    fn work_from_a_pool_thread_runs_there() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool of two threads");
        let (outer, inner) = pool.install(|| {
            let outer = std::thread::current().id();
            (outer, on_pool(|| std::thread::current().id()))
        });
        assert_eq!(outer, inner);
    }
}
