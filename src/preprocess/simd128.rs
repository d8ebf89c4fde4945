//! Preprocessing loops written out in wasm simd128, four pixels at a time,
//! for the wasm module only: LLVM does not vectorise the scalar loops for
//! wasm (they read or write `Vec3`s, three floats apart, or pixel pairs,
//! and branch per pixel), and V8 runs them one pixel at a time.
//!
//! Each lane performs the scalar code's operations in the same order (glam's
//! `cross`, `dot`, `length` and `/ f32`, and `Intrinsics::back_project`,
//! spelled out), and its early exits become masks, so every result is the
//! same bit for bit; a lane that would have left early computes on and is
//! set to zero at the end.

use crate::camera::Intrinsics;
use core::arch::wasm32::{
    f32x4_abs, f32x4_add, f32x4_convert_i32x4, f32x4_div, f32x4_gt, f32x4_le, f32x4_lt, f32x4_mul,
    f32x4_neg, f32x4_splat, f32x4_sqrt, f32x4_sub, i32x4, i32x4_add, i32x4_shuffle, i32x4_splat,
    v128, v128_and, v128_andnot, v128_bitselect, v128_load, v128_not, v128_or, v128_store,
};
use glam::Vec3;

// Four `Vec3`s are three v128s: x y z x | y z x y | z x y z.
const _: () = assert!(std::mem::size_of::<Vec3>() == 12);

/// The x, y and z of four consecutive vertices.
struct Xyz {
    x: v128,
    y: v128,
    z: v128,
}

impl Xyz {
    /// `s[i..i + 4]` (checked), deinterleaved.
    #[inline(always)]
    fn load(s: &[Vec3], i: usize) -> Self {
        let four = &s[i..i + 4];
        let p = four.as_ptr().cast::<v128>();
        // SAFETY: `four` is 48 in-bounds bytes (four 12-byte `Vec3`s, checked
        // above), read as three unaligned v128s (wasm has no alignment rule).
        let (a, b, c) = unsafe { (v128_load(p), v128_load(p.add(1)), v128_load(p.add(2))) };
        // Shuffles taking two lanes from each input, one x64 `shufps` each in V8.
        let x2y2x3y3 = i32x4_shuffle::<2, 3, 5, 6>(b, c);
        let y0z0y1z1 = i32x4_shuffle::<1, 2, 4, 5>(a, b);
        Self {
            x: i32x4_shuffle::<0, 3, 4, 6>(a, x2y2x3y3),
            y: i32x4_shuffle::<0, 2, 5, 7>(y0z0y1z1, x2y2x3y3),
            z: i32x4_shuffle::<1, 3, 4, 7>(y0z0y1z1, c),
        }
    }

    /// Interleaves into `s[i..i + 4]` (checked).
    #[inline(always)]
    fn store(&self, s: &mut [Vec3], i: usize) {
        let (x, y, z) = (self.x, self.y, self.z);
        // As in `load`, two lanes from each input per shuffle.
        let x0x2y0y2 = i32x4_shuffle::<0, 2, 4, 6>(x, y);
        let z0z2x1x3 = i32x4_shuffle::<0, 2, 5, 7>(z, x);
        let y1y3z1z3 = i32x4_shuffle::<1, 3, 5, 7>(y, z);
        let a = i32x4_shuffle::<0, 2, 4, 6>(x0x2y0y2, z0z2x1x3);
        let b = i32x4_shuffle::<0, 2, 5, 7>(y1y3z1z3, x0x2y0y2);
        let c = i32x4_shuffle::<1, 3, 5, 7>(z0z2x1x3, y1y3z1z3);
        let four = &mut s[i..i + 4];
        let p = four.as_mut_ptr().cast::<v128>();
        // SAFETY: as in `load`, 48 in-bounds bytes, borrowed mutably.
        unsafe {
            v128_store(p, a);
            v128_store(p.add(1), b);
            v128_store(p.add(2), c);
        }
    }

