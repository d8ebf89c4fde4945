//! `surfel-slam run`: track and fuse a dataset folder or archive, then
//! write the trajectories, the map and the mesh asked for and print one
//! summary line.
//!
//! Phases of [`run`], in order: `open_sequence`, `select_frames`,
//! `checked_mesh_config`, `checked_session_path`, `start_pipeline` (with
//! `--load`, the session replaces the new pipeline, the tracking options it
//! overrides are named, and `--localise` switches it to localise mode),
//! `track_frames`, `write_outputs` (with `--save`, the session),
//! `print_summary` (or `print_localise_summary`; both in `summary.rs`, with
//! `read_reference`, the `--reference` file read before the run).

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};
use surfel_slam::dataset::{trajectory, DatasetError, DatasetSource, FrameEntry, Sequence};
use surfel_slam::mesh::write_surfel_ply;
use surfel_slam::mesh::MeshConfig;
use surfel_slam::session;
use surfel_slam::{FrameReport, Pipeline, SlamConfig, Verdict};

use crate::frame_log::FrameLog;
use crate::imu_feed::ImuFeed;
use crate::loop_log::LoopLog;
use crate::mesh_file::{mesh_format, write_mesh_file};
use crate::summary::{print_summary, read_reference, Played};
use crate::{
    at_frame_size, config_for, describe, mesh_path, positive, voxel_size, CameraOverrides,
    TrackingArgs,
};

/// Exit code of a run that finished with some frames skipped as unreadable.
const EXIT_FRAMES_SKIPPED: u8 = 3;

#[derive(Args)]
pub struct RunArgs {
    /// Dataset folder, archive (.zip, .tar, .tar.gz / .tgz) read in place,
    /// or recording (RealSense .bag or .db3, Azure Kinect .mkv); layout
    /// detected automatically.
    pub(crate) dataset: PathBuf,
    /// Write the estimated trajectory here (TUM format, world_from_camera).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Also write the online trajectory here: each pose as tracked, before
    /// loop closures corrected it (TUM format, world_from_camera).
    #[arg(long)]
    online_trajectory: Option<PathBuf>,
    /// Write the loop stage's record here (CSV: one row per frame it
    /// checked, what each check found and which refused; with the ground
    /// truth's errors of the tracked and corrected pose when known).
    #[arg(long)]
    loop_log: Option<PathBuf>,
    /// Write one CSV row per input frame here: verdict, tracker statistics,
    /// the pose as tracked and, with ground truth, the frame's relative
    /// pose error (columns: docs/cli.md).
    #[arg(long)]
    frame_log: Option<PathBuf>,
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
    /// Leave the colour images unread: track on depth alone (ICP), the map
    /// grey, as a sequence without colour runs (a Stray Scanner scan whose
    /// video cannot be decoded here); to see what colour is worth.
    #[arg(long)]
    depth_only: bool,
    #[command(flatten)]
    camera: CameraOverrides,
    #[command(flatten)]
    tracking: TrackingArgs,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Write a triangle mesh of the confident surfels here (.glb, .ply or .obj).
    #[arg(long, value_parser = mesh_path)]
    mesh: Option<PathBuf>,
    /// Save the session here when the run ends (a zip: map, keyframes,
    /// trajectory, settings; `--load` continues from it).
    #[arg(long)]
    save: Option<PathBuf>,
    /// Continue the session saved in this file (`--save`): its map,
    /// trajectory and settings; the frames `--first`/`--count` select are
    /// pushed after its last one. The camera must be the session's.
    #[arg(long)]
    pub(crate) load: Option<PathBuf>,
    /// With --load: localise the frames in the saved map without changing
    /// it (no fusion, no loop closure). The first frame is placed by
    /// relocalisation against the session's keyframes; frames that cannot
    /// be placed are named on stderr and left out of --trajectory, which
    /// then holds the placed frames only.
    #[arg(long, requires = "load", conflicts_with = "save")]
    localise: bool,
    /// Score the run against your own reference trajectory too (a T265,
    /// motion capture, another tool's output): TUM text (`t tx ty tz qx qy
    /// qz qw`, matched by timestamp) or CSV with a header `frame, x, y, z,
    /// qx, qy, qz, qw` (matched by frame number, 0-based) or `timestamp,
    /// x, ...` (by timestamp); aligned rigidly as ATE is.
    #[arg(long)]
    pub(crate) reference: Option<PathBuf>,
    /// Voxel edge of the mesh, metres (0.001 to 1).
    #[arg(long, default_value_t = MeshConfig::default().voxel_size_m, allow_negative_numbers = true, value_parser = voxel_size)]
    voxel_size: f32,
}

