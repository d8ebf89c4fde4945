//! Global loop closure end to end (issue #21, item 4a): a loop whose drift
//! at the return is beyond the local check's limit is closed from the
//! keyframes, right against the known truth; a repetitive scene and frames
//! of other places spliced in close no loop. The real sequences:
//! `real_loops.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::synthetic_config;
use glam::{DAffine3, DVec3};
use surfel_slam::eval::ate;
use surfel_slam::loop_closure::global::GlobalClosure;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::synthetic::{
    self, look_at, loop_pose, NoiseModel, Scene, SceneBox, ROOM_MAX, ROOM_MIN,
};
use surfel_slam::{FrameReport, Intrinsics, Pipeline, SlamConfig};

/// One frame to render: the scene, the true pose (`world_from_camera` in
/// the scene) and the intrinsics it is rendered with.
struct Shot {
    scene: Scene,
    pose: DAffine3,
    k: Intrinsics,
}

struct Run {
    slam: Pipeline,
    reports: Vec<FrameReport>,
    /// True pose of each frame in the pipeline's world (the first camera's
    /// frame), `None` for frames spliced in.
    truth: Vec<Option<DAffine3>>,
}

impl Run {
    fn truth_pairs(&self) -> Vec<(f64, DAffine3)> {
        self.truth
            .iter()
            .enumerate()
            .filter_map(|(i, t)| t.map(|t| (i as f64, t)))
            .collect()
    }

    fn ate_m(&self) -> f64 {
        let estimate: Vec<_> = self
            .slam
            .trajectory()
            .iter()
            .enumerate()
            .filter(|(i, _)| self.truth[*i].is_some())
            .map(|(_, p)| *p)
            .collect();
        ate(&estimate, &self.truth_pairs(), 0.01)
            .expect("ate")
            .rmse_m
    }

    fn global(&self) -> impl Iterator<Item = (usize, GlobalClosure)> + '_ {
        self.reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.loop_outcome.global.map(|g| (i, g)))
    }

    fn global_closures(&self) -> usize {
        self.global().filter(|(_, g)| g.closed).count()
    }

    /// Every global match (bent or not) registered the frame within 2 cm
    /// and 1 degree of its true pose, and nearer than the tracker had it.
    fn assert_global_matches_right(&self) {
        for (i, g) in self.global() {
            let truth = self.truth[i].expect("a global match on a spliced frame");
            let off = |p: &DAffine3| {
                let (dt, dr) = motion_magnitude(&(truth.inverse() * *p));
                (dt, dr.to_degrees())
            };
            let (registered, tracked) = (off(&g.registered), off(&g.tracked));
            println!(
                "  global match at frame {i} with keyframe {}: correction {:.2} cm {:.2} deg, \
                 closed {} (pose only {}, {} old surfels active again), {:.2} ms; tracked {:.2} cm {:.2} deg, \
                 registered {:.2} cm {:.2} deg off the truth",
                g.keyframe_frame,
                g.correction_m * 100.0,
                g.correction_deg,
                g.closed,
                g.pose_only,
                self.reports[i].loop_outcome.reactivated,
                self.reports[i].timings.loop_ms,
                tracked.0 * 100.0,
                tracked.1,
                registered.0 * 100.0,
                registered.1
            );
            assert!(
                registered.0 < 0.02 && registered.1 < 1.0,
                "frame {i}: a wrong global match, {registered:?} off the truth"
            );
            assert!(
                registered.0 < tracked.0,
                "frame {i}: the match moved away from the truth"
            );
            // The next frames are tracked against the old surfels the
            // frame sees, whether the map was bent or the pose alone moved.
            assert!(
                !g.closed || self.reports[i].loop_outcome.reactivated > 0,
                "frame {i}: a closure left the old surfels inactive"
            );
        }
    }
}

fn run(config: &SlamConfig, frames: usize, shot: impl Fn(usize) -> (Shot, bool)) -> Run {
    run_on(Pipeline::new(config.clone()).expect("config"), frames, shot)
}