    #[inline(always)]
    fn sub(&self, o: &Self) -> Self {
        Self {
            x: f32x4_sub(self.x, o.x),
            y: f32x4_sub(self.y, o.y),
            z: f32x4_sub(self.z, o.z),
        }
    }
}

/// Row `v` of [`super::back_project_into`] from column 0 in blocks of four
/// (`depth` and `out` that row); returns the first column left for the
/// scalar loop.
#[inline(always)]
pub(super) fn back_project_row(k: &Intrinsics, v: usize, depth: &[f32], out: &mut [Vec3]) -> usize {
    let n = depth.len().min(out.len());
    let (cx, fx, fy) = (f32x4_splat(k.cx), f32x4_splat(k.fx), f32x4_splat(k.fy));
    let v_cy = f32x4_splat(v as f32 - k.cy);
    let zero = f32x4_splat(0.0);
    let mut u = 0;
    // Column numbers as exact integers, converted per block like `u as f32`.
    let mut columns = i32x4(0, 1, 2, 3);
    while u + 4 <= n {
        let lanes = &depth[u..u + 4];
        // SAFETY: `lanes` is four in-bounds f32s; no alignment rule in wasm.
        let d = unsafe { v128_load(lanes.as_ptr().cast::<v128>()) };
        let valid = f32x4_gt(d, zero);
        let u_cx = f32x4_sub(f32x4_convert_i32x4(columns), cx);
        Xyz {
            x: v128_and(f32x4_div(f32x4_mul(u_cx, d), fx), valid),
            y: v128_and(f32x4_div(f32x4_mul(v_cy, d), fy), valid),
            z: v128_and(d, valid),
        }
        .store(out, u);
        columns = i32x4_add(columns, i32x4_splat(4));
        u += 4;
    }
    u
}

/// Row `v` of [`super::downsample::downsample_depth`] (`out`, from `fine` of width `fw`)
/// from column 0 in blocks of four; returns the first column left for the
/// scalar loop. A block's masks follow the scalar code: the reference is the
/// first of the 2x2 depths that is `> 0`; a depth not taken adds `+0` to the
/// sum (which is `+0` or positive) and to the count, which changes neither.
#[inline(always)]
pub(super) fn downsample_depth_row(
    fine: &[f32],
    fw: usize,
    v: usize,
    gate_m: f32,
    out: &mut [f32],
) -> usize {
    let top = &fine[(2 * v) * fw..(2 * v + 1) * fw];
    let bottom = &fine[(2 * v + 1) * fw..(2 * v + 2) * fw];
    let (zero, one, gate) = (f32x4_splat(0.0), f32x4_splat(1.0), f32x4_splat(gate_m));
    let load = |s: &[f32], i: usize| {
        let lanes = &s[i..i + 4];
        // SAFETY: `lanes` is four in-bounds f32s; no alignment rule in wasm.
        unsafe { v128_load(lanes.as_ptr().cast::<v128>()) }
    };
    let mut u = 0;
    while u + 4 <= out.len() && 2 * u + 8 <= fw {
        let (t0, t1) = (load(top, 2 * u), load(top, 2 * u + 4));
        let (b0, b1) = (load(bottom, 2 * u), load(bottom, 2 * u + 4));
        // The 2x2 block's depths in the scalar code's order.
        let depths = [
            i32x4_shuffle::<0, 2, 4, 6>(t0, t1),
            i32x4_shuffle::<1, 3, 5, 7>(t0, t1),
            i32x4_shuffle::<0, 2, 4, 6>(b0, b1),
            i32x4_shuffle::<1, 3, 5, 7>(b0, b1),
        ];
        let valid = depths.map(|d| f32x4_gt(d, zero));
        let reference = v128_bitselect(
            depths[0],
            v128_bitselect(
                depths[1],
                v128_bitselect(depths[2], depths[3], valid[2]),
                valid[1],
            ),
            valid[0],
        );
        let any = v128_or(v128_or(valid[0], valid[1]), v128_or(valid[2], valid[3]));
        let (mut sum, mut count) = (zero, zero);
        for (d, ok) in depths.into_iter().zip(valid) {
            let near = f32x4_lt(f32x4_abs(f32x4_sub(d, reference)), gate);
            let taken = v128_and(ok, near);
            sum = f32x4_add(sum, v128_and(d, taken));
            count = f32x4_add(count, v128_and(one, taken));
        }
        let depth = v128_and(f32x4_div(sum, count), any);
        let lanes = &mut out[u..u + 4];
        // SAFETY: `lanes` is four in-bounds f32s, borrowed mutably.
        unsafe { v128_store(lanes.as_mut_ptr().cast::<v128>(), depth) };
        u += 4;
    }
    u
}