impl RunArgs {
    /// The camera options given.
    pub(crate) fn camera(&self) -> &CameraOverrides {
        &self.camera
    }
}

/// Runs `surfel-slam run`; `given`: the ids of the options given on the
/// command line. Returns the exit code (0, or `EXIT_FRAMES_SKIPPED` when
/// some frames were unreadable); an error (exit 1) when no frame could be
/// pushed at all, before any output is written: an empty map is not a result.
pub fn run(args: &RunArgs, given: &[String]) -> Result<u8> {
    let (mut source, sequence) = open_sequence(args)?;
    let reference = read_reference(args)?;
    let frames = select_frames(&sequence, args)?;
    let mesh_config = checked_mesh_config(args)?;
    checked_session_path(args)?;
    let mut slam = start_pipeline(&mut source, &sequence, &frames, (args, given))?;
    let mut loop_log = args
        .loop_log
        .as_ref()
        .map(|_| LoopLog::new(&sequence.ground_truth));
    let mut frame_log = args.frame_log.as_ref().map(|_| FrameLog::new(&sequence));
    let first_s = frames.first().map_or(0.0, |f| f.timestamp);
    let mut imu = ImuFeed::new(&sequence.imu, first_s);
    let played = track_frames(
        &mut source,
        (&frames, sequence.frames.len()),
        (&mut slam, &mut imu),
        (args.quiet, loop_log.as_mut(), frame_log.as_mut()),
    );
    if played.pushed == 0 {
        bail!(
            "nothing was tracked: all {} frame(s) selected were skipped (named above); \
             no trajectory, map, mesh or session written",
            frames.len()
        );
    }
    write_outputs(args, &slam, mesh_config)?;
    if let (Some(log), Some(path)) = (&loop_log, &args.loop_log) {
        log.write(path)?;
    }
    if let (Some(log), Some(path)) = (&frame_log, &args.frame_log) {
        log.write(path)?;
    }
    print_summary(
        args,
        (&sequence, reference.as_ref()),
        &slam,
        frames.len(),
        played,
    );
    Ok(if played.failed > 0 {
        EXIT_FRAMES_SKIPPED
    } else {
        0
    })
}

/// Opens the dataset (a folder or an archive, read in place) and its
/// sequence; prints the sequence's warnings.
fn open_sequence(args: &RunArgs) -> Result<(DatasetSource, Sequence)> {
    let mut source = DatasetSource::open(&args.dataset)
        .with_context(|| format!("opening {}", args.dataset.display()))?;
    let mut sequence = source
        .sequence()
        .with_context(|| format!("opening {}", args.dataset.display()))?;
    if args.depth_only {
        for frame in &mut sequence.frames {
            frame.colour = None;
        }
    }
    for warning in &sequence.warnings {
        eprintln!("warning: {warning}");
    }
    Ok((source, sequence))
}

/// The frames `--first`, `--stride` and `--count` select; refuses an empty
/// selection.
fn select_frames<'a>(sequence: &'a Sequence, args: &RunArgs) -> Result<Vec<&'a FrameEntry>> {
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
    Ok(frames)
}

