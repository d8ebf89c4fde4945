//! The motion a hand can make between two frames, as a prior inside the
//! tracker's solve.
//!
//! A hand-held camera's acceleration is a few m/s² and its angular
//! acceleration a few tens of rad/s² (TUM RGB-D fr3/teddy's 100 Hz
//! motion-capture truth: per-axis RMS acceleration 0.55-0.61 m/s², |a|
//! 99th percentile 2.8-4.1 m/s², maximum 8.5 m/s²; the constant-velocity
//! prediction at 30 Hz misses the true rotation by 0.89 degrees at the
//! 95th percentile, 14 rad/s²; `docs/design.md`, "Motion prior"). Over a
//! frame interval `dt` the camera therefore leaves the constant-velocity
//! prediction by about `a dt²`: 0.6 mm at 60 Hz, 2.2 mm at 30 Hz for
//! `a = 2 m/s²`.
//!
//! The prior is a Gaussian on the camera's pose around the
//! constant-velocity guess with those deviations, added to each
//! Gauss-Newton system. Its weight against the data is the data's own:
//! the system's residuals are scaled by their measured mean square (their
//! variance), and counted as one independent measurement per
//! [`MotionPriorConfig::correlated_pixels`] pixels, since a depth sensor's
//! errors are shared by neighbouring pixels. Where the data pins a
//! direction, the data decides; where it pins it weakly (a wall filling
//! the view of a 256x192 phone depth map), the prior keeps the estimate
//! within what a hand can do instead of letting noise move it centimetres.

use crate::se3::{self, NormalEquations};
use glam::DAffine3;

/// Settings of the hand-held motion prior.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct MotionPriorConfig {
    /// On or off.
    pub enabled: bool,
    /// Per-axis deviation of the camera's acceleration from constant
    /// velocity, m/s² (TUM fr3/teddy: RMS 0.6, 99th percentile of the
    /// norm about 4).
    pub accel_mps2: f64,
    /// Per-axis deviation of the angular acceleration, rad/s².
    pub angular_accel_radps2: f64,
    /// Full-resolution pixels that count as one independent measurement
    /// (each residual of a coarser level or strided pass at most one).
    /// A sensor's errors are correlated over its matching window (a
    /// Kinect's 9x9) or spot spacing, but the data pins a real frame
    /// better than that count says: on TUM fr3/teddy (30 Hz) 81 gave
    /// 0.778 cm ATE, 25 0.704, 9 0.683, 1 0.668 (0.669 without the
    /// prior); 1 still stops the synthetic phone walk's 20 m/s jump
    /// (`tests/hand_held_phone.rs`).
    pub correlated_pixels: f64,
    /// Frame intervals longer than this (seconds) get no prior: a gap in
    /// the recording, or timestamps that are frame numbers.
    pub max_interval_s: f64,
    /// Time constant (seconds) with which a held frame's translation
    /// velocity comes to rest: a hand's velocity changes within about a
    /// second (TUM fr3/teddy: 0.35 m/s median speed, 0.6 m/s² RMS
    /// acceleration), so a guess kept along free directions fades rather
    /// than coasting; 0 = keep it.
    pub held_velocity_decay_s: f64,
}

impl Default for MotionPriorConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            accel_mps2: 2.0,
            angular_accel_radps2: 15.0,
            correlated_pixels: 1.0,
            max_interval_s: 0.25,
            held_velocity_decay_s: 0.3,
        }
    }
}

/// The prior of one frame: where a hand's constant-velocity motion puts
/// the camera, and how far it may leave it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionPrior {
    /// The constant-velocity guess, `camera_from_world`.
    guess_camera_from_world: DAffine3,
    /// Deviation of the translation, metres (per axis).
    sigma_t_m: f64,
    /// Deviation of the rotation, radians (per axis).
    sigma_r_rad: f64,
    /// Pixels per independent measurement.
    correlated_pixels: f64,
}

impl MotionPrior {
    /// The prior for a frame `interval_s` seconds after the last placed
    /// one, around `guess_world_from_camera`; `None` when off, for an
    /// interval that is not a frame's (non-positive, non-finite or over
    /// [`MotionPriorConfig::max_interval_s`]) or a guess that is not finite.
    #[must_use]
    pub fn around(
        guess_world_from_camera: &DAffine3,
        interval_s: f64,
        config: &MotionPriorConfig,
    ) -> Option<Self> {
        let usable = config.enabled
            && interval_s.is_finite()
            && interval_s > 0.0
            && interval_s <= config.max_interval_s
            && guess_world_from_camera.is_finite();
        let dt2 = interval_s * interval_s;
        let sigma_t_m = config.accel_mps2 * dt2;
        let sigma_r_rad = config.angular_accel_radps2 * dt2;
        (usable && sigma_t_m > 0.0 && sigma_r_rad > 0.0 && config.correlated_pixels > 0.0).then(
            || Self {
                guess_camera_from_world: guess_world_from_camera.inverse(),
                sigma_t_m,
                sigma_r_rad,
                correlated_pixels: config.correlated_pixels,
            },
        )
    }

