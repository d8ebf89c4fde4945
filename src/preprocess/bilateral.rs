//! The bilateral filter of the depth image (metres, 0 = invalid): a
//! sparse set of taps, each applied to whole rows so that the compiler
//! vectorises the loop (in wasm, hand-written simd128 in
//! `bilateral_simd128.rs`), with a range weight that is computed, not looked up.

use rayon::prelude::*;

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
use super::bilateral_simd128;

/// Bilateral filter of a depth image (metres, 0 = invalid) over a sparse set of taps
/// `(dx, dy, spatial weight)`. Loops over a whole row per tap, so the compiler
/// vectorises it (the range weight is computed, not looked up).
pub(super) fn bilateral_into(
    depth: &[f32],
    w: usize,
    taps: &[(isize, isize, f32)],
    inv_two_sigma2: f32,
    wsum: &mut [f32],
    out: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    out.par_chunks_mut(w)
        .zip(wsum.par_chunks_mut(w))
        .enumerate()
        .for_each(|(v, (acc, wacc))| {
            let row = BilateralRow {
                depth,
                w,
                taps,
                inv_two_sigma2,
            };
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: the CPU was just checked to support AVX2.
                unsafe { row.filter_avx2(v, acc, wacc) };
                return;
            }
            row.filter(v, acc, wacc);
        });
}

/// The inputs of the bilateral filter, for filtering one output row.
struct BilateralRow<'a> {
    depth: &'a [f32],
    w: usize,
    taps: &'a [(isize, isize, f32)],
    inv_two_sigma2: f32,
}

impl BilateralRow<'_> {
    /// Output row `v` into `acc`, with `wacc` as the weight sums.
    #[inline(always)]
    fn filter(&self, v: usize, acc: &mut [f32], wacc: &mut [f32]) {
        let (depth, w) = (self.depth, self.w);
        let h = (depth.len() / w) as isize;
        let wi = w as isize;
        acc.fill(0.0);
        wacc.fill(0.0);
        let centre = &depth[v * w..v * w + w];
        for group in self.taps.chunk_by(|a, b| a.1 == b.1) {
            let y = v as isize + group[0].1;
            if y < 0 || y >= h {
                continue;
            }
            let row = &depth[(y * wi) as usize..((y + 1) * wi) as usize];
            // The 7 taps of a row of the default window in one pass over the
            // row: the sums stay in registers instead of being loaded and
            // stored once per tap (measured: wasm preprocessing of
            // TUM fr3/teddy 22.5 -> 9.5 ms in Node; no change natively with AVX2).
            let interior = group.iter().fold((0, wi), |(lo, hi), &(dx, _, _)| {
                (lo.max(-dx), hi.min(wi - dx))
            });
            let (mut lo, mut hi) = (0, 0);
            if let (Ok(taps), true) = (<&[_; 7]>::try_from(group), interior.0 < interior.1) {
                (lo, hi) = (interior.0 as usize, interior.1 as usize);
                #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
                bilateral_simd128::accumulate_row_taps(
                    row,
                    centre,
                    taps,
                    self.inv_two_sigma2,
                    (lo, hi),
                    acc,
                    wacc,
                );
                #[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
                accumulate_row_taps(row, centre, taps, self.inv_two_sigma2, (lo, hi), acc, wacc);
            }
            // Columns the grouped pass did not cover (near the borders, or all).
            for &(dx, _, ws) in group {
                let valid_lo = (-dx).max(0) as usize;
                let valid_hi = (wi - dx).min(wi).max(0) as usize;
                for (a, b) in [(valid_lo, lo.min(valid_hi)), (hi.max(valid_lo), valid_hi)] {
                    if a >= b {
                        continue;
                    }
                    let src = &row[(a as isize + dx) as usize..(b as isize + dx) as usize];
                    accumulate(
                        src,
                        &centre[a..b],
                        ws,
                        self.inv_two_sigma2,
                        &mut acc[a..b],
                        &mut wacc[a..b],
                    );
                }
            }
        }
        normalise(acc, wacc, centre);
    }

    /// [`Self::filter`] compiled for AVX2: 8 lanes instead of baseline
    /// x86-64's 4, the same operations in the same order (no FMA
    /// contraction), so the same results bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn filter_avx2(&self, v: usize, acc: &mut [f32], wacc: &mut [f32]) {
        self.filter(v, acc, wacc);
    }
}

