//! The IMU-to-camera rotation and the IMU clock's offset, found from the
//! recording itself by matching the gyro against the tracked camera.
//!
//! For two consecutive measured frames at `t0`, `t1` the camera turned by
//! `theta_c` (the rotation vector of `camera_t0_from_camera_t1`, camera
//! frame). Over the same interval on the IMU's clock, `[t0 + offset,
//! t1 + offset]`, the gyro integrates to `theta_d` (device frame). The
//! rotation is rigid, so exactly `theta_c = camera_from_imu * (theta_d -
//! bias * (t1 - t0))` to first order in the bias: Wahba's problem for the
//! rotation, then Gauss-Newton on rotation and bias together. The offset
//! is a 1-D search on the fit's cost: every [`COARSE_STEP_S`] over
//! ±[`MAX_OFFSET_S`], then every [`FINE_STEP_S`] around the best. The gyro
//! is integrated once per attempt ([`GyroIntegral`]) and each interval read
//! off it: 600 frame pairs take about 20 ms.
//!
//! Integrated rotations, not rates, are compared: they average the gyro's
//! noise over each frame interval instead of picking one noisy sample,
//! and the camera's rotation between frames is what tracking measures.
//!
//! The answer is refused when the motion cannot show it: a camera that
//! barely turns (pure translation: both sides hold only noise), one that
//! turns about one axis only (turning the IMU about that axis maps the
//! gyro onto the camera as well: the rotation is free about it), or rates
//! so steady that shifting the gyro in time changes nothing (the offset is
//! free). Each bound is a sigma from the fit's own residual.

use glam::{DMat3, DQuat, DVec3};
use nalgebra::{Matrix6, Vector6};
use thiserror::Error;

use super::integrate::{
    gyro_at, integrate_gyro, quat_from_rotation_vector, rotation_vector, GyroIntegral,
};
use super::wahba::{wahba, weakest_axis};
use super::{ImuError, ImuSample};
use crate::portable_math::axis_angle;

/// The largest time offset searched either way, seconds: phone and
/// RGB-D camera IMUs share the frames' clock to a few ms, a USB camera's
/// to tens of ms.
pub const MAX_OFFSET_S: f64 = 0.1;
/// The coarse search's step, seconds (a hand's rate of turn changes over
/// tens of milliseconds: the cost's valley is wider than this).
const COARSE_STEP_S: f64 = 0.004;
/// The fine search's step, seconds, over one coarse step either side.
const FINE_STEP_S: f64 = 0.000_2;
/// Gauss-Newton steps of the coarse search: its offsets are compared, and
/// one step from Wahba's rotation takes most of the bias out.
const COARSE_ROUNDS: usize = 1;
/// The fewest pairs of consecutive measured frames a calibration is made
/// from: a second at 60 Hz, two at 30 Hz.
pub const MIN_PAIRS: usize = 60;
/// Consecutive frames further apart than this (seconds) are not paired:
/// frames were dropped, and a rotation over that long may pass pi.
const MAX_PAIR_INTERVAL_S: f64 = 0.2;
/// The RMS rate of turn below which the camera counts as not turning,
/// rad/s (6 degrees a second; a hand-held scan turns 20-60).
const MIN_RMS_RATE_RADPS: f64 = 0.1;
/// The RMS rate of turn about the two axes across the weakest one below
/// which the rotation counts as about one axis only, rad/s.
const MIN_CROSS_RATE_RADPS: f64 = 0.03;
/// The largest RMS disagreement per frame pair after the fit, radians
/// (1.1 degrees): more is a tracking failure or another device's gyro.
const MAX_RESIDUAL_RMS_RAD: f64 = 0.02;
/// The largest sigma of the rotation about its weakest axis, radians (two
/// degrees). What the mounting is for, a frame's turn, is off by at most
/// the sigma times the turn: 0.1 degree for a turn of 3, below what
/// tracking resolves; and a hand's turns lie mostly along the weakest axis
/// (that is why it is the weakest), about which a mounting's error moves
/// no turn at all.
const MAX_ROTATION_SIGMA_RAD: f64 = 2.0 * std::f64::consts::PI / 180.0;
/// The largest sigma of the time offset, seconds.
const MAX_OFFSET_SIGMA_S: f64 = 0.002;
/// Gauss-Newton steps on rotation and bias together (the problem is
/// nearly linear: two or three converge).
const GAUSS_NEWTON_ROUNDS: usize = 3;
/// The smallest gyro noise density assumed, rad/s/sqrt(Hz): a consumer
/// MEMS gyro's datasheet floor (Bosch BMI160: 0.007 deg/s/sqrt(Hz)).
const MIN_NOISE_DENSITY: f64 = 1.2e-4;

