//! Does the map stop growing where the camera returns (issue #51)? The
//! synthetic room circled ten times along its closed loop
//! (`synthetic::loop_pose`, `--frames-per-circle` frames a turn, default
//! 500: 5000 frames), rendered at 640x480, made noisy with the Kinect-v1
//! recipe (`--simulate-noise kinect-v1`, seed 1; `--clean` for none), tracked
//! and fused at half that size with the ICL-NUIM preset's settings (joint
//! tracker). After each circle:
//! surfels, array slots, peak and current RSS, the circle's median
//! milliseconds a frame, verdicts, loop closures (all / global) and ATE
//! so far; and each closure as it happens, with the current pose's distance
//! from the truth before and after it.
//!
//! With `--interleaved`, a twin pipeline plays the first circle again in
//! turns of 25 frames between the last circle's, and the last line gives
//! the last circle's median frame over the twin's: both measured in the
//! same minutes, so the machine's drift falls on both alike (the `bench`
//! command's `interleaved_late_over_early`). The twin's map counts in the
//! last circle's RSS columns.
//!
//! `cargo run --release --example ten_circles [-- --circles N]
//! [--frames-per-circle N] [--clean] [--range-noise-factor F] [--interleaved]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::eval::ate;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::synthetic::{self, loop_pose, NoiseModel, Scene};
use surfel_slam::{CameraPreset, Pipeline, SlamConfig, Verdict};

fn arg(args: &[String], name: &str, default: usize) -> usize {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// `VmHWM` and `VmRSS` of this process, MiB (0 where /proc is absent).
fn rss_mib() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(0.0, |kib| kib / 1024.0)
    };
    (field("VmHWM:"), field("VmRSS:"))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let circles = arg(&args, "--circles", 10);
    let per_circle = arg(&args, "--frames-per-circle", 500).max(1);
    // Rendered and made noisy at 640x480 (the recipe's disparity steps are
    // a Kinect's at that size), tracked and fused at 320x240.
    let k = synthetic::default_intrinsics();
    let mut config = SlamConfig::from_preset(CameraPreset::IclNuim);
    config.intrinsics = k;
    config.half_resolution = true;
    config.depth = synthetic::depth_settings();
    if !args.iter().any(|a| a == "--clean") {
        config.simulate_noise = Some(NoiseSimulation {
            sensor: SimulatedSensor::KinectV1,
            seed: 1,
        });
    }
    if let Some(factor) = args
        .iter()
        .position(|a| a == "--range-noise-factor")
        .and_then(|i| args.get(i + 1))
    {
        config.preprocess.range_noise_factor = factor.parse()?;
    }
    let interleaved = args.iter().any(|a| a == "--interleaved");
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone())?;
    // Made only when asked: its buffers would count in every circle's RSS.
    let mut twin = if interleaved {
        Some(Pipeline::new(config.clone())?)
    } else {
        None
    };
    let mut twin_ms = Vec::new();
    let render = |i: usize| {
        synthetic::render(
            &scene,
            &k,
            &loop_pose(i, per_circle),
            &NoiseModel::none(),
            i as u64,
        )
        .to_frame(&config.depth)
    };
    let origin = loop_pose(0, per_circle).inverse();
    let mut truth = Vec::new();
    println!(
        "circle  surfels    slots  peak-RSS-MiB  RSS-MiB  median-ms  lost  held  closures  ATE-cm"
    );
    for circle in 0..circles {
        let mut ms = Vec::with_capacity(per_circle);
        let (mut lost, mut held) = (0, 0);
        let mut last = None;
        for j in 0..per_circle {
            let i = circle * per_circle + j;
            if let Some(twin) = twin
                .as_mut()
                .filter(|_| circle + 1 == circles && j % 25 == 0)
            {
                for t in j..(j + 25).min(per_circle) {
                    let report = twin.push_frame(&render(t)?, t as f64)?;
                    twin_ms.push(report.timings.total_ms);
                }
            }
            let pose = loop_pose(i, per_circle);
            let report = slam.push_frame(&render(i)?, i as f64)?;
            ms.push(report.timings.total_ms);
            lost += usize::from(matches!(report.verdict, Verdict::Lost(_)));
            held += usize::from(report.verdict == Verdict::Held);
            truth.push((i as f64, origin * pose));
            let outcome = &report.loop_outcome;
            if outcome.closed {
                // How far the current pose was from the truth before and after the bend.
                let true_pose = origin * pose;
                let off =
                    |p: &glam::DAffine3| 100.0 * (p.translation - true_pose.translation).length();
                let what = match &outcome.global {
                    Some(g) if g.closed => format!(
                        "global{}, keyframe {}, correction {:.2} cm {:.2} deg",
                        if g.pose_only { " (pose only)" } else { "" },
                        g.keyframe_frame,
                        100.0 * g.correction_m,
                        g.correction_deg
                    ),
                    _ => "local".to_string(),
                };
                println!(
                    "  frame {i}: {what} closure, pose {:.2} cm from the truth before, {:.2} cm after",
                    off(&outcome.tracked),
                    off(&report.world_from_camera)
                );
            }
            last = Some(report);
        }
        let median_ms = median(&mut ms);
        let (peak, rss) = rss_mib();
        let a = ate(slam.trajectory(), &truth, 0.01)?;
        let report = last.expect("a frame");
        println!(
            "{:6} {:8} {:8} {:13.0} {:8.0} {:10.1} {:5} {:5} {:5}/{:<3} {:7.3}",
            circle + 1,
            report.surfels,
            report.surfel_slots,
            peak,
            rss,
            median_ms,
            lost,
            held,
            slam.loop_closures(),
            slam.global_loop_closures(),
            100.0 * a.rmse_m
        );
        if !twin_ms.is_empty() {
            let first = median(&mut twin_ms);
            println!(
                "interleaved: circle {circles}'s median frame {median_ms:.1} ms, circle 1's played beside it {first:.1} ms, ratio {:.3}",
                median_ms / first
            );
        }
    }
    Ok(())
}

/// The median of `values` (sorted in place); 0 for none.
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}
