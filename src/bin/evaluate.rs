//! `surfel-slam eval`: ATE and RPE of a trajectory file against ground
//! truth, the per-pose errors as CSV, and a plot.

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use surfel_slam::dataset::trajectory;
use surfel_slam::eval::{ate_report, rpe_with, Association, AteReport};

use crate::{non_negative, plot, MAX_DT};

/// How estimate poses find their ground-truth pose.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AssociateBy {
    /// Nearest timestamp within --max-dt (TUM's associate.py).
    Time,
    /// Equal whole frame numbers in the first column (ICL-NUIM).
    Id,
    /// The i-th pose of each file, whatever its first column.
    Order,
}

#[derive(Args)]
pub struct EvalArgs {
    /// Estimated trajectory (TUM format: `timestamp tx ty tz qx qy qz qw`,
    /// world_from_camera, metres).
    estimate: PathBuf,
    /// Ground-truth trajectory (TUM format).
    ground_truth: PathBuf,
    /// How poses are paired.
    #[arg(long, value_enum, default_value_t = AssociateBy::Time)]
    associate: AssociateBy,
    /// Largest timestamp difference of a pair, in the files' unit (seconds
    /// for TUM); `--associate time` only.
    #[arg(long, default_value_t = MAX_DT, allow_negative_numbers = true, value_parser = non_negative)]
    max_dt: f64,
    /// Write one row per matched pose here: timestamps, position error (m),
    /// rotation error (deg), aligned estimate and ground-truth positions (m).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Plot the trajectories (top view, aligned as ATE aligns them) and the
    /// position error over time here; `.svg` or `.png`.
    #[arg(long, value_parser = plot::parse_path)]
    plot: Option<PathBuf>,
}

impl AssociateBy {
    fn association(self, max_dt: f64) -> Association {
        match self {
            Self::Time => Association::Timestamp { max_dt },
            Self::Id => Association::FrameId,
            Self::Order => Association::Order,
        }
    }

    fn describe(self, max_dt: f64) -> String {
        match self {
            Self::Time => format!("by timestamp, |dt| <= {max_dt}"),
            Self::Id => "by frame id".to_owned(),
            Self::Order => "by row order".to_owned(),
        }
    }
}

/// `v` with at least three decimals and three significant digits (a
/// synthetic sequence's ATE is a hundredth of a millimetre).
fn digits(v: f64) -> String {
    let magnitude = if v > 0.0 { v.log10().floor() } else { 0.0 };
    let decimals = (2.0 - magnitude).clamp(3.0, 9.0) as usize;
    format!("{v:.decimals$}")
}

/// `metres` in centimetres, as [`digits`].
pub fn cm(metres: f64) -> String {
    format!("{} cm", digits(metres * 100.0))
}

fn read(path: &Path) -> Result<Vec<(f64, glam::DAffine3)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(trajectory::parse_tum(&text, &path.display().to_string())?)
}

/// The CSV of `report`: a header, then one row per matched pose.
pub fn csv(report: &AteReport) -> String {
    let mut out = String::from(
        "timestamp,ground_truth_timestamp,position_error_m,rotation_error_deg,\
         estimate_x,estimate_y,estimate_z,ground_truth_x,ground_truth_y,ground_truth_z\n",
    );
    for e in &report.errors {
        let (a, g) = (e.aligned_position, e.ground_truth_position);
        // Display of f64 is the shortest text that reads back exactly.
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{}",
            e.timestamp,
            e.ground_truth_timestamp,
            e.position_error_m,
            e.rotation_error_rad.to_degrees(),
            a.x,
            a.y,
            a.z,
            g.x,
            g.y,
            g.z
        );
    }
    out
}

pub fn evaluate(args: &EvalArgs) -> Result<()> {
    let (est, gt) = (read(&args.estimate)?, read(&args.ground_truth)?);
    let association = args.associate.association(args.max_dt);
    let report = ate_report(&est, &gt, association)?;
    let rpe = rpe_with(&est, &gt, association)?;
    let a = &report.summary;
    println!(
        "ATE rmse {}, mean {}, median {}, max {} ({} of {} estimate poses matched {})",
        cm(a.rmse_m),
        cm(a.mean_m),
        cm(a.median_m),
        cm(a.max_m),
        a.pairs,
        est.len(),
        args.associate.describe(args.max_dt),
    );
    println!(
        "RPE {}, {} deg per frame ({} steps)",
        cm(rpe.translation_rmse_m),
        digits(rpe.rotation_rmse_rad.to_degrees()),
        rpe.pairs
    );
    if let Some(path) = &args.csv {
        std::fs::write(path, csv(&report))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.plot {
        let axis = match args.associate {
            AssociateBy::Order => plot::TimeAxis::Row,
            _ if est.iter().chain(&gt).all(|(t, _)| t.fract() == 0.0) => plot::TimeAxis::Frame,
            _ => plot::TimeAxis::Seconds,
        };
        plot::write(path, &report, axis).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
