//! The sparse feature matcher on the synthetic room: known wide motions
//! recovered from two rendered RGB-D views, and RANSAC's rigid fit with
//! injected wrong matches (up to 70 %), errors against the known motion.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::synthetic_config;
use glam::{DAffine3, DVec3, Vec3};
use surfel_slam::clock::now_ms;
use surfel_slam::features::{
    match_features_into, ransac_rigid, FeatureConfig, FeatureExtractor, RansacConfig,
    SparseEstimator,
};
use surfel_slam::preprocess::back_project_into;
use surfel_slam::se3::{exp, motion_magnitude};
use surfel_slam::synthetic::{self, NoiseModel, Scene};

/// Colour and camera-frame vertices of the room seen from `pose`.
fn view(pose: &DAffine3, noise: &NoiseModel, seed: u64) -> (Vec<u8>, Vec<Vec3>) {
    let k = synthetic::default_intrinsics();
    let config = synthetic_config(k);
    let frame = synthetic::render(&Scene::room(), &k, pose, noise, seed)
        .to_frame(&config.depth)
        .expect("frame");
    let mut vertices = vec![Vec3::ZERO; k.pixel_count()];
    back_project_into(&k, &frame.depth_m, &mut vertices);
    (frame.rgb, vertices)
}

/// Translation (m) and rotation (deg) error of `estimate` against `truth`.
fn error(estimate: &DAffine3, truth: &DAffine3) -> (f64, f64) {
    let (dt, dr) = motion_magnitude(&(truth.inverse() * *estimate));
    (dt, dr.to_degrees())
}

/// Runs the estimator from `reference` to `reference * motion`; returns the
/// errors, inliers and matches.
fn estimate_motion(motion: &DAffine3, noise: &NoiseModel) -> ((f64, f64), usize, usize) {
    let k = synthetic::default_intrinsics();
    let reference = synthetic::trajectory_pose(40);
    let (rgb0, v0) = view(&reference, noise, 1);
    let (rgb1, v1) = view(&(reference * *motion), noise, 2);
    let mut sparse = SparseEstimator::new(FeatureConfig::default()).expect("config");
    sparse
        .extract(&rgb0, &v0, k.width, k.height)
        .expect("extract");
    sparse.current_becomes_reference();
    let t0 = now_ms();
    sparse
        .extract(&rgb1, &v1, k.width, k.height)
        .expect("extract");
    let t1 = now_ms();
    let estimate = sparse.estimate();
    let ms = now_ms() - t0;
    eprintln!(
        "extract {:.1} ms, match+fit {:.1} ms",
        t1 - t0,
        now_ms() - t1
    );
    let estimate = estimate.expect("an estimate");
    let err = error(&estimate.reference_from_current, motion);
    eprintln!(
        "motion {:.2} m / {:.1} deg: {} features, {} matches, {} inliers, error {:.2} mm / {:.3} deg ({ms:.1} ms extract+match+fit)",
        motion_magnitude(motion).0,
        motion_magnitude(motion).1.to_degrees(),
        sparse.current().len(),
        estimate.matches,
        estimate.inliers,
        err.0 * 1000.0,
        err.1
    );
    (err, estimate.inliers, estimate.matches)
}

#[test]
fn wide_motions_are_recovered_from_two_views() {
    // Each far beyond what dense ICP converges from (a few cm / degrees).
    let motions = [
        // 30 cm sideways and forward, 10 degrees of yaw.
        exp(&[0.0, 0.17, 0.0, 0.25, 0.0, 0.15]),
        // 25 degrees of yaw and 10 cm.
        exp(&[0.05, 0.44, 0.0, 0.05, 0.05, 0.05]),
        // 40 degrees of roll about the optical axis: the descriptor must turn with the view.
        exp(&[0.0, 0.0, 0.70, 0.02, 0.0, 0.0]),
        // 50 cm backwards with a tilt.
        exp(&[0.12, 0.05, 0.0, 0.0, 0.1, -0.5]),
    ];
    for noise in [NoiseModel::none(), NoiseModel::kinect()] {
        for motion in &motions {
            let ((dt, dr), inliers, _) = estimate_motion(motion, &noise);
            assert!(inliers >= 20, "only {inliers} inliers");
            assert!(dt < 0.02, "translation error {dt} m");
            assert!(dr < 1.0, "rotation error {dr} deg");
        }
    }
}

