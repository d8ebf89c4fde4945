//! Cost and accuracy of the active window on a revisit: a sequence played
//! forwards then backwards (frames 0..N then N-2..0, timestamps increasing),
//! so that the camera returns over what it saw first. Three pipelines run
//! side by side, frame by frame (a slow spell of the machine falls on all
//! alike): the default window (200 frames), a short one (30) and an
//! unbounded one. Per window: ATE against the ground truth of the frame
//! played, fusion + prediction milliseconds per frame (median per 50
//! frames), and the surfels in the map and active at the turn and at the end.
//!
//! `cargo run --release --example revisit_window -- ../shared/data/tum_fr3_teddy [steps]`
//! (`steps` defaults to 2N-1: one way forwards and back; more keeps
//! bouncing between the ends).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::{FrameReport, Pipeline, SlamConfig};

/// Index into a sequence of `len` frames for step `i` of a ping-pong loop.
fn ping_pong(i: usize, len: usize) -> usize {
    if len < 2 {
        return 0;
    }
    let period = 2 * (len - 1);
    let k = i % period;
    if k < len {
        k
    } else {
        period - k
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// What one pipeline did at one step.
struct Step {
    fuse_predict_ms: f64,
    live: usize,
    active: usize,
    visited: usize,
}

fn step_of(slam: &Pipeline, report: &FrameReport) -> Step {
    let map = slam.map();
    let active = slam.config().fusion.active_at(report.index);
    let live_active = map
        .last_seen()
        .iter()
        .zip(map.confidences())
        .filter(|(f, &c)| c >= 0.0 && active.contains(f))
        .count();
    Step {
        fuse_predict_ms: report.timings.fuse_ms + report.timings.predict_ms,
        live: map.live_len(),
        active: live_active,
        visited: report.fusion.visited,
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(
        args.next()
            .ok_or("usage: revisit_window <dataset> [steps]")?,
    );
    let sequence = Sequence::open(&dir)?;
    let len = sequence.frames.len();
    let steps: usize = args
        .next()
        .map_or(Ok((2 * len).saturating_sub(1)), |s| s.parse())?;
    let windows = [200, 30, u32::MAX];
    let mut runs = Vec::new();
    for &w in &windows {
        let mut config = SlamConfig::from_preset(sequence.preset);
        config.fusion.active_window_frames = w;
        runs.push((Pipeline::new(config)?, Vec::<Step>::new()));
    }
    let depth = runs[0].0.config().depth;
    let mut truth = Vec::new();
    for i in 0..steps {
        let entry = &sequence.frames[ping_pong(i, len)];
        let frame = read_frame(&dir, entry, &depth)?;
        // 30 frames a second, increasing whichever way the frames are played.
        let t = i as f64 / 30.0;
        if let Some(pose) = sequence.ground_truth_for(entry.timestamp, 0.02) {
            truth.push((t, pose));
        }
        for (slam, record) in &mut runs {
            let report = slam.push_frame(&frame, t)?;
            record.push(step_of(slam, &report));
        }
    }
    println!(
        "{}: {len} frames played forwards and back, {steps} steps",
        dir.display()
    );
    let turn = (len - 1).min(steps.saturating_sub(1));
    println!(
        "window | ATE cm | fuse+predict ms/frame, median per 50 frames | surfels live/active at step {turn} | at step {} | visited by fusion, last 50 (median, k)",
        steps - 1
    );
    for (w, (slam, record)) in windows.iter().zip(&runs) {
        let ate_cm = ate(slam.trajectory(), &truth, 0.01).map_or(f64::NAN, |a| a.rmse_m * 100.0);
        let per_50: Vec<String> = record
            .chunks(50)
            .map(|c| {
                let mut v: Vec<f64> = c.iter().map(|s| s.fuse_predict_ms).collect();
                format!("{:.1}", median(&mut v))
            })
            .collect();
        let at = |i: usize| {
            record.get(i).map_or("-".to_string(), |s| {
                format!("{}k/{}k", s.live / 1000, s.active / 1000)
            })
        };
        let mut visited: Vec<f64> = record
            .iter()
            .rev()
            .take(50)
            .map(|s| s.visited as f64 / 1e3)
            .collect();
        let name = if *w == u32::MAX {
            "unbounded".to_string()
        } else {
            w.to_string()
        };
        println!(
            "{name} | {ate_cm:.3} | {} | {} | {} | {:.0}",
            per_50.join(" "),
            at(turn),
            at(steps - 1),
            median(&mut visited)
        );
    }
    Ok(())
}
