//! Sensor noise: the [`NoiseModel`] parameters, the [`StructuredLight`]
//! depth simulation, uniform and gaussian draws from the crate's seeded
//! generator ([`crate::random::SplitMix`]) and depth-edge detection.

use super::texture::sin_turns;
use crate::camera::Intrinsics;
use crate::random::SplitMix;
use rayon::prelude::*;

/// Sensor noise applied by [`render`](fn@super::render).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Standard deviation of depth noise at 1 m, metres; it grows with z^2 (Kinect-like).
    pub depth_sigma_at_1m: f32,
    /// Fraction of pixels dropped at random (depth 0), 0..1.
    pub hole_fraction: f32,
    /// Drop pixels at depth discontinuities, like a structured-light sensor.
    pub edge_holes: bool,
    /// Standard deviation of colour noise per channel, 0..255 units.
    pub colour_sigma: f32,
}

impl NoiseModel {
    /// No noise: raw depth is the exact depth rounded to 1/5000 m, colour exact.
    #[must_use]
    pub const fn none() -> Self {
        Self {
            depth_sigma_at_1m: 0.0,
            hole_fraction: 0.0,
            edge_holes: false,
            colour_sigma: 0.0,
        }
    }

    /// Kinect-like: depth sigma 1.2 mm x z^2 (m) then 16-bit quantisation, 2 %
    /// random holes, holes at depth edges, colour sigma 2.
    #[must_use]
    pub const fn kinect() -> Self {
        Self {
            depth_sigma_at_1m: 0.0012,
            hole_fraction: 0.02,
            edge_holes: true,
            colour_sigma: 2.0,
        }
    }
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self::none()
    }
}

/// Structured-light depth noise (Kinect v1-like), applied to an exact
/// metric depth image: each pixel reads the depth of a neighbour displaced
/// by gaussian lateral jitter (so depth edges fray), that depth is turned
/// into a disparity `d = focal * baseline / z` (pixels), gaussian disparity
/// noise is added and the disparity is quantised, as the sensor's matcher
/// reports it in steps of a fraction of a pixel.
///
/// With `axial_per_m2` the disparity noise is `axial_per_m2 * focal *
/// baseline` pixels, so that its depth deviation is `axial_per_m2 * z^2`
/// metres (Khoshelham and Elberink 2012 measured 1.425e-3 for Kinect v1);
/// quantisation adds steps of `quantum_px * z^2 / (focal * baseline)` metres
/// (11 cm at 6 m for a 525 px Kinect).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructuredLight {
    /// Standard deviation of the lateral jitter, pixels.
    pub lateral_px: f32,
    /// Axial noise coefficient: depth deviation `axial_per_m2 * z^2`, metres.
    pub axial_per_m2: f32,
    /// Disparity quantisation step, pixels (0 = none).
    pub quantum_px: f32,
    /// Projector-camera baseline, metres.
    pub baseline_m: f32,
}

impl StructuredLight {
    /// Kinect v1: 0.5 px lateral jitter, 1.425e-3 z^2 axial, 1/8 px
    /// disparity steps, 7.5 cm baseline.
    #[must_use]
    pub const fn kinect() -> Self {
        Self {
            lateral_px: 0.5,
            axial_per_m2: 1.425e-3,
            quantum_px: 0.125,
            baseline_m: 0.075,
        }
    }

    /// `frame` (intrinsics `k`) as the sensor would deliver it, with depth
    /// from `exact_depth_m` (metres, the rendering's): this noise (drawn
    /// from `seed`), dropped beyond `max_m` as decoding drops it, and
    /// stored in 1/5000 m steps (TUM's depth scale).
    #[must_use]
    pub fn measured(
        &self,
        frame: &crate::frame::RgbdFrame,
        exact_depth_m: &[f32],
        k: &Intrinsics,
        (seed, max_m): (u64, f32),
    ) -> crate::frame::RgbdFrame {
        let mut depth = Vec::new();
        self.apply_into(exact_depth_m, k, seed, &mut depth);
        for z in &mut depth {
            *z = if *z > max_m {
                0.0
            } else {
                (*z * 5000.0).round() / 5000.0
            };
        }
        crate::frame::RgbdFrame {
            depth_deviation: Vec::new(),
            depth_m: depth,
            ..frame.clone()
        }
    }

