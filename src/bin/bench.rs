//! `surfel-slam bench`: per-stage timings, per-frame median and peak memory
//! over a sequence, optionally looped forwards and backwards to any length.

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;
use surfel_slam::dataset::rosbag::RawFrame;
use surfel_slam::dataset::{DatasetKind, DatasetSource, Sequence, DEPTH_ONLY_GREY};
use surfel_slam::eval::ate;
use surfel_slam::{FrameReport, Pipeline, PipelineError, SlamConfig, StageTimings, Verdict};

use crate::{at_frame_size, config_for, CameraOverrides, TrackingArgs, MAX_DT};

#[derive(Args)]
pub struct BenchArgs {
    /// Dataset folder (layout detected automatically), or RealSense
    /// recording (.bag: its frames decoded and registered up front).
    dataset: PathBuf,
    /// Frames to process; past the sequence's end it is played backwards,
    /// then forwards again, so the camera motion stays continuous
    /// [default: the sequence's length].
    #[arg(long, allow_negative_numbers = true, value_parser = crate::positive)]
    frames: Option<usize>,
    #[command(flatten)]
    camera: CameraOverrides,
    #[command(flatten)]
    tracking: TrackingArgs,
}

impl BenchArgs {
    /// The camera options given.
    pub(crate) fn camera(&self) -> &CameraOverrides {
        &self.camera
    }
}

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

/// Starts of the 100-frame windows of an `n`-step ping-pong run over `len`
/// frames that play the same frames, in the same direction, as the window
/// starting at step `start` (one per loop, earliest first; empty when a
/// loop is shorter than 200 steps).
fn same_view_starts(start: usize, n: usize, len: usize) -> Vec<usize> {
    let period = 2 * len.saturating_sub(1);
    if period < 200 {
        return Vec::new();
    }
    (0..)
        .map(|k| start % period + k * period)
        .take_while(|&s| s + 100 <= n)
        .collect()
}

/// The steps of the first pass that played the same frames as `window`
/// (the first pass plays frame `k` at step `k`), in window order.
fn first_pass_steps(window: std::ops::Range<usize>, len: usize) -> Vec<usize> {
    window.map(|i| ping_pong(i, len)).collect()
}

