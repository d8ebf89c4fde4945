//! A stretch of a real sequence with exact ground truth, run through the
//! pipeline and judged as the issue on two-plane views judges it: the ATE,
//! the lost frames, and every frame called `tracked` whose motion since the
//! last fused frame is off the truth's by more than 1 cm or 1 degree.

use glam::DAffine3;
use std::ops::Range;
use std::path::Path;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::{Pipeline, SlamConfig, Verdict};

/// What a run of frames showed against the truth.
pub struct TruthRun {
    pub ate_cm: f64,
    /// Frames called tracked whose motion since the last fused frame is
    /// off the truth's by more than 1 cm or 1 degree: (frame, cm, degrees).
    pub dishonest: Vec<(usize, f64, f64)>,
    pub held: usize,
    pub lost: usize,
}

/// Runs `frames` of `sequence` (read from `dir`) with `config`.
pub fn run_frames(
    sequence: &Sequence,
    dir: &Path,
    config: SlamConfig,
    frames: Range<usize>,
) -> TruthRun {
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    let mut last_fused: Option<(DAffine3, DAffine3)> = None;
    let (mut dishonest, mut held, mut lost) = (Vec::new(), 0, 0);
    for entry in sequence.frames.iter().skip(frames.start).take(frames.len()) {
        let frame = read_frame(dir, entry, &config.depth).expect("frame decodes");
        let report = slam
            .push_frame(&frame, entry.timestamp)
            .expect("frame accepted");
        let truth = sequence
            .ground_truth_for(entry.timestamp, 0.02)
            .expect("exact truth for every frame");
        let pose = report.world_from_camera;
        if let (Verdict::Tracked, Some((before, truth_before))) = (report.verdict, last_fused) {
            let error = (truth_before.inverse() * truth).inverse() * (before.inverse() * pose);
            let (dt, dr) = motion_magnitude(&error);
            if dt > 0.01 || dr.to_degrees() > 1.0 {
                dishonest.push((entry.index, dt * 100.0, dr.to_degrees()));
            }
        }
        held += usize::from(report.verdict == Verdict::Held);
        lost += usize::from(matches!(report.verdict, Verdict::Lost(_)));
        if report.verdict.is_fused() {
            last_fused = Some((pose, truth));
        }
    }
    let ate_cm = ate(slam.trajectory(), &sequence.ground_truth, 0.02)
        .expect("poses match the truth")
        .rmse_m
        * 100.0;
    TruthRun {
        ate_cm,
        dishonest,
        held,
        lost,
    }
}
