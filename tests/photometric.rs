//! Direct (photometric) and joint tracking on the synthetic room: a known
//! motion recovered from colour alone, and joint mode against the better of
//! the two single terms.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{lost_count, run_synthetic_seeded, synthetic_config};
use surfel_slam::eval::ate;
use surfel_slam::se3::{exp, motion_magnitude};
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::track::TrackerMode;
use surfel_slam::{Pipeline, Verdict};

fn small_intrinsics() -> surfel_slam::Intrinsics {
    synthetic::default_intrinsics().half()
}

fn recover_known_motion(mode: TrackerMode) -> (f64, f64) {
    let k = small_intrinsics();
    let scene = Scene::room();
    let mut config = synthetic_config(k);
    config.tracker.mode = mode;
    let start = synthetic::trajectory_pose(30);
    // 2 cm and ~1.3 degrees: a fast handheld frame-to-frame motion.
    let motion = exp(&[0.012, -0.015, 0.008, 0.012, -0.008, 0.012]);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut errors = (f64::NAN, f64::NAN);
    for (i, pose) in [start, start * motion].iter().enumerate() {
        let f = synthetic::render(&scene, &k, pose, &NoiseModel::none(), 1)
            .to_frame(&config.depth)
            .expect("frame");
        let report = slam.push_frame(&f, i as f64).expect("push");
        if i == 1 {
            assert_eq!(report.verdict, Verdict::Tracked, "{}", mode.name());
            let (dt, dr) = motion_magnitude(&(motion.inverse() * report.world_from_camera));
            errors = (dt, dr.to_degrees());
        }
    }
    errors
}

#[test]
fn photometric_alone_recovers_a_known_motion() {
    let (dt, dr) = recover_known_motion(TrackerMode::Rgb);
    eprintln!("rgb: {:.3} mm, {:.4} deg", dt * 1000.0, dr);
    assert!(dt < 1e-3, "translation error {dt} m");
    assert!(dr < 0.05, "rotation error {dr} deg");
}

#[test]
fn joint_recovers_a_known_motion() {
    let (dt, dr) = recover_known_motion(TrackerMode::Joint);
    eprintln!("joint: {:.3} mm, {:.4} deg", dt * 1000.0, dr);
    assert!(dt < 1e-3, "translation error {dt} m");
    assert!(dr < 0.05, "rotation error {dr} deg");
}

/// ATE (m) and lost frames of `mode` on the synthetic room, 60 frames,
/// the noise drawn from `seed`.
fn synthetic_ate(mode: TrackerMode, noise: NoiseModel, seed: u64) -> (f64, usize) {
    let mut config = synthetic_config(small_intrinsics());
    config.tracker.mode = mode;
    let (slam, reports, truth) = run_synthetic_seeded(config, 60, noise, seed);
    assert!(slam.map().all_finite());
    let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
    (a.rmse_m, lost_count(&reports))
}

fn joint_is_never_worse(noise: NoiseModel, label: &str) {
    let [icp, rgb, joint] = [TrackerMode::Icp, TrackerMode::Rgb, TrackerMode::Joint]
        .map(|mode| synthetic_ate(mode, noise, 0));
    eprintln!(
        "{label}: ATE icp {:.3} mm ({} lost), rgb {:.3} mm ({} lost), joint {:.3} mm ({} lost)",
        icp.0 * 1e3,
        icp.1,
        rgb.0 * 1e3,
        rgb.1,
        joint.0 * 1e3,
        joint.1
    );
    assert_eq!(joint.1, 0, "joint lost frames");
    let better = icp.0.min(rgb.0);
    // 5 % or 0.05 mm of slack: "not worse" up to run-to-run float noise.
    assert!(
        joint.0 <= better * 1.05 + 5e-5,
        "joint {} m vs better single term {} m",
        joint.0,
        better
    );
}

#[test]
fn joint_is_never_worse_than_the_better_term_noise_free() {
    joint_is_never_worse(NoiseModel::none(), "noise-free");
}

/// With noise, one draw can favour either single term by chance; what
/// joint tracking promises is to be as good as the better one over draws:
/// its mean ATE over `SEEDS` noise realisations within 5 % of the mean of
/// each draw's better single term, and no frame lost.
#[test]
#[ignore = "fails on every draw: over 4 draws joint 3.9-6.3 mm (mean 5.2) against rgb 3.3-4.7 mm (mean 4.0) and icp 15.6-31.8 mm; under i.i.d. Kinect-like depth noise the joint weighting lets the depth term's slide in (issue #32)"]
fn joint_is_as_good_as_the_better_term_over_kinect_noise_draws() {
    const SEEDS: [u64; 4] = [0, 1_000, 2_000, 3_000];
    let noise = NoiseModel::kinect();
    let (mut joint_sum, mut better_sum) = (0.0, 0.0);
    for seed in SEEDS {
        let [icp, rgb, joint] = [TrackerMode::Icp, TrackerMode::Rgb, TrackerMode::Joint]
            .map(|mode| synthetic_ate(mode, noise, seed));
        eprintln!(
            "kinect noise, seed {seed}: ATE icp {:.3} mm, rgb {:.3} mm, joint {:.3} mm ({} lost)",
            icp.0 * 1e3,
            rgb.0 * 1e3,
            joint.0 * 1e3,
            joint.1
        );
        assert_eq!(joint.1, 0, "joint lost frames with seed {seed}");
        joint_sum += joint.0;
        better_sum += icp.0.min(rgb.0);
    }
    let n = SEEDS.len() as f64;
    let (joint, better) = (joint_sum / n, better_sum / n);
    eprintln!(
        "mean: joint {:.3} mm, better term {:.3} mm",
        joint * 1e3,
        better * 1e3
    );
    assert!(
        joint <= better * 1.05 + 5e-5,
        "joint {joint} m vs better single term {better} m, means over the draws"
    );
}
