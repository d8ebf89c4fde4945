//! A recording as a [`Sequence`]: one [`FrameEntry`] per depth frame,
//! named by its topic and stamp (the names errors give), the depth
//! camera's intrinsics and the recording's depth scale.

use crate::camera::CameraPreset;
use crate::dataset::{DatasetError, DatasetKind, FrameEntry, Sequence};

use super::Recording;

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
    let colour_topic = recording.colour.as_ref().map(|(t, _)| t.as_str());
    let frames = recording
        .frames
        .iter()
        .enumerate()
        .map(|(index, f)| FrameEntry {
            index,
            timestamp: f.time_s,
            colour: colour_topic
                .zip(f.colour)
                .map(|(topic, (t, _))| frame_name(topic, t)),
            depth: frame_name(&recording.depth_topic, f.time_s),
            confidence: None,
            calibrated_size: None,
            pose_file: None,
            missing: None,
        })
        .collect();
    let d = &recording.depth;
    Sequence {
        kind: DatasetKind::RealSenseBag,
        preset: CameraPreset::RealSenseD400,
        intrinsics: Some(d.intrinsics()),
        depth_scale: Some((1.0 / recording.depth_units_m) as f32),
        frames,
        ground_truth: Vec::new(),
        odometry: Vec::new(),
        warnings: recording
            .warnings
            .iter()
            .map(|w| DatasetError::Rosbag {
                path: path.to_owned(),
                source: w.clone(),
            })
            .collect(),
    }
}
