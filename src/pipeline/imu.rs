//! The IMU in the pipeline: samples pushed at any time, the calibration
//! found from the tracked frames once they turned enough, and the rotation
//! prior the tracker asks for between two frame times.
//!
//! Nothing here changes a frame's tracking unless
//! `SlamConfig::imu_rotation_guess` is set: the prior is offered
//! ([`Pipeline::imu_rotation_prior`]), not applied. The state is not saved
//! in sessions: a loaded session calibrates again from the frames pushed
//! after it (it needs samples of those times anyway).

use glam::DQuat;

use super::{Pipeline, PipelineError, Verdict};
use crate::imu::{calibrate, CalibrationRefusal, FramePose, ImuBuffer, ImuCalibration, ImuSample};

/// Frames whose rotations the calibration is tried on: the last 600 (10 s
/// at 60 Hz), so that a start that barely turns is outgrown.
const CALIBRATION_FRAMES: usize = 600;
/// Frames between two calibration attempts: half a second at 60 Hz for
/// the first [`QUICK_ATTEMPTS`], then five seconds. An attempt on 600
/// frames takes 50 ms (2 cores, `tests/imu.rs`'s loop): 1.7 ms a frame at
/// first, 0.17 ms once a recording has shown for a while that it does
/// not turn enough.
const CALIBRATE_EVERY_FRAMES: [u32; 2] = [30, 300];
/// Attempts made every `CALIBRATE_EVERY_FRAMES[0]` frames.
const QUICK_ATTEMPTS: u32 = 10;

/// What the pipeline keeps of the IMU.
#[derive(Debug, Clone, Default)]
pub(super) struct ImuState {
    buffer: ImuBuffer,
    /// The frames' rotations since the first (at most about
    /// [`CALIBRATION_FRAMES`] of them), until calibrated.
    frames: Vec<FramePose>,
    calibration: Option<ImuCalibration>,
    /// Why the last attempt gave no calibration.
    refusal: Option<CalibrationRefusal>,
    since_attempt: u32,
    attempts: u32,
}

impl ImuState {
    /// Records a frame's pose; tries to calibrate every
    /// [`CALIBRATE_EVERY_FRAMES`] frames while there are samples.
    fn observe(&mut self, frame: FramePose) {
        if self.calibration.is_some() {
            return;
        }
        self.frames.push(frame);
        if self.frames.len() > CALIBRATION_FRAMES + CALIBRATION_FRAMES / 4 {
            let excess = self.frames.len() - CALIBRATION_FRAMES;
            self.frames.drain(..excess);
        }
        self.since_attempt += 1;
        let every = CALIBRATE_EVERY_FRAMES[usize::from(self.attempts >= QUICK_ATTEMPTS)];
        if self.since_attempt < every || self.buffer.samples().is_empty() {
            return;
        }
        self.since_attempt = 0;
        self.attempts += 1;
        match calibrate(&self.frames, self.buffer.samples()) {
            Ok(calibration) => {
                self.calibration = Some(calibration);
                self.refusal = None;
                self.frames = Vec::new();
            }
            Err(refusal) => self.refusal = Some(refusal),
        }
    }
}

impl Pipeline {
    /// Adds IMU samples (device frame; seconds on the IMU's clock, m/s²
    /// with gravity, rad/s), at any time, before or after the frames of
    /// their times. Refused whole, nothing kept, when a sample is not
    /// finite or is earlier than the one before it
    /// ([`crate::imu::ImuError`]). The most recent
    /// [`crate::imu::MAX_BUFFERED_SAMPLES`] are kept; [`Self::reset`]
    /// forgets them.
    ///
    /// Every few frames pushed, until it succeeds, the pipeline tries to
    /// calibrate the IMU against the frames it tracked whose times the
    /// samples cover ([`crate::imu::calibrate`]).
    pub fn push_imu(&mut self, samples: &[ImuSample]) -> Result<(), PipelineError> {
        self.imu.buffer.push(samples)?;
        Ok(())
    }

    /// The camera's rotation from frame time `t_now` to frame time
    /// `t_prev` (seconds, the timestamps of [`Self::push_frame`]) as the
    /// gyro saw it, `camera_prev_from_camera_now`, with the sigma of each
    /// component of its error (radians). `None` until the IMU is
    /// calibrated, when the samples pushed do not cover the interval (on
    /// the IMU's clock) or `t_now` is before `t_prev`.
    #[must_use]
    pub fn imu_rotation_prior(&self, t_prev: f64, t_now: f64) -> Option<(DQuat, f64)> {
        if t_now.is_nan() || t_prev.is_nan() || t_now < t_prev {
            return None;
        }
        self.imu
            .calibration?
            .camera_before_from_camera_after(self.imu.buffer.samples(), t_prev, t_now)
            .ok()
    }

    /// The IMU's calibration (mounting, time offset, gyro bias and noise),
    /// once found.
    #[must_use]
    pub fn imu_calibration(&self) -> Option<&ImuCalibration> {
        self.imu.calibration.as_ref()
    }

    /// Why the last calibration attempt gave none (`None` before any
    /// attempt and once calibrated).
    #[must_use]
    pub fn imu_refusal(&self) -> Option<&CalibrationRefusal> {
        self.imu.refusal.as_ref()
    }

    /// The mean rate of the IMU samples kept, Hz; `None` with fewer than two.
    #[must_use]
    pub fn imu_rate_hz(&self) -> Option<f64> {
        self.imu.buffer.rate_hz()
    }

    /// Stage `observe_imu`: the frame just placed, for the calibration;
    /// measured when tracking (or the first frame) placed it.
    pub(super) fn observe_imu(&mut self, timestamp: f64, pose: &glam::DAffine3, verdict: Verdict) {
        let measured = matches!(verdict, Verdict::Tracked | Verdict::Initialised);
        self.imu.observe(FramePose {
            time_s: timestamp,
            world_from_camera: DQuat::from_mat3(&pose.matrix3).normalize(),
            measured,
        });
    }

    /// The constant-velocity motion (`previous_from_current`) the frame
    /// stamped `timestamp` is tracked from: with
    /// `SlamConfig::imu_rotation_guess` and a calibrated IMU covering the
    /// time since the last placed frame, the last step's translation
    /// turned by the gyro's rotation; otherwise the last step.
    pub(super) fn velocity_with_imu(&self, timestamp: f64) -> Option<glam::DAffine3> {
        if !self.config.imu_rotation_guess {
            return self.velocity;
        }
        let rotation = self
            .trajectory
            .get(self.placed_frame as usize)
            .and_then(|&(t_prev, _)| self.imu_rotation_prior(t_prev, timestamp));
        match rotation {
            Some((q, _)) => Some(glam::DAffine3::from_mat3_translation(
                glam::DMat3::from_quat(q),
                self.velocity.map_or(glam::DVec3::ZERO, |v| v.translation),
            )),
            None => self.velocity,
        }
    }

    /// Forgets the samples, the frames and the calibration.
    pub(super) fn reset_imu(&mut self) {
        self.imu = ImuState::default();
    }
}
