//! Real sensor noise (issue 24): structured-light depth noise (lateral
//! jitter 0.5 px, disparity noise matching Khoshelham and Elberink's
//! 1.425e-3 z^2 m, disparity quantised to 1/8 px, seeded) on
//!
//! - a synthetic far-wall scene: a 5 x 6.5 m room, the camera moving a few
//!   millimetres per frame while facing a wall 5.5-6 m away over furniture
//!   at 2-3 m;
//! - the shared ICL-NUIM frames (skipped when ../shared/data is absent).
//!
//! Each is run at default settings with the sensor's noise model
//! (structured light) and with noise weighting off (`SensorNoise::uniform`),
//! and compared with the ground truth: ATE and verdicts, and no frame fused
//! while its pose is far wrong. `SURFEL_NOISE_DETAILS=1` prints every frame.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{shared_dataset, synthetic_config};
use glam::{DAffine3, DQuat, DVec3};
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::synthetic::{self, look_at, NoiseModel, Scene, SceneBox, StructuredLight};
use surfel_slam::{FrameReport, Pipeline, RgbdFrame, SensorNoise, SlamConfig, Verdict};

struct Run {
    ate_m: f64,
    fused: usize,
    frames: usize,
    counts: String,
    /// Largest true position error of a fused frame, metres.
    worst_fused_m: f64,
}

fn details() -> bool {
    std::env::var("SURFEL_NOISE_DETAILS").is_ok_and(|v| v == "1")
}

/// Every weighting setting of the config at once.
fn with_noise(mut config: SlamConfig, noise: SensorNoise) -> SlamConfig {
    config.set_noise(noise);
    config
}

/// Pushes `frames` (with `truth`, world_from_camera per frame) and measures.
fn run(name: &str, config: SlamConfig, frames: &[RgbdFrame], truth: &[DAffine3]) -> Run {
    let mut slam = Pipeline::new(config).expect("config");
    let reports: Vec<FrameReport> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| slam.push_frame(f, i as f64).expect("push"))
        .collect();
    let gt: Vec<(f64, DAffine3)> = truth
        .iter()
        .enumerate()
        .map(|(i, p)| (i as f64, *p))
        .collect();
    let fused: Vec<(f64, DAffine3)> = reports
        .iter()
        .filter(|r| r.verdict.is_fused())
        .map(|r| (r.timestamp, r.world_from_camera))
        .collect();
    // Fewer than three fused frames: no alignment, the ATE counts as infinite.
    let (ate_m, align) = ate(&fused, &gt, 0.01).map_or((f64::INFINITY, DAffine3::IDENTITY), |a| {
        (a.rmse_m, a.ground_truth_from_estimate)
    });
    let mut worst = 0.0f64;
    for (i, r) in reports.iter().enumerate() {
        let error = (align.transform_point3(r.world_from_camera.translation)
            - truth[i].translation)
            .length();
        if r.verdict.is_fused() {
            worst = worst.max(error);
        }
        if details() {
            println!(
                "{name} #{i}: {:<18} err {:.2} cm inliers {} ratio {:.2} res {:.4} cond {:.5}",
                match r.verdict {
                    Verdict::Lost(reason) => reason.name(),
                    v => v.name(),
                },
                error * 100.0,
                r.inliers,
                r.inlier_ratio,
                r.residual_rms_m,
                r.conditioning,
            );
        }
    }
    let counts = slam.counts();
    let run = Run {
        ate_m,
        fused: fused.len(),
        frames: reports.len(),
        counts: format!(
            "{} tracked, {} recovered, {} lost",
            counts.tracked, counts.recovered, counts.lost
        ),
        worst_fused_m: worst,
    };
    eprintln!(
        "{name}: {} frames, {}, ATE {:.3} cm, worst fused frame {:.2} cm",
        run.frames,
        run.counts,
        run.ate_m * 100.0,
        run.worst_fused_m * 100.0
    );
    run
}

/// A 5 x 3 x 6.5 m room (x in -2.5..2.5, z in -0.5..6) with furniture
/// 1.8-3.2 m from the camera path near z = 0 and more against the far wall.
fn far_wall_scene() -> Scene {
    let (lo, hi) = (DVec3::new(-2.5, -3.0, -0.5), DVec3::new(2.5, 0.0, 6.0));
    Scene {
        boxes: vec![
            SceneBox::room(lo, hi, 0),
            // Table and a box on it.
            SceneBox::solid(DVec3::new(-1.0, -0.75, 1.8), DVec3::new(0.4, 0.0, 2.6), 1),
            SceneBox::solid(
                DVec3::new(-0.6, -1.05, 2.0),
                DVec3::new(-0.2, -0.75, 2.3),
                3,
            ),
            // Cabinet.
            SceneBox::solid(DVec3::new(1.2, -1.9, 2.0), DVec3::new(2.5, 0.0, 2.8), 2),
            // Pillar turned about the vertical.
            SceneBox::rotated(
                DVec3::new(-1.7, -0.6, 3.2),
                DVec3::new(0.3, 0.6, 0.35),
                DQuat::from_rotation_y(35f64.to_radians()),
                5,
            ),
            // Against the far wall.
            SceneBox::solid(DVec3::new(-2.5, -1.2, 5.0), DVec3::new(-1.5, 0.0, 6.0), 4),
            SceneBox::solid(DVec3::new(0.8, -0.8, 5.2), DVec3::new(2.0, 0.0, 6.0), 6),
        ],
    }
}

