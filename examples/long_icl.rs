//! A long run made of the shared ICL-NUIM kt0 frames (150) played forwards
//! and backwards until `--frames` (default 1500) are pushed, clean and with
//! Kinect-v1 structured-light noise drawn anew on every pass: the nearest
//! thing here to the 1508-frame ICL-NUIM checks kept outside the project
//! (issue #32). Default settings (the ICL-NUIM preset). Prints ATE, verdict
//! counts, held frames, closures (local / global) and, for every closure,
//! how far the current pose was from the truth before and after it.
//!
//! `cargo run --release --example long_icl [-- --frames N] [--clean|--noisy]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use glam::DAffine3;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::synthetic::StructuredLight;
use surfel_slam::{Pipeline, RgbdFrame, SlamConfig, Verdict};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames: usize = args
        .iter()
        .position(|a| a == "--frames")
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(1500), |s| s.parse())?;
    let which: Vec<bool> = if args.iter().any(|a| a == "--clean") {
        vec![false]
    } else if args.iter().any(|a| a == "--noisy") {
        vec![true]
    } else {
        vec![false, true]
    };
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/icl_office_kt0");
    let sequence = Sequence::open(&dir)?;
    let base = SlamConfig::from_preset(sequence.preset);
    let clean: Vec<(RgbdFrame, DAffine3)> = sequence
        .frames
        .iter()
        .filter_map(|e| {
            let gt = sequence.ground_truth_for(e.timestamp, 0.02)?;
            Some((read_frame(&dir, e, &base.depth).ok()?, gt))
        })
        .collect();
    let n = clean.len();
    // 0, 1, .., n-1, n-2, .., 1, 0, 1, ..: no frame shown twice in a row.
    let order: Vec<usize> = (0..frames)
        .map(|p| {
            let period = 2 * (n - 1);
            let q = p % period;
            if q < n {
                q
            } else {
                period - q
            }
        })
        .collect();
    for noisy in which {
        let noise = StructuredLight::kinect();
        // The pipeline chooses the preset's noise model from the first frame.
        let config = base.clone();
        let mut slam = Pipeline::new(config.clone())?;
        let mut truth = Vec::new();
        let mut held = 0usize;
        let mut closures = Vec::new();
        let mut last = None;
        for (p, &j) in order.iter().enumerate() {
            let (frame, gt) = &clean[j];
            let frame = if noisy {
                noise.measured(
                    frame,
                    &frame.depth_m,
                    &config.intrinsics,
                    (p as u64, config.depth.max_m),
                )
            } else {
                frame.clone()
            };
            let r = slam.push_frame(&frame, p as f64)?;
            truth.push((p as f64, *gt));
            if r.verdict == Verdict::Held {
                held += 1;
            }
            if r.loop_outcome.closed {
                closures.push((
                    p,
                    r.loop_outcome.decision().unwrap_or_default(),
                    (r.loop_outcome.tracked.translation - gt.translation).length(),
                    r.world_from_camera,
                ));
            }
            last = Some(r);
        }
        let a = ate(slam.trajectory(), &truth, 0.01)?;
        let online = ate(slam.online_trajectory(), &truth, 0.01)?;
        let r = last.expect("frames");
        println!(
            "{} {} frames: ATE {:.4} cm (online {:.4} cm), {} tracked, {} recovered, {} lost, {held} held, {} closures",
            if noisy { "noisy" } else { "clean" },
            order.len(),
            a.rmse_m * 100.0,
            online.rmse_m * 100.0,
            r.counts.tracked,
            r.counts.recovered,
            r.counts.lost,
            r.loop_closures,
        );
        for (p, decision, before, after) in closures {
            // Before/after in the first camera's frame: the ground truth is
            // aligned by the whole run's alignment.
            let truth_here = truth[p].1.translation;
            let align = a.ground_truth_from_estimate;
            let after_m = (align.transform_point3(after.translation) - truth_here).length();
            println!(
                "  closure at {p} ({decision}): tracked pose off the truth {:.2} cm (unaligned), corrected {:.2} cm (aligned)",
                before * 100.0,
                after_m * 100.0
            );
        }
    }
    Ok(())
}
