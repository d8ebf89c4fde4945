//! `surfel-slam`: run dense RGB-D SLAM over a dataset folder, or evaluate a trajectory.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use surfel_slam::dataset::{ply::write_ply, read_frame, trajectory, Sequence};
use surfel_slam::eval::{ate, rpe};
use surfel_slam::track::TrackerMode;
use surfel_slam::{CameraPreset, Pipeline, SlamConfig, Verdict};

/// Timestamps of matched poses may differ by this much (seconds; frame numbers match exactly).
const MAX_DT: f64 = 0.02;

#[derive(Parser)]
#[command(
    name = "surfel-slam",
    version,
    about = "Dense RGB-D SLAM with surfel fusion"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Track and fuse a TUM, ICL-NUIM or 7-Scenes folder.
    Run(RunArgs),
    /// ATE and RPE of a TUM-format trajectory against ground truth.
    Eval {
        /// Estimated trajectory (TUM format).
        estimate: PathBuf,
        /// Ground-truth trajectory (TUM format).
        ground_truth: PathBuf,
    },
}

#[derive(Args)]
struct RunArgs {
    /// Dataset folder (layout detected automatically).
    dataset: PathBuf,
    /// Write the estimated trajectory here (TUM format, world_from_camera).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Write the surfel map here (binary PLY).
    #[arg(long)]
    ply: Option<PathBuf>,
    /// First frame to use (0-based).
    #[arg(long, default_value_t = 0)]
    first: usize,
    /// Number of frames to use (default: all).
    #[arg(long)]
    count: Option<usize>,
    /// Camera preset (tum-fr1, tum-fr2, tum-fr3, icl-nuim, 7-scenes); default from the layout.
    #[arg(long)]
    preset: Option<String>,
    /// Tracker: icp (geometry), rgb (photometric) or joint (both).
    #[arg(long)]
    tracker: Option<String>,
    /// Joint mode: weight w of the ICP term (A = A_rgb + w^2 A_icp).
    #[arg(long)]
    icp_weight: Option<f64>,
    #[command(flatten)]
    overrides: CameraOverrides,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct CameraOverrides {
    /// Focal length x, pixels.
    #[arg(long)]
    fx: Option<f32>,
    /// Focal length y, pixels.
    #[arg(long)]
    fy: Option<f32>,
    /// Principal point x, pixels.
    #[arg(long)]
    cx: Option<f32>,
    /// Principal point y, pixels.
    #[arg(long)]
    cy: Option<f32>,
    /// Raw depth units per metre.
    #[arg(long)]
    depth_scale: Option<f32>,
    /// Nearest valid depth, metres.
    #[arg(long)]
    depth_min: Option<f32>,
    /// Farthest valid depth, metres.
    #[arg(long)]
    depth_max: Option<f32>,
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Run(args) => run(&args),
        Command::Eval {
            estimate,
            ground_truth,
        } => evaluate(&estimate, &ground_truth),
    }
}

fn config_for(sequence: &Sequence, args: &RunArgs) -> Result<SlamConfig> {
    let preset = match &args.preset {
        Some(name) => CameraPreset::from_name(name).with_context(|| {
            let names: Vec<_> = CameraPreset::ALL.iter().map(|p| p.name()).collect();
            format!("unknown preset {name:?}; known: {}", names.join(", "))
        })?,
        None => sequence.preset,
    };
    let mut config = SlamConfig::from_preset(preset);
    if let Some(name) = &args.tracker {
        config.tracker.mode = TrackerMode::from_name(name).with_context(|| {
            let names: Vec<_> = TrackerMode::ALL.iter().map(|m| m.name()).collect();
            format!("unknown tracker {name:?}; known: {}", names.join(", "))
        })?;
    }
    if let Some(w) = args.icp_weight {
        if !(w.is_finite() && w >= 0.0) {
            bail!("--icp-weight must be finite and >= 0, got {w}");
        }
        config.tracker.icp_weight = w;
    }
    let o = &args.overrides;
    let k = &mut config.intrinsics;
    k.fx = o.fx.unwrap_or(k.fx);
    k.fy = o.fy.unwrap_or(k.fy);
    k.cx = o.cx.unwrap_or(k.cx);
    k.cy = o.cy.unwrap_or(k.cy);
    let d = &mut config.depth;
    d.scale = o.depth_scale.unwrap_or(d.scale);
    d.min_m = o.depth_min.unwrap_or(d.min_m);
    d.max_m = o.depth_max.unwrap_or(d.max_m);
    Ok(config)
}