/// [`run`] on a pipeline that may have run before (its config renders).
fn run_on(mut slam: Pipeline, frames: usize, shot: impl Fn(usize) -> (Shot, bool)) -> Run {
    let config = slam.config().clone();
    let mut origin_inv = None;
    let (mut reports, mut truth) = (Vec::new(), Vec::new());
    for i in 0..frames {
        let (s, spliced) = shot(i);
        let frame = synthetic::render(&s.scene, &s.k, &s.pose, &NoiseModel::none(), i as u64)
            .to_frame(&config.depth)
            .expect("frame");
        reports.push(slam.push_frame(&frame, i as f64).expect("push"));
        let origin = *origin_inv.get_or_insert_with(|| s.pose.inverse());
        truth.push((!spliced).then_some(origin * s.pose));
    }
    Run {
        slam,
        reports,
        truth,
    }
}

/// The synthetic settings of the loop tests: a 30-frame active window,
/// global looks every 5 frames at keyframes at least 60 frames old.
fn loop_config(global: bool) -> SlamConfig {
    let mut config = synthetic_config(synthetic::default_intrinsics().half());
    config.fusion.active_window_frames = 30;
    let g = &mut config.loop_closure.global;
    g.enabled = global;
    g.min_age_frames = 60;
    g.every_frames = 5;
    g.cooldown_frames = 60;
    config
}

/// The loop, 240 frames a turn, for 280 frames; frames 30..200 are taken
/// with a focal length 3 % longer than the one the pipeline is given (a
/// calibration that drifts for a stretch): the map of that stretch is
/// distorted and the path drifts 21 cm by the return, beyond the local
/// check's limit (0.15 m).
fn drifting_loop(global: bool) -> Run {
    let config = loop_config(global);
    run(&config, 280, drifting_shot(&config))
}

/// Frame `i` of [`drifting_loop`] for `config`.
fn drifting_shot(config: &SlamConfig) -> impl Fn(usize) -> (Shot, bool) + '_ {
    |i| {
        let mut k = config.intrinsics;
        if (30..200).contains(&i) {
            k.fx /= 1.03;
            k.fy /= 1.03;
        }
        let shot = Shot {
            scene: Scene::room(),
            pose: loop_pose(i, 240),
            k,
        };
        (shot, false)
    }
}

fn map_error_of(run: &Run) -> synthetic::MapError {
    synthetic::map_error(
        &Scene::room(),
        run.slam.map().positions(),
        &loop_pose(0, 240),
    )
}

/// Error of pose 240 relative to pose 0 (the same view), metres.
fn end_error(run: &Run) -> f64 {
    let t = run.slam.trajectory();
    motion_magnitude(&(t[0].1.inverse() * t[240].1)).0
}

#[test]
fn a_drift_beyond_the_local_limit_is_closed_globally() {
    let (local, global) = (drifting_loop(false), drifting_loop(true));
    let (local_map, global_map) = (map_error_of(&local), map_error_of(&global));
    println!(
        "synthetic loop, fx +3 % on frames 30..200: ATE {:.2} -> {:.2} cm; pose 240 vs 0 {:.2} -> {:.2} cm; \
         map error rms {:.2} -> {:.2} cm, within 1 cm {:.1} -> {:.1} %; closures {} -> {} ({} global)",
        local.ate_m() * 100.0,
        global.ate_m() * 100.0,
        end_error(&local) * 100.0,
        end_error(&global) * 100.0,
        local_map.rms_m * 100.0,
        global_map.rms_m * 100.0,
        local_map.within_1cm * 100.0,
        global_map.within_1cm * 100.0,
        local.slam.loop_closures(),
        global.slam.loop_closures(),
        global.global_closures(),
    );
    global.assert_global_matches_right();
    assert_eq!(common::lost_count(&global.reports), 0);
    assert_eq!(local.global().count(), 0);
    assert!(
        end_error(&local) > 0.15,
        "the drift ({} m) is not beyond the local limit",
        end_error(&local)
    );
    assert!(global.global_closures() >= 1, "no global closure");
    assert!(end_error(&global) <= 0.2 * end_error(&local));
    assert!(global.ate_m() <= 0.8 * local.ate_m());
    assert!(
        global_map.rms_m <= 0.8 * local_map.rms_m,
        "{global_map:?} vs {local_map:?}"
    );
    assert!(global.slam.map().all_finite());
}

