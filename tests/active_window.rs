//! Time in the map (issue #21, item 1): surfels not updated for
//! `FusionConfig::active_window_frames` are inactive. Tracking and fusion
//! read only the active ones; inactive ones stay in the map and the PLY, and
//! can be rendered on their own (what loop closure registers against).
//!
//! The synthetic room, noise-free, from a camera that turns in place away
//! from its first view and back: the first view's surfaces are out of sight
//! for longer than a short window, so on the return they are inactive.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::synthetic_config;
use glam::{DAffine3, Vec3};
use std::collections::HashSet;
use surfel_slam::eval::ate;
use surfel_slam::fusion::{FusionConfig, Measured, Prediction};
use surfel_slam::mesh::write_surfel_ply;
use surfel_slam::preprocess::FramePyramid;
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{Intrinsics, Pipeline, SlamConfig, SurfelMap};

/// Frames held at the start pose, and half the turn (out, then back).
const HOLD: usize = 5;
const HALF_TURN: usize = 70;
/// The turn's widest angle: beyond the 62 degree field of view plus margin,
/// so nothing of the first view stays in sight at the far end.
const TURN_DEG: f64 = 120.0;

fn intrinsics() -> Intrinsics {
    synthetic::default_intrinsics().half()
}

/// Pose `i` of the turn: the trajectory's first pose, turned about the
/// vertical through the camera by 0 -> -TURN_DEG -> 0 (a smooth cosine),
/// held still for `HOLD` frames at both ends. Turned the other way, the far
/// end faces a bare wall and ICP slips 5 cm along it.
fn turn_pose(i: usize) -> DAffine3 {
    let start = synthetic::trajectory_pose(0);
    let t = i.saturating_sub(HOLD).min(2 * HALF_TURN) as f64;
    let angle =
        TURN_DEG.to_radians() * 0.5 * (1.0 - (std::f64::consts::PI * t / HALF_TURN as f64).cos());
    DAffine3::from_translation(start.translation)
        * DAffine3::from_rotation_y(-angle)
        * DAffine3::from_mat3(start.matrix3)
}

fn turn_frames() -> usize {
    2 * HOLD + 2 * HALF_TURN
}

/// The window alone, or with loop closure, which on the return registers
/// the active model against the inactive one and reactivates what matched.
fn config(window: u32, loop_closure: bool) -> SlamConfig {
    let mut config = synthetic_config(intrinsics());
    config.fusion.active_window_frames = window;
    config.loop_closure.enabled = loop_closure;
    // Noise-free, ICP solves even the turn's weakest views exactly; held at
    // the motion prior they are less exact, and the return then closes the
    // difference (one bend). These tests are about what the window does to
    // the map, on exact tracking: nothing held.
    config.tracker.hold_below_eigenvalue = 0.0;
    // What the window alone does: copies are not merged (see
    // `the_copy_laid_on_the_return_is_merged_into_the_first_one`).
    config.fusion.merge_copies_after_frames = 0;
    config
}

/// Plays the turn (frames `0..frames`); checks every frame tracked and the
/// trajectory against the truth, so that what the map shows is fusion's
/// doing, not a tracking failure.
fn run_turn(window: u32, loop_closure: bool, frames: usize) -> Pipeline {
    run_turn_with(&config(window, loop_closure), frames)
}

/// [`run_turn`] with `config`.
fn run_turn_with(config: &SlamConfig, frames: usize) -> Pipeline {
    let window = config.fusion.active_window_frames;
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let origin = turn_pose(0).inverse();
    let mut truth = Vec::new();
    for i in 0..frames {
        let pose = turn_pose(i);
        let frame = synthetic::render(&scene, &intrinsics(), &pose, &NoiseModel::none(), i as u64)
            .to_frame(&config.depth)
            .expect("frame");
        let report = slam.push_frame(&frame, i as f64).expect("push");
        assert!(
            report.verdict.is_fused(),
            "window {window}, frame {i}: {:?}",
            report.verdict
        );
        truth.push((i as f64, origin * pose));
    }
    let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
    assert!(
        a.rmse_m < 0.01,
        "window {window}: ATE {:.2} cm",
        a.rmse_m * 100.0
    );
    slam
}

/// Live surfels (not absorbed) satisfying `f(i)`.
fn count(map: &SurfelMap, f: impl Fn(usize) -> bool) -> usize {
    (0..map.len())
        .filter(|&i| map.confidences()[i] >= 0.0 && f(i))
        .count()
}