/// Slow motion facing the far wall: 3-5 mm and about 0.1 degrees per
/// frame, the camera 1.3-1.5 m above the floor, 5.5-6 m from the far wall.
fn far_wall_path(frames: usize) -> Vec<DAffine3> {
    (0..frames)
        .map(|i| {
            let t = i as f64;
            let eye = DVec3::new(
                -0.5 + 0.004 * t,
                -1.4 - 0.1 * (0.02 * t).sin(),
                0.2 + 0.2 * (0.015 * t).sin(),
            );
            let target = DVec3::new(1.2 * (0.008 * t - 0.4).sin(), -0.6, 6.0);
            look_at(eye, target)
        })
        .collect()
}

#[test]
fn far_walls_with_structured_light_noise() {
    let k = synthetic::default_intrinsics();
    let config = synthetic_config(k);
    let scene = far_wall_scene();
    let world_from_camera = far_wall_path(120);
    let origin = world_from_camera[0].inverse();
    let truth: Vec<DAffine3> = world_from_camera.iter().map(|p| origin * *p).collect();
    let noise = StructuredLight::kinect();
    let (mut clean, mut noisy) = (Vec::new(), Vec::new());
    for (i, pose) in world_from_camera.iter().enumerate() {
        let rendered = synthetic::render(&scene, &k, pose, &NoiseModel::none(), i as u64);
        let frame = rendered.to_frame(&config.depth).expect("frame");
        noisy.push(noise.measured(
            &frame,
            &rendered.depth_m,
            &k,
            (i as u64, config.depth.max_m),
        ));
        clean.push(frame);
    }
    let reference = run(
        "far walls, no noise",
        with_noise(config.clone(), SensorNoise::rendered()),
        &clean,
        &truth,
    );
    let weighted = run(
        "far walls, structured light, weighted",
        with_noise(config.clone(), SensorNoise::structured_light()),
        &noisy,
        &truth,
    );
    let unweighted = run(
        "far walls, structured light, unweighted",
        with_noise(config, SensorNoise::uniform()),
        &noisy,
        &truth,
    );
    assert!(reference.fused == reference.frames, "{}", reference.counts);
    // The noise-free run is exact to a few hundredths of a millimetre, so
    // "a small factor" of it is read as: at most 5x it or 2.5 mm.
    assert!(
        weighted.ate_m <= (5.0 * reference.ate_m).max(0.0025),
        "weighted ATE {:.3} cm against {:.3} cm without noise",
        weighted.ate_m * 100.0,
        reference.ate_m * 100.0
    );
    assert!(
        weighted.worst_fused_m <= 0.02,
        "weighted: a fused frame is {:.1} cm wrong",
        weighted.worst_fused_m * 100.0
    );
    assert!(
        weighted.fused * 10 >= weighted.frames * 9,
        "weighted: {}",
        weighted.counts
    );
    assert!(
        unweighted.ate_m > 3.0 * weighted.ate_m,
        "unweighted ATE {:.3} cm is not worse than weighted {:.3} cm",
        unweighted.ate_m * 100.0,
        weighted.ate_m * 100.0
    );
}

#[test]
fn icl_nuim_with_kinect_noise() {
    let Some(dir) = shared_dataset("icl_office_kt0") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence opens");
    let config = SlamConfig::from_preset(sequence.preset);
    let k = config.intrinsics;
    let noise = StructuredLight::kinect();
    let mut truth = Vec::new();
    let mut frames = Vec::new();
    for (i, entry) in sequence.frames.iter().enumerate() {
        let Some(gt) = sequence.ground_truth_for(entry.timestamp, 0.02) else {
            continue;
        };
        let frame = read_frame(&dir, entry, &config.depth).expect("frame decodes");
        let exact = frame.depth_m.clone();
        frames.push(noise.measured(&frame, &exact, &k, (i as u64, config.depth.max_m)));
        truth.push(gt);
    }
    // The preset's own model: what a user gets without choosing one.
    assert!(!config.fusion.noise.is_uniform());
    let weighted = run(
        "ICL-NUIM kt0 + Kinect noise, preset (weighted)",
        config.clone(),
        &frames,
        &truth,
    );
    let unweighted = run(
        "ICL-NUIM kt0 + Kinect noise, unweighted",
        with_noise(config, SensorNoise::uniform()),
        &frames,
        &truth,
    );
    assert!(
        weighted.worst_fused_m <= 0.05,
        "weighted: a fused frame is {:.1} cm wrong",
        weighted.worst_fused_m * 100.0
    );
    // Measured 0.35 cm weighted, 0.87 cm unweighted (issue 24's goal for
    // held-out noisy data: 1.5 cm).
    assert!(weighted.ate_m <= 0.005, "weighted ATE {} m", weighted.ate_m);
    assert!(
        unweighted.ate_m > 2.0 * weighted.ate_m,
        "unweighted ATE {:.3} cm is not worse than weighted {:.3} cm",
        unweighted.ate_m * 100.0,
        weighted.ate_m * 100.0
    );
}
