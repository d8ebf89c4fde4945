//! Stateful property test of the `Pipeline` API (issue 19): seeded random
//! sequences of valid frames (synthetic, and TUM fr3/teddy and ICL-NUIM kt0
//! from ../shared/data when present), garbage (corrupt or truncated PNG,
//! wrong size, 8-bit depth, colour/depth size mismatch, wrong pixel buffer,
//! NaN or infinite timestamp), reset, a change of configuration (a new
//! pipeline, as the page and the wasm `Slam` do; a quarter of them with
//! simulated Kinect noise), PLY export, changed range
//! and trajectory reads, a session saved and loaded in place (a cut copy
//! refused first), IMU samples before frames (a third of the cases, half
//! of them with the gyro as the rotation guess; now and then a batch with
//! a NaN or going back in time, refused), in any order. The runs are long enough to cross the
//! periodic cleanups, the spatial sorting and merging of settled surfels,
//! the compaction of absorbed surfels and the surfel budget, and a reset
//! after 100+ frames (what panicked in issue 19).
//!
//! After every step: no panic; every surfel array equally long and finite;
//! live + absorbed surfels = array length = what the budget counts; the PLY
//! holds the live surfels; verdict counts sum to the frames accepted, which
//! equal the trajectory's length and the timestamps pushed; a refused push
//! changes nothing; the changed range lies within the arrays.
//!
//! `SURFEL_SLAM_PROPERTY_CASES=N` runs N synthetic cases instead of the
//! default (seeds 0..N); a failure prints the seed and the step.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;
#[path = "pipeline_properties/frames.rs"]
mod frames;
#[path = "pipeline_properties/invariants.rs"]
mod invariants;

use common::synthetic_config;
use frames::{encode_synthetic, odd_frame, png_8bit, real_pool, synthetic_pool, Garbage, Pool};
use glam::DVec3;
use invariants::{check, session_round_trip, Mapped, Model};
use std::io::Cursor;
use surfel_slam::imu::ImuSample;
use surfel_slam::mesh::write_surfel_ply;
use surfel_slam::random::SplitMix;
use surfel_slam::session;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::synthetic::{self, NoiseModel};
use surfel_slam::track::TrackerMode;
use surfel_slam::Verdict;
use surfel_slam::{Pipeline, PipelineError, RgbdFrame, SlamConfig};

/// The crate's seeded generator, with the draws this test needs.
struct Rng(SplitMix);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi - lo + 1)
    }

    fn chance(&mut self, p: f64) -> bool {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }
}

/// A random configuration of `pool`'s camera: tracker, resolution, budget.
fn random_config(pool: &Pool, rng: &mut Rng) -> SlamConfig {
    let mut config = pool.base.clone();
    config.tracker.mode = match rng.below(6) {
        0 => TrackerMode::Rgb,
        1 => TrackerMode::Joint,
        _ => TrackerMode::Icp,
    };
    config.half_resolution = rng.chance(0.25);
    if rng.chance(0.5) {
        config.fusion.max_surfels = rng.range(pool.small_budget.0, pool.small_budget.1);
    }
    if rng.chance(0.3) {
        // A short active window: surfels go inactive within a case.
        config.fusion.active_window_frames = rng.range(1, 30) as u32;
    }
    // Simulated Kinect noise on a quarter of the configurations, drawn from
    // a copy of the stream so that the cases drawn before it existed (and
    // the coverage they give) stay as they were.
    let mut side = rng.0.clone();
    let draw = side.next_u64() ^ side.next_u64().rotate_left(17);
    if draw % 4 == 0 {
        config.simulate_noise = Some(NoiseSimulation {
            sensor: SimulatedSensor::KinectV1,
            seed: draw >> 2,
        });
    }
    // A third restart mapping after 1-3 lost frames: frames pushed out of
    // order are lost, so segments begin, join and are saved within a case.
    if (draw >> 8) % 3 == 0 {
        config.restart_after_lost = 1 + ((draw >> 12) % 3) as u32;
    }
    config.imu_rotation_guess = (draw >> 16) % 2 == 0;
    config
}

