//! A camera lost for long restarts mapping in a new segment, and the
//! segment moves onto the map before it once the camera is back: the
//! synthetic room, whose truth is known, with a camera turned half round
//! at once (nothing it sees then is mapped), held there, and turned back.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::synthetic_config;
use glam::{DAffine3, DMat3};
use std::io::Cursor;
use surfel_slam::eval::ate;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{session, FrameReport, Intrinsics, Pipeline, SlamConfig, Verdict};

/// Frames mapped along the room's path before the turn.
const MAPPED: usize = 50;
/// Frames held turned half round.
const TURNED: usize = 20;
/// Frames turning back, from half round to the mapped view.
const TURNING_BACK: usize = 36;
/// Frames on along the path after.
const AFTER: usize = 20;

fn small() -> Intrinsics {
    synthetic::default_intrinsics().half()
}

/// The camera's pose at frame `i` (scene frame): along the path, then at
/// the last mapped frame's place turned `yaw` about the vertical, then
/// along the path again.
fn view(i: usize) -> DAffine3 {
    let at = |frame: usize, yaw_deg: f64| {
        let pose = synthetic::trajectory_pose(frame);
        // About the world vertical (y), through the camera centre.
        let turn = DMat3::from_rotation_y(yaw_deg.to_radians());
        DAffine3::from_mat3_translation(turn * pose.matrix3, pose.translation)
    };
    let last_mapped = MAPPED - 1;
    if i < MAPPED {
        return at(i, 0.0);
    }
    if i < MAPPED + TURNED {
        return at(last_mapped, 180.0);
    }
    let back = i - MAPPED - TURNED;
    if back < TURNING_BACK {
        let left = 1.0 - (back + 1) as f64 / TURNING_BACK as f64;
        return at(last_mapped, 180.0 * left);
    }
    at(last_mapped + back - TURNING_BACK + 1, 0.0)
}

fn frames() -> usize {
    MAPPED + TURNED + TURNING_BACK + AFTER
}

fn frame(config: &SlamConfig, scene: &Scene, i: usize) -> surfel_slam::RgbdFrame {
    let noise = NoiseModel {
        depth_sigma_at_1m: 0.0,
        ..NoiseModel::kinect()
    };
    synthetic::render(scene, &config.intrinsics, &view(i), &noise, i as u64)
        .to_frame(&config.depth)
        .expect("frame")
}

/// The frames `range` pushed into `slam`, their reports.
fn push(slam: &mut Pipeline, scene: &Scene, range: std::ops::Range<usize>) -> Vec<FrameReport> {
    let config = slam.config().clone();
    range
        .map(|i| {
            slam.push_frame(&frame(&config, scene, i), i as f64)
                .expect("push")
        })
        .collect()
}

/// Stable surfels first seen before frame `before`: (first seen, position bits).
fn stable_before(slam: &Pipeline, before: u32) -> Vec<(u32, [u32; 3])> {
    let map = slam.map();
    let stable = slam.config().fusion.stable_confidence;
    let mut out: Vec<_> = (0..map.len())
        .filter(|&i| map.first_seen()[i] < before && map.confidences()[i] >= stable)
        .map(|i| {
            (
                map.first_seen()[i],
                map.positions()[i].to_array().map(f32::to_bits),
            )
        })
        .collect();
    out.sort_unstable();
    out
}

fn config() -> SlamConfig {
    let mut config = synthetic_config(small());
    // The turn is a place never mapped: keyframes cannot place it, and
    // without them the test shows the join from where the camera was lost.
    config.relocalise.enabled = false;
    config
}