/// A frame's rotation as the calibration reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FramePose {
    /// The frame's timestamp, seconds (the frames' clock).
    pub time_s: f64,
    /// Its rotation, `world_from_camera`.
    pub world_from_camera: DQuat,
    /// Whether tracking measured it (not a guess, a hold or a dead
    /// reckoning): only pairs of measured frames are compared.
    pub measured: bool,
}

/// What the recording says about its IMU: how it is mounted, how its
/// clock runs, its gyro's bias and noise, and how sure each is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuCalibration {
    /// The IMU's axes in the camera frame: `camera_from_imu * v_imu` is
    /// `v_imu` in camera coordinates.
    pub camera_from_imu: DQuat,
    /// Seconds to add to a frame's timestamp for the IMU clock's time of
    /// the same instant.
    pub time_offset_s: f64,
    /// The gyro's constant bias, rad/s, IMU frame (taken off its rates).
    pub gyro_bias_radps: DVec3,
    /// The gyro's white noise, rad/s/sqrt(Hz), measured on its samples
    /// (from the spread of their second differences: motion adds to it,
    /// so it errs high).
    pub gyro_noise_density: f64,
    /// Sigma of `camera_from_imu` about its least pinned axis, radians
    /// (with the bias's uncertainty, which trades against it).
    pub rotation_sigma_rad: f64,
    /// Sigma of `time_offset_s`, seconds.
    pub offset_sigma_s: f64,
    /// Sigma of `gyro_bias_radps` along its least pinned direction, rad/s.
    pub bias_sigma_radps: f64,
    /// Frame pairs the fit used (after outliers went).
    pub pairs: usize,
    /// RMS disagreement per frame pair after the fit, radians.
    pub residual_rms_rad: f64,
}

impl ImuCalibration {
    /// `camera_from_imu` as an axis (unit, camera frame) and an angle in
    /// degrees in [0, 180].
    #[must_use]
    pub fn rotation_axis_angle_deg(&self) -> (DVec3, f64) {
        let q = if self.camera_from_imu.w < 0.0 {
            -self.camera_from_imu
        } else {
            self.camera_from_imu
        };
        let (axis, angle) = axis_angle(q);
        (axis, angle.to_degrees())
    }

    /// [`Self::time_offset_s`] in milliseconds.
    #[must_use]
    pub fn time_offset_ms(&self) -> f64 {
        self.time_offset_s * 1000.0
    }

    /// The camera's rotation from frame time `t_after` to frame time
    /// `t_before` (seconds, the frames' clock), as the gyro saw it:
    /// `camera_before_from_camera_after`, and the sigma of each component
    /// of its error, radians (the gyro's noise over the interval, the
    /// bias's, the offset's and the mounting's uncertainty). Errors when
    /// `samples` do not cover the interval on the IMU's clock.
    pub fn camera_before_from_camera_after(
        &self,
        samples: &[ImuSample],
        t_before: f64,
        t_after: f64,
    ) -> Result<(DQuat, f64), ImuError> {
        let (a, b) = (t_before + self.time_offset_s, t_after + self.time_offset_s);
        let device = integrate_gyro(samples, a, b, self.gyro_bias_radps)?;
        let r = self.camera_from_imu;
        let camera = (r * device * r.inverse()).normalize();
        let dt = (t_after - t_before).abs();
        let angle = rotation_vector(camera).length();
        // A wrong offset shifts the window: the rotation is off by the
        // change of rate across it times the shift.
        let rate_change = (gyro_at(samples, b)? - gyro_at(samples, a)?).length();
        let variance = self.gyro_noise_density * self.gyro_noise_density * dt
            + (self.bias_sigma_radps * dt).powi(2)
            + (self.rotation_sigma_rad * angle).powi(2)
            + (self.offset_sigma_s * rate_change).powi(2);
        Ok((camera, variance.sqrt()))
    }
}