/// IMU samples at 100 Hz after `after_s` up to `until_s` (seconds), turning
/// at `rate_radps` about a fixed axis, at rest otherwise.
fn imu_samples(after_s: f64, until_s: f64, rate_radps: f64) -> Vec<ImuSample> {
    let first = (after_s * 100.0).floor() as i64 + 1;
    let last = (until_s * 100.0).floor() as i64;
    (first..=last)
        .map(|k| ImuSample {
            time_s: k as f64 / 100.0,
            accel_mps2: DVec3::new(0.0, 9.81, 0.0),
            gyro_radps: DVec3::new(0.3, -0.2, 0.9).normalize() * rate_radps,
        })
        .collect()
}

/// What a case crossed, summed over cases.
#[derive(Debug, Default, Clone, Copy)]
struct Coverage {
    cases: usize,
    steps: usize,
    longest_case: usize,
    longest_run: usize,
    frames: usize,
    lost: usize,
    restarts: usize,
    joins: usize,
    refused: usize,
    resets: usize,
    resets_after_100: usize,
    config_changes: usize,
    cleanups: usize,
    compactions: usize,
    budget_full: usize,
    exports: usize,
    sessions: usize,
    /// Calls of `finish` (the recording ended).
    finishes: usize,
    /// Times localise mode was started, and frames pushed in it.
    localise_starts: usize,
    localised: usize,
    /// Frames pushed with simulated noise on.
    noisy_frames: usize,
    /// Frames pushed with a depth deviation map (a sensor's confidence).
    marked_frames: usize,
    /// IMU batches accepted, and refused (a NaN, or back in time).
    imu_batches: usize,
    imu_refused: usize,
}

/// `frame` with every third pixel's depth deviation `factor` (1 elsewhere).
fn marked(frame: &RgbdFrame, factor: f32) -> RgbdFrame {
    RgbdFrame {
        depth_deviation: (0..frame.depth_m.len())
            .map(|i| if i % 3 == 0 { factor } else { 1.0 })
            .collect(),
        ..frame.clone()
    }
}

fn fail(seed: u64, step: usize, what: &str) -> String {
    format!("seed {seed}, step {step}: {what}")
}

/// Frames a case localises before it resets (localise mode lasts until a reset).
const LOCALISED_BEFORE_RESET: u32 = 25;

