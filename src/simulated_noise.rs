//! Sensor noise simulated on clean input depth, so that a noise-free
//! sequence (ICL-NUIM as published, a rendering) can be run as a real
//! sensor would have seen it: `SlamConfig::simulate_noise`, the CLI's
//! `run --simulate-noise kinect-v1 --noise-seed N`, the JS config's
//! `simulateNoise` / `noiseSeed`.
//!
//! The Kinect v1 recipe is ICL-NUIM's (Handa et al., ICRA 2014, after
//! Barron and Malik): each depth pixel is resampled bilinearly at a
//! position jittered by N(0, 0.5 px) in x and y (so depth edges smear),
//! turned into a disparity `d = f b / z` (b = 7.5 cm, f the camera's |fx|,
//! pixels), given N(0, 0.05 px) of noise, rounded to 1/8 px and turned back
//! into depth. A pixel whose four bilinear neighbours are not all valid
//! stays invalid.
//!
//! Every draw comes from [`SplitMix`] streams seeded by the seed, the frame
//! number and the row, so the noise does not depend on thread count.

use crate::random::SplitMix;
use rayon::prelude::*;

/// A simulated depth sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SimulatedSensor {
    /// Kinect v1 structured light, ICL-NUIM's recipe (module doc).
    KinectV1,
}

impl SimulatedSensor {
    /// Every sensor, in CLI order.
    pub const ALL: [SimulatedSensor; 1] = [SimulatedSensor::KinectV1];

    /// Name as the CLI and the JS config spell it: `kinect-v1`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::KinectV1 => "kinect-v1",
        }
    }

    /// The sensor called `name` (as printed by [`Self::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// Noise to add to every pushed frame's depth: which sensor, which draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct NoiseSimulation {
    /// The sensor whose noise is simulated.
    pub sensor: SimulatedSensor,
    /// The draw: the same seed gives the same noise on every frame.
    pub seed: u64,
}

/// Kinect v1 (ICL-NUIM recipe): lateral jitter, pixels.
const LATERAL_PX: f32 = 0.5;
/// Projector-camera baseline, metres.
const BASELINE_M: f32 = 0.075;
/// Disparity noise, pixels.
const DISPARITY_SIGMA_PX: f32 = 0.05;
/// Disparity quantisation, pixels.
const DISPARITY_STEP_PX: f32 = 0.125;

impl NoiseSimulation {
    /// Writes `depth_m` (metres, 0 = none, row-major, `width` a row) as the
    /// sensor would have measured it into `out`, for frame number `frame`
    /// of the sequence; `focal_px` is the camera's |fx|, pixels. A
    /// `depth_m` that is not whole rows gives an all-zero `out`.
    pub fn apply_into(
        &self,
        depth_m: &[f32],
        width: usize,
        focal_px: f32,
        frame: u64,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        out.resize(depth_m.len(), 0.0);
        if width == 0 || depth_m.len() % width != 0 {
            return;
        }
        let height = depth_m.len() / width;
        let fb = focal_px.abs() * BASELINE_M;
        if !(fb.is_finite() && fb > 0.0) {
            return;
        }
        let frame_seed = SplitMix::new(self.seed ^ 0x4B1E_C7A1_0000_0000).next_u64() ^ frame;
        let valid = |u: usize, v: usize| {
            let z = depth_m[v * width + u];
            z > 0.0 && z.is_finite()
        };
        out.par_chunks_mut(width).enumerate().for_each(|(v, row)| {
            let mut rng = Normal::new(
                SplitMix::new(frame_seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)).next_u64()
                    ^ (v as u64).wrapping_mul(0xE703_7ED1_A0B4_28DB),
            );
            for (u, z_out) in row.iter_mut().enumerate() {
                let (du, dv, dd) = (rng.next(), rng.next(), rng.next());
                let x = u as f32 + LATERAL_PX * du;
                let y = v as f32 + LATERAL_PX * dv;
                if !(x >= 0.0 && y >= 0.0) {
                    continue;
                }
                let (x0, y0) = (x as usize, y as usize);
                if x0 + 1 >= width || y0 + 1 >= height {
                    continue;
                }
                if !(valid(x0, y0)
                    && valid(x0 + 1, y0)
                    && valid(x0, y0 + 1)
                    && valid(x0 + 1, y0 + 1))
                {
                    continue;
                }
                let (ax, ay) = (x - x0 as f32, y - y0 as f32);
                let at = |uu: usize, vv: usize| depth_m[vv * width + uu];
                let top = at(x0, y0) * (1.0 - ax) + at(x0 + 1, y0) * ax;
                let bottom = at(x0, y0 + 1) * (1.0 - ax) + at(x0 + 1, y0 + 1) * ax;
                let z = top * (1.0 - ay) + bottom * ay;
                let d = fb / z + DISPARITY_SIGMA_PX * dd;
                let d = (d / DISPARITY_STEP_PX).round() * DISPARITY_STEP_PX;
                if d > 0.0 {
                    *z_out = fb / d;
                }
            }
        });
    }
}

