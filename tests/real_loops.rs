//! Loop closure on the real sequences (teddy, ICL-NUIM), against their
//! ground truth: played forwards and back without loop closure, with the
//! local check and with the global one too, it must not be worse, and every
//! global match must be right. The synthetic loops with known truth are in
//! `loop_closure.rs` and `global_loop.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use glam::DAffine3;
use surfel_slam::eval::ate;
use surfel_slam::loop_closure::global::GlobalClosure;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::{Pipeline, SlamConfig};

/// Which loop closure a real run has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Loops {
    /// None.
    Off,
    /// The local check only.
    Local,
    /// The local and the global check: the default.
    Global,
}

/// Frames `0..n` and then `n-1..0` of a real sequence,
/// stamped with the play position: ATE against the ground truth of the
/// frame each position shows, the global matches with their position
/// error (after the ATE alignment of the final trajectory), and the loop
/// stage's milliseconds on the frames that looked.
struct RealRun {
    ate_m: f64,
    /// ATE when the first `n` positions had been played (the forward
    /// pass): what a forward-only run ends with, since a run does not
    /// depend on timing.
    forward_ate_m: f64,
    lost: u32,
    forward_lost: u32,
    matches: Vec<Match>,
    /// The loop stage's milliseconds, per frame.
    loop_ms: Vec<f64>,
    /// Whether the global check looked, per frame.
    looked: Vec<bool>,
}

/// A global match on a real sequence and the error (metres, degrees) of
/// the tracked and the registered pose.
struct Match {
    frame: usize,
    closure: GlobalClosure,
    tracked: (f64, f64),
    registered: (f64, f64),
}

impl Match {
    /// One line: the match, its correction and both poses' errors.
    fn describe(&self) -> String {
        let g = &self.closure;
        format!(
            "frame {}: keyframe {}, correction {:.2} cm {:.2} deg, closed {}; relative to the keyframe \
             tracked {:.2} cm {:.2} deg, registered {:.2} cm {:.2} deg off the truth",
            self.frame,
            g.keyframe_frame,
            g.correction_m * 100.0,
            g.correction_deg,
            g.closed,
            self.tracked.0 * 100.0,
            self.tracked.1,
            self.registered.0 * 100.0,
            self.registered.1
        )
    }

    /// Fails unless the registered pose is within 2 cm and 1.5 degrees of the truth.
    fn assert_right(&self) {
        assert!(
            self.registered.0 < 0.02 && self.registered.1 < 1.5,
            "a wrong global match: {}",
            self.describe()
        );
    }
}

fn real_run(dir: &std::path::Path, loops: Loops) -> RealRun {
    let n = surfel_slam::dataset::Sequence::open(dir)
        .expect("sequence opens")
        .frames
        .len();
    let order: Vec<usize> = (0..n).chain((0..n).rev()).collect();
    real_run_in(dir, loops, &order)
}

/// [`real_run`] of the frames in `order`.
fn real_run_in(dir: &std::path::Path, loops: Loops, order: &[usize]) -> RealRun {
    use surfel_slam::dataset::{read_frame, Sequence};
    let sequence = Sequence::open(dir).expect("sequence opens");
    let mut config = SlamConfig::from_preset(sequence.preset);
    config.loop_closure.enabled = loops != Loops::Off;
    config.loop_closure.global.enabled = loops == Loops::Global;
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut truth = Vec::new();
    let mut reports = Vec::new();
    let mut forward = None;
    for (position, &j) in order.iter().enumerate() {
        let entry = &sequence.frames[j];
        let frame = read_frame(dir, entry, &config.depth).expect("frame decodes");
        reports.push(slam.push_frame(&frame, position as f64).expect("accepted"));
        if let Some(gt) = sequence.ground_truth_for(entry.timestamp, 0.02) {
            truth.push((position as f64, gt));
        }
        if position + 1 == sequence.frames.len() {
            let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
            forward = Some((a.rmse_m, slam.counts().lost));
        }
    }
    let (forward_ate_m, forward_lost) = forward.expect("the order plays the sequence's length");
    let a = ate(slam.trajectory(), &truth, 0.01).expect("ate");
    let align = a.ground_truth_from_estimate;
    // A match is judged by the pose it gives relative to its keyframe's
    // frame (alignment free; both frames' ground truth), else by the
    // position after the ATE alignment of the final trajectory.
    let truth_at = |i: usize| truth.iter().find(|(t, _)| *t == i as f64).map(|(_, p)| *p);
    let matches = reports
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let g = r.loop_outcome.global?;
            let gt = truth_at(i)?;
            let kf = g.keyframe_frame as usize;
            let off = |p: &DAffine3| {
                let error = match (truth_at(kf), slam.trajectory().get(kf)) {
                    (Some(gk), Some((_, ek))) => {
                        (gk.inverse() * gt).inverse() * (ek.inverse() * *p)
                    }
                    _ => gt.inverse() * align * *p,
                };
                let (dt, dr) = motion_magnitude(&error);
                (dt, dr.to_degrees())
            };
            Some(Match {
                frame: i,
                closure: g,
                tracked: off(&g.tracked),
                registered: off(&g.registered),
            })
        })
        .collect();
    let loop_ms = reports.iter().map(|r| r.timings.loop_ms).collect();
    let looked = reports
        .iter()
        .map(|r| r.loop_outcome.global_looked)
        .collect();
    RealRun {
        ate_m: a.rmse_m,
        forward_ate_m,
        lost: slam.counts().lost,
        forward_lost,
        matches,
        loop_ms,
        looked,
    }
}