    /// Writes the noisy version of `depth_m` (metres, 0 = none, row-major,
    /// `width * height` of `k`) into `out`, deterministically from `seed`.
    /// A `depth_m` of the wrong length gives an all-zero `out`.
    pub fn apply_into(&self, depth_m: &[f32], k: &Intrinsics, seed: u64, out: &mut Vec<f32>) {
        let (w, h) = (k.width, k.height);
        out.clear();
        out.resize(depth_m.len(), 0.0);
        if depth_m.len() != w * h || w == 0 {
            return;
        }
        let lateral = sanitise(self.lateral_px);
        let fb = k.focal_abs() * sanitise(self.baseline_m);
        if fb <= 0.0 {
            out.copy_from_slice(depth_m);
            return;
        }
        let sigma_d = sanitise(self.axial_per_m2) * fb;
        let quantum = sanitise(self.quantum_px);
        out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
            let mut rng = NoiseStream::new(row_seed(seed, v, 0x57A0_C7ED));
            for (u, z_out) in row.iter_mut().enumerate() {
                let (du, dv, gd) = (rng.gaussian(), rng.gaussian(), rng.gaussian());
                let su = (u as f32 + lateral * du).round();
                let sv = (v as f32 + lateral * dv).round();
                let su = su.clamp(0.0, (w - 1) as f32) as usize;
                let sv = sv.clamp(0.0, (h - 1) as f32) as usize;
                let z = depth_m[sv * w + su];
                if !(z > 0.0 && z.is_finite()) {
                    *z_out = 0.0;
                    continue;
                }
                let mut d = fb / z + sigma_d * gd;
                if quantum > 0.0 {
                    d = (d / quantum).round() * quantum;
                }
                *z_out = if d > 0.0 { fb / d } else { 0.0 };
            }
        });
    }
}

/// Relative depth jump between 4-neighbours that counts as a discontinuity.
const EDGE_RELATIVE_JUMP: f32 = 0.04;

pub(super) fn is_depth_edge(depth: &[f32], w: usize, h: usize, u: usize, v: usize) -> bool {
    let z = depth[v * w + u];
    let limit = EDGE_RELATIVE_JUMP * z;
    let jump = |zn: f32| zn <= 0.0 || (zn - z).abs() > limit;
    (u > 0 && jump(depth[v * w + u - 1]))
        || (u + 1 < w && jump(depth[v * w + u + 1]))
        || (v > 0 && jump(depth[(v - 1) * w + u]))
        || (v + 1 < h && jump(depth[(v + 1) * w + u]))
}

