//! The IMU, where a recording has one: its samples, the gyro integrated
//! between two times, and the IMU-to-camera rotation and time offset found
//! from the recording itself (no per-device constant).
//!
//! Frames: a sample is in the IMU's own (device) frame; the camera frame is
//! ours (+x right, +y down, +z forward). Times are seconds; an IMU's clock
//! may run `time_offset_s` ahead of the frames' ([`ImuCalibration`]).
//! Rotation rates are rad/s, accelerations m/s², angles radians.
//!
//! One path for every recording with an IMU: the dataset loaders fill
//! [`crate::dataset::Sequence::imu`], the caller hands the samples to
//! [`crate::Pipeline::push_imu`], and the pipeline calibrates from its own
//! tracked poses ([`calibrate`]) and then predicts each frame's rotation
//! ([`crate::Pipeline::imu_rotation_prior`]).

mod buffer;
mod calibrate;
mod integrate;
mod wahba;

pub use buffer::{ImuBuffer, MAX_BUFFERED_SAMPLES};
pub use calibrate::{
    calibrate, CalibrationRefusal, FramePose, ImuCalibration, MAX_OFFSET_S, MIN_PAIRS,
};
pub use integrate::{gyro_at, integrate_gyro, quat_from_rotation_vector, rotation_vector};

use glam::DVec3;
use thiserror::Error;

/// One IMU reading, in the device's own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// When it was measured, seconds, on the IMU's clock.
    pub time_s: f64,
    /// Specific force, m/s², gravity included: a device at rest reads 9.81
    /// m/s² pointing up (away from the ground), device frame.
    pub accel_mps2: DVec3,
    /// Rotation rate, rad/s, device frame (right-handed, the device's own
    /// axes: the rate at which the device turns relative to the world).
    pub gyro_radps: DVec3,
}

impl ImuSample {
    /// Whether every field is a finite number.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.time_s.is_finite() && self.accel_mps2.is_finite() && self.gyro_radps.is_finite()
    }
}

/// Why IMU samples were refused or a rotation could not be integrated.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ImuError {
    /// A sample holds NaN or an infinity.
    #[error("IMU sample {index} (time {time_s} s) is not finite: every field must be a number")]
    NotFinite {
        /// Its position in the samples given.
        index: usize,
        /// Its time, seconds (possibly the non-finite field).
        time_s: f64,
    },
    /// A sample is earlier than the one before it (in the batch, or the
    /// last one kept from an earlier batch).
    #[error("IMU sample {index} at {time_s} s is earlier than the sample before it ({previous_s} s): samples must come in time order")]
    OutOfOrder {
        /// Its position in the samples given.
        index: usize,
        /// Its time, seconds.
        time_s: f64,
        /// The time of the sample before it, seconds.
        previous_s: f64,
    },
    /// The samples do not cover the interval asked for.
    #[error("the IMU samples ({first_s} to {last_s} s) do not cover {from_s} to {to_s} s")]
    NotCovered {
        /// Start of the interval asked for, seconds (IMU clock).
        from_s: f64,
        /// Its end, seconds.
        to_s: f64,
        /// The first sample's time (NaN when there is none), seconds.
        first_s: f64,
        /// The last sample's time (NaN when there is none), seconds.
        last_s: f64,
    },
    /// Two samples inside the interval asked for lie too far apart for
    /// the rate between them to be interpolated.
    #[error("the IMU samples have a gap of {gap_s} s at {at_s} s (at most {max_gap_s} s is interpolated)")]
    Gap {
        /// Where the gap starts, seconds.
        at_s: f64,
        /// Its length, seconds.
        gap_s: f64,
        /// The longest gap interpolated, seconds.
        max_gap_s: f64,
    },
}
