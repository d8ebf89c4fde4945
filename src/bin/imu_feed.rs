//! `run`'s IMU: the recording's samples handed to the pipeline a little
//! ahead of each frame (as a live device delivers them), and the line
//! printed once the pipeline has calibrated the IMU from the frames it
//! tracked (or, at the end, why it could not).

use surfel_slam::imu::ImuSample;
use surfel_slam::Pipeline;

/// Seconds of samples pushed beyond a frame's timestamp: the IMU's clock
/// may run up to `imu::MAX_OFFSET_S` (0.1 s) either way, and the
/// calibration integrates a little beyond each frame pair.
const LEAD_S: f64 = 0.25;

/// The samples not yet pushed, and what was printed.
pub struct ImuFeed<'a> {
    samples: &'a [ImuSample],
    /// The first sample not yet pushed.
    next: usize,
    /// The calibration line was printed.
    announced: bool,
    /// A push was refused: the rest are not pushed.
    refused: bool,
}

impl<'a> ImuFeed<'a> {
    /// The feed of `samples` (IMU clock, seconds) for frames from
    /// `first_frame_s` on: older samples are never pushed.
    pub fn new(samples: &'a [ImuSample], first_frame_s: f64) -> Self {
        let next = samples.partition_point(|s| s.time_s < first_frame_s - LEAD_S);
        Self {
            samples,
            next,
            announced: false,
            refused: false,
        }
    }

    /// Pushes the samples up to [`LEAD_S`] past `timestamp` (seconds). A
    /// refused batch is named on stderr, and the IMU then left out.
    pub fn before_frame(&mut self, slam: &mut Pipeline, timestamp: f64) {
        if self.refused || self.next >= self.samples.len() {
            return;
        }
        let rest = &self.samples[self.next..];
        let count = rest.partition_point(|s| s.time_s <= timestamp + LEAD_S);
        if let Err(e) = slam.push_imu(&rest[..count]) {
            eprintln!("warning: imu: {e}; the IMU is not used from here on");
            self.refused = true;
        }
        self.next += count;
    }

    /// The line to print once the pipeline has calibrated the IMU (once).
    pub fn announcement(&mut self, slam: &Pipeline, frame: usize) -> Option<String> {
        if self.announced {
            return None;
        }
        let calibration = slam.imu_calibration()?;
        self.announced = true;
        let (axis, angle) = calibration.rotation_axis_angle_deg();
        Some(format!(
            "imu: {}, camera from imu rotation (axis {:.3}, {:.3}, {:.3}; {angle:.2} deg), time offset {:.1} ms (calibrated at frame {frame} from {} frame pairs; sigma {:.2} deg, {:.1} ms)",
            rate(slam),
            axis.x,
            axis.y,
            axis.z,
            calibration.time_offset_ms(),
            calibration.pairs,
            calibration.rotation_sigma_rad.to_degrees(),
            calibration.offset_sigma_s * 1000.0,
        ))
    }

    /// At the end of a run with samples that never calibrated: why.
    pub fn closing(&self, slam: &Pipeline) -> Option<String> {
        if self.announced || self.samples.is_empty() {
            return None;
        }
        let why = slam
            .imu_refusal()
            .map_or_else(|| "too few frames tracked".to_owned(), ToString::to_string);
        Some(format!("imu: {}, not calibrated: {why}", rate(slam)))
    }
}

/// The samples' rate as printed.
fn rate(slam: &Pipeline) -> String {
    slam.imu_rate_hz()
        .map_or_else(|| "rate unknown".to_owned(), |hz| format!("{hz:.0} Hz"))
}
