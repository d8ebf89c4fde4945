//! `surfel-slam`: run dense RGB-D SLAM over a dataset folder, or evaluate a trajectory.
//!
//! Exit codes (the table in docs/cli.md): 0 success; 1 the run could not start or
//! finish (unreadable folder, unknown layout, a setting that does not fit
//! this data: a focal length implausible for the image size, a principal
//! point outside it, a depth bound beyond the preset's other bound; the
//! message names the file or setting); 2 bad command line, whatever the
//! data: unknown command, option, tracker or preset, a number that is not a
//! number, not finite or outside the option's range, `--depth-min` not
//! below `--depth-max`, an output file extension of no known format. Exit 2
//! is decided before any file is read; 3 the run finished but some frames
//! were skipped as unreadable (each was named on stderr).

mod bench;
mod evaluate;
mod frame_log;
mod imu_feed;
mod loop_log;
mod mesh_file;
mod plot;
mod run;
mod summary;

use anyhow::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::parser::ValueSource;
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use surfel_slam::camera::Intrinsics;
use surfel_slam::dataset::Sequence;
use surfel_slam::fusion::FusionConfig;
use surfel_slam::mesh::{MeshFormat, VOXEL_SIZE_RANGE_M};
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::track::{TrackerConfig, TrackerMode};
use surfel_slam::{CameraPreset, SensorNoise, SlamConfig};

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
    /// Track and fuse a TUM, ICL-NUIM, 7-Scenes, RealSense or Stray Scanner folder.
    Run(Box<run::RunArgs>),
    /// Time every stage over a sequence (files preloaded; decode included):
    /// medians per stage and per frame, peak memory.
    Bench(bench::BenchArgs),
    /// Mesh a saved surfel map (binary PLY, as `run --ply` writes it).
    Mesh(mesh_file::MeshArgs),
    /// ATE and RPE of a TUM-format trajectory against ground truth;
    /// optionally the per-pose errors as CSV and a plot.
    Eval(evaluate::EvalArgs),
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
    /// Tracker: icp (geometry), rgb (photometric) or joint (both)
    /// [default: the preset's: joint for icl-nuim, icp for the others].
    #[arg(long, value_parser = tracker_parser())]
    tracker: Option<TrackerMode>,
    /// Joint mode: weight w of the ICP term (A = A_rgb + w^2 A_icp).
    #[arg(
        long,
        default_value_t = TrackerConfig::default().icp_weight,
        allow_negative_numbers = true,
        value_parser = non_negative
    )]
    icp_weight: f64,
    /// Depth noise model weighting tracking and fusion: kinect-v1,
    /// structured-light, simulated-kinect, active-stereo, lidar, rendered,
    /// uniform (no weighting), or coefficients
    /// `base,quadratic[,offset[,angle[,lateral_px[,edge]]]]` of
    /// sigma_z = base + quadratic (z - offset)^2 (metres) [default: preset's:
    /// uniform for tum-fr1/tum-fr2/tum-fr3, kinect-v1 for 7-scenes,
    /// active-stereo for realsense-d400, lidar for stray-lidar; icl-nuim:
    /// rendered when the first frame's depth is clean, else simulated-kinect].
    #[arg(long, value_parser = noise_parser)]
    noise: Option<SensorNoise>,
    /// Experiments: smallest noise weight of a fused measurement.
    #[arg(long, hide = true, allow_negative_numbers = true, value_parser = non_negative_f32)]
    min_noise_weight: Option<f32>,
    /// Hold a lost camera at its last placed pose instead of carrying it on
    /// frame to frame by the feature estimate (to see what dead reckoning
    /// does on a sequence).
    #[arg(long)]
    no_dead_reckoning: bool,
    /// After this many frames lost in a row, map on from the last placed
    /// pose in a new segment, joined to the map so far once a frame is
    /// placed in it (0: stay lost until re-acquired).
    #[arg(long, default_value_t = surfel_slam::pipeline::DEFAULT_RESTART_AFTER_LOST)]
    restart_after_lost: u32,
    /// Track and fuse near parts of the image that stay put while the
    /// camera moves (a hand holding it), which are otherwise left out.
    #[arg(long)]
    no_hand_mask: bool,
    /// Simulate a sensor's noise on the (clean) input depth: kinect-v1
    /// (ICL-NUIM's recipe: jitter, disparity noise, 1/8 px steps).
    #[arg(long, value_parser = simulated_sensor_parser)]
    simulate_noise: Option<SimulatedSensor>,
    /// With --simulate-noise: the draw (the same seed gives the same noise).
    #[arg(long, default_value_t = 1, requires = "simulate_noise")]
    noise_seed: u64,
}