/// Standard normal draws (Box-Muller on one [`SplitMix`] stream; the
/// second value of each pair is kept for the next call).
struct Normal {
    rng: SplitMix,
    spare: Option<f32>,
}

impl Normal {
    fn new(seed: u64) -> Self {
        Self {
            rng: SplitMix::new(seed),
            spare: None,
        }
    }

    fn next(&mut self) -> f32 {
        if let Some(g) = self.spare.take() {
            return g;
        }
        let bits = self.rng.next_u64();
        // u1 in (0, 1] so that ln(u1) is finite.
        let u1 = ((bits >> 40) as f32 + 1.0) * (1.0 / (1u64 << 24) as f32);
        let u2 = (bits & 0xFF_FFFF) as f32 * (1.0 / (1u64 << 24) as f32);
        let r = (-2.0 * libm::logf(u1)).sqrt();
        let angle = core::f32::consts::TAU * u2;
        self.spare = Some(r * libm::sinf(angle));
        r * libm::cosf(angle)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KINECT: NoiseSimulation = NoiseSimulation {
        sensor: SimulatedSensor::KinectV1,
        seed: 1,
    };

    #[test]
    fn a_flat_wall_gets_disparity_steps_of_the_right_size() {
        let (w, h, f) = (64usize, 48usize, 525.0f32);
        for z in [1.0f32, 2.0, 4.0] {
            let depth = vec![z; w * h];
            let mut out = Vec::new();
            KINECT.apply_into(&depth, w, f, 3, &mut out);
            let inner: Vec<f32> = out.iter().copied().filter(|&d| d > 0.0).collect();
            // Only the last row and column lack a bilinear neighbour.
            assert!(inner.len() >= (w - 1) * (h - 1) * 9 / 10, "{}", inner.len());
            let fb = f * BASELINE_M;
            for &d in &inner {
                let disparity = fb / d;
                let steps = disparity / DISPARITY_STEP_PX;
                assert!(
                    (steps - steps.round()).abs() < 1e-2,
                    "{disparity} not on a 1/8 px step"
                );
                // Noise of 0.05 px cannot move it more than a step or two.
                assert!(
                    (disparity - fb / z).abs() <= 0.3,
                    "{disparity} vs {}",
                    fb / z
                );
            }
            let mean = inner.iter().map(|&d| f64::from(d)).sum::<f64>() / inner.len() as f64;
            let step_m = f64::from(z * z * DISPARITY_STEP_PX / fb);
            assert!(
                (mean - f64::from(z)).abs() < 0.5 * step_m,
                "bias at {z}: {mean}"
            );
        }
    }

    #[test]
    fn same_seed_same_noise_other_seed_or_frame_other_noise() {
        let (w, h) = (40usize, 30usize);
        let depth: Vec<f32> = (0..w * h).map(|i| 1.0 + (i % w) as f32 * 0.05).collect();
        let run = |sim: NoiseSimulation, frame| {
            let mut out = Vec::new();
            sim.apply_into(&depth, w, 480.0, frame, &mut out);
            out
        };
        assert_eq!(run(KINECT, 0), run(KINECT, 0));
        assert_ne!(run(KINECT, 0), run(KINECT, 1));
        assert_ne!(
            run(KINECT, 0),
            run(NoiseSimulation { seed: 2, ..KINECT }, 0)
        );
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(pool.install(|| run(KINECT, 5)), run(KINECT, 5));
    }

    #[test]
    fn holes_spread_to_their_neighbours_and_bad_input_gives_zeros() {
        let (w, h) = (20usize, 20usize);
        let mut depth = vec![1.5f32; w * h];
        depth[10 * w + 10] = 0.0;
        depth[5 * w + 5] = f32::NAN;
        let mut out = Vec::new();
        KINECT.apply_into(&depth, w, 500.0, 0, &mut out);
        assert!(out.iter().all(|d| d.is_finite() && *d >= 0.0));
        // Every valid output read four valid neighbours: none near a hole
        // reads the hole's zero as a depth.
        assert!(out.iter().all(|&d| d == 0.0 || (d - 1.5).abs() < 0.05));
        KINECT.apply_into(&[1.0; 7], 3, 500.0, 0, &mut out);
        assert_eq!(out, vec![0.0; 7]);
        KINECT.apply_into(&[1.0; 6], 3, f32::NAN, 0, &mut out);
        assert_eq!(out, vec![0.0; 6]);
        KINECT.apply_into(&[], 0, 500.0, 0, &mut out);
        assert!(out.is_empty());
    }
}
