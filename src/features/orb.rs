//! Oriented, steered BRIEF descriptors (ORB-style): each corner's orientation
//! is the angle of its patch's intensity centroid, and the 256 binary
//! intensity comparisons are rotated by it, so a camera roll between two
//! views leaves the descriptor (nearly) unchanged. Comparisons read a
//! smoothed image: single pixels are too noisy to compare.

use super::Descriptor;
use crate::portable_math::unit_vec2;
use crate::random::SplitMix;
use glam::Vec2;

/// Radius of the circular patch around a corner, pixels of the level the
/// corner was found at.
pub const PATCH_RADIUS: usize = 15;
/// Pairs are drawn within this radius, so that every rotated and rounded
/// pair still lies inside the patch.
const PAIR_RADIUS: f32 = 13.0;
/// Orientation bins of the precomputed steered patterns (12 degrees each, as ORB).
const ANGLE_BINS: usize = 30;
/// Comparisons per descriptor.
pub const BITS: usize = 256;

/// The comparison pairs `(ax, ay, bx, by)`, pixel offsets, for each orientation bin.
#[derive(Debug, Clone)]
pub struct SteeredPattern {
    bins: Vec<[[i8; 4]; BITS]>,
}

impl Default for SteeredPattern {
    fn default() -> Self {
        Self::new()
    }
}

impl SteeredPattern {
    /// Gaussian pairs (sigma = patch size / 5, BRIEF's best by its authors'
    /// tests) from a fixed seed, rotated to every bin.
    #[must_use]
    pub fn new() -> Self {
        let mut rng = SplitMix::new(0x0b1e_f00d);
        let sigma = (2 * PATCH_RADIUS + 1) as f32 / 5.0;
        let mut gaussian_point = || loop {
            // Box-Muller.
            let (u1, u2) = (rng.next_f32().max(1e-7), rng.next_f32());
            let r = sigma * (-2.0 * libm::logf(u1)).sqrt();
            let p = unit_vec2(std::f32::consts::TAU * u2) * r;
            if p.length() <= PAIR_RADIUS {
                return p;
            }
        };
        let pairs: Vec<(Vec2, Vec2)> = (0..BITS)
            .map(|_| (gaussian_point(), gaussian_point()))
            .collect();
        let bins = (0..ANGLE_BINS)
            .map(|bin| {
                let rot = unit_vec2(bin as f32 * std::f32::consts::TAU / ANGLE_BINS as f32);
                let mut out = [[0i8; 4]; BITS];
                for (o, (a, b)) in out.iter_mut().zip(&pairs) {
                    let (a, b) = (rot.rotate(*a), rot.rotate(*b));
                    *o = [a.x, a.y, b.x, b.y].map(|c| c.round() as i8);
                }
                out
            })
            .collect();
        Self { bins }
    }

    /// Descriptor of the corner at pixel `(u, v)` of `smoothed` (`width`
    /// wide) with orientation `angle` (radians). The caller keeps the corner
    /// at least [`PATCH_RADIUS`] from the border.
    #[must_use]
    pub fn describe(
        &self,
        smoothed: &[f32],
        width: usize,
        (u, v): (usize, usize),
        angle: f32,
    ) -> Descriptor {
        let turns = angle / std::f32::consts::TAU;
        let bin = ((turns * ANGLE_BINS as f32).round() as i64).rem_euclid(ANGLE_BINS as i64);
        let pattern = &self.bins[bin as usize];
        let at = |dx: i8, dy: i8| {
            let x = (u as isize + isize::from(dx)) as usize;
            let y = (v as isize + isize::from(dy)) as usize;
            smoothed[y * width + x]
        };
        let mut bits = [0u64; 4];
        for (k, &[ax, ay, bx, by]) in pattern.iter().enumerate() {
            if at(ax, ay) < at(bx, by) {
                bits[k / 64] |= 1 << (k % 64);
            }
        }
        Descriptor(bits)
    }
}

/// Orientation of the patch around `(u, v)`: the angle from the centre to
/// the intensity centroid of the disc of radius [`PATCH_RADIUS`] (Rosin's
/// measure, as ORB), radians, image axes (+x right, +y down).
#[must_use]
pub fn orientation(grey: &[f32], width: usize, (u, v): (usize, usize)) -> f32 {
    let r = PATCH_RADIUS as isize;
    let (mut m10, mut m01) = (0.0f32, 0.0f32);
    for dy in -r..=r {
        // Half-width of the disc's row.
        let half = ((r * r - dy * dy) as f32).sqrt() as isize;
        let row = (v as isize + dy) as usize * width;
        for dx in -half..=half {
            let g = grey[row + (u as isize + dx) as usize];
            m10 += dx as f32 * g;
            m01 += dy as f32 * g;
        }
    }
    libm::atan2f(m01, m10)
}

/// Separable [1 4 6 4 1] / 16 blur of `grey` into `out` (`tmp` as scratch),
/// edges clamped.
pub fn smooth_into(
    grey: &[f32],
    width: usize,
    height: usize,
    tmp: &mut Vec<f32>,
    out: &mut Vec<f32>,
) {
    const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    tmp.resize(grey.len(), 0.0);
    out.resize(grey.len(), 0.0);
    if width == 0 || height == 0 {
        return;
    }
    for (row_in, row_out) in grey.chunks_exact(width).zip(tmp.chunks_exact_mut(width)) {
        for (x, o) in row_out.iter_mut().enumerate() {
            *o = TAPS
                .iter()
                .enumerate()
                .map(|(k, t)| t * row_in[(x + k).saturating_sub(2).min(width - 1)])
                .sum();
        }
    }
    for y in 0..height {
        for x in 0..width {
            out[y * width + x] = TAPS
                .iter()
                .enumerate()
                .map(|(k, t)| t * tmp[(y + k).saturating_sub(2).min(height - 1) * width + x])
                .sum();
        }
    }
}
