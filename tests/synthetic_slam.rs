//! Exact-answer tests on the synthetic room: ICP against a known motion,
//! fusion of a static view, and the whole pipeline against the known trajectory.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{lost_count, run_synthetic, synthetic_config};
use glam::DVec3;
use surfel_slam::eval::ate;
use surfel_slam::se3::{exp, motion_magnitude};
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{Pipeline, Verdict};

fn small_intrinsics() -> surfel_slam::Intrinsics {
    synthetic::default_intrinsics().half()
}

#[test]
fn icp_recovers_a_known_motion() {
    let k = small_intrinsics();
    let scene = Scene::room();
    let config = synthetic_config(k);
    let start = synthetic::trajectory_pose(30);
    // 3 cm and ~2 degrees: larger than a frame of handheld motion.
    let motion = exp(&[0.02, -0.025, 0.01, 0.02, -0.01, 0.02]);
    let moved = start * motion;
    let mut slam = Pipeline::new(config.clone()).expect("config");
    for (i, pose) in [start, moved].iter().enumerate() {
        let f = synthetic::render(&scene, &k, pose, &NoiseModel::none(), 1)
            .to_frame(&config.depth)
            .expect("frame");
        let report = slam.push_frame(&f, i as f64).expect("push");
        if i == 1 {
            assert_eq!(report.verdict, Verdict::Tracked);
            let error = motion.inverse() * report.world_from_camera;
            let (dt, dr) = motion_magnitude(&error);
            assert!(dt < 1e-3, "translation error {dt} m");
            assert!(
                dr.to_degrees() < 0.05,
                "rotation error {} deg",
                dr.to_degrees()
            );
        }
    }
}

#[test]
fn fusing_a_static_noisy_view_converges_to_the_surface() {
    let k = small_intrinsics();
    let scene = Scene::room();
    let config = synthetic_config(k);
    let pose = synthetic::trajectory_pose(0);
    let noise = NoiseModel::kinect();
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let surface_error = |points: &mut dyn Iterator<Item = DVec3>| {
        let (mut sum2, mut n) = (0.0, 0usize);
        for p in points {
            let d = scene.distance_to_surface(pose.transform_point3(p));
            sum2 += d * d;
            n += 1;
        }
        (sum2 / n.max(1) as f64).sqrt()
    };
    let mut single_frame_rms = 0.0;
    for i in 0..20u64 {
        let f = synthetic::render(&scene, &k, &pose, &noise, 100 + i)
            .to_frame(&config.depth)
            .expect("frame");
        if i == 0 {
            let raw = surfel_slam::preprocess::FramePyramid::new(&k, &config.preprocess);
            let mut raw = raw;
            raw.build(&f, &config.preprocess, &config.tracker.noise);
            single_frame_rms = surface_error(
                &mut raw.levels[0]
                    .vertices
                    .iter()
                    .filter(|p| p.z > 0.0)
                    .map(|p| p.as_dvec3()),
            );
        }
        let r = slam.push_frame(&f, i as f64).expect("push");
        assert_ne!(r.verdict.name(), "lost", "static frame {i} lost");
    }
    let map = slam.map();
    let stable: Vec<usize> = (0..map.len())
        .filter(|&i| map.confidences()[i] >= config.fusion.stable_confidence)
        .collect();
    assert!(
        stable.len() > k.pixel_count() / 4,
        "only {} stable surfels",
        stable.len()
    );
    let fused_rms = surface_error(&mut stable.iter().map(|&i| map.positions()[i].as_dvec3()));
    assert!(
        fused_rms < 0.5 * single_frame_rms && fused_rms < 0.003,
        "fused surfels {fused_rms:.5} m from the surface vs {single_frame_rms:.5} m for one frame"
    );
    assert!(map.all_finite());
}

