//! A recording as a [`Sequence`]: one [`FrameEntry`] per depth frame,
//! named by its topic and stamp (the names errors give), the depth
//! camera's intrinsics and the recording's depth scale.

use crate::camera::CameraPreset;
use crate::dataset::{DatasetError, DatasetKind, FrameEntry, Sequence};

use super::{ImuSample, Recording};
use glam::DVec3;

/// How a frame's image is named in a [`FrameEntry`] (and so in errors):
/// its topic and stamp, seconds.
#[must_use]
pub fn frame_name(topic: &str, time_s: f64) -> String {
    format!("{topic} at {time_s:.6} s")
}

/// The sequence of `recording` in the bag `path` (named in its warnings):
/// kind [`DatasetKind::RealSenseBag`], preset `realsense-d400`, the depth
/// camera's intrinsics, depth scale `1 / depth units`; a frame without a
/// paired colour image has no [`FrameEntry::colour`].
#[must_use]
pub fn sequence_of(recording: &Recording, path: &str) -> Sequence {
    let mut sequence = frames_of(recording, DatasetKind::RealSenseBag);
    sequence.warnings = recording
        .warnings
        .iter()
        .map(|w| DatasetError::Rosbag {
            path: path.to_owned(),
            source: w.clone(),
        })
        .collect();
    sequence
}

/// The sequence of `recording` as `kind`, without its warnings (each
/// recording format names its own file in them).
#[must_use]
pub(crate) fn frames_of<L>(recording: &Recording<L>, kind: DatasetKind) -> Sequence {
    let colour_topic = recording.colour.as_ref().map(|(t, _)| t.as_str());
    let frames = recording
        .frames
        .iter()
        .enumerate()
        .map(|(index, f)| FrameEntry {
            index,
            timestamp: f.time_s,
            colour: colour_topic
                .zip(f.colour.as_ref())
                .map(|(topic, (t, _))| frame_name(topic, *t)),
            depth: frame_name(&recording.depth_topic, f.time_s),
            confidence: None,
            calibrated_size: None,
            pose_file: None,
            missing: None,
        })
        .collect();
    let d = &recording.depth;
    Sequence {
        kind,
        preset: CameraPreset::RealSenseD400,
        intrinsics: Some(d.intrinsics()),
        depth_scale: Some((1.0 / recording.depth_units_m) as f32),
        frames,
        ground_truth: Vec::new(),
        odometry: Vec::new(),
        imu: merged_imu(&recording.imu),
        warnings: Vec::new(),
    }
}

/// The bag's IMU streams as the pipeline takes them: one sample at each
/// gyro stamp, with the accelerometer (a stream of its own, at its own
/// rate) interpolated linearly between its stamps and held beyond them;
/// empty unless the recording has both.
fn merged_imu(samples: &[ImuSample]) -> Vec<crate::imu::ImuSample> {
    let mut accel: Vec<(f64, DVec3)> = samples
        .iter()
        .filter_map(|s| Some((s.time_s, DVec3::from_array(s.accel_mps2?))))
        .collect();
    let mut gyro: Vec<(f64, DVec3)> = samples
        .iter()
        .filter_map(|s| Some((s.time_s, DVec3::from_array(s.gyro_radps?))))
        .collect();
    accel.sort_by(|a, b| a.0.total_cmp(&b.0));
    gyro.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (Some(&first), Some(&last)) = (accel.first(), accel.last()) else {
        return Vec::new();
    };
    let accel_at = |t: f64| {
        let after = accel.partition_point(|a| a.0 <= t);
        match (
            after.checked_sub(1).and_then(|i| accel.get(i)),
            accel.get(after),
        ) {
            (Some(&(t0, a0)), Some(&(t1, a1))) if t1 > t0 => a0.lerp(a1, (t - t0) / (t1 - t0)),
            (None, _) => first.1,
            (_, None) => last.1,
            (Some(&(_, a0)), Some(_)) => a0,
        }
    };
    gyro.iter()
        .map(|&(time_s, gyro_radps)| crate::imu::ImuSample {
            time_s,
            accel_mps2: accel_at(time_s),
            gyro_radps,
        })
        .collect()
}

#[cfg(test)]
mod imu_tests {
    use super::*;

    #[test]
    fn the_accelerometer_is_read_at_the_gyro_stamps() {
        let a = |t: f64, x: f64| ImuSample {
            time_s: t,
            accel_mps2: Some([x, 0.0, 0.0]),
            gyro_radps: None,
        };
        let g = |t: f64| ImuSample {
            time_s: t,
            accel_mps2: None,
            gyro_radps: Some([0.0, 0.0, t]),
        };
        let merged = merged_imu(&[g(0.5), a(1.0, 1.0), g(1.5), a(2.0, 3.0), g(2.5)]);
        let x: Vec<f64> = merged.iter().map(|s| s.accel_mps2.x).collect();
        assert_eq!(x, vec![1.0, 2.0, 3.0]);
        assert!(merged.iter().all(|s| s.gyro_radps.z == s.time_s));
        assert!(merged_imu(&[g(0.5), g(1.0)]).is_empty());
    }
}