/// Why no calibration was given.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CalibrationRefusal {
    /// Too few pairs of consecutive measured frames lie within the samples.
    #[error("{pairs} pairs of consecutive tracked frames lie within the IMU samples ({MAX_OFFSET_S} s to spare either side); {needed} are needed")]
    TooFewPairs {
        /// Pairs found.
        pairs: usize,
        /// Pairs needed.
        needed: usize,
    },
    /// The camera barely turned (pure translation): the gyro then holds
    /// only its noise, which no rotation maps onto the camera's.
    #[error("the camera turned too little to see how the IMU is mounted ({rms_rate_radps:.3} rad/s RMS, {needed_radps} needed)")]
    TooLittleRotation {
        /// The camera's RMS rate of turn, rad/s.
        rms_rate_radps: f64,
        /// The least accepted, rad/s.
        needed_radps: f64,
    },
    /// The camera turned about one axis only: turning the IMU about that
    /// axis maps the gyro onto the camera as well, so the rotation is
    /// free about it.
    #[error("the camera turned about one axis only ({axis:.2} in the camera frame; {cross_rate_radps:.3} rad/s RMS across it, {needed_radps} needed): the IMU's mounting about that axis is not seen")]
    OneAxis {
        /// The axis, camera frame (unit).
        axis: DVec3,
        /// The RMS rate of turn across it, rad/s.
        cross_rate_radps: f64,
        /// The least accepted, rad/s.
        needed_radps: f64,
    },
    /// The best offset is at the end of the search.
    #[error("the gyro matches the camera best {offset_s} s apart, at the end of the ±{MAX_OFFSET_S} s searched: the clocks are further apart, or the samples are not this camera's")]
    OffsetAtLimit {
        /// The offset found, seconds.
        offset_s: f64,
    },
    /// Gyro and camera disagree beyond what noise explains.
    #[error("the gyro and the tracked camera disagree by {residual_rms_rad:.4} rad RMS per frame pair after the fit ({max_rad:.4} accepted): tracking slid, or the samples are not this recording's")]
    PoorFit {
        /// RMS disagreement, radians.
        residual_rms_rad: f64,
        /// The most accepted, radians.
        max_rad: f64,
    },
    /// The rotation is not pinned well enough.
    #[error("the IMU's mounting is pinned to {sigma_rad:.4} rad only ({max_rad:.4} accepted): the camera must turn about more than one axis")]
    RotationUncertain {
        /// Sigma about the weakest axis, radians.
        sigma_rad: f64,
        /// The most accepted, radians.
        max_rad: f64,
    },
    /// The offset is not pinned well enough: the rate of turn changed too
    /// little for a shift in time to show.
    #[error("the IMU's time offset is pinned to {sigma_s:.4} s only ({max_s} accepted): the camera's rate of turn changed too little")]
    OffsetUncertain {
        /// Sigma of the offset, seconds.
        sigma_s: f64,
        /// The most accepted, seconds.
        max_s: f64,
    },
    /// The rotation fit failed (SVD or eigen-solver).
    #[error("the rotation fit did not converge")]
    Numerical,
}

/// Two consecutive measured frames: their times (seconds) and the camera's
/// rotation vector between them (camera frame at the first, radians).
#[derive(Debug, Clone, Copy)]
struct Pair {
    t0: f64,
    t1: f64,
    camera: DVec3,
}

impl Pair {
    fn dt(&self) -> f64 {
        self.t1 - self.t0
    }
}

/// A fit at one offset.
#[derive(Debug, Clone, Copy)]
struct Fit {
    offset_s: f64,
    camera_from_imu: DQuat,
    bias: DVec3,
    cost: f64,
}

