//! Issue #85 part 1, on the long ICL-NUIM office (the 10 Hz cut): each
//! frame pushed REPEAT times (default 1 and 3), each push with its own
//! Kinect-v1 noise draw (`--simulate-noise kinect-v1`, seed 1: the
//! pipeline draws by push number). Three pushes a frame give the tracker
//! and fusion three times the noisy frames on the same path (a step, then
//! two standing still), as a 30 Hz recording would: if each tracked and
//! fused noisy frame adds a bias, the repeated run drifts more.
//!
//! Env: DIR (another sequence), NOSIM=1 (its depth as recorded), REPEAT ("1,3"), COUNT (frames of the sequence, default all),
//! TRACKER (icp, rgb, joint), WINDOW (active window), SETTLED (settled
//! confidence), UNIFORM=1 (no noise weights), FUSION_UNIFORM=1 or
//! TRACK_UNIFORM=1 (one stage's weights off), VERBOSE=1 (every repeated
//! push more than 2 mm off its frame's first).
//! `cargo run --release --example repeat_frames`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::{Pipeline, SlamConfig};

fn main() {
    let dir = std::env::var("DIR").map_or_else(
        |_| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../shared/data/icl_office_kt0_long")
        },
        std::path::PathBuf::from,
    );
    let sequence = Sequence::open(&dir).unwrap();
    let mut config = SlamConfig::from_preset(sequence.preset);
    config.simulate_noise = Some(NoiseSimulation {
        sensor: SimulatedSensor::KinectV1,
        seed: 1,
    });
    if let Some(w) = std::env::var("WINDOW").ok().and_then(|s| s.parse().ok()) {
        config.fusion.active_window_frames = w;
    }
    if let Some(c) = std::env::var("SETTLED").ok().and_then(|s| s.parse().ok()) {
        config.fusion.settled_confidence = c;
    }
    if std::env::var_os("UNIFORM").is_some() {
        let keep = config.simulate_noise;
        config.set_noise(surfel_slam::SensorNoise::uniform());
        config.simulate_noise = keep;
    }
    // Either stage's noise weights alone off.
    if std::env::var_os("FUSION_UNIFORM").is_some() {
        config.fusion.noise = surfel_slam::SensorNoise::uniform();
    }
    if std::env::var_os("TRACK_UNIFORM").is_some() {
        config.tracker.noise = surfel_slam::SensorNoise::uniform();
    }
    if let Some(mode) = std::env::var("TRACKER")
        .ok()
        .and_then(|s| surfel_slam::track::TrackerMode::from_name(&s))
    {
        config.tracker.mode = mode;
    }
    if std::env::var_os("NOSIM").is_some() {
        config.simulate_noise = None;
    }
    let count: usize = std::env::var("COUNT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(usize::MAX);
    let repeats: Vec<usize> = std::env::var("REPEAT")
        .unwrap_or_else(|_| "1,3".into())
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    for repeat in repeats {
        let mut slam = Pipeline::new(config.clone()).unwrap();
        let mut truth = Vec::new();
        let mut pushes = 0usize;
        // Per repeated push: its pose against the frame's first push, in
        // that push's camera frame (the truth: no motion).
        let (mut sum, mut sq, mut n) = (glam::DVec3::ZERO, glam::DVec3::ZERO, 0.0);
        let mut rot_sum = glam::DVec3::ZERO;
        for e in sequence.frames.iter().take(count) {
            let Some(gt) = sequence.ground_truth_for(e.timestamp, 0.02) else {
                continue;
            };
            let frame = read_frame(&dir, e, &config.depth).unwrap();
            let mut first = None;
            for r in 0..repeat {
                // Timestamps as the sequence's (frame numbers), a third apart.
                let t = e.timestamp + r as f64 / repeat as f64;
                let report = slam.push_frame(&frame, t).unwrap();
                let pose = report.world_from_camera;
                if let Some(first) = first {
                    let d: glam::DAffine3 = glam::DAffine3::inverse(&first) * pose;
                    sum += d.translation;
                    sq += d.translation * d.translation;
                    let q = glam::DQuat::from_mat3(&d.matrix3);
                    rot_sum += glam::DVec3::new(q.x, q.y, q.z) * 2.0 * q.w.signum();
                    n += 1.0;
                    if std::env::var_os("VERBOSE").is_some() && d.translation.length() > 0.002 {
                        println!(
                            "  frame {} push {r}: ({:.1}, {:.1}, {:.1}) mm off its first push, inliers {}, conditioning {:.2e}",
                            e.index, d.translation.x * 1e3, d.translation.y * 1e3, d.translation.z * 1e3,
                            report.inliers, report.conditioning
                        );
                    }
                } else {
                    first = Some(pose);
                }
                if r + 1 == repeat {
                    truth.push((t, gt));
                }
                pushes += 1;
            }
        }
        // Only each frame's last push is scored (the truth has one pose a frame).
        let a = ate(slam.trajectory(), &truth, 0.01).unwrap();
        if n > 0.0 {
            let mean = sum / n;
            let rms = (sq / n).to_array().map(f64::sqrt);
            let rot = rot_sum / n;
            println!(
                "  repeated pushes against the first, camera frame: mean ({:.4}, {:.4}, {:.4}) mm, rms ({:.3}, {:.3}, {:.3}) mm, mean rotation ({:.5}, {:.5}, {:.5}) deg, {n} pushes",
                mean.x * 1e3, mean.y * 1e3, mean.z * 1e3, rms[0] * 1e3, rms[1] * 1e3, rms[2] * 1e3,
                rot.x.to_degrees(), rot.y.to_degrees(), rot.z.to_degrees()
            );
        }
        println!(
            "repeat {repeat}: {pushes} pushes, ATE {:.3} cm, {:?}",
            a.rmse_m * 100.0,
            slam.counts()
        );
    }
}