/// A reset after a global closure (280 frames, past every cleanup and the
/// cooldown) forgets the closure counts, and the same frames pushed again
/// close the same loop and give the same trajectory.
#[test]
fn a_reset_after_a_global_closure_starts_clean() {
    let first = drifting_loop(true);
    let closures = (
        first.slam.loop_closures(),
        first.slam.global_loop_closures(),
    );
    assert!(closures.1 >= 1, "no global closure to forget");
    assert_eq!(closures.1 as usize, first.global_closures());
    let mut slam = first.slam;
    slam.reset();
    assert_eq!((slam.loop_closures(), slam.global_loop_closures()), (0, 0));
    assert_eq!((slam.frames(), slam.map().len()), (0, 0));
    let config = slam.config().clone();
    let again = run_on(slam, 280, drifting_shot(&config));
    assert_eq!(
        (
            again.slam.loop_closures(),
            again.slam.global_loop_closures()
        ),
        closures
    );
    let worst = first
        .reports
        .iter()
        .zip(&again.reports)
        .map(|(a, b)| (a.world_from_camera.translation - b.world_from_camera.translation).length())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-3,
        "poses differ by up to {worst} m after the reset"
    );
    assert!(again.slam.map().all_finite());
}

/// A recording that ends where it began, a few frames after the last
/// scheduled look: `finish` looks its last frame up and closes the loop
/// there; a second call does nothing, and frames pushed after it are
/// tracked from the corrected pose.
#[test]
fn the_last_frame_of_a_recording_is_looked_up_whatever_the_schedule() {
    let mut config = loop_config(true);
    // No scheduled look reaches the return (frame 240).
    config.loop_closure.global.every_frames = 1000;
    let mut fresh = Pipeline::new(config.clone()).expect("config");
    assert!(!fresh.finish().global_looked, "looked with no frame");
    let mut run = run(&config, 241, drifting_shot(&config));
    assert_eq!(run.global().count(), 0, "a scheduled look ran");
    let before = end_error(&run);
    let outcome = run.slam.finish();
    let after = end_error(&run);
    println!(
        "pose 240 vs 0 {:.2} -> {:.2} cm, ATE {:.2} cm, match (keyframe, m, pose only) {:?}",
        before * 100.0,
        after * 100.0,
        run.ate_m() * 100.0,
        outcome
            .global
            .map(|g| (g.keyframe_frame, g.correction_m, g.pose_only))
    );
    assert!(before > 0.15, "no drift to close ({before} m)");
    assert!(outcome.global_looked && outcome.closed, "{outcome:?}");
    assert!(after <= 0.2 * before, "{after} m after, {before} m before");
    assert_eq!(run.slam.global_loop_closures(), 1);
    assert!(
        !run.slam.finish().global_looked,
        "the last frame looked up twice"
    );
    assert!(run.slam.map().all_finite());
    // The recording goes on after all.
    let (shot, _) = drifting_shot(&config)(241);
    let frame = synthetic::render(&shot.scene, &shot.k, &shot.pose, &NoiseModel::none(), 241)
        .to_frame(&config.depth)
        .expect("frame");
    let report = run.slam.push_frame(&frame, 241.0).expect("push");
    let truth = loop_pose(0, 240).inverse() * shot.pose;
    let (dt, _) = motion_magnitude(&(truth.inverse() * report.world_from_camera));
    assert!(report.verdict.is_fused(), "{:?}", report.verdict);
    assert!(dt < 0.02, "frame 241 {dt} m off after the finish");
    run.slam.reset();
    assert!(!run.slam.finish().global_looked, "looked after a reset");
}

/// The room with a row of identical boxes (one material) 0.7 m apart along
/// the +z wall: each looks like its neighbours, less than the largest
/// correction (1 m) away.
fn repeated_boxes() -> Scene {
    let mut boxes = vec![SceneBox::room(ROOM_MIN, ROOM_MAX, 0)];
    for j in -3..=3 {
        let x = 0.7 * f64::from(j);
        boxes.push(SceneBox::solid(
            DVec3::new(x - 0.2, -0.8, 2.3),
            DVec3::new(x + 0.2, 0.0, 2.8),
            1,
        ));
    }
    Scene { boxes }
}