/// Whether world point `p` lies in the first camera's view (the world frame
/// is the first camera's frame).
fn in_first_view(p: Vec3) -> bool {
    let k = intrinsics();
    p.z > 0.3 && k.pixel_index(k.project(p)).is_some()
}

#[test]
fn a_surface_seen_again_after_the_window_gets_a_second_copy_and_the_first_stays() {
    let frames = turn_frames();
    let last = frames as u32 - 1;
    let back = (HOLD + 2 * HALF_TURN) as u32;
    // Twenty frames: far less than the time the first view is out of sight.
    let short = run_turn(20, false, frames);
    let long = run_turn(u32::MAX, false, frames);
    let (s, l) = (short.map(), long.map());

    // Surfels made at the start and in the first view.
    let early = |m: &SurfelMap, i: usize| {
        m.first_seen()[i] < HOLD as u32 && in_first_view(m.positions()[i])
    };
    let early_short = count(s, |i| early(s, i));
    let early_long = count(l, |i| early(l, i));
    // ... updated again when the camera is back.
    let early_updated_short = count(s, |i| early(s, i) && s.last_seen()[i] >= back);
    let early_updated_long = count(l, |i| early(l, i) && l.last_seen()[i] >= back);
    // New surfels in the first view made on the way back.
    let late_copy = |m: &SurfelMap, i: usize| {
        m.first_seen()[i] >= HALF_TURN as u32 && in_first_view(m.positions()[i])
    };
    let copies_short = count(s, |i| late_copy(s, i));
    let copies_long = count(l, |i| late_copy(l, i));
    eprintln!(
        "early surfels {early_short} / {early_long} (short / unbounded window), \
         updated on the return {early_updated_short} / {early_updated_long}, \
         new ones in the first view on the way back {copies_short} / {copies_long}, \
         map {} / {}",
        s.live_len(),
        l.live_len()
    );
    // The first copy stays in the map, untouched by the return.
    assert!(early_short > 5000, "{early_short} early surfels");
    assert!(early_short * 10 >= early_long * 9);
    assert_eq!(early_updated_short, 0, "inactive surfels were merged into");
    assert!(
        early_updated_long * 2 > early_long,
        "with an unbounded window the return merges into the first copy"
    );
    // The return lays a second copy where the window is short, not where it is unbounded.
    assert!(copies_short * 2 > early_short, "{copies_short} new surfels");
    assert!(copies_long * 10 < copies_short, "{copies_long} new surfels");

    // Inactive surfels are in the PLY export like the others.
    let inactive = FusionConfig {
        active_window_frames: 20,
        ..FusionConfig::default()
    }
    .inactive_at(last);
    let inactive_count = count(s, |i| inactive.contains(&s.last_seen()[i]));
    assert!(inactive_count >= early_short);
    let ply = write_surfel_ply(s);
    let header = String::from_utf8_lossy(&ply[..200.min(ply.len())]).to_string();
    assert!(
        header.contains(&format!("element vertex {}\n", s.live_len())),
        "{header}"
    );

    // Active surfels in view keep merging: the surfaces of the last view.
    let active_now = count(s, |i| s.last_seen()[i] == last);
    assert!(
        active_now > 5000,
        "{active_now} surfels updated at the last frame"
    );
}

/// With loop closure on, the return registers the active model against the
/// inactive first copy: on noise-free data the two already coincide, so
/// nothing is bent (an overlap that only pins some directions must not
/// slide the map), and the matched first copy is reactivated and merged
/// into instead of doubled.
#[test]
fn with_loop_closure_the_return_reactivates_the_first_copy_without_bending() {
    let frames = turn_frames();
    let back = (HOLD + 2 * HALF_TURN) as u32;
    let closing = run_turn(20, true, frames);
    let plain = run_turn(20, false, frames);
    let (c, p) = (closing.map(), plain.map());
    let early = |m: &SurfelMap, i: usize| {
        m.first_seen()[i] < HOLD as u32 && in_first_view(m.positions()[i])
    };
    let early_closing = count(c, |i| early(c, i));
    let updated = count(c, |i| early(c, i) && c.last_seen()[i] >= back);
    let late_copy = |m: &SurfelMap, i: usize| {
        m.first_seen()[i] >= HALF_TURN as u32 && in_first_view(m.positions()[i])
    };
    let (copies_closing, copies_plain) =
        (count(c, |i| late_copy(c, i)), count(p, |i| late_copy(p, i)));
    eprintln!(
        "early surfels {early_closing}, updated on the return {updated}, \
         new ones on the way back {copies_closing} (without closure {copies_plain}), \
         closures {}",
        closing.loop_closures()
    );
    assert_eq!(
        closing.loop_closures(),
        0,
        "the map was bent on noise-free data"
    );
    assert!(
        updated * 2 > early_closing,
        "{updated} of {early_closing} reactivated"
    );
    assert!(
        copies_closing * 2 < copies_plain,
        "{copies_closing} new surfels"
    );
}