#[test]
fn ransac_survives_up_to_seventy_percent_wrong_matches() {
    let k = synthetic::default_intrinsics();
    let reference = synthetic::trajectory_pose(40);
    let motion = exp(&[0.03, 0.2, 0.05, 0.2, -0.05, 0.1]);
    let noise = NoiseModel::kinect();
    let (rgb0, v0) = view(&reference, &noise, 1);
    let (rgb1, v1) = view(&(reference * motion), &noise, 2);
    let config = FeatureConfig::default();
    let mut extractor = FeatureExtractor::new(config).expect("config");
    let (mut f0, mut f1) = (Vec::new(), Vec::new());
    extractor
        .extract_into(&rgb0, &v0, k.width, k.height, &mut f0)
        .expect("extract");
    extractor
        .extract_into(&rgb1, &v1, k.width, k.height, &mut f1)
        .expect("extract");
    let mut matches = Vec::new();
    match_features_into(&f0, &f1, &config, &mut matches);
    // Keep only the matches the known motion confirms (within 3 cm: depth
    // noise), so that the injected ones are the only wrong ones.
    let pairs: Vec<(Vec3, Vec3)> = matches
        .iter()
        .map(|&(i, j)| (f0[i].point_in_camera, f1[j].point_in_camera))
        .filter(|(a, b)| (a.as_dvec3() - motion.transform_point3(b.as_dvec3())).length() < 0.03)
        .collect();
    assert!(pairs.len() >= 40, "only {} confirmed matches", pairs.len());
    let mut inlier = Vec::new();
    for outlier_percent in [0usize, 30, 50, 60, 70] {
        let good = pairs.len();
        let bad = good * outlier_percent / (100 - outlier_percent);
        let (mut a, mut b): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
        // Wrong matches: a reference point paired with another match's
        // current point (as a repeated texture would), at least 20 cm wrong.
        let mut s = 0usize;
        while a.len() < good + bad {
            s += 1;
            let (i, j) = ((s * 7919) % good, (s * 104_729 + 13) % good);
            let wrong = motion.transform_point3(pairs[j].1.as_dvec3());
            if (pairs[i].0.as_dvec3() - wrong).length() > 0.2 {
                a.push(pairs[i].0);
                b.push(pairs[j].1);
            }
        }
        let fit = ransac_rigid(&a, &b, &RansacConfig::default(), &mut inlier).expect("fit");
        let (dt, dr) = error(&fit.a_from_b, &motion);
        let wrong_kept = inlier[good..].iter().filter(|&&x| x).count();
        eprintln!(
            "{outlier_percent}% wrong ({good} right, {bad} wrong): error {:.2} mm / {:.3} deg, {} inliers ({wrong_kept} of them wrong)",
            dt * 1000.0,
            dr,
            fit.inliers
        );
        assert!(dt < 0.01, "{outlier_percent}%: translation error {dt} m");
        assert!(dr < 0.5, "{outlier_percent}%: rotation error {dr} deg");
        assert!(
            wrong_kept * 20 <= bad.max(1),
            "{wrong_kept} wrong matches kept"
        );
    }
}

#[test]
fn unrelated_views_give_no_estimate_or_few_inliers() {
    // Opposite walls of the room: nothing in common, so nothing may agree.
    let k = synthetic::default_intrinsics();
    let eye = DVec3::new(0.0, -1.4, 0.0);
    let one = synthetic::look_at(eye, DVec3::new(2.0, -1.0, 0.0));
    let other = synthetic::look_at(eye, DVec3::new(-2.0, -1.0, 0.0));
    let (rgb0, v0) = view(&one, &NoiseModel::none(), 1);
    let (rgb1, v1) = view(&other, &NoiseModel::none(), 2);
    let mut sparse = SparseEstimator::new(FeatureConfig::default()).expect("config");
    sparse
        .extract(&rgb0, &v0, k.width, k.height)
        .expect("extract");
    sparse.current_becomes_reference();
    sparse
        .extract(&rgb1, &v1, k.width, k.height)
        .expect("extract");
    let estimate = sparse.estimate();
    eprintln!("unrelated views: {estimate:?}");
    assert!(estimate.is_none(), "{estimate:?}");
}
