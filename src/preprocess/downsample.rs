//! 2x2 downsampling of a frame's images for the coarser pyramid levels and
//! half resolution: depth (gated at depth edges), grey levels and depth
//! deviation (block means). Row-major; a coarse image is half the fine
//! one's width and height, rounded down.

use rayon::prelude::*;

/// 2x2 block average of the depths close to the block's first valid depth.
pub(super) fn downsample_depth(
    fine: &[f32],
    fw: usize,
    coarse: &mut [f32],
    cw: usize,
    gate_m: f32,
) {
    coarse.par_chunks_mut(cw).enumerate().for_each(|(v, row)| {
        // The wasm module does four pixels at a time up to `from`.
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        let from = super::simd128::downsample_depth_row(fine, fw, v, gate_m, row);
        #[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
        let from = 0;
        for (u, o) in row.iter_mut().enumerate().skip(from) {
            *o = downsampled_depth_at(fine, fw, gate_m, u, v);
        }
    });
}

/// Coarse pixel `(u, v)` of [`downsample_depth`].
#[inline(always)]
pub(super) fn downsampled_depth_at(
    fine: &[f32],
    fw: usize,
    gate_m: f32,
    u: usize,
    v: usize,
) -> f32 {
    let idx = [
        (2 * v) * fw + 2 * u,
        (2 * v) * fw + 2 * u + 1,
        (2 * v + 1) * fw + 2 * u,
        (2 * v + 1) * fw + 2 * u + 1,
    ];
    let reference = idx.iter().map(|&i| fine[i]).find(|&d| d > 0.0);
    match reference {
        None => 0.0,
        Some(r) => {
            let (mut s, mut n) = (0.0, 0.0);
            for &i in &idx {
                let d = fine[i];
                if d > 0.0 && (d - r).abs() < gate_m {
                    s += d;
                    n += 1.0;
                }
            }
            s / n
        }
    }
}

/// [`downsample_mean`] of a depth deviation map into `coarse`, resized to
/// `cw` x `ch`; an empty map (1 everywhere) stays empty.
pub(super) fn downsample_deviation(
    fine: &[f32],
    fw: usize,
    coarse: &mut Vec<f32>,
    (cw, ch): (usize, usize),
) {
    if fine.len() < 4 * cw * ch {
        coarse.clear();
        return;
    }
    coarse.resize(cw * ch, 1.0);
    downsample_mean(fine, fw, coarse, cw);
}

pub(super) fn downsample_mean(fine: &[f32], fw: usize, coarse: &mut [f32], cw: usize) {
    coarse.par_chunks_mut(cw).enumerate().for_each(|(v, row)| {
        for (u, o) in row.iter_mut().enumerate() {
            let a = (2 * v) * fw + 2 * u;
            let b = a + fw;
            *o = 0.25 * (fine[a] + fine[a + 1] + fine[b] + fine[b + 1]);
        }
    });
}
