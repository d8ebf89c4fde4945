//! `surfel-slam`: run dense RGB-D SLAM over a dataset folder, or evaluate a trajectory.
//!
//! Exit codes: 0 success; 1 the run could not start or finish (unreadable
//! folder, unknown layout, camera settings that do not fit the images, ...;
//! the message names the file or setting); 2 bad command line (unknown
//! option, tracker or preset, a number that is not finite or out of range;
//! clap names the option); 3 the run finished but some frames were skipped
//! as unreadable (each was named on stderr).

mod bench;
mod evaluate;
mod plot;

use anyhow::{bail, Context, Result};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use surfel_slam::dataset::{ply::write_ply, trajectory, DatasetSource, FrameEntry, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::fusion::{FusionConfig, SurfelMap};
use surfel_slam::mesh::{
    read_surfel_ply, write_mesh, MeshConfig, MeshFormat, Mesher, TriangleMesh,
};
use surfel_slam::track::{TrackerConfig, TrackerMode};
use surfel_slam::{CameraPreset, Pipeline, SensorNoise, SlamConfig, Verdict};

/// Timestamps of matched poses may differ by this much (seconds; frame numbers match exactly).
pub(crate) const MAX_DT: f64 = 0.02;

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
    /// Time every stage over a sequence (files preloaded; decode included):
    /// medians per stage and per frame, peak memory.
    Bench(bench::BenchArgs),
    /// Mesh a saved surfel map (binary PLY, as `run --ply` writes it).
    Mesh(MeshArgs),
    /// ATE and RPE of a TUM-format trajectory against ground truth;
    /// optionally the per-pose errors as CSV and a plot.
    Eval(evaluate::EvalArgs),
}

#[derive(Args)]
struct RunArgs {
    /// Dataset folder, or archive (.zip, .tar, .tar.gz / .tgz) read in place;
    /// layout detected automatically.
    dataset: PathBuf,
    /// Write the estimated trajectory here (TUM format, world_from_camera).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Also write the online trajectory here: each pose as tracked, before
    /// loop closures corrected it (TUM format, world_from_camera).
    #[arg(long)]
    online_trajectory: Option<PathBuf>,
    /// Write the surfel map here (binary PLY).
    #[arg(long)]
    ply: Option<PathBuf>,
    /// First frame to use (0-based).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    first: usize,
    /// Number of frames to use [default: all].
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    count: Option<usize>,
    /// Keep every Nth frame only (simulates dropped frames or a slower camera).
    #[arg(
        long,
        default_value_t = 1,
        allow_negative_numbers = true,
        value_parser = clap::value_parser!(u32).range(1..)
    )]
    stride: u32,
    #[command(flatten)]
    camera: CameraOverrides,
    #[command(flatten)]
    tracking: TrackingArgs,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Write a triangle mesh of the confident surfels here (.glb, .ply or .obj).
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Voxel edge of the mesh, metres.
    #[arg(long, default_value_t = MeshConfig::default().voxel_size_m)]
    voxel_size: f32,
}

#[derive(Args)]
struct MeshArgs {
    /// Surfel map (binary little-endian PLY with x y z nx ny nz; colours,
    /// radius and confidence used when present).
    map: PathBuf,
    /// Output mesh (.glb, .ply or .obj).
    #[arg(long, short)]
    output: PathBuf,
    /// Voxel edge, metres.
    #[arg(long, default_value_t = MeshConfig::default().voxel_size_m)]
    voxel_size: f32,
    /// Use only surfels at least this confident (default: fusion's stable confidence).
    #[arg(long, default_value_t = MeshConfig::default().min_confidence)]
    min_confidence: f32,
}

/// Processing options shared by `run` and `bench`.
#[derive(Args)]
pub(crate) struct TrackingArgs {
    /// Track and fuse at half resolution (e.g. 320x240 from 640x480).
    #[arg(long)]
    half: bool,
    /// Surfel budget: when the map holds this many, stale unstable surfels
    /// are evicted and further new surfels skipped (merges continue).
    #[arg(
        long,
        default_value_t = FusionConfig::default().max_surfels,
        allow_negative_numbers = true,
        value_parser = positive
    )]
    max_surfels: usize,
    /// Tracker: icp (geometry), rgb (photometric) or joint (both).
    #[arg(
        long,
        default_value = TrackerMode::default().name(),
        value_parser = tracker_parser()
    )]
    tracker: TrackerMode,
    /// Joint mode: weight w of the ICP term (A = A_rgb + w^2 A_icp).
    #[arg(
        long,
        default_value_t = TrackerConfig::default().icp_weight,
        allow_negative_numbers = true,
        value_parser = non_negative
    )]
    icp_weight: f64,
    /// Depth noise model weighting tracking and fusion: kinect-v1,
    /// structured-light, rendered, uniform (no weighting), or coefficients
    /// `base,quadratic[,offset[,angle[,lateral_px[,edge]]]]` of
    /// sigma_z = base + quadratic (z - offset)^2 (metres) [default: preset's:
    /// uniform for tum-fr1/tum-fr2/tum-fr3/7-scenes, rendered icl-nuim].
    #[arg(long, value_parser = noise_parser)]
    noise: Option<SensorNoise>,
    /// Experiments: smallest noise weight of a fused measurement.
    #[arg(long, hide = true)]
    min_noise_weight: Option<f32>,
}