#[test]
fn settled_surfels_are_no_longer_moved_by_merges() {
    let k = small_intrinsics();
    let scene = Scene::room();
    let pose = synthetic::trajectory_pose(0);
    // Surfels of confidence >= 3 before the 10th view of a static noisy
    // scene, and how many of them that view moved. No cleanup runs between
    // (it renumbers surfels), the next one being at frame 10.
    let moved_by_tenth_view = |settled_confidence: f32| {
        let mut config = synthetic_config(k);
        config.fusion.settled_confidence = settled_confidence;
        let mut slam = Pipeline::new(config.clone()).expect("config");
        let mut before = Vec::new();
        for i in 0..10u64 {
            let map = slam.map();
            before = (0..map.len())
                .filter(|&s| map.confidences()[s] >= 3.0)
                .map(|s| (s, map.positions()[s]))
                .collect();
            let f = synthetic::render(&scene, &k, &pose, &NoiseModel::kinect(), 200 + i)
                .to_frame(&config.depth)
                .expect("frame");
            let r = slam.push_frame(&f, i as f64).expect("push");
            assert_ne!(r.verdict.name(), "lost", "static frame {i} lost");
        }
        let map = slam.map();
        assert!(map.all_finite());
        let moved = before
            .iter()
            .filter(|&&(s, p)| map.positions()[s] != p)
            .count();
        (before.len(), moved)
    };
    let (settled, moved) = moved_by_tenth_view(3.0);
    assert!(
        settled > k.pixel_count() / 4,
        "only {settled} settled surfels"
    );
    assert_eq!(moved, 0, "{moved} of {settled} settled surfels moved");
    let (merging, moved) = moved_by_tenth_view(f32::INFINITY);
    assert!(
        moved > merging / 2,
        "without the limit only {moved} of {merging} surfels moved"
    );
}

#[test]
fn pipeline_follows_the_known_trajectory_noise_free() {
    let (slam, reports, truth) = run_synthetic(small_intrinsics(), 60, NoiseModel::none());
    assert_eq!(lost_count(&reports), 0);
    let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
    assert!(a.rmse_m < 0.002, "ATE {} m", a.rmse_m);
}

#[test]
fn pipeline_follows_the_known_trajectory_with_kinect_noise() {
    let (slam, reports, truth) = run_synthetic(small_intrinsics(), 60, NoiseModel::kinect());
    assert_eq!(lost_count(&reports), 0);
    let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
    // Depth noise here is 1.2 mm * z^2 per pixel, white, at 1.1-4.7 m: up to
    // 2.6 cm, far more than teddy's 1-2 m. Frames 11-21 view a wall and the
    // floor: with the free direction solved they stepped ~1 cm a frame the
    // wrong way, reported tracked (ATE 1.4 cm); held at the feature
    // estimate, which is itself ~1 cm off a frame at this noise, they are
    // reported held and the ATE is 2.1 cm.
    assert!(a.rmse_m < 0.025, "ATE {} m", a.rmse_m);
    assert!(slam.map().all_finite());
}

#[test]
fn a_frame_without_depth_is_lost_and_leaves_the_map_alone() {
    let k = small_intrinsics();
    let scene = Scene::room();
    let config = synthetic_config(k);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let frame = |i: usize| {
        synthetic::render(
            &scene,
            &k,
            &synthetic::trajectory_pose(i),
            &NoiseModel::none(),
            0,
        )
        .to_frame(&config.depth)
        .expect("frame")
    };
    for i in 0..3 {
        slam.push_frame(&frame(i), i as f64).expect("push");
    }
    let surfels = slam.map().len();
    let mut blank = frame(3);
    blank.depth_m.iter_mut().for_each(|d| *d = 0.0);
    let r = slam.push_frame(&blank, 3.0).expect("push");
    assert!(matches!(r.verdict, Verdict::Lost(_)), "{:?}", r.verdict);
    assert_eq!(slam.map().len(), surfels);
    assert!(slam.push_png(b"garbage", b"garbage", 4.0).is_err());
    assert_eq!(slam.map().len(), surfels);
    let r = slam.push_frame(&frame(4), 4.0).expect("push");
    assert_eq!(r.verdict, Verdict::Recovered);
}