/// Parses a simulated sensor's name (see `--simulate-noise`).
fn simulated_sensor_parser(s: &str) -> Result<SimulatedSensor, String> {
    SimulatedSensor::from_name(s).ok_or_else(|| {
        let names: Vec<_> = SimulatedSensor::ALL.iter().map(|s| s.name()).collect();
        format!("expected one of {}", names.join(", "))
    })
}

/// A noise model's name, or its coefficients when it has none.
fn noise_name(noise: &SensorNoise) -> String {
    SensorNoise::NAMES
        .iter()
        .find(|n| SensorNoise::from_name(n).as_ref() == Some(noise))
        .map_or_else(|| format!("{noise:?}"), |n| (*n).to_owned())
}

impl TrackingArgs {
    /// The options among `given` (ids given on the command line) whose
    /// value differs from `session`'s configuration (`session_noise`: its
    /// tracker noise model as configured), each as `--option value (the
    /// session's: value)`: a loaded session keeps its own settings.
    pub(crate) fn overridden_by(
        &self,
        given: &[String],
        session: &SlamConfig,
        session_noise: &SensorNoise,
    ) -> Vec<String> {
        let noise = self
            .noise
            .map(|n| (noise_name(&n), noise_name(session_noise)));
        let min_weight = self
            .min_noise_weight
            .map(|w| (w.to_string(), session.fusion.min_noise_weight.to_string()));
        let options = [
            (
                "half",
                "--half",
                Some((self.half.to_string(), session.half_resolution.to_string())),
            ),
            (
                "max_surfels",
                "--max-surfels",
                Some((
                    self.max_surfels.to_string(),
                    session.fusion.max_surfels.to_string(),
                )),
            ),
            (
                "tracker",
                "--tracker",
                self.tracker.map(|mode| {
                    (
                        mode.name().to_owned(),
                        session.tracker.mode.name().to_owned(),
                    )
                }),
            ),
            (
                "icp_weight",
                "--icp-weight",
                Some((
                    self.icp_weight.to_string(),
                    session.tracker.icp_weight.to_string(),
                )),
            ),
            ("noise", "--noise", noise),
            ("min_noise_weight", "--min-noise-weight", min_weight),
        ];
        options
            .into_iter()
            .filter(|(id, ..)| given.iter().any(|g| g == id))
            .filter_map(|(_, flag, values)| {
                let (ours, theirs) = values?;
                (ours != theirs).then(|| format!("{flag} {ours} (the session's: {theirs})"))
            })
            .collect()
    }

    pub(crate) fn apply(&self, config: &mut SlamConfig) {
        config.half_resolution = self.half;
        config.fusion.max_surfels = self.max_surfels;
        if let Some(mode) = self.tracker {
            config.tracker.mode = mode;
        }
        config.tracker.icp_weight = self.icp_weight;
        if let Some(noise) = self.noise {
            config.set_noise(noise);
        }
        if let Some(w) = self.min_noise_weight {
            config.fusion.min_noise_weight = w;
        }
        config.tracker.verify.dead_reckoning = !self.no_dead_reckoning;
        config.restart_after_lost = self.restart_after_lost;
        if self.no_hand_mask {
            config.preprocess.camera_fixed_frames = 0;
        }
        config.simulate_noise = self.simulate_noise.map(|sensor| NoiseSimulation {
            sensor,
            seed: self.noise_seed,
        });
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

/// Exit code of a bad command line (clap's own).
const EXIT_USAGE: u8 = 2;

/// A finite number (negative allowed: a principal point may lie left of the image).
pub(crate) fn finite(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("{v} is not a finite number")),
        Err(e) => Err(e.to_string()),
    }
}