impl TrackingArgs {
    pub(crate) fn apply(&self, config: &mut SlamConfig) {
        config.half_resolution = self.half;
        config.fusion.max_surfels = self.max_surfels;
        config.tracker.mode = self.tracker;
        config.tracker.icp_weight = self.icp_weight;
        if let Some(noise) = self.noise {
            config.set_noise(noise);
        }
        if let Some(w) = self.min_noise_weight {
            config.fusion.min_noise_weight = w;
        }
    }
}

/// Parses a noise model name or its coefficients (see `--noise`).
fn noise_parser(s: &str) -> Result<SensorNoise, String> {
    if let Some(noise) = SensorNoise::from_name(s) {
        return Ok(noise);
    }
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<Result<_, _>>()
        .map_err(|e| {
            format!(
                "expected one of {} or base,quadratic[,offset,angle,lateral_px,edge]: {e}",
                SensorNoise::NAMES.join(", ")
            )
        })?;
    if !(2..=6).contains(&values.len()) {
        return Err(format!(
            "expected 2 to 6 coefficients, got {}",
            values.len()
        ));
    }
    let at = |i: usize| values.get(i).copied();
    let noise = SensorNoise {
        base_m: values[0],
        quadratic_per_m: values[1],
        offset_m: at(2).unwrap_or(0.0),
        angle_m: at(3).unwrap_or(0.0),
        lateral_px: at(4).unwrap_or(0.0),
        edge_factor: at(5).unwrap_or(1.0),
    };
    match noise.problem() {
        Some(problem) => Err(problem),
        None => Ok(noise),
    }
}

/// Parses a tracker name; the names are listed in `--help` and in the error.
fn tracker_parser() -> impl TypedValueParser<Value = TrackerMode> {
    PossibleValuesParser::new(TrackerMode::ALL.map(TrackerMode::name)).try_map(|name: String| {
        TrackerMode::from_name(&name).ok_or_else(|| format!("unknown tracker {name:?}"))
    })
}

/// Parses a camera preset name; the names are listed in `--help` and in the error.
fn preset_parser() -> impl TypedValueParser<Value = CameraPreset> {
    PossibleValuesParser::new(CameraPreset::ALL.map(CameraPreset::name)).try_map(|name: String| {
        CameraPreset::from_name(&name).ok_or_else(|| format!("unknown preset {name:?}"))
    })
}

/// A finite number (negative allowed: ICL-NUIM's fy is -480).
fn finite(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("{v} is not a finite number")),
        Err(e) => Err(e.to_string()),
    }
}

/// A whole number >= 1.
pub(crate) fn positive(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1".to_owned()),
        Ok(v) => Ok(v),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number >= 0.
pub(crate) fn non_negative(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Ok(v) => Err(format!("{v} is not a finite number >= 0")),
        Err(e) => Err(e.to_string()),
    }
}

/// Help text for a camera setting whose default depends on the preset:
/// each distinct preset value with the presets that use it.
fn preset_help(what: &str, value: fn(CameraPreset) -> f32) -> String {
    let mut groups: Vec<(f32, Vec<&str>)> = Vec::new();
    for p in CameraPreset::ALL {
        let v = value(p);
        match groups.iter_mut().find(|(g, _)| *g == v) {
            Some((_, names)) => names.push(p.name()),
            None => groups.push((v, vec![p.name()])),
        }
    }
    let list: Vec<String> = groups
        .iter()
        .map(|(v, names)| format!("{v} {}", names.join("/")))
        .collect();
    match groups.as_slice() {
        [(v, _)] => format!("{what} [default: {v}, every preset]"),
        _ => format!("{what} [default: preset's: {}]", list.join(", ")),
    }
}

#[derive(Args)]
pub(crate) struct CameraOverrides {
    /// Camera preset [default: from the folder's layout].
    #[arg(long, value_parser = preset_parser())]
    preset: Option<CameraPreset>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Focal length x, pixels", |p| p.intrinsics().fx))]
    fx: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Focal length y, pixels (negative: image y axis points up)", |p| p.intrinsics().fy))]
    fy: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Principal point x, pixels", |p| p.intrinsics().cx))]
    cx: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Principal point y, pixels", |p| p.intrinsics().cy))]
    cy: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Raw depth units per metre", |p| p.depth_settings().scale))]
    depth_scale: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Nearest valid depth, metres", |p| p.depth_settings().min_m))]
    depth_min: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Farthest valid depth, metres", |p| p.depth_settings().max_m))]
    depth_max: Option<f32>,
}