fn median_max(v: &[f64]) -> (f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    (
        s.get(s.len() / 2).copied().unwrap_or(0.0),
        s.last().copied().unwrap_or(0.0),
    )
}

/// Sequence `name` played forwards then backwards, without loop closure,
/// with the local check only and with the global check too (the default):
/// loop closure must not make the ATE worse, forward or both ways, and
/// every global match must be right and the ATE no worse than without
/// the global check. (Forward-only runs are not played as well: they are
/// these runs' first halves, frame for frame, since a run does not depend
/// on timing.)
fn real_sequence_not_worse(name: &str, limit_m: f64) {
    let Some(dir) = common::shared_dataset(name) else {
        return;
    };
    let none = real_run(&dir, Loops::Off);
    let off = real_run(&dir, Loops::Local);
    let on = real_run(&dir, Loops::Global);
    for (way, without, with) in [
        (
            "forward",
            (none.forward_ate_m, none.forward_lost),
            (on.forward_ate_m, on.forward_lost),
        ),
        (
            "forward+backward",
            (none.ate_m, none.lost),
            (on.ate_m, on.lost),
        ),
    ] {
        println!(
            "{name} {way}: ATE {:.3} cm without loop closure, {:.3} cm with; lost {} / {}",
            without.0 * 100.0,
            with.0 * 100.0,
            without.1,
            with.1
        );
        assert!(with.1 <= without.1, "{way}: loop closure lost more frames");
        assert!(
            with.0 <= without.0 * 1.05 + 1e-4,
            "{way}: {} m with loop closure vs {} m without",
            with.0,
            without.0
        );
    }
    let closed = on.matches.iter().filter(|m| m.closure.closed).count();
    // The cost of a look that found nothing: the loop stage on those
    // frames less the same frames' loop stage without the global check.
    let look_ms: Vec<f64> = (0..on.looked.len())
        .filter(|&i| on.looked[i] && on.matches.iter().all(|m| m.frame != i))
        .map(|i| on.loop_ms[i] - off.loop_ms[i])
        .collect();
    let (median, max) = median_max(&look_ms);
    println!(
        "{name} forward+backward: ATE {:.3} cm without the global check, {:.3} cm with; {} global looks \
         without a match ({median:.1} ms median, {max:.1} ms max), {} matches, {closed} closures; lost {} / {}",
        off.ate_m * 100.0,
        on.ate_m * 100.0,
        look_ms.len(),
        on.matches.len(),
        off.lost,
        on.lost
    );
    for m in &on.matches {
        println!(
            "  {} (loop stage {:.1} ms)",
            m.describe(),
            on.loop_ms[m.frame]
        );
        m.assert_right();
        assert!(
            m.registered.0 < m.tracked.0 || m.registered.1 < m.tracked.1,
            "frame {}: the match moved the pose away from the truth",
            m.frame
        );
    }
    assert!(on.lost <= off.lost);
    assert!(
        on.ate_m <= off.ate_m * 1.05 + 1e-4,
        "{} m with vs {} m without",
        on.ate_m,
        off.ate_m
    );
    assert!(on.ate_m <= limit_m, "ATE {} m", on.ate_m);
}

#[test]
fn teddy_is_not_worse_with_loop_closure_and_the_global_check() {
    real_sequence_not_worse("tum_fr3_teddy", 0.0075);
}

#[test]
fn icl_is_not_worse_with_loop_closure_and_the_global_check() {
    real_sequence_not_worse("icl_office_kt0", 0.0002);
}