#[test]
fn a_repetitive_scene_closes_no_global_loop() {
    // Along the row once, never back: every older keyframe of a box is of
    // another box, as alike as the rendering can make it.
    let mut config = loop_config(true);
    config.loop_closure.global.every_frames = 1;
    let run = run(&config, 280, |i| {
        let x = -2.1 + 0.015 * i as f64;
        let eye = DVec3::new(x, -1.4, 0.4);
        let shot = Shot {
            scene: repeated_boxes(),
            pose: look_at(
                eye,
                DVec3::new(x + 0.2 * (0.05 * i as f64).sin(), -0.4, 2.7),
            ),
            k: config.intrinsics,
        };
        (shot, false)
    });
    let looks = run
        .reports
        .iter()
        .filter(|r| r.loop_outcome.global_looked)
        .count();
    println!(
        "repetitive row: {looks} global looks, {} matches, ATE {:.3} cm",
        run.global().count(),
        run.ate_m() * 100.0
    );
    run.assert_global_matches_right();
    assert!(looks >= 200, "{looks} looks");
    assert_eq!(run.global().count(), 0);
    assert_eq!(run.slam.loop_closures(), 0);
}

#[test]
fn frames_of_other_places_spliced_in_close_no_global_loop() {
    // The loop without drift, looked up every frame with the smallest
    // correction lowered to 1 cm; frames of the far side of the room and
    // of another room spliced in after the camera came back.
    let mut config = loop_config(true);
    let g = &mut config.loop_closure.global;
    g.every_frames = 1;
    g.min_correction_m = 0.01;
    g.min_correction_deg = 0.5;
    let spliced = |i: usize| (225..228).contains(&i) || (250..253).contains(&i);
    let run = run(&config, 270, |i| {
        let shot = if (225..228).contains(&i) {
            Shot {
                scene: Scene::room(),
                pose: loop_pose(i - 120, 240),
                k: config.intrinsics,
            }
        } else if (250..253).contains(&i) {
            Shot {
                scene: repeated_boxes(),
                pose: loop_pose(i, 240),
                k: config.intrinsics,
            }
        } else {
            Shot {
                scene: Scene::room(),
                pose: loop_pose(i, 240),
                k: config.intrinsics,
            }
        };
        (shot, spliced(i))
    });
    let looks = run
        .reports
        .iter()
        .filter(|r| r.loop_outcome.global_looked)
        .count();
    println!(
        "spliced frames: {looks} global looks, {} matches, ATE {:.3} cm",
        run.global().count(),
        run.ate_m() * 100.0
    );
    for (i, r) in run.reports.iter().enumerate().filter(|(i, _)| spliced(*i)) {
        assert!(
            r.loop_outcome.global.is_none(),
            "spliced frame {i} matched {:?}",
            r.loop_outcome.global
        );
    }
    run.assert_global_matches_right();
    assert!(run.ate_m() < 0.005, "ATE {} m", run.ate_m());
}

/// The loop under Kinect-like noise for 290 frames (`examples/noisy_loop`
/// on main: the tracker slides on the planar walls from frame ~62 and
/// ends about 38 cm off, every frame reported tracked).
fn noisy_loop(global: bool) -> Run {
    loop_run(&loop_config(global), 290, 240, &NoiseModel::kinect())
}

/// `frames` frames of the synthetic room's loop at `per_loop` frames a
/// turn, rendered with `config`'s intrinsics and `noise`, pushed into a
/// new pipeline with `config`; truth in the first camera's frame.
fn loop_run(config: &SlamConfig, frames: usize, per_loop: usize, noise: &NoiseModel) -> Run {
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let scene = Scene::room();
    let origin_inv = loop_pose(0, per_loop).inverse();
    let (mut reports, mut truth) = (Vec::new(), Vec::new());
    for i in 0..frames {
        let pose = loop_pose(i, per_loop);
        let frame = synthetic::render(&scene, &config.intrinsics, &pose, noise, i as u64)
            .to_frame(&config.depth)
            .expect("frame");
        reports.push(slam.push_frame(&frame, i as f64).expect("push"));
        truth.push(Some(origin_inv * pose));
    }
    Run {
        slam,
        reports,
        truth,
    }
}