/// Runs one case; returns what it crossed.
/// `first_run` (when not 0): frames before the first reset or change of
/// configuration may happen, and a reset right then.
fn run_case(pool: &Pool, garbage: &Garbage, seed: u64, steps: usize, first_run: usize) -> Coverage {
    let mut rng = Rng(SplitMix::new(
        seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ 0x5eed,
    ));
    let mut cov = Coverage {
        cases: 1,
        longest_case: steps,
        ..Coverage::default()
    };
    let mut slam = Pipeline::new(random_config(pool, &mut rng)).expect("config");
    let mut model = Model::default();
    // A third of the cases have an IMU, on a stream of its own so that the
    // cases' other draws stay as they were.
    let mut imu_rng = Rng(SplitMix::new(seed ^ 0x1a2b_3c4d));
    let imu_rate = imu_rng
        .chance(0.33)
        .then(|| imu_rng.below(100) as f64 / 50.0);
    // Frames are played forwards and backwards (continuous motion).
    let period = (2 * pool.len()).saturating_sub(2).max(1);
    let mut cursor = rng.below(pool.len());
    let mut clock = 0.0;
    let run_length = |rng: &mut Rng| {
        if rng.chance(0.35) {
            rng.range(100, 220)
        } else {
            rng.range(5, 60)
        }
    };
    let mut run_target = run_length(&mut rng).max(first_run);
    let mut forced_reset = false;
    // While localising: the mapping state that must not change.
    let mut localising: Option<Mapped> = None;
    for step in 0..steps {
        let frames = slam.frames();
        let at = |what: &str| {
            fail(
                seed,
                step,
                &format!("{} ({frames} frames): {what}", pool.name),
            )
        };
        let mut roll = rng.below(100);
        // Resets and new configurations mostly wait for the run's target
        // length, so that runs cross many cleanups before they end.
        if (84..90).contains(&roll)
            && (slam.frames() as usize) < run_target
            && (run_target >= 100 || !rng.chance(0.1))
        {
            roll = 0;
        }
        let localised = slam.localisation().map_or(0, |l| l.frames());
        if localised >= LOCALISED_BEFORE_RESET && roll < 72 {
            roll = 84;
        }
        if first_run > 0 && slam.frames() as usize == first_run && !forced_reset {
            roll = 84;
            forced_reset = true;
        }
        if roll < 72 {
            // A valid frame, through one of the three entry points.
            let k = cursor % period;
            let e = pool.frame(if k < pool.len() { k } else { period - k });
            cursor += 1;
            if let Some(rate) = imu_rate {
                push_imu(
                    &mut slam,
                    &mut imu_rng,
                    (clock, clock + 1.0 / 30.0),
                    rate,
                    &mut cov,
                    &at,
                );
            }
            clock += 1.0 / 30.0;
            let before = (slam.map().len(), slam.map().absorbed_len());
            if let Some(mapped) = &localising {
                let placed_before = slam.localisation().map_or(0, |l| l.frames());
                let r = slam.push_frame(&e.frame, clock).unwrap_or_else(|err| {
                    panic!("{}", at(&format!("valid frame refused localising: {err}")))
                });
                assert!(
                    r.pose().is_none_or(|p| p.is_finite()),
                    "{}",
                    at("placed pose")
                );
                assert_eq!(
                    slam.localisation().map(|l| l.frames()),
                    Some(placed_before + 1),
                    "{}",
                    at("localised frames")
                );
                assert_eq!(
                    &Mapped::of(&slam),
                    mapped,
                    "{}",
                    at("localising changed the map")
                );
                cov.localised += 1;
                check(&slam, &model, &at);
                cov.steps += 1;
                continue;
            }
            let r = match rng.below(4) {
                3 => slam.push_raw(e.width, e.height, &e.rgb, &e.depth_raw, clock),
                0 => slam.push_png(&e.colour_png, &e.depth_png, clock),
                1 => slam.push_rgba_depth_png(e.width, e.height, &e.rgb, &e.depth_png, clock),
                // Every other frame pushed as a frame carries a confidence
                // map: a third of its pixels twice as uncertain.
                _ if cursor % 2 == 0 => {
                    cov.marked_frames += 1;
                    slam.push_frame(&marked(&e.frame, 2.0), clock)
                }
                _ => slam.push_frame(&e.frame, clock),
            };
            let r =
                r.unwrap_or_else(|err| panic!("{}", at(&format!("valid frame refused: {err}"))));
            model.accepted.push(clock);
            cov.frames += 1;
            cov.noisy_frames += usize::from(slam.config().simulate_noise.is_some());
            cov.lost += usize::from(!r.verdict.is_fused());
            cov.restarts += usize::from(r.verdict == Verdict::Restarted);
            cov.joins += usize::from(r.loop_outcome.joined.is_some());
            let interval = slam.config().fusion.cleanup_interval_frames.max(1);
            if r.verdict.is_fused() && r.index > 0 && r.index % interval == 0 {
                cov.cleanups += 1;
                // Absorbed surfels before the young tail wait until they are
                // 5 % of the map; then one cleanup removes them all.
                if before.1 * 20 >= before.0 && before.1 > 0 && slam.map().absorbed_len() == 0 {
                    cov.compactions += 1;
                }
            }
            cov.budget_full += usize::from(r.fusion.skipped > 0);
            model.last_report = Some(r);
            cov.longest_run = cov.longest_run.max(model.accepted.len());
        } else if roll < 84 {
            // Garbage: refused, and nothing changes.
            let e = pool.frame(cursor % pool.len());
            let before = (
                slam.frames(),
                slam.map().len(),
                slam.map().live_len(),
                slam.counts(),
            );
            let kind = rng.below(9);
            let result = match kind {
                0 => {
                    let cut = rng.range(1, e.depth_png.len() - 1);
                    slam.push_png(&e.colour_png, &e.depth_png[..cut], clock + 1.0)
                }
                1 => {
                    let mut colour = e.colour_png.clone();
                    colour[..8].fill(0);
                    slam.push_png(&colour, &e.depth_png, clock + 1.0)
                }
                2 => slam.push_png(&garbage.odd.colour_png, &garbage.odd.depth_png, clock + 1.0),
                3 => slam.push_png(&e.colour_png, &png_8bit(e.width, e.height), clock + 1.0),
                4 => slam.push_png(&garbage.odd.colour_png, &e.depth_png, clock + 1.0),
                5 => slam.push_rgba_depth_png(
                    e.width,
                    e.height,
                    &e.rgb[..e.rgb.len() - 1],
                    &e.depth_png,
                    clock + 1.0,
                ),
                6 if cursor % 2 == 0 => slam.push_frame(&marked(&e.frame, f32::NAN), clock + 1.0),
                6 => slam.push_frame(&garbage.odd.frame, clock + 1.0),
                7 => slam.push_raw(
                    e.width,
                    e.height,
                    &e.rgb,
                    &e.depth_raw[..e.depth_raw.len() - e.width],
                    clock + 1.0,
                ),
                _ => {
                    let t = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][rng.below(3)];
                    let r = if rng.chance(0.5) {
                        slam.push_png(&e.colour_png, &e.depth_png, t)
                    } else {
                        slam.push_frame(&e.frame, t)
                    };
                    if let Err(err) = &r {
                        assert!(
                            matches!(err, PipelineError::InvalidTimestamp(_)),
                            "{}",
                            at(&format!("timestamp {t}: {err}"))
                        );
                    }
                    r
                }
            };
            assert!(
                result.is_err(),
                "{}",
                at(&format!("garbage {kind} accepted"))
            );
            let after = (
                slam.frames(),
                slam.map().len(),
                slam.map().live_len(),
                slam.counts(),
            );
            assert_eq!(
                before,
                after,
                "{}",
                at(&format!("garbage {kind} changed the state"))
            );
            assert!(
                slam.last_decoded_frame().is_none(),
                "{}",
                at("refused frame kept")
            );
            cov.refused += 1;
        } else if roll < 88 && localising.is_none() && slam.frames() > 0 && rng.chance(0.3) {
            // At the end of a run: localise in its map for a while, then reset.
            slam.start_localising();
            localising = Some(Mapped::of(&slam));
            cov.localise_starts += 1;
        } else if roll < 88 {
            cov.resets += 1;
            cov.resets_after_100 += usize::from(slam.frames() >= 100);
            slam.reset();
            localising = None;
            model = Model::default();
            run_target = run_length(&mut rng);
            assert_eq!(
                slam.take_changed_range(),
                0..0,
                "{}",
                at("changed range after reset")
            );
            assert_eq!(slam.map().len(), 0, "{}", at("map after reset"));
            if rng.chance(0.5) {
                cursor = rng.below(pool.len());
            }
        } else if roll < 90 {
            cov.config_changes += 1;
            slam = Pipeline::new(random_config(pool, &mut rng)).expect("config");
            localising = None;
            model = Model::default();
            run_target = run_length(&mut rng);
        } else if roll < 94 {
            let ply = write_surfel_ply(slam.map());
            let text = String::from_utf8_lossy(&ply[..ply.len().min(600)]).to_string();
            let end = text.find("end_header\n").expect("PLY header") + "end_header\n".len();
            let live = slam.map().live_len();
            assert!(
                text.contains(&format!("element vertex {live}\n")),
                "{}",
                at(&format!("PLY header for {live} surfels: {text}"))
            );
            assert_eq!(ply.len(), end + live * 35, "{}", at("PLY size"));
            cov.exports += 1;
        } else if roll == 97 {
            // The recording "ends" here; more frames may follow.
            let frames = slam.frames();
            let outcome = slam.finish();
            assert!(
                outcome.global_looked || !outcome.closed,
                "{}",
                at("finish closed without looking")
            );
            assert!(
                localising.is_none() || !outcome.global_looked,
                "{}",
                at("finish looked while localising")
            );
            assert!(
                !slam.finish().global_looked,
                "{}",
                at("the last frame looked up twice")
            );
            assert_eq!(slam.frames(), frames, "{}", at("finish pushed a frame"));
            cov.finishes += 1;
        } else if roll < 98 {
            let r = slam.take_changed_range();
            assert!(
                r.start <= r.end && r.end <= slam.map().len(),
                "{}",
                at(&format!("changed range {r:?} of {}", slam.map().len()))
            );
            assert_eq!(
                slam.take_changed_range(),
                0..0,
                "{}",
                at("range taken twice")
            );
        } else {
            assert_eq!(
                slam.trajectory().len(),
                slam.frames() as usize,
                "{}",
                at("trajectory")
            );
            if localising.is_some() {
                let refused = session::save(&slam, Cursor::new(Vec::new()));
                assert!(
                    matches!(refused, Err(session::SessionError::Localising)),
                    "{}",
                    at("a localising pipeline saved")
                );
            } else {
                session_round_trip(&mut slam, &at);
                cov.sessions += 1;
            }
        }
        check(&slam, &model, &at);
        cov.steps += 1;
    }
    cov
}