#[test]
fn a_camera_lost_for_long_maps_on_and_its_segment_moves_onto_the_map_when_it_returns() {
    let scene = Scene::room();
    let config = config();
    let restart_after = config.restart_after_lost;
    let mut slam = Pipeline::new(config).expect("config");
    let mut reports = push(&mut slam, &scene, 0..MAPPED);
    let before = stable_before(&slam, MAPPED as u32);
    assert!(before.len() > 10_000, "{} stable surfels", before.len());
    reports.extend(push(&mut slam, &scene, MAPPED..MAPPED + TURNED));
    // While the camera looks away, the map before the loss is as it was:
    // the segment was neither fused into it nor moved it.
    let kept = stable_before(&slam, MAPPED as u32);
    let missing = before
        .iter()
        .filter(|s| kept.binary_search(s).is_err())
        .count();
    assert_eq!(
        missing,
        0,
        "of {} stable surfels from before the loss",
        before.len()
    );
    assert!(slam.map().all_finite());
    reports.extend(push(&mut slam, &scene, MAPPED + TURNED..frames()));
    let verdicts: Vec<&str> = reports.iter().map(|r| r.verdict.name()).collect();
    let restart = MAPPED + restart_after as usize;
    for (i, v) in verdicts.iter().enumerate().take(restart).skip(MAPPED) {
        assert_eq!(*v, "lost", "frame {i} after the turn: {verdicts:?}");
    }
    assert_eq!(
        reports[restart].verdict,
        Verdict::Restarted,
        "frame {restart}: {verdicts:?}"
    );
    let counts = slam.counts();
    assert_eq!(counts.restarted, 1, "{verdicts:?}");
    assert_eq!(counts.lost, restart_after, "{verdicts:?}");
    assert!(slam.map().all_finite());
    // Turned back, the segment was placed from where the camera was lost,
    // and moved onto the map: every frame from the restart on is where the
    // truth says, in the map's frame (the first camera's).
    let joined: Vec<_> = reports
        .iter()
        .filter_map(|r| r.loop_outcome.joined.map(|j| (r.index, j)))
        .collect();
    assert_eq!(joined.len(), 1, "joins {joined:?}");
    let (at, join) = joined[0];
    assert_eq!(join.segment_start, restart as u32);
    assert!(join.keyframe_frame.is_none(), "{join:?}");
    assert!(join.correction.1 > 90.0, "moved only {join:?}");
    let world_from_scene = view(0).inverse();
    for (i, &(_, pose)) in slam.trajectory().iter().enumerate().skip(restart) {
        let truth = world_from_scene * view(i);
        let (dt, dr) = motion_magnitude(&(truth.inverse() * pose));
        assert!(
            dt < 0.03 && dr.to_degrees() < 2.0,
            "frame {i} ({}, joined at {at}): {dt:.3} m {:.2} deg from the truth",
            verdicts[i],
            dr.to_degrees()
        );
    }
    // After the join the camera tracks against the whole map again.
    assert!(
        verdicts[frames() - AFTER..]
            .iter()
            .all(|v| *v == "tracked" || *v == "held"),
        "{verdicts:?}"
    );
    let truth: Vec<(f64, DAffine3)> = (0..frames())
        .map(|i| (i as f64, world_from_scene * view(i)))
        .collect();
    let a = ate(slam.trajectory(), &truth, 1e-3).expect("ate");
    assert!(a.rmse_m < 0.02, "ATE {:.2} cm", a.rmse_m * 100.0);
}

#[test]
fn without_restarts_the_camera_stays_lost() {
    let scene = Scene::room();
    let mut config = config();
    config.restart_after_lost = 0;
    let mut slam = Pipeline::new(config).expect("config");
    let reports = push(&mut slam, &scene, 0..MAPPED + TURNED);
    assert!(reports[MAPPED..]
        .iter()
        .all(|r| matches!(r.verdict, Verdict::Lost(_))));
    assert_eq!(slam.counts().restarted, 0);
}

#[test]
fn a_session_saved_in_a_segment_not_yet_joined_continues_exactly() {
    let scene = Scene::room();
    let config = config();
    let save_at = MAPPED + config.restart_after_lost as usize + 5;
    let mut whole = Pipeline::new(config.clone()).expect("config");
    push(&mut whole, &scene, 0..frames());
    let mut first = Pipeline::new(config).expect("config");
    push(&mut first, &scene, 0..save_at);
    assert_eq!(first.counts().restarted, 1);
    let bytes = session::save(&first, Cursor::new(Vec::new()))
        .expect("saves")
        .into_inner();
    let mut resumed = session::load(Cursor::new(&bytes)).expect("loads");
    let reports = push(&mut resumed, &scene, save_at..frames());
    assert!(
        reports.iter().any(|r| r.loop_outcome.joined.is_some()),
        "the resumed run joined its segment"
    );
    let bits = |p: &Pipeline| -> Vec<u64> {
        p.trajectory()
            .iter()
            .flat_map(|(_, pose)| pose.to_cols_array())
            .map(f64::to_bits)
            .collect()
    };
    assert_eq!(bits(&resumed), bits(&whole), "trajectories differ");
    assert_eq!(resumed.map().len(), whole.map().len());
    assert_eq!(resumed.counts(), whole.counts());
}
