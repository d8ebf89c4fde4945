//! Issue #85 part 1: does the same camera path drift more when tracked at
//! every frame (30 Hz) than at every third (10 Hz), under simulated
//! Kinect-v1 noise? The synthetic room walked along `trajectory_pose`
//! (30 Hz, 1-1.4 cm a frame), each frame's noise drawn from its own frame
//! number so that both rates see the same draws of the frames they share.
//!
//! Env: FRAMES (30 Hz frames, default 900), STRIDES ("1,3"), FULL=1 (640x480,
//! default 320x240), CLEAN=1 (no noise), and one switch per candidate:
//! PRIOR=0 (no motion prior), SETTLED=c (fusion's settled confidence),
//! UNIFORM=1 (no noise weights in tracking or fusion), WINDOW=n (active
//! window), JOINT=1 (the joint tracker, ICL-NUIM's; the default here is
//! TUM's ICP). Prints ATE, the final position error
//! and the true error at quarters of the path.
//!
//! `cargo run --release --example frame_rate_drift`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::eval::ate;
use surfel_slam::noise::SensorNoise;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::synthetic::{self, trajectory_pose, NoiseModel, Scene};
use surfel_slam::{CameraPreset, Pipeline, SlamConfig};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

fn main() {
    let frames: usize = env("FRAMES").unwrap_or(900);
    let strides: Vec<usize> = std::env::var("STRIDES")
        .unwrap_or_else(|_| "1,3".into())
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    let full = std::env::var_os("FULL").is_some();
    let k = if full {
        synthetic::default_intrinsics()
    } else {
        synthetic::default_intrinsics().half()
    };
    let mut config = SlamConfig::from_preset(CameraPreset::TumFr3);
    config.intrinsics = k;
    config.depth = synthetic::depth_settings();
    config.set_noise(SensorNoise::simulated_kinect());
    if let Some(m) = env::<f32>("MAXD") {
        config.depth.max_m = m;
    }
    if env::<u32>("PRIOR") == Some(0) {
        config.tracker.motion_prior.enabled = false;
    }
    if let Some(c) = env::<f32>("SETTLED") {
        config.fusion.settled_confidence = c;
    }
    if std::env::var_os("UNIFORM").is_some() {
        config.set_noise(SensorNoise::uniform());
    }
    if let Some(w) = env::<u32>("WINDOW") {
        config.fusion.active_window_frames = w;
    }
    if std::env::var_os("JOINT").is_some() {
        config.tracker.mode = surfel_slam::track::TrackerMode::Joint;
    }
    let clean = std::env::var_os("CLEAN").is_some();
    let iid = std::env::var_os("IID").is_some();
    let frame_times = std::env::var_os("FRAME_TIMES").is_some();
    let simulation = NoiseSimulation {
        sensor: SimulatedSensor::KinectV1,
        seed: 1,
    };
    let scene = Scene::room();
    let origin = trajectory_pose(0).inverse();
    for stride in strides {
        let mut slam = Pipeline::new(config.clone()).unwrap();
        let mut gt = Vec::new();
        let mut errs = Vec::new();
        let mut depth = Vec::new();
        for i in (0..frames).step_by(stride) {
            let pose = trajectory_pose(i);
            let model = if iid {
                NoiseModel::kinect()
            } else {
                NoiseModel::none()
            };
            let mut frame = synthetic::render(&scene, &k, &pose, &model, i as u64)
                .to_frame(&config.depth)
                .unwrap();
            if !clean && !iid {
                // At 320x240 the disparity noise of a 640-wide Kinect (its focal
                // length): the depth noise a Kinect has, on half the pixels.
                let focal = if full { k.fx } else { 2.0 * k.fx };
                simulation.apply_into(&frame.depth_m, k.width, focal, i as u64, &mut depth);
                for z in &mut depth {
                    *z = if *z > config.depth.max_m {
                        0.0
                    } else {
                        (*z * 5000.0).round() / 5000.0
                    };
                }
                frame.depth_m.clone_from(&depth);
            }
            // FRAME_TIMES=1: timestamps that are frame numbers, as ICL-NUIM's
            // (no motion prior, the interval is over its limit).
            let t = if frame_times {
                i as f64
            } else {
                i as f64 / 30.0
            };
            let r = slam.push_frame(&frame, t).unwrap();
            let truth = origin * pose;
            let err = (truth.translation - r.world_from_camera.translation).length();
            if std::env::var_os("EVERY").is_some() && i % 30 == 0 {
                println!(
                    "{i}: {:?} inliers {} error {:.2} cm",
                    r.verdict,
                    r.inliers,
                    err * 100.0
                );
            }
            if std::env::var_os("VERBOSE").is_some()
                && (errs
                    .last()
                    .map_or(0.0, |e: &(usize, f64)| (err - e.1).abs())
                    > 0.01
                    || i < 3)
            {
                println!(
                    "{i}: {:?} inliers {} rms {:.4} valid {}",
                    r.verdict,
                    r.inliers,
                    r.residual_rms_m,
                    frame.depth_m.iter().filter(|z| **z > 0.0).count()
                );
            }
            gt.push((t, truth));
            errs.push((
                i,
                (truth.translation - r.world_from_camera.translation).length(),
            ));
        }
        let a = ate(slam.trajectory(), &gt, 0.01).map_or(f64::NAN, |a| a.rmse_m);
        let quarters: Vec<String> = (1..=4)
            .map(|q| {
                let idx = (errs.len() * q / 4).saturating_sub(1);
                format!("{:.2}", errs[idx].1 * 100.0)
            })
            .collect();
        let counts = slam.counts();
        println!(
            "stride {stride}: {} frames, ATE {:.3} cm, error at quarters {} cm, {:?}",
            errs.len(),
            a * 100.0,
            quarters.join(" / "),
            counts
        );
    }
}
