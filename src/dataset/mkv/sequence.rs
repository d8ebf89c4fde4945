//! An Azure Kinect recording as a [`Sequence`]: one [`FrameEntry`] per
//! depth frame, named by its track and time, the depth mode's pinhole
//! intrinsics, millimetres.

use crate::camera::{CameraPreset, Intrinsics};
use crate::dataset::{DatasetError, DatasetKind, FrameEntry, Sequence};

use super::AzureRecording;

/// The sequence of `recording` in the file `path` (named in its
/// warnings): kind [`DatasetKind::AzureKinect`], preset `realsense-d400`
/// (its depth range and noise; there is no Azure Kinect preset yet), the
/// depth camera's intrinsics, depth scale 1000 (millimetres).
#[must_use]
pub fn sequence_of<R>(recording: &AzureRecording<R>, path: &str) -> Sequence {
    let frames = recording
        .frames
        .iter()
        .enumerate()
        .map(|(index, f)| FrameEntry {
            index,
            timestamp: f.time_s,
            colour: f
                .colour
                .map(|c| format!("COLOR at {:.6} s", c.time_ns as f64 * 1e-9)),
            depth: format!("DEPTH at {:.6} s", f.time_s),
            confidence: None,
            calibrated_size: None,
            pose_file: None,
            missing: None,
        })
        .collect();
    let d = &recording.depth;
    Sequence {
        kind: DatasetKind::AzureKinect,
        preset: CameraPreset::RealSenseD400,
        intrinsics: Some(Intrinsics::new(
            d.fx as f32,
            d.fy as f32,
            d.cx as f32,
            d.cy as f32,
            d.width,
            d.height,
        )),
        depth_scale: Some(1000.0),
        frames,
        ground_truth: Vec::new(),
        odometry: Vec::new(),
        // The IMU track is not read yet.
        imu: Vec::new(),
        warnings: recording
            .warnings
            .iter()
            .map(|w| DatasetError::Mkv {
                path: path.to_owned(),
                source: w.clone(),
            })
            .collect(),
    }
}