/// Finds the IMU's mounting, clock offset and gyro bias from `frames` (in
/// time order; rotations as tracked) and `samples` (in time order, IMU
/// clock), or says why the motion does not show them.
pub fn calibrate(
    frames: &[FramePose],
    samples: &[ImuSample],
) -> Result<ImuCalibration, CalibrationRefusal> {
    let pairs = covered_pairs(frames, samples);
    check_motion(&pairs)?;
    let margin = MAX_OFFSET_S + 2.0 * COARSE_STEP_S;
    let lo = pairs.first().map_or(0.0, |p| p.t0) - margin;
    let hi = pairs.last().map_or(0.0, |p| p.t1) + margin;
    let first = samples
        .partition_point(|s| s.time_s <= lo)
        .saturating_sub(1);
    let last = samples.partition_point(|s| s.time_s < hi) + 1;
    let integral = GyroIntegral::new(
        samples
            .get(first..last.min(samples.len()))
            .unwrap_or_default(),
    );
    let coarse = search(
        &pairs,
        &integral,
        (-MAX_OFFSET_S, MAX_OFFSET_S),
        COARSE_STEP_S,
        COARSE_ROUNDS,
    )?;
    if coarse.offset_s.abs() > MAX_OFFSET_S - 0.5 * COARSE_STEP_S {
        return Err(CalibrationRefusal::OffsetAtLimit {
            offset_s: coarse.offset_s,
        });
    }
    let pairs = without_outliers(&pairs, &integral, &coarse);
    if pairs.len() < MIN_PAIRS {
        return Err(CalibrationRefusal::TooFewPairs {
            pairs: pairs.len(),
            needed: MIN_PAIRS,
        });
    }
    let (lo, hi) = (
        coarse.offset_s - COARSE_STEP_S,
        coarse.offset_s + COARSE_STEP_S,
    );
    let fit = search(
        &pairs,
        &integral,
        (lo, hi),
        FINE_STEP_S,
        GAUSS_NEWTON_ROUNDS,
    )?;
    judge(&pairs, (samples, &integral), &fit)
}

/// The pairs of consecutive measured frames whose interval, shifted by any
/// offset searched, the samples cover without a gap.
fn covered_pairs(frames: &[FramePose], samples: &[ImuSample]) -> Vec<Pair> {
    let margin = MAX_OFFSET_S + 2.0 * COARSE_STEP_S;
    frames
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (w[0], w[1]);
            let dt = b.time_s - a.time_s;
            let usable = a.measured && b.measured && dt > 0.0 && dt <= MAX_PAIR_INTERVAL_S;
            let covered = usable
                && integrate_gyro(samples, a.time_s - margin, b.time_s + margin, DVec3::ZERO)
                    .is_ok();
            covered.then(|| Pair {
                t0: a.time_s,
                t1: b.time_s,
                camera: rotation_vector(a.world_from_camera.inverse() * b.world_from_camera),
            })
        })
        .collect()
}

/// Refuses too few pairs, too little rotation and rotation about one axis.
fn check_motion(pairs: &[Pair]) -> Result<(), CalibrationRefusal> {
    if pairs.len() < MIN_PAIRS {
        return Err(CalibrationRefusal::TooFewPairs {
            pairs: pairs.len(),
            needed: MIN_PAIRS,
        });
    }
    let time2: f64 = pairs.iter().map(|p| p.dt() * p.dt()).sum();
    let angle2: f64 = pairs.iter().map(|p| p.camera.length_squared()).sum();
    let rms_rate_radps = (angle2 / time2).sqrt();
    if rms_rate_radps.is_nan() || rms_rate_radps < MIN_RMS_RATE_RADPS {
        return Err(CalibrationRefusal::TooLittleRotation {
            rms_rate_radps,
            needed_radps: MIN_RMS_RATE_RADPS,
        });
    }
    let (weakest, axis) =
        weakest_axis(pairs.iter().map(|p| p.camera)).ok_or(CalibrationRefusal::Numerical)?;
    let cross_rate_radps = (weakest / time2).sqrt();
    if cross_rate_radps.is_nan() || cross_rate_radps < MIN_CROSS_RATE_RADPS {
        return Err(CalibrationRefusal::OneAxis {
            axis,
            cross_rate_radps,
            needed_radps: MIN_CROSS_RATE_RADPS,
        });
    }
    Ok(())
}