/// Error of the last pose against the truth, metres.
fn last_error(run: &Run) -> f64 {
    let (Some((_, estimate)), Some(Some(truth))) = (run.slam.trajectory().last(), run.truth.last())
    else {
        return f64::INFINITY;
    };
    motion_magnitude(&(truth.inverse() * *estimate)).0
}

#[test]
fn the_slide_of_the_noisy_loop_is_closed_globally() {
    let (open, closed) = (noisy_loop(false), noisy_loop(true));
    let (open_map, closed_map) = (map_error_of(&open), map_error_of(&closed));
    println!(
        "noisy loop: ATE {:.2} -> {:.2} cm; last pose {:.2} -> {:.2} cm off; map error rms {:.2} -> {:.2} cm, \
         within 1 cm {:.1} -> {:.1} %; {} global closures",
        open.ate_m() * 100.0,
        closed.ate_m() * 100.0,
        last_error(&open) * 100.0,
        last_error(&closed) * 100.0,
        open_map.rms_m * 100.0,
        closed_map.rms_m * 100.0,
        open_map.within_1cm * 100.0,
        closed_map.within_1cm * 100.0,
        closed.global_closures()
    );
    closed.assert_global_matches_right();
    assert!(closed.slam.map().all_finite());
    if last_error(&open) < 0.15 {
        // The tracker no longer slides here: nothing beyond the local
        // check's reach to close; the global check must not make it worse.
        println!("the open loop ends within 15 cm: no slide to close");
        assert!(closed.ate_m() <= open.ate_m() * 1.05 + 1e-4);
        return;
    }
    assert!(closed.global_closures() >= 1, "no global closure");
    assert!(last_error(&closed) <= 0.1 * last_error(&open));
    assert!(closed.ate_m() < open.ate_m());
    assert!(
        closed_map.rms_m < open_map.rms_m,
        "{closed_map:?} vs {open_map:?}"
    );
}

/// The synthetic room circled `circles` times at 500 frames a circle,
/// rendered at 640x480 with the Kinect-v1 recipe (seed 1), tracked and
/// fused at half size with the ICL-NUIM preset, as
/// `examples/ten_circles.rs` runs it; loop closure on or off.
fn noisy_circles(circles: usize, loop_closure: bool) -> Run {
    use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
    let k = synthetic::default_intrinsics();
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::IclNuim);
    config.intrinsics = k;
    config.half_resolution = true;
    config.depth = synthetic::depth_settings();
    config.simulate_noise = Some(NoiseSimulation {
        sensor: SimulatedSensor::KinectV1,
        seed: 1,
    });
    config.loop_closure.enabled = loop_closure;
    loop_run(&config, circles * 500, 500, &NoiseModel::none())
}

/// Issue #50 (loop closure judged on exact truth), a measurement of about
/// four minutes: `cargo test --release --test global_loop -- --ignored
/// --nocapture six_noisy_circles`. Tracked from 80x60, tracking slid 4-5 cm
/// on single frames where a circle starts and the global check put them
/// back; tracked from 160x120 (`SlamConfig::working_levels`) nothing
/// slides: 0.075 cm without loop closure, 0.078 cm with, no global
/// closure. So: every global match, if any, moves the pose toward the
/// truth, and loop closure costs at most 0.01 cm (bending the map for a
/// slide once gave 1.36 cm against 0.40 cm without).
#[test]
#[ignore = "a measurement: 6000 frames rendered and tracked"]
fn six_noisy_circles_end_nearer_the_truth_with_loop_closure() {
    let (open, closed) = (noisy_circles(6, false), noisy_circles(6, true));
    println!(
        "six noisy circles: ATE {:.3} cm without loop closure, {:.3} cm with ({} global closures, {} pose only); \
         {} -> {} surfels",
        open.ate_m() * 100.0,
        closed.ate_m() * 100.0,
        closed.global().count(),
        closed.global().filter(|(_, g)| g.pose_only).count(),
        open.slam.map().len(),
        closed.slam.map().len()
    );
    closed.assert_global_matches_right();
    assert!(closed.ate_m() <= open.ate_m() + 1e-4);
}