fn run(args: &RunArgs) -> Result<()> {
    let sequence = Sequence::open(&args.dataset)
        .with_context(|| format!("opening {}", args.dataset.display()))?;
    let frames: Vec<_> = sequence
        .frames
        .iter()
        .skip(args.first)
        .take(args.count.unwrap_or(usize::MAX))
        .collect();
    if frames.is_empty() {
        bail!(
            "no frames selected: the sequence has {} frames, --first is {}",
            sequence.frames.len(),
            args.first
        );
    }
    let mut config = config_for(&sequence, args)?;
    // The sequence's own image size wins over the preset's.
    let first = read_frame(&args.dataset, frames[0], &config.depth)?;
    config.intrinsics.width = first.width;
    config.intrinsics.height = first.height;
    let mut slam = Pipeline::new(config)?;

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames.len() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let (mut lost, mut failed, mut ms) = (0usize, 0usize, Vec::new());
    for entry in &frames {
        let result = read_frame(&args.dataset, entry, &slam.config().depth)
            .map_err(anyhow::Error::from)
            .and_then(|f| {
                let t0 = std::time::Instant::now();
                let r = slam.push_frame(&f, entry.timestamp)?;
                Ok((r, t0.elapsed().as_secs_f64() * 1000.0))
            });
        match result {
            Ok((report, elapsed)) => {
                ms.push(elapsed);
                if let Verdict::Lost(reason) = report.verdict {
                    lost += 1;
                    bar.println(format!(
                        "frame {} ({}) lost: {}",
                        entry.index,
                        entry.timestamp,
                        reason.name()
                    ));
                }
                bar.set_message(format!("{} surfels", report.surfels));
            }
            Err(e) => {
                failed += 1;
                bar.println(format!("frame {} skipped: {e:#}", entry.index));
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();

    if let Some(path) = &args.trajectory {
        std::fs::write(path, trajectory::format_tum(slam.trajectory()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.ply {
        std::fs::write(path, write_ply(slam.map()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    ms.sort_by(f64::total_cmp);
    let mean = ms.iter().sum::<f64>() / ms.len().max(1) as f64;
    let median = ms.get(ms.len() / 2).copied().unwrap_or(0.0);
    let tracked = slam.trajectory().len() - lost;
    let accuracy = if sequence.ground_truth.is_empty() {
        "ATE n/a (no ground truth)".to_string()
    } else {
        match ate(slam.trajectory(), &sequence.ground_truth, MAX_DT) {
            Ok(a) => format!("ATE {:.3} cm ({} poses)", a.rmse_m * 100.0, a.pairs),
            Err(e) => format!("ATE n/a ({e})"),
        }
    };
    println!(
        "{}: {} frames, {tracked} tracked, {lost} lost, {failed} unreadable, {} surfels, {accuracy}, {mean:.1} ms/frame (median {median:.1})",
        args.dataset.display(),
        frames.len(),
        slam.map().len(),
    );
    Ok(())
}

fn evaluate(estimate: &Path, ground_truth: &Path) -> Result<()> {
    let read = |p: &Path| -> Result<_> {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
        Ok(trajectory::parse_tum(&text, &p.display().to_string())?)
    };
    let (est, gt) = (read(estimate)?, read(ground_truth)?);
    let a = ate(&est, &gt, MAX_DT)?;
    let r = rpe(&est, &gt, MAX_DT)?;
    println!(
        "ATE rmse {:.4} m, mean {:.4} m, median {:.4} m, max {:.4} m ({} poses); RPE {:.4} m, {:.3} deg per frame ({} pairs)",
        a.rmse_m,
        a.mean_m,
        a.median_m,
        a.max_m,
        a.pairs,
        r.translation_rmse_m,
        r.rotation_rmse_rad.to_degrees(),
        r.pairs
    );
    Ok(())
}