/// The mesh settings; a bad mesh path or voxel size is refused before the
/// run, not after it.
fn checked_mesh_config(args: &RunArgs) -> Result<MeshConfig> {
    let mesh_config = MeshConfig {
        voxel_size_m: args.voxel_size,
        ..MeshConfig::default()
    };
    if let Some(path) = &args.mesh {
        mesh_format(path)?;
        mesh_config.validate()?;
    }
    Ok(mesh_config)
}

/// The pipeline for the command line's settings, at the image size of the
/// sequence's first readable frame (it wins over the preset's).
fn start_pipeline(
    source: &mut DatasetSource,
    sequence: &Sequence,
    frames: &[&FrameEntry],
    (args, given): (&RunArgs, &[String]),
) -> Result<Pipeline> {
    let mut config = config_for(sequence, &args.camera, &args.tracking)?;
    let (first, width, height) = first_readable(source, frames, &config)?;
    config.intrinsics = at_frame_size(&config.intrinsics, (width, height), &args.camera);
    let mut slam = Pipeline::new(config)?;
    check_settings(source, sequence, first, args, &mut slam);
    if let Some(path) = &args.load {
        let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
        session::load_into(&mut slam, BufReader::new(file))
            .with_context(|| format!("loading {}", path.display()))?;
        let session_noise = slam.state().scalars.configured_noise.0;
        let overridden = args
            .tracking
            .overridden_by(given, slam.config(), &session_noise);
        if !overridden.is_empty() {
            eprintln!(
                "warning: {} not used: a loaded session keeps its own settings ({})",
                overridden.join(", "),
                path.display()
            );
        }
        if args.localise {
            slam.start_localising();
        }
    }
    Ok(slam)
}

/// Refuses, before the run, a `--save` path whose folder does not exist
/// or that names a folder: the run's result would be lost at its end.
fn checked_session_path(args: &RunArgs) -> Result<()> {
    let Some(path) = &args.save else {
        return Ok(());
    };
    if path.is_dir() {
        bail!("--save {}: is a folder, not a file", path.display());
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    if parent.is_some_and(|p| !p.is_dir()) {
        bail!("--save {}: its folder does not exist", path.display());
    }
    Ok(())
}

/// Writes the session to `path` through a temporary file beside it, so
/// that a failed save leaves an earlier file (perhaps the one loaded) whole.
fn save_session(slam: &Pipeline, path: &Path) -> Result<()> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let partial = path.with_file_name(name);
    let written = File::create(&partial)
        .map_err(anyhow::Error::from)
        .and_then(|f| {
            let out = session::save(slam, BufWriter::new(f))?;
            out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
            Ok(())
        })
        .and_then(|()| Ok(std::fs::rename(&partial, path)?));
    if written.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    written.with_context(|| format!("saving the session to {}", path.display()))
}

/// Warns (stderr) about camera settings that look wrong for the data: the
/// preset and values against the folder's layout, the depth scale against
/// the first readable frame's depth image.
fn check_settings(
    source: &mut DatasetSource,
    sequence: &Sequence,
    first: &FrameEntry,
    args: &RunArgs,
    slam: &mut Pipeline,
) {
    let chosen = args.camera.preset.unwrap_or(sequence.preset);
    if sequence.depth_scale.is_some() {
        slam.check_recorded_layout(sequence.preset, chosen);
    } else {
        slam.check_layout(sequence.preset, chosen);
    }
    if let DatasetSource::Bag { .. } | DatasetSource::Db3 { .. } | DatasetSource::Mkv { .. } =
        source
    {
        if let Ok(raw) = source.read_raw(first) {
            slam.check_depth_raw(&raw.depth);
        }
    } else if let Ok(depth_png) = source.read(&first.depth) {
        slam.check_depth_png(&depth_png);
    }
    for warning in slam.settings_warnings() {
        eprintln!("warning: camera settings: {warning}");
    }
}

