//! Helpers shared by the integration tests: synthetic sequences and the real
//! datasets in ../shared/data (skipped with a message when absent).

#![allow(dead_code)]

pub mod revisit;
pub mod run_bits;
pub mod truth_run;

use glam::DAffine3;
use std::path::{Path, PathBuf};
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{FrameReport, Intrinsics, Pipeline, SlamConfig, Verdict};

/// A real dataset folder under ../shared/data, or `None` (with a message)
/// when absent; panics when absent and `CI=true`.
pub fn shared_dataset(name: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name);
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var("CI").is_ok_and(|v| v == "true") {
        // CI has shared/ beside the checkout: a missing sequence there is a
        // broken setup, not a reason to pass without testing.
        panic!("{} not found and CI=true", dir.display());
    } else {
        eprintln!(
            "skipping: {} not found (../shared/data is absent)",
            dir.display()
        );
        None
    }
}

/// Config for synthetic frames rendered with `k` (5000 units/m, 0.3..8 m).
pub fn synthetic_config(k: Intrinsics) -> SlamConfig {
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = k;
    config.depth = synthetic::depth_settings();
    config
}

/// Runs the synthetic room along its known trajectory; returns the pipeline,
/// the reports and the ground truth expressed in the first camera's frame
/// (the pipeline's world).
pub fn run_synthetic(
    k: Intrinsics,
    frames: usize,
    noise: NoiseModel,
) -> (Pipeline, Vec<FrameReport>, Vec<(f64, DAffine3)>) {
    run_synthetic_with(synthetic_config(k), frames, noise)
}

/// [`run_synthetic`] with a caller-adjusted config (from [`synthetic_config`]).
pub fn run_synthetic_with(
    config: SlamConfig,
    frames: usize,
    noise: NoiseModel,
) -> (Pipeline, Vec<FrameReport>, Vec<(f64, DAffine3)>) {
    run_synthetic_seeded(config, frames, noise, 0)
}

/// [`run_synthetic_with`] with frame `i`'s noise drawn from seed
/// `seed + i` (another realisation of the same noise per `seed`).
pub fn run_synthetic_seeded(
    config: SlamConfig,
    frames: usize,
    noise: NoiseModel,
    seed: u64,
) -> (Pipeline, Vec<FrameReport>, Vec<(f64, DAffine3)>) {
    let k = config.intrinsics;
    let scene = Scene::room();
    let poses = synthetic::trajectory(frames);
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    let origin_inv = poses[0].inverse();
    let mut reports = Vec::new();
    let mut truth = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        let rendered = synthetic::render(&scene, &k, pose, &noise, seed + i as u64);
        let frame = rendered.to_frame(&config.depth).expect("frame");
        reports.push(slam.push_frame(&frame, i as f64).expect("push"));
        truth.push((i as f64, origin_inv * *pose));
    }
    (slam, reports, truth)
}

/// Runs a real dataset folder through the pipeline with its preset.
pub fn run_dataset(dir: &Path) -> (Pipeline, Sequence, Vec<FrameReport>) {
    run_dataset_with(dir, |_| {})
}

/// [`run_dataset`] with the preset's configuration changed by `adjust`.
pub fn run_dataset_with(
    dir: &Path,
    adjust: impl FnOnce(&mut SlamConfig),
) -> (Pipeline, Sequence, Vec<FrameReport>) {
    let sequence = Sequence::open(dir).expect("sequence opens");
    let mut config = SlamConfig::from_preset(sequence.preset);
    adjust(&mut config);
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    let reports = sequence
        .frames
        .iter()
        .map(|entry| {
            let frame = read_frame(dir, entry, &config.depth).expect("frame decodes");
            slam.push_frame(&frame, entry.timestamp)
                .expect("frame accepted")
        })
        .collect();
    (slam, sequence, reports)
}

/// Number of reports judged lost.
pub fn lost_count(reports: &[FrameReport]) -> usize {
    reports
        .iter()
        .filter(|r| matches!(r.verdict, Verdict::Lost(_)))
        .count()
}

/// A scratch directory, removed on drop.
pub struct Scratch(pub PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// An empty scratch directory named after this test process and `name`.
pub fn scratch(name: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("surfel-slam-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    Scratch(dir)
}