/// Fills `out` (row `v` of the normal map, `0 < v < h - 1`) from column 0
/// in blocks of four; returns the first column left for the scalar loop.
#[inline(always)]
pub(super) fn normals_row(vertices: &[Vec3], w: usize, v: usize, out: &mut [Vec3]) -> usize {
    if w < 6 {
        return 0;
    }
    let prev = &vertices[(v - 1) * w..v * w];
    let cur = &vertices[v * w..(v + 1) * w];
    let next = &vertices[(v + 1) * w..(v + 2) * w];
    out[0] = Vec3::ZERO;
    let zero = f32x4_splat(0.0);
    let mut u = 1;
    // The last block's right neighbours end at column w - 1.
    while u + 5 <= w {
        let c = Xyz::load(cur, u);
        let (l, r) = (Xyz::load(cur, u - 1), Xyz::load(cur, u + 1));
        let (t, b) = (Xyz::load(prev, u), Xyz::load(next, u));
        // `c.z <= 0` leaves early (a NaN depth does not).
        let mut keep = v128_not(f32x4_le(c.z, zero));
        let jump = f32x4_add(f32x4_mul(f32x4_splat(0.05), c.z), f32x4_splat(0.02));
        for p in [&l, &r, &t, &b] {
            let far = f32x4_gt(f32x4_abs(f32x4_sub(p.z, c.z)), jump);
            keep = v128_andnot(keep, v128_or(f32x4_le(p.z, zero), far));
        }
        // (r - l).cross(b - t), glam's order.
        let (a, e) = (r.sub(&l), b.sub(&t));
        let n = Xyz {
            x: f32x4_sub(f32x4_mul(a.y, e.z), f32x4_mul(e.y, a.z)),
            y: f32x4_sub(f32x4_mul(a.z, e.x), f32x4_mul(e.z, a.x)),
            z: f32x4_sub(f32x4_mul(a.x, e.y), f32x4_mul(e.x, a.y)),
        };
        let len = f32x4_sqrt(dot(&n, &n));
        let short = f32x4_le(len, f32x4_splat(1e-12));
        let finite = f32x4_lt(f32x4_abs(len), f32x4_splat(f32::INFINITY));
        keep = v128_and(v128_andnot(keep, short), finite);
        let n = Xyz {
            x: f32x4_div(n.x, len),
            y: f32x4_div(n.y, len),
            z: f32x4_div(n.z, len),
        };
        let flip = f32x4_gt(dot(&n, &c), zero);
        let oriented = |a: v128| v128_and(v128_bitselect(f32x4_neg(a), a, flip), keep);
        Xyz {
            x: oriented(n.x),
            y: oriented(n.y),
            z: oriented(n.z),
        }
        .store(out, u);
        u += 4;
    }
    u
}

