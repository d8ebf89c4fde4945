//! Cache hints for random per-pixel reads: fusion's per-surfel loops and
//! ICP's reads of the frame at the model points' projections. They change
//! no result: a hint only starts a load early.

/// Hints the processor to bring `slice[i]` into its caches, so that a
/// later read of it, some iterations on, does not wait on memory. No effect
/// when `i` is out of range or on targets without such a hint (wasm).
#[inline(always)]
pub(crate) fn prefetch<T>(slice: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(item) = slice.get(i) {
        // SAFETY: a prefetch never faults and does not read into Rust's
        // memory model; the pointer is to a live element anyway.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                std::ptr::from_ref(item).cast::<i8>(),
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (slice, i);
}