/// Pushes the IMU samples of `span` (seconds) at `rate` rad/s; one batch in
/// ten is spoiled first (a NaN, or a sample back in time) and must be
/// refused without changing what the pipeline holds.
fn push_imu(
    slam: &mut Pipeline,
    rng: &mut Rng,
    span: (f64, f64),
    rate: f64,
    cov: &mut Coverage,
    at: &dyn Fn(&str) -> String,
) {
    let samples = imu_samples(span.0, span.1, rate);
    if samples.is_empty() {
        return;
    }
    if rng.chance(0.1) {
        let mut spoiled = samples.clone();
        let i = rng.below(spoiled.len());
        if rng.chance(0.5) {
            spoiled[i].gyro_radps.y = f64::NAN;
        } else {
            spoiled[i].time_s = span.0 - 1.0;
        }
        let before = (
            slam.imu_rate_hz(),
            slam.imu_calibration().cloned(),
            slam.frames(),
        );
        let refused = slam.push_imu(&spoiled);
        assert!(refused.is_err(), "{}", at("a spoiled IMU batch accepted"));
        let after = (
            slam.imu_rate_hz(),
            slam.imu_calibration().cloned(),
            slam.frames(),
        );
        assert_eq!(
            before,
            after,
            "{}",
            at("a refused IMU batch changed the state")
        );
        cov.imu_refused += 1;
    }
    slam.push_imu(&samples)
        .unwrap_or_else(|err| panic!("{}", at(&format!("IMU samples refused: {err}"))));
    cov.imu_batches += 1;
}

