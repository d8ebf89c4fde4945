//! Loaders on the real sequences in `../shared/data` (skipped with a message
//! when that folder is absent).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::shared_dataset;
use std::path::Path;

use surfel_slam::dataset::{read_frame, DatasetKind, Sequence};
use surfel_slam::CameraPreset;

fn check_first_frame(dir: &Path, sequence: &Sequence, min_valid_fraction: f64) {
    let settings = sequence.preset.depth_settings();
    let frame = read_frame(dir, &sequence.frames[0], &settings).expect("first frame decodes");
    assert_eq!((frame.width, frame.height), (640, 480));
    assert_eq!(frame.rgb.len(), 640 * 480 * 3);
    let valid = frame.valid_depth_count() as f64 / (640.0 * 480.0);
    assert!(
        valid > min_valid_fraction,
        "only {valid:.3} of the pixels have depth"
    );
    let mean = frame
        .depth_m
        .iter()
        .filter(|d| **d > 0.0)
        .map(|d| f64::from(*d))
        .sum::<f64>()
        / frame.valid_depth_count() as f64;
    assert!(
        (0.3..8.0).contains(&mean),
        "mean depth {mean} m is implausible"
    );
}

#[test]
fn tum_fr3_teddy() {
    let Some(dir) = shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("opens");
    assert_eq!(sequence.kind, DatasetKind::Tum);
    assert_eq!(sequence.preset, CameraPreset::TumFr3);
    // 200 colour and 200 depth images, but 7 colour images have no depth
    // within 0.02 s: TUM's associate.py pairs 193 (checked independently).
    assert_eq!(sequence.frames.len(), 193);
    assert!(sequence
        .frames
        .windows(2)
        .all(|w| w[0].timestamp < w[1].timestamp));
    assert!(sequence
        .frames
        .iter()
        .enumerate()
        .all(|(i, f)| f.index == i));
    assert!(!sequence.ground_truth.is_empty());
    // Ground truth starts after the first ~4 frames.
    assert!(sequence
        .ground_truth_for(sequence.frames[0].timestamp, 0.02)
        .is_none());
    let with_gt = sequence
        .frames
        .iter()
        .filter(|f| sequence.ground_truth_for(f.timestamp, 0.02).is_some())
        .count();
    assert_eq!(with_gt, 189, "all but the first 4 frames have ground truth");
    check_first_frame(&dir, &sequence, 0.5);
}

#[test]
fn icl_office_kt0() {
    let Some(dir) = shared_dataset("icl_office_kt0") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("opens");
    assert_eq!(sequence.kind, DatasetKind::IclNuim);
    assert_eq!(sequence.preset, CameraPreset::IclNuim);
    assert!(sequence.preset.intrinsics().fy < 0.0);
    assert_eq!(sequence.frames.len(), 150);
    assert_eq!(sequence.frames[0].timestamp, 1.0);
    assert_eq!(sequence.ground_truth.len(), 149);
    assert!(sequence.ground_truth_for(1.0, 0.0).is_none());
    assert!(sequence.ground_truth_for(2.0, 0.0).is_some());
    check_first_frame(&dir, &sequence, 0.95);
}