/// The best fit over offsets `lo..=hi` every `step` seconds (the first of
/// equal costs), each with `rounds` Gauss-Newton steps.
fn search(
    pairs: &[Pair],
    integral: &GyroIntegral<'_>,
    (lo, hi): (f64, f64),
    step: f64,
    rounds: usize,
) -> Result<Fit, CalibrationRefusal> {
    let steps = ((hi - lo) / step).round() as usize;
    let mut best: Option<Fit> = None;
    for k in 0..=steps {
        let fit = fit_at(pairs, integral, lo + k as f64 * step, rounds)?;
        if best.is_none_or(|b| fit.cost < b.cost) {
            best = Some(fit);
        }
    }
    best.ok_or(CalibrationRefusal::Numerical)
}

/// The gyro's rotation vector over each pair's interval shifted by
/// `offset_s` (IMU frame, radians, bias not taken off).
fn device_rotations(
    pairs: &[Pair],
    integral: &GyroIntegral<'_>,
    offset_s: f64,
) -> Result<Vec<DVec3>, CalibrationRefusal> {
    pairs
        .iter()
        .map(|p| {
            integral
                .rotation(p.t0 + offset_s, p.t1 + offset_s)
                .map(rotation_vector)
                // covered_pairs checked every offset searched.
                .map_err(|_| CalibrationRefusal::Numerical)
        })
        .collect()
}

/// Rotation and bias at `offset_s`: Wahba's rotation without a bias, then
/// `rounds` joint Gauss-Newton steps on both (alternating the two crawls:
/// while the rate of turn stays near one vector `w`, a bias across `w` and
/// a turn of the mounting about an axis across `w` move the fit alike).
fn fit_at(
    pairs: &[Pair],
    integral: &GyroIntegral<'_>,
    offset_s: f64,
    rounds: usize,
) -> Result<Fit, CalibrationRefusal> {
    let device = device_rotations(pairs, integral, offset_s)?;
    let mut rotation = wahba(pairs.iter().zip(&device).map(|(p, &d)| (p.camera, d)))
        .ok_or(CalibrationRefusal::Numerical)?;
    let mut bias = DVec3::ZERO;
    for _ in 0..rounds {
        let (h, g) = normal_equations(pairs, &device, rotation, bias);
        let step = solve6(&h, &g).ok_or(CalibrationRefusal::Numerical)?;
        let turn = DVec3::new(step[0], step[1], step[2]);
        rotation = (quat_from_rotation_vector(turn) * rotation).normalize();
        bias += DVec3::new(step[3], step[4], step[5]);
    }
    let cost = pairs
        .iter()
        .zip(&device)
        .map(|(p, &d)| (p.camera - rotation * (d - bias * p.dt())).length_squared())
        .sum();
    Ok(Fit {
        offset_s,
        camera_from_imu: rotation,
        bias,
        cost,
    })
}