/// Non-finite or negative noise parameters mean "no noise".
pub(super) fn sanitise(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

pub(super) fn row_seed(seed: u64, row: usize, stream: u64) -> u64 {
    let mut s = SplitMix::new(seed ^ stream.wrapping_mul(0xA076_1D64_78BD_642F));
    s.next_u64() ^ (row as u64).wrapping_mul(0xE703_7ED1_A0B4_28DB)
}

/// Uniform and gaussian draws from one [`SplitMix`] stream.
#[derive(Debug, Clone)]
pub(super) struct NoiseStream {
    rng: SplitMix,
    spare: Option<f32>,
}

impl NoiseStream {
    pub(super) fn new(seed: u64) -> Self {
        Self {
            rng: SplitMix::new(seed),
            spare: None,
        }
    }

    /// Uniform in [0, 1).
    pub(super) fn next_f32(&mut self) -> f32 {
        self.rng.next_f32()
    }

    /// Standard normal (Box-Muller; the second value of each pair is kept for the next call).
    pub(super) fn gaussian(&mut self) -> f32 {
        if let Some(g) = self.spare.take() {
            return g;
        }
        let bits = self.rng.next_u64();
        // u1 in (0, 1] so that ln(u1) is finite.
        let u1 = ((bits >> 40) as f32 + 1.0) * (1.0 / (1u64 << 24) as f32);
        let u2 = (bits & 0xFF_FFFF) as f32 * (1.0 / (1u64 << 24) as f32);
        let r = (-2.0 * libm::logf(u1)).sqrt();
        let (s, c) = (sin_turns(u2), sin_turns(u2 + 0.25));
        self.spare = Some(r * s);
        r * c
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;
    use crate::synthetic::test_support::small;
    use crate::synthetic::{default_intrinsics, render, render_into, trajectory_pose, Scene};

    #[test]
    fn noise_none_is_deterministic_and_exact() {
        let scene = Scene::room();
        let k = small();
        let pose = trajectory_pose(42);
        let a = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let b = render(&scene, &k, &pose, &NoiseModel::none(), 99);
        assert_eq!(a, b);
        for (&raw, &z) in a.depth_raw.iter().zip(&a.depth_m) {
            assert_eq!(raw, (z * 5000.0).round() as u16);
        }
        // Reusing buffers gives the same frame.
        let mut c = render(
            &scene,
            &default_intrinsics(),
            &pose,
            &NoiseModel::kinect(),
            3,
        );
        render_into(&mut c, &scene, &k, &pose, &NoiseModel::none(), 5);
        assert_eq!(a, c);
    }

    #[test]
    fn structured_light_matches_khoshelham() {
        let k = default_intrinsics();
        let n = k.pixel_count();
        let noise = StructuredLight::kinect();
        for z in [1.0f32, 3.0, 6.0] {
            let depth = vec![z; n];
            let mut out = Vec::new();
            noise.apply_into(&depth, &k, 7, &mut out);
            let e: Vec<f64> = out.iter().map(|&d| f64::from(d - z)).collect();
            let mean = e.iter().sum::<f64>() / e.len() as f64;
            let std = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
            // Disparity noise 1.425e-3 z^2 plus the 1/8 px steps' own
            // (uniform, step / sqrt(12)) part.
            let fb = f64::from(k.focal_abs()) * 0.075;
            let step = 0.125 * f64::from(z * z) / fb;
            let expected = (1.425e-3f64 * f64::from(z * z)).hypot(step / 12f64.sqrt());
            assert!(
                (std / expected - 1.0).abs() < 0.15,
                "z {z}: {std} vs {expected}"
            );
            assert!(mean.abs() < 0.1 * expected + 1e-4, "bias {mean} at {z}");
            let mut again = Vec::new();
            noise.apply_into(&depth, &k, 7, &mut again);
            assert_eq!(out, again);
        }
        // A wrong-sized input gives zeros, not a panic.
        let mut out = Vec::new();
        noise.apply_into(&[1.0; 3], &k, 1, &mut out);
        assert_eq!(out, vec![0.0; 3]);
    }

    #[test]
    fn kinect_noise_has_the_right_size() {
        let scene = Scene::room();
        let k = default_intrinsics();
        let pose = trajectory_pose(100);
        let exact = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let noisy = render(&scene, &k, &pose, &NoiseModel::kinect(), 1);
        assert_eq!(noisy, render(&scene, &k, &pose, &NoiseModel::kinect(), 1));
        assert_ne!(noisy, render(&scene, &k, &pose, &NoiseModel::kinect(), 2));
        assert_eq!(noisy.depth_m, exact.depth_m);

        let n = k.pixel_count() as f64;
        let holes = noisy.depth_raw.iter().filter(|&&r| r == 0).count() as f64 / n;
        assert!((0.02..0.10).contains(&holes), "hole fraction {holes}");

        // Normalised depth error (error / z^2) should have std ~ 1.2 mm.
        let (mut sum, mut sum2, mut count) = (0.0f64, 0.0f64, 0.0f64);
        for (&raw, &z) in noisy.depth_raw.iter().zip(&noisy.depth_m) {
            if raw > 0 {
                let e = f64::from(f32::from(raw) / 5000.0 - z) / f64::from(z * z);
                sum += e;
                sum2 += e * e;
                count += 1.0;
            }
        }
        let mean = sum / count;
        let std = (sum2 / count - mean * mean).sqrt();
        assert!(mean.abs() < 2e-4, "bias {mean}");
        assert!((0.0009..0.0016).contains(&std), "sigma at 1 m {std}");

        let diffs: Vec<f64> = noisy
            .rgb
            .iter()
            .zip(&exact.rgb)
            .map(|(&a, &b)| f64::from(a) - f64::from(b))
            .collect();
        let colour_std = (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64).sqrt();
        assert!(
            (1.5..2.5).contains(&colour_std),
            "colour sigma {colour_std}"
        );
    }
}