/// Weight of a neighbour of depth `d` (0 = invalid) for a pixel of depth
/// `c`: `spatial * exp(-(d - c)^2 / (2 sigma^2))`, the exponential replaced by
/// `(1 - x/16)^16`: close to it over the useful range, zero beyond x = 16,
/// and cheap enough to vectorise (a cheaper kernel lost accuracy:
/// `docs/performance.md#range-weight`).
#[inline(always)]
pub(super) fn range_weight(d: f32, c: f32, spatial: f32, inv_two_sigma2: f32) -> f32 {
    let diff = d - c;
    let x = diff * diff * inv_two_sigma2;
    let t = 1.0 - x * (1.0 / 16.0);
    // A compare-and-select, not `f32::max`, whose NaN rule keeps wasm's
    // f32x4.max from being used and the loop from vectorising there.
    let mut t = if t > 0.0 { t } else { 0.0 };
    t *= t;
    t *= t;
    t *= t;
    t *= t;
    if d > 0.0 {
        spatial * t
    } else {
        0.0
    }
}

/// One tap of the bilateral filter over a row: `acc += wgt * src`,
/// `wacc += wgt`, with `wgt` the [`range_weight`].
#[inline(always)]
fn accumulate(
    src: &[f32],
    centre: &[f32],
    spatial: f32,
    inv_two_sigma2: f32,
    acc: &mut [f32],
    wacc: &mut [f32],
) {
    for (((&d, &c), a), wa) in src
        .iter()
        .zip(centre)
        .zip(acc.iter_mut())
        .zip(wacc.iter_mut())
    {
        let wgt = range_weight(d, c, spatial, inv_two_sigma2);
        *a += wgt * d;
        *wa += wgt;
    }
}

/// The taps of one window row (`(dx, dy, spatial weight)`, same `dy`) over
/// the columns `lo..hi` of `row`, where every tap stays inside it.
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
    let n = hi - lo;
    let srcs: [&[f32]; 7] =
        std::array::from_fn(|t| &row[(lo as isize + taps[t].0) as usize..][..n]);
    let spatial: [f32; 7] = std::array::from_fn(|t| taps[t].2);
    let (centre, acc, wacc) = (&centre[lo..hi], &mut acc[lo..hi], &mut wacc[lo..hi]);
    for i in 0..n {
        let c = centre[i];
        let (mut sum, mut weight) = (0.0, 0.0);
        for t in 0..7 {
            let d = srcs[t][i];
            let wgt = range_weight(d, c, spatial[t], inv_two_sigma2);
            sum += wgt * d;
            weight += wgt;
        }
        acc[i] += sum;
        wacc[i] += weight;
    }
}

/// `acc /= wacc`, keeping invalid centres invalid (the filter fills no holes).
#[inline(always)]
fn normalise(acc: &mut [f32], wacc: &[f32], centre: &[f32]) {
    for ((a, &wa), &c) in acc.iter_mut().zip(wacc).zip(centre) {
        *a = if c > 0.0 && wa > 0.0 { *a / wa } else { c };
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    #[test]
    fn row_grouped_bilateral_matches_the_per_pixel_definition() {
        let (w, h) = (53, 17);
        let mut state = 12345u32;
        let depth: Vec<f32> = (0..w * h)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let r = (state >> 8) as f32 / (1u32 << 24) as f32;
                if r < 0.1 {
                    0.0
                } else {
                    1.0 + 0.05 * r
                }
            })
            .collect();
        let config = PreprocessConfig::default();
        let k = Intrinsics::new(50.0, 50.0, 26.0, 8.0, w, h);
        let pyramid = FramePyramid::new(&k, &config);
        let inv = 1.0 / (2.0 * config.sigma_depth_m * config.sigma_depth_m);
        let (mut out, mut weights) = (vec![0.0; w * h], vec![0.0; w * h]);
        bilateral_into(&depth, w, &pyramid.taps, inv, &mut weights, &mut out);
        for v in 0..h {
            for u in 0..w {
                let c = depth[v * w + u];
                let (mut sum, mut weight) = (0.0f64, 0.0f64);
                for &(dx, dy, ws) in &pyramid.taps {
                    let (x, y) = (u as isize + dx, v as isize + dy);
                    if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
                        continue;
                    }
                    let d = depth[y as usize * w + x as usize];
                    let wgt = range_weight(d, c, ws, inv);
                    sum += f64::from(wgt * d);
                    weight += f64::from(wgt);
                }
                let expected = if c > 0.0 && weight > 0.0 {
                    sum / weight
                } else {
                    f64::from(c)
                };
                let got = f64::from(out[v * w + u]);
                assert!(
                    (got - expected).abs() < 1e-5,
                    "({u}, {v}): {got} vs {expected}"
                );
            }
        }
    }
}