/// glam's `Vec3::dot`: `(x * x') + (y * y') + (z * z')`, left to right.
#[inline(always)]
fn dot(a: &Xyz, b: &Xyz) -> v128 {
    f32x4_add(
        f32x4_add(f32x4_mul(a.x, b.x), f32x4_mul(a.y, b.y)),
        f32x4_mul(a.z, b.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use wasm_bindgen_test::wasm_bindgen_test;

    /// Pseudo-random floats in `0..1`.
    fn uniform(state: &mut u32) -> f32 {
        *state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (*state >> 8) as f32 / (1u32 << 24) as f32
    }

    /// A depth image with the cases the masks must get right: holes, a few
    /// NaNs, infinities and negative depths, and jumps between surfaces.
    fn awkward_depth(n: usize) -> Vec<f32> {
        let mut state = 7;
        (0..n)
            .map(|_| match uniform(&mut state) {
                r if r < 0.08 => 0.0,
                r if r < 0.09 => f32::NAN,
                r if r < 0.095 => f32::INFINITY,
                r if r < 0.10 => -1.0,
                r if r < 0.25 => 3.0 + r,
                r => 1.0 + 0.01 * r,
            })
            .collect()
    }

    fn same_bits(a: Vec3, b: Vec3) -> bool {
        a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)
    }

    #[wasm_bindgen_test]
    fn back_projection_and_normals_match_the_scalar_code_bit_for_bit() {
        let (w, h) = (39, 11);
        let k = Intrinsics::new(52.5, 51.0, 19.25, 5.5, w, h);
        let depth = awkward_depth(w * h);
        let mut vertices = vec![Vec3::splat(9.0); w * h];
        for v in 0..h {
            let row = &mut vertices[v * w..(v + 1) * w];
            let from = back_project_row(&k, v, &depth[v * w..(v + 1) * w], row);
            assert_eq!(from, w - w % 4);
            // The scalar code's values: compared where the simd128 code
            // wrote, filled in after it (the normals read them).
            for (u, (o, &d)) in row.iter_mut().zip(&depth[v * w..]).enumerate() {
                let expected = if d > 0.0 {
                    k.back_project(u as f32, v as f32, d)
                } else {
                    Vec3::ZERO
                };
                if u < from {
                    assert!(same_bits(*o, expected), "({u}, {v}): {o:?} vs {expected:?}");
                } else {
                    *o = expected;
                }
            }
        }
        let mut normals = vec![Vec3::splat(9.0); w];
        let mut defined = 0;
        for v in 1..h - 1 {
            let from = normals_row(&vertices, w, v, &mut normals);
            assert!(from + 4 >= w - 1, "row {v}: only {from} columns");
            for (u, &n) in normals.iter().enumerate().take(from) {
                let expected = super::super::normal_at(&vertices, w, h, u, v);
                assert!(same_bits(n, expected), "({u}, {v}): {n:?} vs {expected:?}");
                defined += usize::from(expected != Vec3::ZERO);
            }
        }
        assert!(
            defined > 20,
            "only {defined} defined normals: the data tests too little"
        );
    }

    #[wasm_bindgen_test]
    fn downsampled_depth_matches_the_scalar_code_bit_for_bit() {
        for fw in [38, 39] {
            let (fh, cw) = (6, fw / 2);
            let fine = awkward_depth(fw * fh);
            // The default gate (3 sigma), one that takes every valid depth
            // and one that takes none (0 / 0: NaN in both).
            for gate in [0.09, 1e9, 0.0] {
                let mut defined = 0;
                for v in 0..fh / 2 {
                    let mut row = vec![9.0; cw];
                    let from = downsample_depth_row(&fine, fw, v, gate, &mut row);
                    assert!(from + 4 > cw, "row {v}: only {from} of {cw} columns");
                    for (u, &got) in row.iter().enumerate().take(from) {
                        let want =
                            super::super::downsample::downsampled_depth_at(&fine, fw, gate, u, v);
                        let same = got.to_bits() == want.to_bits() || got.is_nan() && want.is_nan();
                        assert!(same, "fw {fw}, gate {gate}, ({u}, {v}): {got} vs {want}");
                        defined += usize::from(want > 0.0);
                    }
                }
                assert!(gate == 0.0 || defined > 10, "only {defined} depths tested");
            }
        }
    }
}