/// `J^T J` and `-J^T r` of the residuals `r = theta_c - R (theta_d - b
/// dt)` in a turn `phi` of `R` (`R -> exp(phi) R`, camera frame) and a
/// change of `b`: `dr/dphi = [v]x` with `v = R (theta_d - b dt)`, `dr/db =
/// R dt`. Summed in closed form: `[v]x^T [v]x = |v|^2 I - v v^T`, and the
/// cross block needs only the sum of `v dt` (`R` is the same for all).
fn normal_equations(
    pairs: &[Pair],
    device: &[DVec3],
    rotation: DQuat,
    bias: DVec3,
) -> (Matrix6<f64>, Vector6<f64>) {
    let mut turn_turn = DMat3::ZERO;
    let (mut v_dt, mut r_dt, mut v_cross_r) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
    let mut time2 = 0.0;
    for (p, &d) in pairs.iter().zip(device) {
        let dt = p.dt();
        let v = rotation * (d - bias * dt);
        let r = p.camera - v;
        let n2 = v.length_squared();
        turn_turn +=
            DMat3::from_diagonal(DVec3::splat(n2)) - DMat3::from_cols(v * v.x, v * v.y, v * v.z);
        v_dt += v * dt;
        r_dt += r * dt;
        v_cross_r += v.cross(r);
        time2 += dt * dt;
    }
    let r_mat = DMat3::from_quat(rotation);
    // [v]x^T R dt summed: -[sum v dt]x R.
    let turn_bias = -(crate::se3::skew(v_dt) * r_mat);
    let bias_g = -(r_mat.transpose() * r_dt);
    let mut h = Matrix6::<f64>::zeros();
    for row in 0..3 {
        for col in 0..3 {
            h[(row, col)] = turn_turn.col(col)[row];
            h[(row, col + 3)] = turn_bias.col(col)[row];
            h[(col + 3, row)] = turn_bias.col(col)[row];
        }
        h[(row + 3, row + 3)] = time2;
    }
    // -[v]x^T r = v x r.
    let g = Vector6::new(
        v_cross_r.x,
        v_cross_r.y,
        v_cross_r.z,
        bias_g.x,
        bias_g.y,
        bias_g.z,
    );
    (h, g)
}