/// [`run_case`], naming the case when the library panics inside it.
fn run_case_or_name_it(
    pool: &Pool,
    garbage: &Garbage,
    seed: u64,
    (steps, first_run): (usize, usize),
) -> Coverage {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        run_case(pool, garbage, seed, steps, first_run)
    }))
    .unwrap_or_else(|_| panic!("{}: seed {seed} ({steps} steps) panicked", pool.name))
}

fn add(total: &mut Coverage, c: Coverage) {
    total.cases += c.cases;
    total.steps += c.steps;
    total.longest_case = total.longest_case.max(c.longest_case);
    total.longest_run = total.longest_run.max(c.longest_run);
    total.frames += c.frames;
    total.lost += c.lost;
    total.restarts += c.restarts;
    total.joins += c.joins;
    total.refused += c.refused;
    total.resets += c.resets;
    total.resets_after_100 += c.resets_after_100;
    total.config_changes += c.config_changes;
    total.cleanups += c.cleanups;
    total.compactions += c.compactions;
    total.budget_full += c.budget_full;
    total.exports += c.exports;
    total.sessions += c.sessions;
    total.finishes += c.finishes;
    total.localise_starts += c.localise_starts;
    total.localised += c.localised;
    total.noisy_frames += c.noisy_frames;
    total.marked_frames += c.marked_frames;
    total.imu_batches += c.imu_batches;
    total.imu_refused += c.imu_refused;
}