/// The active and the inactive model rendered from the same pose: each
/// shows only its own surfels, and where a surface was mapped twice both
/// show it (what loop closure registers one against the other).
#[test]
fn the_active_and_the_inactive_model_render_separately_from_one_pose() {
    let frames = turn_frames();
    let last = frames as u32 - 1;
    let slam = run_turn(20, false, frames);
    let map = slam.map();
    let config = slam.config().clone();
    let k = config.working_intrinsics();
    // The last frame's measurement, from its tracked pose.
    let pose = slam.trajectory()[frames - 1].1;
    let frame = synthetic::render(
        &Scene::room(),
        &k,
        &turn_pose(frames - 1),
        &NoiseModel::none(),
        frames as u64 - 1,
    )
    .to_frame(&config.depth)
    .expect("frame");
    let mut pyramid = FramePyramid::new(&k, &config.preprocess);
    pyramid.build(&frame, &config.preprocess, &config.tracker.noise);
    let vertices = &pyramid.levels[0].vertices;
    let mut tiles = surfel_slam::fusion::DepthTiles::default();
    tiles.build(vertices, k.width);
    let render = |seen: std::ops::Range<u32>| {
        let mut p = Prediction::new(false);
        p.render(
            map,
            &pose,
            &k,
            (config.fusion.depth_gate_m, config.depth.max_m),
            Measured {
                vertices,
                tiles: &tiles,
            },
            seen,
            |i| config.fusion.predicts(map, i, last),
        );
        p
    };
    let active = render(config.fusion.active_at(last));
    let inactive = render(config.fusion.inactive_at(last));
    let all = render(0..u32::MAX);
    let positions_of = |keep: &dyn Fn(u32) -> bool| -> HashSet<[u32; 3]> {
        (0..map.len())
            .filter(|&i| keep(map.last_seen()[i]))
            .map(|i| map.positions()[i].to_array().map(f32::to_bits))
            .collect()
    };
    let active_set = positions_of(&|f| config.fusion.active_at(last).contains(&f));
    let inactive_set = positions_of(&|f| config.fusion.inactive_at(last).contains(&f));
    let shown = |p: &Prediction| -> Vec<[u32; 3]> {
        p.vertices
            .iter()
            .filter(|v| **v != Vec3::ZERO)
            .map(|v| v.to_array().map(f32::to_bits))
            .collect()
    };
    let (a, n) = (shown(&active), shown(&inactive));
    eprintln!(
        "pixels showing active {} / inactive {} / all {} surfels of {}",
        a.len(),
        n.len(),
        all.valid,
        k.pixel_count()
    );
    assert!(a.iter().all(|v| active_set.contains(v)));
    assert!(n.iter().all(|v| inactive_set.contains(v)));
    // Back at the start: the view is mapped twice, old and new (the new
    // copy is still becoming stable).
    assert!(a.len() * 3 > k.pixel_count(), "{} active pixels", a.len());
    assert!(n.len() * 2 > k.pixel_count(), "{} inactive pixels", n.len());
    assert_eq!(active.valid, a.len());
    // The inactive copy lies on the active one (tracking is exact here).
    let offsets: Vec<f32> = active
        .vertices
        .iter()
        .zip(&inactive.vertices)
        .filter(|(a, n)| **a != Vec3::ZERO && **n != Vec3::ZERO)
        .map(|(a, n)| (*a - *n).length())
        .collect();
    let close = offsets.iter().filter(|&&d| d < 0.01).count();
    assert!(
        close * 10 > offsets.len() * 9,
        "{close} of {}",
        offsets.len()
    );
}

