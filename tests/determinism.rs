//! Same input, same output (issue #37): a run's trajectory and map do not
//! depend on the number of threads, on work-stealing timing or on machine
//! load. One synthetic sequence that works every stage (tracking, fusion,
//! cleanup, loss and relocalisation, local and global loop checks against
//! the inactive model, deformation, copies merged) is played in rayon pools
//! of 1, 2 and 4 threads, then five times in a row while other threads keep
//! every core busy; every run must give the same bits.
//!
//! `cargo test --release --test determinism -- --nocapture` prints what the
//! sequence exercised.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::revisit::{config, frames};
use common::run_bits::{first_difference, RunBits};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use surfel_slam::{FrameReport, Pipeline, RgbdFrame, SlamConfig, StageTimings, Verdict};

/// Everything a run leaves behind, as bits: both trajectories, every
/// surfel array of the map, and what each frame reported (timings aside).
#[derive(PartialEq, Eq)]
struct Outcome {
    run: RunBits,
    reports: Vec<String>,
}

/// A frame's report without its timings (`Debug` prints floats exactly).
fn report_text(r: &FrameReport) -> String {
    let timeless = FrameReport {
        timings: StageTimings::default(),
        ..*r
    };
    format!("{timeless:?}")
}

/// What a run went through (counted from its reports).
#[derive(Debug, Default)]
struct Coverage {
    lost: usize,
    relocalised: usize,
    registrations: usize,
    closures: u32,
    global_looks: usize,
    absorbed: usize,
}

impl Coverage {
    fn of(reports: &[FrameReport]) -> Self {
        let mut c = Self::default();
        for r in reports {
            c.lost += usize::from(matches!(r.verdict, Verdict::Lost(_)));
            c.relocalised += usize::from(r.checks.relocalised_from.is_some());
            c.registrations += usize::from(r.loop_outcome.registration.is_some());
            c.global_looks += usize::from(r.loop_outcome.global_looked);
            c.absorbed += r.fusion.absorbed;
        }
        c.closures = reports.last().map_or(0, |r| r.loop_closures);
        c
    }
}

fn play(config: &SlamConfig, frames: &[RgbdFrame]) -> (Outcome, Coverage) {
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    let reports: Vec<FrameReport> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| slam.push_frame(f, i as f64).expect("frame accepted"))
        .collect();
    let outcome = Outcome {
        run: RunBits::of(&slam),
        reports: reports.iter().map(report_text).collect(),
    };
    (outcome, Coverage::of(&reports))
}

fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a rayon pool")
        .install(f)
}

/// Every difference between two outcomes, one line each (empty: the same bits).
fn differences(a: &Outcome, b: &Outcome) -> Vec<String> {
    first_difference("reports", &a.reports, &b.reports)
        .into_iter()
        .chain(a.run.differences(&b.run))
        .collect()
}

fn assert_same(what: &str, reference: &Outcome, other: &Outcome) {
    let diffs = differences(reference, other);
    assert!(
        diffs.is_empty(),
        "{what} differs:\n  {}",
        diffs.join("\n  ")
    );
}

/// The sequence must reach every stage whose order of work could differ.
fn check_coverage(c: &Coverage) {
    println!("{c:?}");
    assert!(c.lost >= 1, "the covered frames were not lost");
    assert!(c.relocalised >= 1, "no relocalisation");
    assert!(c.registrations >= 1, "the loop stage registered nothing");
    assert!(
        c.closures >= 1,
        "no loop closed (the deformation never ran)"
    );
    assert!(c.global_looks >= 1, "no global look");
    assert!(c.absorbed >= 1, "nothing merged");
}

/// Keeps every core busy with float work until dropped.
struct Load {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<f64>>,
}

impl Load {
    fn start() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let cores = std::thread::available_parallelism().map_or(2, usize::from);
        let threads = (0..cores)
            .map(|t| {
                let stop = Arc::clone(&stop);
                std::thread::spawn(move || {
                    let mut x = 1.0 + t as f64;
                    while !stop.load(Ordering::Relaxed) {
                        for _ in 0..10_000 {
                            x = (x * 1.000_001).sqrt() + 0.5;
                        }
                    }
                    x
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Rayon pools of 1, 2, 4, 2 and 4 threads, one after the other, while
/// other threads keep every core busy: five runs, the same bits.
#[test]
fn five_runs_on_one_two_and_four_threads_under_load_give_the_same_trajectory_and_map() {
    let config = config();
    let frames = frames(&config);
    let _load = Load::start();
    let (first, coverage) = in_pool(1, || play(&config, &frames));
    check_coverage(&coverage);
    assert_eq!(first.run.trajectory.len(), frames.len());
    for (run, threads) in [2, 4, 2, 4].into_iter().enumerate() {
        let (again, _) = in_pool(threads, || play(&config, &frames));
        assert_same(
            &format!("run {} on {threads} threads vs run 1 on 1 thread", run + 2),
            &first,
            &again,
        );
    }
}
