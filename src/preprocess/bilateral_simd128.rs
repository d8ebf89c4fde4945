//! The bilateral filter's grouped row pass written out in wasm simd128, for
//! the wasm module only (natively `accumulate_row_taps` is compiled for AVX2).
//! Four pixels per iteration (eight, two vectors, measured slower in V8).
//!
//! Per pixel it computes [`super::bilateral::range_weight`]'s values bit for bit, with
//! two instructions fewer per tap than what the auto-vectoriser makes of the
//! scalar loop:
//! - the clamp `if t > 0 { t } else { 0 }` is one `f32x4.pmax(0, t)`
//!   (`0 < t ? t : 0`, the same value for every input, NaN and -0 included)
//!   instead of a compare and a mask (LLVM turns a select against a known
//!   zero back into the mask, so the zero is made opaque);
//! - `(diff^2 * inv) * (1/16)` is `diff^2 * (inv / 16)`: scaling by 2^-4
//!   commutes with rounding while the result is a normal float, and where
//!   it is not (below 2^-122) both give `t = 1 - tiny = 1`, or (overflow)
//!   both give a `t` below 0, clamped to 0. `inv / 16` must itself be exact,
//!   so other sigmas take the plain loop.

use core::arch::wasm32::{
    f32x4_add, f32x4_gt, f32x4_mul, f32x4_pmax, f32x4_splat, f32x4_sub, v128, v128_and, v128_load,
    v128_store,
};

/// Four lanes of `s` from `i` (checked: `i + 4 <= s.len()`).
#[inline(always)]
fn load(s: &[f32], i: usize) -> v128 {
    let lanes = &s[i..i + 4];
    // SAFETY: `lanes` is four in-bounds f32s; v128.load has no alignment requirement.
    unsafe { v128_load(lanes.as_ptr().cast::<v128>()) }
}

/// Writes `v` to the four lanes of `s` from `i` (checked: `i + 4 <= s.len()`).
#[inline(always)]
fn store(s: &mut [f32], i: usize, v: v128) {
    let lanes = &mut s[i..i + 4];
    // SAFETY: `lanes` is four in-bounds f32s, borrowed mutably; no alignment requirement.
    unsafe { v128_store(lanes.as_mut_ptr().cast::<v128>(), v) }
}

/// The constants of the range weight, splatted once per row.
struct Consts {
    /// `inv_two_sigma2 / 16`, exact.
    inv_sixteenth: v128,
    one: v128,
    zero: v128,
    /// Zero that LLVM cannot see through, for `f32x4.pmax`.
    floor: v128,
}

/// [`super::bilateral::range_weight`] for four pixels: `d` the neighbours, `c` the centres.
#[inline(always)]
fn range_weight4(d: v128, c: v128, spatial: v128, k: &Consts) -> v128 {
    let diff = f32x4_sub(d, c);
    let t = f32x4_sub(k.one, f32x4_mul(f32x4_mul(diff, diff), k.inv_sixteenth));
    let mut t = f32x4_pmax(k.floor, t);
    t = f32x4_mul(t, t);
    t = f32x4_mul(t, t);
    t = f32x4_mul(t, t);
    t = f32x4_mul(t, t);
    v128_and(f32x4_gt(d, k.zero), f32x4_mul(spatial, t))
}

/// The running sums of four pixels over a window row's taps.
struct Sums {
    centre: v128,
    sum: v128,
    weight: v128,
}

impl Sums {
    #[inline(always)]
    fn new(centre: &[f32], i: usize, k: &Consts) -> Self {
        Self {
            centre: load(centre, i),
            sum: k.zero,
            weight: k.zero,
        }
    }

    /// One tap: `src` the neighbours of the pixels from `i`. (The weight is
    /// summed first: V8 ran that order 2% faster.)
    #[inline(always)]
    fn tap(&mut self, src: &[f32], i: usize, spatial: v128, k: &Consts) {
        let d = load(src, i);
        let g = range_weight4(d, self.centre, spatial, k);
        self.weight = f32x4_add(self.weight, g);
        self.sum = f32x4_add(self.sum, f32x4_mul(g, d));
    }

    /// `acc += sum`, `wacc += weight` for the pixels from `i`.
    #[inline(always)]
    fn add_to(&self, i: usize, acc: &mut [f32], wacc: &mut [f32]) {
        store(wacc, i, f32x4_add(load(wacc, i), self.weight));
        store(acc, i, f32x4_add(load(acc, i), self.sum));
    }
}

