//! Shi-Tomasi ("good features to track") corners: the smaller eigenvalue of
//! the gradient structure tensor over a 5x5 window, one strongest corner per
//! cell of `min_distance_px`, the strongest `max_corners` overall.

use super::pyramid::GreyLevel;
use super::FlowConfig;
use glam::Vec2;

/// Half side of the structure-tensor window, pixels.
const TENSOR_RADIUS: usize = 2;

/// Writes the corners of `level` into `corners` (pixels, strongest first),
/// using `scores` as scratch; points closer than `margin` to the border are skipped.
pub fn shi_tomasi_into(
    level: &GreyLevel,
    config: &FlowConfig,
    margin: usize,
    scores: &mut Vec<f32>,
    corners: &mut Vec<Vec2>,
) {
    corners.clear();
    let (w, h) = (level.width, level.height);
    let margin = margin.max(TENSOR_RADIUS + 1);
    if w <= 2 * margin || h <= 2 * margin || config.max_corners == 0 {
        return;
    }
    let cell = config.min_distance_px.max(1);
    let (cells_x, cells_y) = (w.div_ceil(cell), h.div_ceil(cell));
    // Per cell: best score, then its pixel (as two more f32 slots).
    scores.clear();
    scores.resize(3 * cells_x * cells_y, 0.0);
    let mut strongest = 0.0f32;
    for v in margin..h - margin {
        for u in margin..w - margin {
            let (mut a, mut b, mut c) = (0.0f32, 0.0f32, 0.0f32);
            for y in v - TENSOR_RADIUS..=v + TENSOR_RADIUS {
                for x in u - TENSOR_RADIUS..=u + TENSOR_RADIUS {
                    let [_, gx, gy] = level.pixels[y * w + x];
                    a += gx * gx;
                    b += gx * gy;
                    c += gy * gy;
                }
            }
            let half_trace = 0.5 * (a + c);
            let min_eig = half_trace - (0.25 * (a - c) * (a - c) + b * b).sqrt();
            let slot = 3 * ((v / cell) * cells_x + u / cell);
            if min_eig > scores[slot] {
                scores[slot] = min_eig;
                scores[slot + 1] = u as f32;
                scores[slot + 2] = v as f32;
            }
            strongest = strongest.max(min_eig);
        }
    }
    let floor = (config.quality * strongest).max(f32::MIN_POSITIVE);
    corners.extend(
        scores
            .chunks_exact(3)
            .filter(|s| s[0] >= floor)
            .map(|s| Vec2::new(s[1], s[2])),
    );
    // Strongest first, then keep the requested number.
    let score_of = |p: &Vec2| {
        let slot = 3 * ((p.y as usize / cell) * cells_x + p.x as usize / cell);
        scores[slot]
    };
    corners.sort_by(|p, q| score_of(q).total_cmp(&score_of(p)));
    corners.truncate(config.max_corners);
}