/// Medians of `value` over the 100 frames from each of `starts`, one decimal, space-separated.
fn window_medians(starts: &[usize], value: impl Fn(usize) -> f64) -> String {
    starts
        .iter()
        .map(|&s| {
            let mut v: Vec<f64> = (s..s + 100).map(&value).collect();
            format!("{:.1}", median(&mut v))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// Peak resident memory of this process, MiB (Linux; `None` elsewhere).
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn stage_medians(timings: &[StageTimings]) -> Vec<(&'static str, f64)> {
    let stage = |f: fn(&StageTimings) -> f64| {
        let mut v: Vec<f64> = timings.iter().map(f).collect();
        median(&mut v)
    };
    vec![
        ("decode", stage(|t| t.decode_ms)),
        ("preprocess", stage(|t| t.preprocess_ms)),
        ("track", stage(|t| t.track_ms)),
        ("fuse", stage(|t| t.fuse_ms)),
        ("loop", stage(|t| t.loop_ms)),
        ("predict", stage(|t| t.predict_ms)),
        ("total", stage(|t| t.total_ms)),
    ]
}

/// Steps played by the twin run between two runs of the main run's last
/// 100 steps: short enough that a slow spell of the machine (seconds) falls
/// on both windows alike, long enough that each turn starts with the map
/// mostly in cache.
const INTERLEAVE: usize = 25;

/// One frame as read up front: a folder's colour and depth PNG bytes, or
/// a `.bag`'s raw depth with its colour registered to it (no colour: grey).
enum FrameInput {
    Png(Vec<u8>, Vec<u8>),
    Raw(RawFrame),
}

impl FrameInput {
    /// Pushes the frame: `push_png`, or `push_raw` (the depth converted
    /// to metres in the frame's time, its decoding and registration not).
    fn push(&self, slam: &mut Pipeline, timestamp: f64) -> Result<FrameReport, PipelineError> {
        match self {
            Self::Png(colour, depth) => slam.push_png(colour, depth, timestamp),
            Self::Raw(f) if f.rgb.is_empty() => {
                let grey = vec![DEPTH_ONLY_GREY; 3 * f.width * f.height];
                slam.push_raw(f.width, f.height, &grey, &f.depth, timestamp)
            }
            Self::Raw(f) => slam.push_raw(f.width, f.height, &f.rgb, &f.depth, timestamp),
        }
    }
}

/// Verdicts of a run that are not plain tracking.
#[derive(Default)]
struct Counts {
    lost: usize,
    recovered: usize,
    held: usize,
    restarted: usize,
    failed: usize,
}

/// Plays step `i` of the ping-pong loop over `frames` (colour and depth
/// PNG bytes) on `slam`: its timings, surfels in the map and surfels visited
/// by fusion, or `None` when the frame was refused.
fn play(
    slam: &mut Pipeline,
    frames: &[FrameInput],
    sequence: &Sequence,
    i: usize,
    counts: &mut Counts,
) -> Option<(StageTimings, (f64, f64))> {
    let k = ping_pong(i, frames.len());
    match frames[k].push(slam, sequence.frames[k].timestamp) {
        Ok(report) => {
            match report.verdict {
                Verdict::Lost(_) => counts.lost += 1,
                Verdict::Recovered => counts.recovered += 1,
                Verdict::Held => counts.held += 1,
                Verdict::Restarted => counts.restarted += 1,
                _ => {}
            }
            Some((
                report.timings,
                (report.surfels as f64, report.fusion.visited as f64),
            ))
        }
        Err(e) => {
            counts.failed += 1;
            eprintln!("frame {i} ({}) skipped: {e}", sequence.frames[k].depth);
            None
        }
    }
}

/// Runs `surfel-slam bench`: plays the sequence (files read up front),
/// then prints the run's line, its ATE, the stage medians and, for runs of
/// 400 frames or more, how the cost changed along the run.
///
/// Phases, in order: `read_sequence`, `bench_config`, `record`,
/// `print_run`, `print_flatness`, `print_totals`.
pub fn bench(args: &BenchArgs) -> Result<()> {
    let (sequence, bytes) = read_sequence(args)?;
    let total = args.frames.unwrap_or(sequence.frames.len());
    let config = bench_config(args, &sequence, &bytes)?;
    let mut slam = Pipeline::new(config.clone())?;
    let recording = record(&mut slam, &config, (&bytes, &sequence), total)?;
    print_run(args, &sequence, &slam, total, &recording);
    if recording.timings.len() >= 400 {
        print_flatness(&recording, sequence.frames.len());
    }
    print_totals(&recording);
    Ok(())
}

/// The sequence and every frame's colour and depth PNG bytes, read up
/// front so that disk speed is not part of the timings.
fn read_sequence(args: &BenchArgs) -> Result<(Sequence, Vec<FrameInput>)> {
    let opening = || format!("opening {}", args.dataset.display());
    let mut source = DatasetSource::open(&args.dataset).with_context(opening)?;
    let sequence = source.sequence().with_context(opening)?;
    if sequence.frames.is_empty() {
        bail!("{} holds no frames", args.dataset.display());
    }
    if matches!(
        sequence.kind,
        DatasetKind::RealSenseBag | DatasetKind::RealSenseDb3 | DatasetKind::AzureKinect
    ) {
        for warning in &sequence.warnings {
            eprintln!("warning: {warning}");
        }
        let frames = sequence
            .frames
            .iter()
            .map(|entry| source.read_raw(entry).map(FrameInput::Raw))
            .collect::<Result<Vec<_>, _>>()?;
        return Ok((sequence, frames));
    }
    if sequence.frames[0].confidence.is_some() || sequence.is_depth_only() {
        bail!(
            "{}: bench times colour and depth PNG pairs; this {} sequence (depth only or with \
             confidence images) runs with `surfel-slam run`",
            args.dataset.display(),
            sequence.kind.name()
        );
    }
    let mut bytes = Vec::with_capacity(sequence.frames.len());
    for entry in &sequence.frames {
        let read = |name: &str| {
            let path = args.dataset.join(name);
            std::fs::read(&path).with_context(|| format!("reading {}", path.display()))
        };
        let colour = entry.colour.as_deref().unwrap_or_default();
        bytes.push(FrameInput::Png(read(colour)?, read(&entry.depth)?));
    }
    Ok((sequence, bytes))
}

/// The configuration for the command line's settings, at the first frame's
/// image size.
fn bench_config(args: &BenchArgs, sequence: &Sequence, bytes: &[FrameInput]) -> Result<SlamConfig> {
    let mut config = config_for(sequence, &args.camera, &args.tracking)?;
    let size = match &bytes[0] {
        FrameInput::Png(colour, depth) => {
            let first = surfel_slam::RgbdFrame::from_png_bytes(colour, depth, &config.depth)
                .context("decoding the first frame")?;
            (first.width, first.height)
        }
        FrameInput::Raw(f) => (f.width, f.height),
    };
    config.intrinsics = at_frame_size(&config.intrinsics, size, &args.camera);
    Ok(config)
}

/// What a bench run recorded.
struct Recording {
    /// Stage timings of each frame the main run pushed.
    timings: Vec<StageTimings>,
    /// Per frame pushed: surfels in the map and surfels visited by fusion.
    sizes: Vec<(f64, f64)>,
    /// The main run's verdicts that are not plain tracking.
    counts: Counts,
    /// The twin run's steps 100-200 (timings, sizes), played between the
    /// main run's last 100 steps.
    twin_steps: Vec<(StageTimings, (f64, f64))>,
    /// Peak resident memory before the twin run started (it holds a second
    /// map), MiB; `None` without a twin run or off Linux.
    peak_rss: Option<f64>,
}

/// Plays `total` ping-pong steps over `frames` (PNG bytes of `sequence`'s
/// frames) on `slam`; from `total` = 400 on, a second run of the same
/// frames (`config`) plays its steps 100-200 between the main run's last 100
/// steps, a few at a time.
fn record(
    slam: &mut Pipeline,
    config: &SlamConfig,
    (frames, sequence): (&[FrameInput], &Sequence),
    total: usize,
) -> Result<Recording> {
    let mut recording = Recording {
        timings: Vec::with_capacity(total),
        sizes: Vec::with_capacity(total),
        counts: Counts::default(),
        twin_steps: Vec::with_capacity(100),
        peak_rss: None,
    };
    let mut twin: Option<Pipeline> = None;
    let late_start = total.saturating_sub(100);
    for i in 0..total {
        if total >= 400 && i >= late_start && (i - late_start) % INTERLEAVE == 0 {
            let twin = match &mut twin {
                Some(t) => t,
                None => {
                    recording.peak_rss = peak_rss_mib();
                    let mut t = Pipeline::new(config.clone())?;
                    for s in 0..100 {
                        play(&mut t, frames, sequence, s, &mut Counts::default());
                    }
                    twin.insert(t)
                }
            };
            let s = 100 + i - late_start;
            for s in s..s + INTERLEAVE {
                recording.twin_steps.extend(play(
                    twin,
                    frames,
                    sequence,
                    s,
                    &mut Counts::default(),
                ));
            }
        }
        if let Some(step) = play(slam, frames, sequence, i, &mut recording.counts) {
            recording.timings.push(step.0);
            recording.sizes.push(step.1);
        }
    }
    Ok(recording)
}

/// Prints the run's line (frames, verdicts, map size, threads), its ATE
/// when the sequence has ground truth, and the median time of each stage.
fn print_run(
    args: &BenchArgs,
    sequence: &Sequence,
    slam: &Pipeline,
    total: usize,
    recording: &Recording,
) {
    let Counts {
        lost,
        recovered,
        held,
        restarted,
        failed,
    } = recording.counts;
    let size = slam.config().intrinsics;
    println!(
        "{}: {} frames at {}x{}, {lost} lost, {recovered} recovered, {held} held, {restarted} restarted, {failed} unreadable, {} surfels, {} rayon threads",
        args.dataset.display(),
        total,
        size.width,
        size.height,
        slam.map().live_len(),
        rayon::current_num_threads(),
    );
    if !sequence.ground_truth.is_empty() {
        match ate(slam.trajectory(), &sequence.ground_truth, MAX_DT) {
            Ok(a) => println!("ate_cm: {:.3} ({} poses)", a.rmse_m * 100.0, a.pairs),
            Err(e) => println!("ate_cm: n/a ({e})"),
        }
    }
    for (name, ms) in stage_medians(&recording.timings) {
        println!("median_ms_{name}: {ms:.2}");
    }
}

/// Median total time per frame over `window`, milliseconds.
fn median_total_ms(window: &[StageTimings]) -> f64 {
    let mut v: Vec<f64> = window.iter().map(|t| t.total_ms).collect();
    median(&mut v)
}

/// Flatness over a long run (at least 400 frames pushed) of a sequence of
/// `len` frames: the same window length early and late, every window, the
/// same views on each pass, and the interleaved twin comparison.
fn print_flatness(recording: &Recording, len: usize) {
    print_early_and_late(recording);
    print_every_window(recording);
    print_same_views(recording, len);
    print_late_over_early(recording);
}

/// Stage medians and map sizes of frames 100-200 against the last 100.
fn print_early_and_late(recording: &Recording) {
    let (timings, sizes) = (&recording.timings, &recording.sizes);
    let n = timings.len();
    let (early, late) = (&timings[100..200], &timings[n - 100..n]);
    for ((name, e), (_, l)) in stage_medians(early).into_iter().zip(stage_medians(late)) {
        println!("window_ms_{name}: {e:.2} early, {l:.2} late");
    }
    let window_sizes = |range: std::ops::Range<usize>| {
        let window = &sizes[range];
        let mut map: Vec<f64> = window.iter().map(|s| s.0).collect();
        let mut visited: Vec<f64> = window.iter().map(|s| s.1).collect();
        (median(&mut map) / 1e3, median(&mut visited) / 1e3)
    };
    let ((map_e, visited_e), (map_l, visited_l)) =
        (window_sizes(100..200), window_sizes(n - 100..n));
    println!("window_k_surfels: {map_e:.0} early, {map_l:.0} late");
    println!("window_k_visited_by_fusion: {visited_e:.0} early, {visited_l:.0} late");
}

/// Every window of 100 frames, to tell the first pass over the scene
/// (still being mapped) from revisits of a bigger map.
fn print_every_window(recording: &Recording) {
    let (timings, sizes) = (&recording.timings, &recording.sizes);
    let every: Vec<usize> = (0..timings.len() / 100).map(|w| 100 * w).collect();
    println!(
        "windows_ms_per_frame: {}",
        window_medians(&every, |i| timings[i].total_ms)
    );
    println!(
        "windows_k_visited_by_fusion: {}",
        window_medians(&every, |i| sizes[i].1 / 1e3)
    );
    println!(
        "windows_k_surfels: {}",
        window_medians(&every, |i| sizes[i].0 / 1e3)
    );
}

/// The cost of the same views (the same frames in the same direction) on
/// each pass over a sequence of `len` frames, as the map grows around them.
fn print_same_views(recording: &Recording, len: usize) {
    let (timings, sizes) = (&recording.timings, &recording.sizes);
    let n = timings.len();
    let late = &timings[n - 100..n];
    let total_ms = |i: usize| timings[i].total_ms;
    let k_surfels = |i: usize| sizes[i].0 / 1e3;
    let k_visited = |i: usize| sizes[i].1 / 1e3;
    // The windows of `starts` (the same views in the same direction):
    // the cost of one view as the map grows around it.
    let print_series = |name: &str, starts: &[usize]| {
        let at: Vec<String> = starts.iter().map(|s| format!("{s}-{}", s + 100)).collect();
        println!("{name}_frames: {}", at.join(" "));
        println!("{name}_ms_per_frame: {}", window_medians(starts, total_ms));
        println!("{name}_k_surfels: {}", window_medians(starts, k_surfels));
        println!(
            "{name}_k_visited_by_fusion: {}",
            window_medians(starts, k_visited)
        );
    };
    // Frames 100-200 and the same views on each later pass.
    let starts = same_view_starts(100, n, len);
    if starts.len() > 1 {
        print_series("same_views", &starts);
    }
    // The last 100 frames' views on each pass: from the first way back
    // on, the scene is mapped and only the map's growth remains.
    let late_starts = same_view_starts(n - 100, n, len);
    if let [first, .., _] = late_starts[..] {
        print_series("late_views", &late_starts);
        let mut earliest: Vec<f64> = (first..first + 100).map(total_ms).collect();
        println!(
            "late_over_its_first_revisit: {:.3}",
            median_total_ms(late) / median(&mut earliest).max(1e-9)
        );
    }
    // The last 100 frames show other views than frames 100-200, and
    // views differ in cost whatever the map holds; the first pass over
    // the same views as the last 100 frames tells the two apart.
    if n - 100 >= len {
        let mut first: Vec<f64> = first_pass_steps(n - 100..n, len)
            .into_iter()
            .filter_map(|s| timings.get(s).map(|t| t.total_ms))
            .collect();
        let first = median(&mut first);
        println!(
            "late_views_first_pass_ms: {first:.2}\nlate_over_its_first_pass: {:.3}",
            median_total_ms(late) / first.max(1e-9)
        );
    }
}

/// Median time per frame of frames 100-200 against the last 100, played
/// one after the other and, with the twin run, in turns.
fn print_late_over_early(recording: &Recording) {
    let (timings, sizes) = (&recording.timings, &recording.sizes);
    let n = timings.len();
    let (early, late) = (
        median_total_ms(&timings[100..200]),
        median_total_ms(&timings[n - 100..n]),
    );
    println!(
        "median_ms_frames_100_200: {early:.2}\nmedian_ms_frames_{}_{n}: {late:.2}\nlate_over_early: {:.3}",
        n - 100,
        late / early.max(1e-9)
    );
    // The same comparison with the two windows played in turns, so that
    // the machine's slow spells fall on both alike; the twin run must
    // have done exactly the work of the main run's steps 100-200.
    let twin_steps = &recording.twin_steps;
    if twin_steps.len() == 100 {
        let same_work = twin_steps
            .iter()
            .map(|t| t.1)
            .eq(sizes[100..200].iter().copied());
        let mut twin_ms: Vec<f64> = twin_steps.iter().map(|t| t.0.total_ms).collect();
        let twin_early = median(&mut twin_ms);
        println!(
            "interleaved_same_work: {same_work}\ninterleaved_ms_frames_100_200: {twin_early:.2}\ninterleaved_late_over_early: {:.3}",
            late / twin_early.max(1e-9)
        );
    }
}

/// Peak resident memory and the median time per frame of the whole run.
fn print_totals(recording: &Recording) {
    match recording.peak_rss.or_else(peak_rss_mib) {
        Some(mib) => println!("peak_rss_mib: {mib:.1}"),
        None => println!("peak_rss_mib: n/a"),
    }
    let mut totals: Vec<f64> = recording.timings.iter().map(|t| t.total_ms).collect();
    println!("median_ms_per_frame: {:.2}", median(&mut totals));
}

#[cfg(test)]
mod tests {
    use super::{first_pass_steps, ping_pong, same_view_starts};

    #[test]
    fn first_pass_steps_play_the_same_frames_as_the_window() {
        let steps = first_pass_steps(1400..1500, 193);
        assert_eq!(steps.len(), 100);
        assert_eq!((steps[0], steps[99]), (136, 37));
        for (i, &s) in (1400..1500).zip(&steps) {
            assert!(s < 193);
            assert_eq!(ping_pong(s, 193), ping_pong(i, 193));
        }
    }

    #[test]
    fn same_view_windows_play_the_frames_of_the_given_window() {
        let starts = same_view_starts(100, 1500, 193);
        assert_eq!(starts, [100, 484, 868, 1252]);
        for s in starts {
            assert!((0..100).all(|j| ping_pong(s + j, 193) == ping_pong(100 + j, 193)));
        }
        assert_eq!(same_view_starts(100, 1500, 100), Vec::<usize>::new());
        assert_eq!(same_view_starts(100, 300, 193), [100]);
        // The last 100 steps of a 1500-step run over teddy's 193 frames play
        // frames 136 down to 37, as steps 248-348 did on the first way back.
        let late = same_view_starts(1400, 1500, 193);
        assert_eq!(late, [248, 632, 1016, 1400]);
        for s in late {
            assert!((0..100).all(|j| ping_pong(s + j, 193) == ping_pong(1400 + j, 193)));
        }
    }

    #[test]
    fn ping_pong_turns_at_both_ends() {
        let seq: Vec<usize> = (0..9).map(|i| ping_pong(i, 4)).collect();
        assert_eq!(seq, [0, 1, 2, 3, 2, 1, 0, 1, 2]);
        assert_eq!(ping_pong(5, 1), 0);
    }
}
