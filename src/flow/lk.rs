//! Pyramidal Lucas-Kanade for one point (Bouguet's formulation).
//!
//! At each level, from the coarsest, the displacement `d` of the window
//! around the point solves the least squares `sum [Ix Iy]^T [Ix Iy] d =
//! sum [Ix Iy]^T (I(x) - J(x + g + d))` iteratively (Gauss-Newton with the
//! first image's gradients, so the 2x2 matrix is built once per level); the
//! level's result, doubled, seeds the next finer level.

use super::pyramid::GreyPyramid;
use super::FlowConfig;
use glam::Vec2;

/// Smallest determinant (per window pixel, grey^4) of a trackable window.
const MIN_DETERMINANT: f32 = 1e-4;

/// Where `from` (pixels in `first`) moved to in `second`, or `None` when the
/// window leaves the image or has too little texture.
pub fn track_point(
    first: &GreyPyramid,
    second: &GreyPyramid,
    from: Vec2,
    config: &FlowConfig,
) -> Option<Vec2> {
    let levels = first.len().min(second.len());
    let r = config.window_radius as i32;
    let area = ((2 * r + 1) * (2 * r + 1)) as f32;
    let mut guess = Vec2::ZERO;
    for l in (0..levels).rev() {
        let scale = (1u32 << l) as f32;
        // Level coordinates of a full-resolution pixel centre (2x2 means).
        let p = (from + 0.5) / scale - 0.5;
        let (a, b) = (first.level(l), second.level(l));
        let (mut gxx, mut gxy, mut gyy) = (0.0f32, 0.0f32, 0.0f32);
        for dy in -r..=r {
            for dx in -r..=r {
                let [_, ix, iy] = a.sample(p + Vec2::new(dx as f32, dy as f32))?;
                gxx += ix * ix;
                gxy += ix * iy;
                gyy += iy * iy;
            }
        }
        let det = gxx * gyy - gxy * gxy;
        // Also rejects NaN (the comparison is false).
        if det.is_nan() || det <= MIN_DETERMINANT * area * area {
            return None;
        }
        let mut d = Vec2::ZERO;
        for _ in 0..config.iterations {
            let (mut bx, mut by) = (0.0f32, 0.0f32);
            for dy in -r..=r {
                for dx in -r..=r {
                    let offset = Vec2::new(dx as f32, dy as f32);
                    let [i, ix, iy] = a.sample(p + offset)?;
                    let [j, _, _] = b.sample(p + guess + d + offset)?;
                    let diff = i - j;
                    bx += diff * ix;
                    by += diff * iy;
                }
            }
            let step = Vec2::new(gyy * bx - gxy * by, gxx * by - gxy * bx) / det;
            d += step;
            if step.length() < config.epsilon_px {
                break;
            }
        }
        guess = if l == 0 { guess + d } else { 2.0 * (guess + d) };
    }
    let to = from + guess;
    to.is_finite().then_some(to)
}