/// `h x = g` for a symmetric positive (semi-)definite `h`, damped by a
/// millionth of its mean diagonal so that a rotation about one axis (a
/// singular `h`, refused before) still solves.
fn solve6(h: &Matrix6<f64>, g: &Vector6<f64>) -> Option<Vector6<f64>> {
    let damping = 1e-12 * h.trace() / 6.0;
    let damped = h + Matrix6::<f64>::identity() * damping;
    let x = damped.cholesky()?.solve(g);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The largest eigenvalue of the 3x3 block of `m` at `(k, k)`.
fn block_max_eigenvalue(m: &Matrix6<f64>, k: usize) -> Option<f64> {
    let block: nalgebra::Matrix3<f64> = m.fixed_view::<3, 3>(k, k).into_owned();
    let eigen = block.try_symmetric_eigen(1e-12, 200)?;
    eigen.eigenvalues.iter().copied().reduce(f64::max)
}

/// Each pair's disagreement with `fit`, radians.
fn residuals(
    pairs: &[Pair],
    integral: &GyroIntegral<'_>,
    fit: &Fit,
) -> Result<Vec<f64>, CalibrationRefusal> {
    let device = device_rotations(pairs, integral, fit.offset_s)?;
    Ok(pairs
        .iter()
        .zip(&device)
        .map(|(p, &d)| (p.camera - fit.camera_from_imu * (d - fit.bias * p.dt())).length())
        .collect())
}

/// The pairs within three times the median disagreement of `fit` (a
/// frame where tracking slid is not the gyro's error); at least 1 mrad.
fn without_outliers(pairs: &[Pair], integral: &GyroIntegral<'_>, fit: &Fit) -> Vec<Pair> {
    let Ok(r) = residuals(pairs, integral, fit) else {
        return pairs.to_vec();
    };
    let mut sorted = r.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let gate = (3.0 * median).max(1e-3);
    pairs
        .iter()
        .zip(&r)
        .filter(|(_, &e)| e <= gate)
        .map(|(p, _)| *p)
        .collect()
}

/// The calibration of `fit` with its sigmas, or why it is refused.
fn judge(
    pairs: &[Pair],
    (samples, integral): (&[ImuSample], &GyroIntegral<'_>),
    fit: &Fit,
) -> Result<ImuCalibration, CalibrationRefusal> {
    let n = pairs.len();
    let residual_rms_rad = (fit.cost / n as f64).sqrt();
    if residual_rms_rad.is_nan() || residual_rms_rad > MAX_RESIDUAL_RMS_RAD {
        return Err(CalibrationRefusal::PoorFit {
            residual_rms_rad,
            max_rad: MAX_RESIDUAL_RMS_RAD,
        });
    }
    // Three components a pair; rotation, bias and offset: 7 unknowns.
    let dof = (3 * n).saturating_sub(7).max(1) as f64;
    let sigma2 = fit.cost / dof;
    // Rotation and bias together: their covariance is sigma^2 (J^T J)^-1.
    let device = device_rotations(pairs, integral, fit.offset_s)?;
    let (h, _) = normal_equations(pairs, &device, fit.camera_from_imu, fit.bias);
    let covariance = h.try_inverse().ok_or(CalibrationRefusal::Numerical)? * sigma2;
    let rotation_sigma_rad = block_max_eigenvalue(&covariance, 0)
        .ok_or(CalibrationRefusal::Numerical)?
        .max(0.0)
        .sqrt();
    let bias_sigma_radps = block_max_eigenvalue(&covariance, 3)
        .ok_or(CalibrationRefusal::Numerical)?
        .max(0.0)
        .sqrt();
    if rotation_sigma_rad.is_nan() || rotation_sigma_rad > MAX_ROTATION_SIGMA_RAD {
        return Err(CalibrationRefusal::RotationUncertain {
            sigma_rad: rotation_sigma_rad,
            max_rad: MAX_ROTATION_SIGMA_RAD,
        });
    }
    // The cost's curvature in the offset: var = 2 sigma^2 / cost''.
    let h = 5.0 * FINE_STEP_S;
    let before = fit_at(pairs, integral, fit.offset_s - h, GAUSS_NEWTON_ROUNDS)?.cost;
    let after = fit_at(pairs, integral, fit.offset_s + h, GAUSS_NEWTON_ROUNDS)?.cost;
    let curvature = (before - 2.0 * fit.cost + after) / (h * h);
    let offset_sigma_s = if curvature > 0.0 {
        (2.0 * sigma2 / curvature).sqrt()
    } else {
        f64::INFINITY
    };
    if offset_sigma_s.is_nan() || offset_sigma_s > MAX_OFFSET_SIGMA_S {
        return Err(CalibrationRefusal::OffsetUncertain {
            sigma_s: offset_sigma_s,
            max_s: MAX_OFFSET_SIGMA_S,
        });
    }
    let first = pairs.first().map_or(0.0, |p| p.t0) + fit.offset_s;
    let last = pairs.last().map_or(0.0, |p| p.t1) + fit.offset_s;
    Ok(ImuCalibration {
        camera_from_imu: fit.camera_from_imu,
        time_offset_s: fit.offset_s,
        gyro_bias_radps: fit.bias,
        gyro_noise_density: noise_density(samples, first, last),
        rotation_sigma_rad,
        offset_sigma_s,
        bias_sigma_radps,
        pairs: n,
        residual_rms_rad,
    })
}

/// The gyro's white noise density over `first..=last` (IMU clock),
/// rad/s/sqrt(Hz): a second difference of white noise of sigma s has
/// sigma s * sqrt(6), while a hand's smooth rate nearly cancels in it; the
/// median absolute value over every axis, as a robust sigma, over the
/// square root of the sample rate. At least [`MIN_NOISE_DENSITY`].
fn noise_density(samples: &[ImuSample], first: f64, last: f64) -> f64 {
    let lo = samples.partition_point(|s| s.time_s < first);
    let hi = samples.partition_point(|s| s.time_s <= last);
    let window = samples.get(lo..hi).unwrap_or_default();
    let mut values: Vec<f64> = window
        .windows(3)
        .flat_map(|w| {
            let d = w[0].gyro_radps - 2.0 * w[1].gyro_radps + w[2].gyro_radps;
            [d.x.abs(), d.y.abs(), d.z.abs()]
        })
        .collect();
    let span = window.last().map_or(0.0, |s| s.time_s) - window.first().map_or(0.0, |s| s.time_s);
    if values.is_empty() || span <= 0.0 {
        return MIN_NOISE_DENSITY;
    }
    let rate_hz = (window.len() - 1) as f64 / span;
    values.sort_by(f64::total_cmp);
    let median = values[values.len() / 2];
    let sigma = 1.4826 * median / 6f64.sqrt();
    (sigma / rate_hz.sqrt()).max(MIN_NOISE_DENSITY)
}