#[test]
fn revisiting_the_same_views_does_not_grow_the_map() {
    // Kinect-like noise, played back and forth over 12 poses: after the first
    // passes the surfaces are mapped, so later passes must merge into the
    // map, not pile up duplicates that turn stable. Measured at 320x240:
    // 35 k stable surfels after two passes, 47 k after eight, 123 k in all;
    // without absorbing redundant surfels, with the 3-D cover test and
    // unstable surfels kept 20 frames it was 52 k, 97 k and 305 k. Without noise the stable count is flat after
    // three passes either way. (Noise here reaches 2.6 cm on the far wall.)
    let k = small_intrinsics();
    let scene = Scene::room();
    let config = synthetic_config(k);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let noise = NoiseModel::kinect();
    let stable = |slam: &Pipeline| {
        let map = slam.map();
        (0..map.len())
            .filter(|&i| map.confidences()[i] >= config.fusion.stable_confidence)
            .count()
    };
    let mut after_two_passes = 0;
    let passes = 8;
    for pass in 0..passes {
        for step in 0..12 {
            let i = if pass % 2 == 0 { step } else { 11 - step };
            let f = synthetic::render(
                &scene,
                &k,
                &synthetic::trajectory_pose(i),
                &noise,
                (pass * 12 + step) as u64,
            )
            .to_frame(&config.depth)
            .expect("frame");
            let r = slam
                .push_frame(&f, (pass * 12 + step) as f64)
                .expect("push");
            assert_ne!(r.verdict.name(), "lost", "pass {pass} step {step} lost");
        }
        if pass == 1 {
            after_two_passes = stable(&slam);
        }
    }
    let last = stable(&slam);
    let all = slam.map().len();
    assert!(
        all < 5 * k.pixel_count() / 2,
        "{all} surfels for {} pixels",
        k.pixel_count()
    );
    assert!(
        (last as f64) < 1.5 * after_two_passes as f64,
        "stable surfels grew from {after_two_passes} after two passes to {last} after {passes}"
    );
    assert!(slam.map().all_finite());
}

#[test]
fn fusion_visits_what_the_camera_sees_not_the_whole_map() {
    // A full turn around the room, every second pose of the known trajectory
    // (2 to 3 cm and 1 to 2 degrees a frame): each view sees about a quarter of
    // the walls, and the map grows as the turn reveals the rest. Fusion must
    // visit the blocks in view only, so its work stays that of one view.
    // Measured at 320x240: 65 k surfels visited at frame 30, at most 68 k
    // over the last 20 frames of a 221 k map. Without sorting settled
    // surfels in space, or with 4096-surfel boxes, it was 111 k or 88 k; with
    // neither (boxes over creation order only), 125 k of 223 k.
    // Loop closure off: the turn ends where it began, and the closure there
    // (frame 272, 6.5 mm) rightly reactivates the first view's surfels,
    // which fusion then visits beside the new copy until they merge (57 k
    // -> 95 k visited); that is the closure's cost, not culling's.
    let k = small_intrinsics();
    let scene = Scene::room();
    let mut config = synthetic_config(k);
    config.loop_closure.enabled = false;
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut early = None;
    let mut late = Vec::new();
    let frames = 285;
    for i in 0..frames {
        let f = synthetic::render(
            &scene,
            &k,
            &synthetic::trajectory_pose(2 * i),
            &NoiseModel::none(),
            i as u64,
        )
        .to_frame(&config.depth)
        .expect("frame");
        let r = slam.push_frame(&f, i as f64).expect("push");
        assert_ne!(r.verdict.name(), "lost", "frame {i} lost");
        // Fusion visits array slots, absorbed surfels awaiting compaction
        // included: compare with the arrays' length, not the live count.
        if i == 30 {
            early = Some((r.fusion.visited, r.surfel_slots));
        }
        if i >= frames - 20 {
            late.push((r.fusion.visited, r.surfel_slots));
        }
    }
    let (early_visited, early_map) = early.expect("frame 30");
    let late_visited = late.iter().map(|v| v.0).max().unwrap_or(usize::MAX);
    let late_map = late.iter().map(|v| v.1).min().unwrap_or(0);
    assert!(
        late_map > 2 * early_map,
        "the map did not grow: {early_map} -> {late_map}"
    );
    assert!(
        (late_visited as f64) < 0.4 * late_map as f64,
        "fusion visited {late_visited} of {late_map} surfels"
    );
    assert!(
        (late_visited as f64) < 1.25 * early_visited as f64,
        "fusion visited {early_visited} surfels at frame 30 and {late_visited} at the end"
    );
}