/// A camera that stays still for many windows keeps its surfaces active:
/// each frame merges into them instead of laying new copies.
#[test]
fn a_still_camera_keeps_merging_into_the_same_surfels() {
    let window = 5;
    let config = config(window, true);
    let scene = Scene::room();
    let pose = synthetic::trajectory_pose(0);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut sizes = Vec::new();
    for i in 0..40u64 {
        let frame = synthetic::render(&scene, &intrinsics(), &pose, &NoiseModel::none(), i)
            .to_frame(&config.depth)
            .expect("frame");
        let report = slam.push_frame(&frame, i as f64).expect("push");
        assert!(report.verdict.is_fused(), "frame {i}: {:?}", report.verdict);
        sizes.push(report.surfels);
    }
    let map = slam.map();
    eprintln!("surfels after 10, 40 frames: {}, {}", sizes[9], sizes[39]);
    assert!(sizes[39] * 100 <= sizes[9] * 102, "{sizes:?}");
    let updated_last = count(map, |i| map.last_seen()[i] == 39);
    assert!(
        updated_last * 10 > map.live_len() * 9,
        "{updated_last} of {} updated at the last frame",
        map.live_len()
    );
}

#[test]
fn reset_forgets_the_times() {
    let config = config(10, true);
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone()).expect("config");
    for i in 0..12usize {
        let frame = synthetic::render(
            &scene,
            &intrinsics(),
            &synthetic::trajectory_pose(i),
            &NoiseModel::none(),
            i as u64,
        )
        .to_frame(&config.depth)
        .expect("frame");
        slam.push_frame(&frame, i as f64).expect("push");
    }
    assert!(slam.map().last_seen().iter().any(|&f| f > 0));
    slam.reset();
    assert!(slam.map().last_seen().is_empty());
    assert!(slam.map().first_seen().is_empty());
    let frame = synthetic::render(
        &scene,
        &intrinsics(),
        &synthetic::trajectory_pose(20),
        &NoiseModel::none(),
        20,
    )
    .to_frame(&config.depth)
    .expect("frame");
    slam.push_frame(&frame, 100.0).expect("push");
    let map = slam.map();
    assert!(!map.is_empty());
    assert!(map.last_seen().iter().all(|&f| f == 0));
    assert!(map.first_seen().iter().all(|&f| f == 0));
    assert_eq!(map.last_seen().len(), map.len());
}

/// With copies merged (the default, `FusionConfig::merge_copies_after_frames`)
/// and loop closure off, the copy the return lays over the inactive first
/// one is merged into it once it is old enough: the first copy is active
/// again and the map holds one copy of the first view, not two.
#[test]
fn the_copy_laid_on_the_return_is_merged_into_the_first_one() {
    // The turn, then the camera rests at the start for longer than the delay.
    let delay = FusionConfig::default().merge_copies_after_frames as usize;
    assert!(delay > 0);
    let frames = turn_frames() + delay + 20;
    let back = (HOLD + 2 * HALF_TURN) as u32;
    let mut merging = config(20, false);
    merging.fusion.merge_copies_after_frames = delay as u32;
    let merged = run_turn_with(&merging, frames);
    let plain = run_turn(20, false, frames);
    let (m, p) = (merged.map(), plain.map());
    let early = |map: &SurfelMap, i: usize| {
        map.first_seen()[i] < HOLD as u32 && in_first_view(map.positions()[i])
    };
    let late_copy = |map: &SurfelMap, i: usize| {
        map.first_seen()[i] >= HALF_TURN as u32 && in_first_view(map.positions()[i])
    };
    let early_merged = count(m, |i| early(m, i));
    let updated = count(m, |i| early(m, i) && m.last_seen()[i] >= back);
    let (copies_merged, copies_plain) =
        (count(m, |i| late_copy(m, i)), count(p, |i| late_copy(p, i)));
    eprintln!(
        "early surfels {early_merged}, active again {updated}; copies of the first view {copies_merged} \
         (not merged {copies_plain}); map {} (not merged {})",
        m.live_len(),
        p.live_len()
    );
    assert!(early_merged > 5000, "{early_merged} early surfels");
    assert!(
        updated * 2 > early_merged,
        "{updated} of {early_merged} merged into"
    );
    assert!(
        copies_merged * 3 < copies_plain,
        "{copies_merged} copies left, {copies_plain} without merging"
    );
    assert!(m.live_len() < p.live_len());
    assert!(m.all_finite());
}