/// Teddy played forwards and backwards for 1500 frames (issue #21's long
/// run), with and without the global check (minutes): every match must be
/// right. Before the check refused matches the old model also holds at the
/// tracked pose, it closed frame 590 onto keyframe 166 (10.6 cm 6.3
/// degrees, 9 cm off the truth), ATE 0.90 -> 2.76 cm. Now its one closure
/// is right but still costs ATE (0.86 -> 1.06 cm): why it is off by default.
/// `cargo test --test real_loops teddy_ping_pong -- --ignored --nocapture`.
#[test]
#[ignore]
fn teddy_ping_pong_1500_frames() {
    let Some(dir) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let n = surfel_slam::dataset::Sequence::open(&dir)
        .expect("sequence opens")
        .frames
        .len();
    let order: Vec<usize> = (0..n).chain((1..n - 1).rev()).cycle().take(1500).collect();
    let mut ate_m = Vec::new();
    for global in [false, true] {
        let loops = if global { Loops::Global } else { Loops::Local };
        let run = real_run_in(&dir, loops, &order);
        ate_m.push(run.ate_m);
        let looks = run.looked.iter().filter(|l| **l).count();
        let closed = run.matches.iter().filter(|m| m.closure.closed).count();
        println!(
            "teddy 1500 frames, global {global}: ATE {:.3} cm, lost {}, {looks} looks, {} matches, {closed} closures",
            run.ate_m * 100.0,
            run.lost,
            run.matches.len()
        );
        for m in &run.matches {
            println!("  {}", m.describe());
            m.assert_right();
        }
    }
    // A closure it makes must pay for itself (it once cost 0.86 -> 1.06 cm).
    assert!(
        ate_m[1] <= ate_m[0] * 1.05,
        "the global check made teddy worse: {:.3} -> {:.3} cm",
        ate_m[0] * 100.0,
        ate_m[1] * 100.0
    );
}

/// The long ICL-NUIM office with the Kinect-v1 recipe (seed 1), forwards
/// once, against its exact truth (issue 50): with loop closure the ATE is
/// lower than without, and no closure moves the current pose more than
/// 0.5 cm away from the truth (the first frame is the world, so the truth
/// needs no alignment here). Measured: 0.386 cm with, 0.399 without; the
/// one closure (local, frame 488) 0.45 -> 0.12 cm; seeds 2 and 3 0.378 /
/// 0.390 and 0.372 / 0.393 cm. No global closure: every revisit at 10 Hz
/// falls inside the active window.
#[test]
fn the_noisy_long_office_ends_nearer_the_truth_with_loop_closure() {
    use surfel_slam::dataset::{read_frame, Sequence};
    use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
    let Some(dir) = common::shared_dataset("icl_office_kt0_long") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence opens");
    let run = |loops: bool| {
        let mut config = SlamConfig::from_preset(sequence.preset);
        config.simulate_noise = Some(NoiseSimulation {
            sensor: SimulatedSensor::KinectV1,
            seed: 1,
        });
        config.loop_closure.enabled = loops;
        let mut slam = Pipeline::new(config.clone()).expect("config");
        let mut first_truth = None;
        let mut closures = Vec::new();
        for entry in &sequence.frames {
            let frame = read_frame(&dir, entry, &config.depth).expect("frame decodes");
            let report = slam.push_frame(&frame, entry.timestamp).expect("accepted");
            let gt = sequence
                .ground_truth_for(entry.timestamp, 0.02)
                .expect("exact truth for every frame");
            let truth = first_truth.get_or_insert(gt).inverse() * gt;
            if report.loop_outcome.closed {
                let off = |p: &DAffine3| (p.translation - truth.translation).length() * 100.0;
                closures.push((
                    entry.index,
                    off(&report.loop_outcome.tracked),
                    off(&report.world_from_camera),
                ));
            }
        }
        let a = ate(slam.trajectory(), &sequence.ground_truth, 0.02).expect("ate");
        (a.rmse_m * 100.0, closures)
    };
    let (with_cm, closures) = run(true);
    let (without_cm, none) = run(false);
    eprintln!(
        "noisy long office, seed 1: ATE {with_cm:.3} cm with loop closure, {without_cm:.3} cm without; \
         closures (frame, cm from the truth before, after): {closures:?}"
    );
    assert!(none.is_empty());
    assert!(
        !closures.is_empty(),
        "no closure: the test no longer judges one"
    );
    for &(frame, before, after) in &closures {
        assert!(
            after <= before + 0.5,
            "the closure at frame {frame} moved the pose away from the truth: {before:.2} -> {after:.2} cm"
        );
    }
    assert!(
        with_cm < without_cm,
        "{with_cm:.3} cm with, {without_cm:.3} without"
    );
}