/// `super::bilateral::accumulate_row_taps` in simd128: the seven taps of one window row
/// over the columns `lo..hi` of `row`, where every tap stays inside it.
#[inline(always)]
pub(super) fn accumulate_row_taps(
    row: &[f32],
    centre: &[f32],
    taps: &[(isize, isize, f32); 7],
    inv_two_sigma2: f32,
    (lo, hi): (usize, usize),
    acc: &mut [f32],
    wacc: &mut [f32],
) {
    let inv_sixteenth = inv_two_sigma2 * (1.0 / 16.0);
    if !inv_sixteenth.is_normal() {
        super::bilateral::accumulate_row_taps(
            row,
            centre,
            taps,
            inv_two_sigma2,
            (lo, hi),
            acc,
            wacc,
        );
        return;
    }
    let n = hi - lo;
    let srcs: [&[f32]; 7] =
        std::array::from_fn(|t| &row[(lo as isize + taps[t].0) as usize..][..n]);
    let (centre, acc, wacc) = (&centre[lo..hi], &mut acc[lo..hi], &mut wacc[lo..hi]);
    let k = Consts {
        inv_sixteenth: f32x4_splat(inv_sixteenth),
        one: f32x4_splat(1.0),
        zero: f32x4_splat(0.0),
        floor: std::hint::black_box(f32x4_splat(0.0)),
    };
    // The taps unrolled by hand, each source slice and spatial weight in
    // locals: LLVM keeps a loop over them, whose array stays in memory in wasm.
    let [s0, s1, s2, s3, s4, s5, s6] = srcs;
    let [w0, w1, w2, w3, w4, w5, w6] = taps.map(|tap| f32x4_splat(tap.2));
    let mut i = 0;
    while i + 4 <= n {
        let mut sums = Sums::new(centre, i, &k);
        sums.tap(s0, i, w0, &k);
        sums.tap(s1, i, w1, &k);
        sums.tap(s2, i, w2, &k);
        sums.tap(s3, i, w3, &k);
        sums.tap(s4, i, w4, &k);
        sums.tap(s5, i, w5, &k);
        sums.tap(s6, i, w6, &k);
        sums.add_to(i, acc, wacc);
        i += 4;
    }
    for i in i..n {
        let c = centre[i];
        let (mut sum, mut weight) = (0.0, 0.0);
        for t in 0..7 {
            let d = srcs[t][i];
            let wgt = super::bilateral::range_weight(d, c, taps[t].2, inv_two_sigma2);
            sum += wgt * d;
            weight += wgt;
        }
        acc[i] += sum;
        wacc[i] += weight;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wasm_bindgen_test::wasm_bindgen_test;

    /// Depths with the cases the weight must get right: holes, NaN,
    /// infinity, negative and tiny depths, equal neighbours, far surfaces.
    fn awkward_row(n: usize, seed: u32) -> Vec<f32> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let r = (state >> 8) as f32 / (1u32 << 24) as f32;
                match r {
                    r if r < 0.05 => 0.0,
                    r if r < 0.06 => f32::NAN,
                    r if r < 0.07 => f32::INFINITY,
                    r if r < 0.08 => -1.0,
                    r if r < 0.09 => 1e-30 * r,
                    r if r < 0.15 => 1.0,
                    r if r < 0.25 => 2.0 + 1e3 * r,
                    r => 1.0 + 0.05 * r,
                }
            })
            .collect()
    }

    #[wasm_bindgen_test]
    fn row_taps_match_the_scalar_loop_bit_for_bit() {
        let n = 61;
        let row = awkward_row(n + 12, 3);
        let centre = awkward_row(n + 12, 11);
        let taps: [(isize, isize, f32); 7] =
            std::array::from_fn(|t| (2 * t as isize - 6, 2, 0.3 + 0.1 * t as f32));
        // The default sigma (0.03 m), sigmas whose `inv / 16` is not exact
        // (subnormal, zero, infinite) and one whose products overflow.
        for inv in [555.5556, 1e-37, 0.0, f32::INFINITY, 1e36] {
            let start: Vec<f32> = awkward_row(n + 12, 5).iter().map(|d| d.abs()).collect();
            let (mut acc, mut wacc) = (start.clone(), start.clone());
            let (mut want_acc, mut want_wacc) = (start.clone(), start);
            accumulate_row_taps(&row, &centre, &taps, inv, (6, 6 + n), &mut acc, &mut wacc);
            super::super::bilateral::accumulate_row_taps(
                &row,
                &centre,
                &taps,
                inv,
                (6, 6 + n),
                &mut want_acc,
                &mut want_wacc,
            );
            for i in 0..n + 12 {
                assert_eq!(
                    acc[i].to_bits(),
                    want_acc[i].to_bits(),
                    "inv {inv}, acc[{i}]"
                );
                assert_eq!(
                    wacc[i].to_bits(),
                    want_wacc[i].to_bits(),
                    "inv {inv}, wacc[{i}]"
                );
            }
        }
    }
}