#[test]
fn any_sequence_of_calls_keeps_the_pipeline_consistent_on_synthetic_frames() {
    let cases: u64 = std::env::var("SURFEL_SLAM_PROPERTY_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(16);
    let pool = synthetic_pool(120);
    let garbage = odd_frame();
    let mut total = Coverage::default();
    for seed in 0..cases {
        // Every fourth case is long enough for a reset after 100+ frames.
        let steps = if seed % 4 == 0 {
            400
        } else {
            60 + (seed as usize * 37) % 160
        };
        add(
            &mut total,
            run_case_or_name_it(&pool, &garbage, seed, (steps, 0)),
        );
    }
    eprintln!("synthetic: {total:?}");
    assert!(total.cleanups > 0 && total.compactions > 0, "{total:?}");
    assert!(
        total.budget_full > 0 && total.resets_after_100 > 0,
        "{total:?}"
    );
    assert!(
        total.refused > 0 && total.config_changes > 0 && total.exports > 0,
        "{total:?}"
    );
    assert!(
        total.sessions > 0 && total.restarts > 0 && total.finishes > 0,
        "{total:?}"
    );
    assert!(
        total.localise_starts > 0 && total.localised > 0,
        "{total:?}"
    );
    // Past a cleanup interval (150 frames) with simulated noise on, and
    // with confidence maps.
    assert!(total.noisy_frames > 150, "{total:?}");
    assert!(total.marked_frames > 150, "{total:?}");
    assert!(
        total.imu_batches > 150 && total.imu_refused > 0,
        "{total:?}"
    );
}

#[test]
fn any_sequence_of_calls_keeps_the_pipeline_consistent_on_real_frames() {
    let pools: Vec<Pool> = [
        real_pool("TUM fr3/teddy", "tum_fr3_teddy"),
        real_pool("ICL-NUIM kt0", "icl_office_kt0"),
    ]
    .into_iter()
    .flatten()
    .collect();
    if pools.is_empty() {
        return;
    }
    let garbage = odd_frame();
    let mut total = Coverage::default();
    for (seed, pool) in (1000..).zip(&pools) {
        // A reset after 100+ real frames, then a shorter run.
        add(
            &mut total,
            run_case_or_name_it(pool, &garbage, seed, (190, 110)),
        );
    }
    eprintln!("real: {total:?}");
    assert!(total.cleanups > 0 && total.refused > 0, "{total:?}");
    assert!(
        total.resets_after_100 + total.config_changes > 0,
        "{total:?}"
    );
}

#[test]
fn nan_and_infinite_timestamps_are_refused_by_the_library() {
    let k = synthetic::default_intrinsics().half().half();
    let config = synthetic_config(k);
    let e = encode_synthetic(&k, &config, 0, &NoiseModel::none());
    let mut slam = Pipeline::new(config).expect("config");
    for t in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = slam
            .push_png(&e.colour_png, &e.depth_png, t)
            .expect_err("refused");
        assert!(
            err.to_string()
                .contains("timestamp must be a finite number"),
            "{err}"
        );
        slam.push_frame(&e.frame, t).expect_err("refused");
        slam.push_rgba_depth_png(e.width, e.height, &e.rgb, &e.depth_png, t)
            .expect_err("refused");
    }
    assert_eq!((slam.frames(), slam.map().len()), (0, 0));
    slam.push_frame(&e.frame, 0.0)
        .expect("a finite timestamp is accepted");
}