/// A focal length in pixels: finite, 1 <= |f| <= 1e6 (negative allowed:
/// ICL-NUIM's fy is -480). Whether it is plausible for the image size is
/// the camera check's, once the image is read.
fn focal(s: &str) -> Result<f32, String> {
    let v = finite(s)?;
    if (1.0..=1e6).contains(&v.abs()) {
        Ok(v)
    } else {
        Err(format!(
            "{v} px: a focal length is 1 to 1e6 px (or -1e6 to -1)"
        ))
    }
}

/// A finite number > 0.
fn positive_f32(s: &str) -> Result<f32, String> {
    match finite(s)? {
        v if v > 0.0 => Ok(v),
        v => Err(format!("{v} is not a number > 0")),
    }
}

/// A finite number >= 0.
fn non_negative_f32(s: &str) -> Result<f32, String> {
    match finite(s)? {
        v if v >= 0.0 => Ok(v),
        v => Err(format!("{v} is not a number >= 0")),
    }
}

/// A mesh voxel edge, metres, within [`VOXEL_SIZE_RANGE_M`].
pub(crate) fn voxel_size(s: &str) -> Result<f32, String> {
    let (lo, hi) = VOXEL_SIZE_RANGE_M;
    match finite(s)? {
        v if (lo..=hi).contains(&v) => Ok(v),
        v => Err(format!("{v} m: the voxel size is {lo} to {hi} m")),
    }
}

/// An output mesh path whose extension names a format (.glb, .ply, .obj).
pub(crate) fn mesh_path(s: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match MeshFormat::from_path(&path) {
        Some(_) => Ok(path),
        None => Err("the mesh file must end in .glb, .ply or .obj".to_owned()),
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
    #[arg(long, allow_negative_numbers = true, value_parser = focal,
        help = preset_help("Focal length x, pixels", |p| p.intrinsics().fx))]
    fx: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = focal,
        help = preset_help("Focal length y, pixels (negative: image y axis points up)", |p| p.intrinsics().fy))]
    fy: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Principal point x, pixels", |p| p.intrinsics().cx))]
    cx: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = finite,
        help = preset_help("Principal point y, pixels", |p| p.intrinsics().cy))]
    cy: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = positive_f32,
        help = preset_help("Raw depth units per metre", |p| p.depth_settings().scale))]
    depth_scale: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = non_negative_f32,
        help = preset_help("Nearest valid depth, metres", |p| p.depth_settings().min_m))]
    depth_min: Option<f32>,
    #[arg(long, allow_negative_numbers = true, value_parser = positive_f32,
        help = preset_help("Farthest valid depth, metres", |p| p.depth_settings().max_m))]
    depth_max: Option<f32>,
}

impl CameraOverrides {
    /// What clap cannot judge option by option: `--depth-min` below
    /// `--depth-max` when both are given.
    fn usage_problem(&self) -> Option<String> {
        match (self.depth_min, self.depth_max) {
            (Some(lo), Some(hi)) if lo >= hi => {
                Some(format!("--depth-min {lo} must be below --depth-max {hi}"))
            }
            _ => None,
        }
    }
}

fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    // Bad command lines exit 2 before any file is read.
    let usage = match &cli.command {
        Command::Run(args) => args.camera().usage_problem(),
        Command::Bench(args) => args.camera().usage_problem(),
        Command::Mesh(_) | Command::Eval(_) => None,
    };
    if let Some(problem) = usage {
        eprintln!("error: {problem}\n\nFor more information, try '--help'.");
        return ExitCode::from(EXIT_USAGE);
    }
    let result = match cli.command {
        Command::Run(args) => run::run(&args, &given_options(&matches, "run")),
        Command::Bench(args) => bench::bench(&args).map(|()| 0),
        Command::Mesh(args) => mesh_file::mesh_file(&args).map(|()| 0),
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

/// The ids of the options of `subcommand` given on the command line (not
/// defaulted): a loaded session names those its settings override.
fn given_options(matches: &clap::ArgMatches, subcommand: &str) -> Vec<String> {
    let Some(sub) = matches.subcommand_matches(subcommand) else {
        return Vec::new();
    };
    sub.ids()
        .filter(|id| sub.value_source(id.as_str()) == Some(ValueSource::CommandLine))
        .map(|id| id.as_str().to_owned())
        .collect()
}

/// The error and its causes joined by ": ", skipping a cause whose text the
/// message already holds (library errors name their file and repeat their
/// source's text).
pub(crate) fn describe(e: &anyhow::Error) -> String {
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

/// The camera for frames of `width` x `height`: a preset's calibration
/// scaled to them (a resized recording; another aspect ratio is warned
/// about by the settings check), the values given on the command line as
/// they are. A folder's own calibration is of its frames' size already.
pub(crate) fn at_frame_size(
    k: &Intrinsics,
    (width, height): (usize, usize),
    given: &CameraOverrides,
) -> Intrinsics {
    let scaled = k.for_image_size(width, height);
    if (width, height) != (k.width, k.height) && k.same_aspect(width, height) {
        eprintln!(
            "note: the frames are {width}x{height}: the camera's {}x{} calibration is scaled to them",
            k.width, k.height
        );
    }
    Intrinsics {
        fx: given.fx.unwrap_or(scaled.fx),
        fy: given.fy.unwrap_or(scaled.fy),
        cx: given.cx.unwrap_or(scaled.cx),
        cy: given.cy.unwrap_or(scaled.cy),
        ..scaled
    }
}

/// The configuration for `sequence` with the command line's camera and
/// tracking options applied, validated.
pub(crate) fn config_for(
    sequence: &Sequence,
    o: &CameraOverrides,
    tracking: &TrackingArgs,
) -> Result<SlamConfig> {
    let preset = o.preset.unwrap_or(sequence.preset);
    let mut config = SlamConfig::from_preset(preset);
    // The folder's own calibration file, unless another camera was chosen.
    if let (true, Some(k)) = (preset == sequence.preset, sequence.intrinsics) {
        config.intrinsics = k;
    }
    let k = &mut config.intrinsics;
    k.fx = o.fx.unwrap_or(k.fx);
    k.fy = o.fy.unwrap_or(k.fy);
    k.cx = o.cx.unwrap_or(k.cx);
    k.cy = o.cy.unwrap_or(k.cy);
    let d = &mut config.depth;
    // The recording's own depth units (a .bag's), whatever the preset.
    d.scale = o.depth_scale.or(sequence.depth_scale).unwrap_or(d.scale);
    d.min_m = o.depth_min.unwrap_or(d.min_m);
    d.max_m = o.depth_max.unwrap_or(d.max_m);
    tracking.apply(&mut config);
    if sequence.is_depth_only() {
        let instead = match config.tracker.mode {
            TrackerMode::Icp => String::new(),
            other => format!(", not --tracker {}", other.name()),
        };
        config.tracker.mode = TrackerMode::Icp;
        eprintln!(
            "note: no colour images are read for this {} sequence: tracking on depth alone (icp{instead}), \
             the map coloured grey",
            sequence.kind.name()
        );
    }
    // Refuse bad camera settings before reading any image.
    config.validate()?;
    Ok(config)
}