    /// Deviation of the translation this prior allows, metres.
    #[must_use]
    pub fn sigma_t_m(&self) -> f64 {
        self.sigma_t_m
    }

    /// `system` (to be solved for a step from `camera_from_world`) with
    /// the prior added, weighed against `data`, the measurements' own
    /// system before any held direction was stiffened: its mean squared
    /// residual is the measurements' variance in the system's units, and
    /// each of its residuals stands for `pixels_per_residual` pixels of the
    /// full-resolution image (a coarser level or a strided pass).
    #[must_use]
    pub fn added_to(
        &self,
        mut system: NormalEquations,
        data: &NormalEquations,
        camera_from_world: &DAffine3,
        pixels_per_residual: f64,
    ) -> NormalEquations {
        if data.count == 0 || data.cost.is_nan() || data.cost <= 0.0 {
            return system;
        }
        // Information per unit of the system: residuals of variance
        // `cost / count`, one independent measurement per
        // `correlated_pixels` pixels (each residual at most one).
        let shared = (self.correlated_pixels / pixels_per_residual.max(1.0)).max(1.0);
        let scale = shared * data.cost / data.count as f64;
        // The step that takes the estimate to the guess (applied on the left).
        let to_guess = se3::log(&(self.guess_camera_from_world * camera_from_world.inverse()));
        if !to_guess.iter().all(|v| v.is_finite()) {
            return system;
        }
        for (i, step) in to_guess.iter().enumerate() {
            let sigma = if i < 3 {
                self.sigma_r_rad
            } else {
                self.sigma_t_m
            };
            let information = scale / (sigma * sigma);
            system.a[i][i] += information;
            // Solved as (A) x = -b: the prior's pull towards `to_guess`.
            system.b[i] -= information * step;
        }
        system
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn data(information: f64) -> NormalEquations {
        let mut system = NormalEquations {
            cost: 1.0,
            count: 1,
            ..NormalEquations::default()
        };
        for i in 0..6 {
            system.a[i][i] = information;
        }
        system
    }

    #[test]
    fn with_no_data_the_step_goes_to_the_guess() {
        let guess = DAffine3::from_translation(DVec3::new(0.01, 0.0, 0.0));
        let config = MotionPriorConfig::default();
        let prior = MotionPrior::around(&guess, 1.0 / 60.0, &config).unwrap();
        let estimate = DAffine3::IDENTITY;
        let mut weak = data(1e-12);
        weak.cost = 1e-6;
        let system = prior.added_to(NormalEquations::default(), &weak, &estimate.inverse(), 1.0);
        let step = system.solve(0.0).unwrap();
        let moved = se3::exp(&step) * estimate.inverse();
        let centre = moved.inverse().translation;
        assert!((centre - guess.translation).length() < 1e-9, "{centre}");
    }

    #[test]
    fn strong_data_outweighs_the_prior_and_weak_data_does_not() {
        let config = MotionPriorConfig::default();
        let guess = DAffine3::IDENTITY;
        let prior = MotionPrior::around(&guess, 1.0 / 30.0, &config).unwrap();
        // The data asks for a 1 cm step along x; the prior for none.
        let ask = |information: f64| {
            let mut d = data(information);
            d.b[3] = -0.01 * information;
            let step = prior
                .added_to(d, &d, &DAffine3::IDENTITY, 81.0)
                .solve(0.0)
                .unwrap();
            step[3]
        };
        // Residuals of unit variance worth 1e8 pin x to 0.1 mm, well
        // under the prior's 2.2 mm.
        assert!((ask(1e8) - 0.01).abs() < 1e-4, "{}", ask(1e8));
        // A direction pinned 1e8 times more weakly stays near the guess.
        assert!(ask(1.0).abs() < 1e-3, "{}", ask(1.0));
    }

    #[test]
    fn no_prior_for_gaps_frame_numbers_or_when_off() {
        let config = MotionPriorConfig::default();
        let pose = DAffine3::IDENTITY;
        assert!(MotionPrior::around(&pose, 1.0, &config).is_none());
        assert!(MotionPrior::around(&pose, 0.0, &config).is_none());
        assert!(MotionPrior::around(&pose, f64::NAN, &config).is_none());
        let off = MotionPriorConfig {
            enabled: false,
            ..config
        };
        assert!(MotionPrior::around(&pose, 1.0 / 30.0, &off).is_none());
    }
}