/// The first frame that decodes and its size (the sequence's image size);
/// the frames before it are named on stderr.
fn first_readable<'a>(
    source: &mut DatasetSource,
    frames: &[&'a FrameEntry],
    config: &SlamConfig,
) -> Result<(&'a FrameEntry, usize, usize)> {
    let mut last_error = None;
    for entry in frames {
        match source.read_frame(entry, &config.depth) {
            Ok(f) => return Ok((entry, f.width, f.height)),
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

/// The progress bar of the frame loop (hidden with `--quiet`).
fn progress_bar(frames: usize, quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames as u64)
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
    bar
}

/// Reads and pushes every frame into `slam` (the IMU's samples up to it
/// first), naming lost, recovered and skipped frames on stderr, and the
/// IMU's calibration once found; recording the loop stage in `loop_log`
/// when given. `in_sequence`: the sequence's frame count, whose last
/// frame's undecodable image is a recording cut short, named as a warning.
fn track_frames(
    source: &mut DatasetSource,
    (frames, in_sequence): (&[&FrameEntry], usize),
    (slam, imu): (&mut Pipeline, &mut ImuFeed<'_>),
    (quiet, mut loop_log, mut frame_log): (
        bool,
        Option<&mut LoopLog<'_>>,
        Option<&mut FrameLog<'_>>,
    ),
) -> Played {
    let bar = progress_bar(frames.len(), quiet);
    let (mut failed, mut streak, mut ms) = (0usize, 0u32, Vec::new());
    let mut last = None;
    for entry in frames {
        imu.before_frame(slam, entry.timestamp);
        let read = source.read_frame(entry, &slam.config().depth);
        let cut_off = entry.index + 1 == in_sequence
            && read.as_ref().is_err_and(DatasetError::is_undecodable_image);
        let result = read.map_err(anyhow::Error::from).and_then(|f| {
            let t0 = std::time::Instant::now();
            let r = slam
                .push_frame(&f, entry.timestamp)
                .with_context(|| match &entry.colour {
                    Some(colour) => format!("{colour} + {}", entry.depth),
                    None => entry.depth.clone(),
                })?;
            Ok((r, t0.elapsed().as_secs_f64() * 1000.0))
        });
        match result {
            Ok((report, elapsed)) => {
                ms.push(elapsed);
                if let Some(log) = loop_log.as_deref_mut() {
                    log.record(slam, &report);
                }
                if let Some(log) = frame_log.as_deref_mut() {
                    let online = match report.pose() {
                        Some(_) if !slam.is_localising() => {
                            slam.online_trajectory().last().map(|(_, p)| *p)
                        }
                        pose => pose,
                    };
                    log.record(entry, &report, online);
                }
                report_verdict(&bar, entry, &report, (streak, slam.is_localising()));
                if let Some(line) = imu.announcement(slam, entry.index) {
                    bar.suspend(|| eprintln!("{line}"));
                }
                streak = report.counts.lost_streak;
                bar.set_message(format!(
                    "{} surfels, {} lost, {} recovered",
                    report.surfels, report.counts.lost, report.counts.recovered
                ));
                last = Some((*entry, report));
            }
            Err(e) => {
                if let Some(log) = frame_log.as_deref_mut() {
                    log.record_unreadable(entry);
                }
                if cut_off {
                    // A recorder stopped mid-write leaves its last image
                    // half written: the recording is whole up to it.
                    bar.suspend(|| {
                        eprintln!(
                            "warning: frame {} skipped, the recording's last image does not decode (cut off when it stopped?): {}",
                            entry.index,
                            describe(&e)
                        );
                    });
                } else {
                    failed += 1;
                    bar.suspend(|| eprintln!("frame {} skipped: {}", entry.index, describe(&e)));
                }
            }
        }
        bar.inc(1);
    }
    if let Some((entry, mut report)) = last {
        // The recording ended: its last frame is looked up among the old
        // keyframes too, whatever the global check's schedule.
        report.loop_outcome = slam.finish();
        if let Some(log) = loop_log {
            log.record(slam, &report);
        }
        if let Some(g) = report.loop_outcome.global.filter(|g| g.closed) {
            bar.suspend(|| {
                eprintln!(
                    "frame {} ({}), the last, closed a loop with the keyframe of frame {}: moved {:.1} cm, {:.1} deg",
                    entry.index, entry.timestamp, g.keyframe_frame, g.correction_m * 100.0, g.correction_deg
                );
            });
        }
    }
    bar.finish_and_clear();
    if let Some(line) = imu.closing(slam) {
        eprintln!("{line}");
    }
    ms.sort_by(f64::total_cmp);
    Played {
        pushed: ms.len(),
        failed,
        mean_ms: ms.iter().sum::<f64>() / ms.len().max(1) as f64,
        median_ms: ms.get(ms.len() / 2).copied().unwrap_or(0.0),
    }
}

/// Names a lost, recovered or unplaced frame on stderr; `streak` is the
/// number of lost frames before this one; `localising`: in localise mode
/// (a recovered frame is one relocalised in the saved map).
fn report_verdict(
    bar: &ProgressBar,
    entry: &FrameEntry,
    report: &FrameReport,
    (streak, localising): (u32, bool),
) {
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
        Verdict::Unplaced => bar.suspend(|| {
            eprintln!(
                "frame {} ({}) unplaced: not found in the saved map (no pose)",
                entry.index, entry.timestamp
            );
        }),
        Verdict::Recovered if localising => bar.suspend(|| {
            let keyframe = report.checks.relocalised_from;
            let how = keyframe.map_or("re-acquired".to_owned(), |k| {
                format!("relocalised by the keyframe of frame {k}")
            });
            eprintln!(
                "frame {} ({}) placed in the saved map: {how}",
                entry.index, entry.timestamp
            );
        }),
        Verdict::Restarted => bar.suspend(|| {
            eprintln!(
                "frame {} ({}) restarted: lost for {streak} frames, mapping goes on from the last placed pose in a new segment (the map so far is kept, not tracked against until the segment is joined to it)",
                entry.index, entry.timestamp,
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
    if let Some(joined) = report.loop_outcome.joined {
        bar.suspend(|| {
            let from = joined.keyframe_frame.map_or_else(
                || "from where the camera was lost".to_owned(),
                |k| format!("by the keyframe of frame {k}"),
            );
            let since = report.index.saturating_sub(joined.segment_start);
            eprintln!(
                "frame {} ({}) joined the segment restarted {since} frame(s) before to the map before it, {from}: moved {:.1} cm, {:.1} deg",
                entry.index,
                entry.timestamp,
                joined.correction.0 * 100.0,
                joined.correction.1
            );
        });
    }
}

/// Writes the trajectories (TUM), the map (PLY) and the mesh asked for.
fn write_outputs(args: &RunArgs, slam: &Pipeline, mesh_config: MeshConfig) -> Result<()> {
    // Localising: the frames placed in the saved map (no closures bend them).
    let (poses, online) = match slam.localisation() {
        Some(l) => (l.trajectory(), l.trajectory()),
        None => (slam.trajectory(), slam.online_trajectory()),
    };
    for (path, poses) in [(&args.trajectory, poses), (&args.online_trajectory, online)] {
        if let Some(path) = path {
            std::fs::write(path, trajectory::format_tum(poses))
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if let Some(path) = &args.ply {
        std::fs::write(path, write_surfel_ply(slam.map()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.save {
        save_session(slam, path)?;
    }
    if let Some(path) = &args.mesh {
        let config = MeshConfig {
            min_confidence: slam.config().fusion.stable_confidence,
            ..mesh_config
        };
        write_mesh_file(slam.map(), &config, path, args.quiet)?;
    }
    Ok(())
}