/// Exit code of a run that finished with some frames skipped as unreadable.
const EXIT_FRAMES_SKIPPED: u8 = 3;

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Run(args) => run(&args),
        Command::Bench(args) => bench::bench(&args).map(|()| 0),
        Command::Mesh(args) => mesh_file(&args).map(|()| 0),
        Command::Eval(args) => evaluate::evaluate(&args).map(|()| 0),
    };
    match result {
        Ok(0) => ExitCode::SUCCESS,
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {}", describe(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by ": ", skipping a cause whose text the
/// message already holds (library errors name their file and repeat their
/// source's text).
fn describe(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

/// The configuration for `sequence` with the command line's camera and
/// tracking options applied, validated.
pub(crate) fn config_for(
    sequence: &Sequence,
    o: &CameraOverrides,
    tracking: &TrackingArgs,
) -> Result<SlamConfig> {
    let mut config = SlamConfig::from_preset(o.preset.unwrap_or(sequence.preset));
    let k = &mut config.intrinsics;
    k.fx = o.fx.unwrap_or(k.fx);
    k.fy = o.fy.unwrap_or(k.fy);
    k.cx = o.cx.unwrap_or(k.cx);
    k.cy = o.cy.unwrap_or(k.cy);
    let d = &mut config.depth;
    d.scale = o.depth_scale.unwrap_or(d.scale);
    d.min_m = o.depth_min.unwrap_or(d.min_m);
    d.max_m = o.depth_max.unwrap_or(d.max_m);
    tracking.apply(&mut config);
    // Refuse bad camera settings before reading any image.
    config.validate()?;
    Ok(config)
}

/// The first frame that decodes, for the sequence's image size; the frames
/// before it are named on stderr.
fn first_readable(
    source: &mut DatasetSource,
    frames: &[&FrameEntry],
    config: &SlamConfig,
) -> Result<(usize, usize)> {
    let mut last_error = None;
    for entry in frames {
        match source.read_frame(entry, &config.depth) {
            Ok(f) => return Ok((f.width, f.height)),
            Err(e) => {
                eprintln!("frame {} unreadable: {e}", entry.index);
                last_error = Some(e);
            }
        }
    }
    match last_error {
        Some(e) => Err(e).context("no frame of the sequence could be read"),
        None => bail!("no frames selected"),
    }
}

fn run(args: &RunArgs) -> Result<u8> {
    // A folder or an archive (.zip, .tar, .tar.gz), read in place.
    let mut source = DatasetSource::open(&args.dataset)
        .with_context(|| format!("opening {}", args.dataset.display()))?;
    let sequence = source
        .sequence()
        .with_context(|| format!("opening {}", args.dataset.display()))?;
    for warning in &sequence.warnings {
        eprintln!("warning: {warning}");
    }
    let frames: Vec<_> = sequence
        .frames
        .iter()
        .skip(args.first)
        .step_by(args.stride as usize)
        .take(args.count.unwrap_or(usize::MAX))
        .collect();
    if frames.is_empty() {
        bail!(
            "no frames selected: the sequence has {} frames, --first is {}",
            sequence.frames.len(),
            args.first
        );
    }
    // Refuse a bad mesh path or voxel size before the run, not after it.
    let mesh_config = MeshConfig {
        voxel_size_m: args.voxel_size,
        ..MeshConfig::default()
    };
    if let Some(path) = &args.mesh {
        mesh_format(path)?;
        mesh_config.validate()?;
    }
    let mut config = config_for(&sequence, &args.camera, &args.tracking)?;
    // The sequence's own image size wins over the preset's.
    let (width, height) = first_readable(&mut source, &frames, &config)?;
    config.intrinsics.width = width;
    config.intrinsics.height = height;
    let mut slam = Pipeline::new(config)?;

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames.len() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames, {fps}, ETA {eta}, {msg}")
            .map(|s| {
                s.with_key(
                    "fps",
                    |state: &ProgressState, w: &mut dyn std::fmt::Write| {
                        let _ = write!(w, "{:.1} fps", state.per_sec());
                    },
                )
            })
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let (mut failed, mut streak, mut ms) = (0usize, 0u32, Vec::new());
    for entry in &frames {
        let result = source
            .read_frame(entry, &slam.config().depth)
            .map_err(anyhow::Error::from)
            .and_then(|f| {
                let t0 = std::time::Instant::now();
                let r = slam
                    .push_frame(&f, entry.timestamp)
                    .with_context(|| format!("{} + {}", entry.colour, entry.depth))?;
                Ok((r, t0.elapsed().as_secs_f64() * 1000.0))
            });
        match result {
            Ok((report, elapsed)) => {
                ms.push(elapsed);
                match report.verdict {
                    // suspend, not println: a hidden bar (--quiet, no
                    // terminal) drops println's lines.
                    Verdict::Lost(reason) => bar.suspend(|| {
                        eprintln!(
                            "frame {} ({}) lost: {} (map kept, frame not fused)",
                            entry.index,
                            entry.timestamp,
                            reason.name()
                        );
                    }),
                    Verdict::Recovered => bar.suspend(|| {
                        let why = if streak == 0 {
                            "the normal tracker failed".to_owned()
                        } else {
                            format!("{streak} lost frame(s)")
                        };
                        eprintln!(
                            "frame {} ({}) recovered: re-acquired against the map after {why}",
                            entry.index, entry.timestamp,
                        );
                    }),
                    _ => {}
                }
                streak = report.counts.lost_streak;
                bar.set_message(format!(
                    "{} surfels, {} lost, {} recovered",
                    report.surfels, report.counts.lost, report.counts.recovered
                ));
            }
            Err(e) => {
                failed += 1;
                bar.suspend(|| eprintln!("frame {} skipped: {}", entry.index, describe(&e)));
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();

    for (path, poses) in [
        (&args.trajectory, slam.trajectory()),
        (&args.online_trajectory, slam.online_trajectory()),
    ] {
        if let Some(path) = path {
            std::fs::write(path, trajectory::format_tum(poses))
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if let Some(path) = &args.ply {
        std::fs::write(path, write_ply(slam.map()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.mesh {
        let config = MeshConfig {
            min_confidence: slam.config().fusion.stable_confidence,
            ..mesh_config
        };
        write_mesh_file(slam.map(), &config, path, args.quiet)?;
    }
    ms.sort_by(f64::total_cmp);
    let mean = ms.iter().sum::<f64>() / ms.len().max(1) as f64;
    let median = ms.get(ms.len() / 2).copied().unwrap_or(0.0);
    let counts = slam.counts();
    let accuracy = if sequence.ground_truth.is_empty() {
        "ATE n/a (no ground truth)".to_string()
    } else {
        match ate(slam.trajectory(), &sequence.ground_truth, MAX_DT) {
            Ok(a) => format!("ATE {} ({} poses)", evaluate::cm(a.rmse_m), a.pairs),
            Err(e) => format!("ATE n/a ({e})"),
        }
    };
    println!(
        "{}: {} frames, {} tracked, {} lost, {} recovered, {failed} unreadable, {} loop closures, {} surfels, {accuracy}, {mean:.1} ms/frame (median {median:.1})",
        args.dataset.display(),
        frames.len(),
        counts.tracked,
        counts.lost,
        counts.recovered,
        slam.loop_closures(),
        slam.map().live_len(),
    );
    Ok(if failed > 0 { EXIT_FRAMES_SKIPPED } else { 0 })
}

fn mesh_format(path: &Path) -> Result<MeshFormat> {
    MeshFormat::from_path(path).with_context(|| {
        format!(
            "{}: unknown mesh format; use a .glb, .ply or .obj file name",
            path.display()
        )
    })
}

/// Meshes `map` and writes the mesh to `path` (format from the extension);
/// prints one line with the counts and the time.
fn write_mesh_file(map: &SurfelMap, config: &MeshConfig, path: &Path, quiet: bool) -> Result<()> {
    let format = mesh_format(path)?;
    let t0 = std::time::Instant::now();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(100)
    };
    let mut mesh = TriangleMesh::default();
    let stats = Mesher::new().mesh_into(map, config, &mut mesh, &mut |f| {
        bar.set_position((f * 100.0) as u64);
    })?;
    bar.finish_and_clear();
    let ms = t0.elapsed().as_secs_f64() * 1000.0;
    std::fs::write(path, write_mesh(&mesh, format))
        .with_context(|| format!("writing {}", path.display()))?;
    println!(
        "{}: {} vertices, {} triangles from {} surfels ({} voxel blocks of {} m voxels), meshed in {ms:.0} ms",
        path.display(),
        stats.vertices,
        stats.triangles,
        stats.surfels_used,
        stats.blocks,
        config.voxel_size_m
    );
    Ok(())
}

fn mesh_file(args: &MeshArgs) -> Result<()> {
    mesh_format(&args.output)?;
    let config = MeshConfig {
        voxel_size_m: args.voxel_size,
        min_confidence: args.min_confidence,
        ..MeshConfig::default()
    };
    config.validate()?;
    let bytes =
        std::fs::read(&args.map).with_context(|| format!("reading {}", args.map.display()))?;
    let map = read_surfel_ply(&bytes).with_context(|| args.map.display().to_string())?;
    write_mesh_file(&map, &config, &args.output, false)
}
