//! Parallel sums whose result does not depend on the thread count or on
//! work-stealing timing.
//!
//! Floating-point addition is not associative: rayon's `fold`/`reduce`
//! splits work adaptively, so which items share a partial sum, and the order
//! partial sums meet in, change from run to run. On a poorly conditioned
//! tracking step the last bits grow into millimetres, then centimetres.
//! Here the items are cut into blocks of a fixed size, each block is summed
//! on its own (in parallel), and the block sums are combined in block order
//! on one thread: the same input gives the same bits on 1, 2 or 8 threads.

use rayon::prelude::*;
use std::ops::Range;

/// Sums `block_sum(range)` over `0..len` cut into blocks of `block` items
/// (the last may be shorter), combining the block sums with `merge` in
/// block order; `T::default()` is the sum of nothing.
#[must_use]
pub fn sum_in_blocks<T, F, M>(len: usize, block: usize, block_sum: F, merge: M) -> T
where
    T: Send + Default,
    F: Fn(Range<usize>) -> T + Sync + Send,
    M: Fn(T, T) -> T,
{
    let block = block.max(1);
    let sums: Vec<T> = (0..len.div_ceil(block))
        .into_par_iter()
        .map(|b| block_sum(b * block..((b + 1) * block).min(len)))
        .collect();
    sums.into_iter().fold(T::default(), merge)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum_with_threads(threads: usize, values: &[f64]) -> f64 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            sum_in_blocks(
                values.len(),
                7,
                |r| values[r].iter().sum::<f64>(),
                |a, b| a + b,
            )
        })
    }

    #[test]
    fn same_bits_on_any_thread_count() {
        // Values of wildly different magnitude: the order of addition shows.
        let values: Vec<f64> = (0..10_000u32)
            .map(|i| {
                let x = f64::from(i.wrapping_mul(2_654_435_761) % 1000);
                if i % 3 == 0 {
                    x * 1e12
                } else {
                    x * 1e-3 - 0.5
                }
            })
            .collect();
        let one = sum_with_threads(1, &values);
        for threads in [2, 3, 4, 8] {
            for _ in 0..5 {
                assert_eq!(sum_with_threads(threads, &values).to_bits(), one.to_bits());
            }
        }
    }

    #[test]
    fn empty_and_short_inputs() {
        let v = [1.0f64, 2.0, 3.0];
        let s: f64 = sum_in_blocks(v.len(), 100, |r| v[r].iter().sum(), |a, b| a + b);
        assert_eq!(s, 6.0);
        let e: f64 = sum_in_blocks(0, 4, |_| 1.0, |a, b| a + b);
        assert_eq!(e, 0.0);
    }
}
