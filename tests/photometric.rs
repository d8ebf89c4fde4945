//! Direct (photometric) and joint tracking on the synthetic room: a known
//! motion recovered from colour alone, and joint mode against the better of
//! the two single terms.

mod common;

use common::{lost_count, run_synthetic_with, synthetic_config};
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
