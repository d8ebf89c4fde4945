//! What `surfel-slam run` says at the end: the summary line (frames and
//! verdicts, map size, ATE against the ground truth, the difference from the
//! device's odometry and from `--reference`, time per frame), and the
//! `--reference` file it scores against, read before the run.

use anyhow::{Context, Result};
use std::path::Path;
use surfel_slam::dataset::reference::{parse_reference, Reference};
use surfel_slam::dataset::Sequence;
use surfel_slam::eval::{ate, ate_in_frame};
use surfel_slam::pipeline::Localisation;
use surfel_slam::Pipeline;

use crate::run::RunArgs;
use crate::{evaluate, MAX_DT};

/// What the frame loop leaves for the summary.
#[derive(Clone, Copy)]
pub(crate) struct Played {
    /// Frames the pipeline took (whatever their verdict).
    pub(crate) pushed: usize,
    /// Frames skipped as unreadable (or refused by the pipeline); not the
    /// recording's last frame when only its image is cut off (a warning).
    pub(crate) failed: usize,
    /// Mean and median time of `push_frame` over the frames pushed,
    /// milliseconds (decoding not included).
    pub(crate) mean_ms: f64,
    pub(crate) median_ms: f64,
}

/// The `--reference` file, parsed (its warnings on stderr), or `None`; a
/// file that cannot be read is refused before the run, not after it.
pub(crate) fn read_reference(args: &RunArgs) -> Result<Option<Reference>> {
    let Some(path) = &args.reference else {
        return Ok(None);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the reference {}", path.display()))?;
    let reference = parse_reference(&text, &path.display().to_string())
        .with_context(|| format!("reading the reference {}", path.display()))?;
    for warning in &reference.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(Some(reference))
}

/// Prints the run's one summary line: frames and verdicts, map size, ATE
/// against the ground truth when there is one, the difference from the
/// device's odometry and from `--reference`, time per frame.
pub(crate) fn print_summary(
    args: &RunArgs,
    (sequence, reference): (&Sequence, Option<&Reference>),
    slam: &Pipeline,
    frames: usize,
    played: Played,
) {
    let Played {
        failed,
        mean_ms: mean,
        median_ms: median,
        ..
    } = played;
    if let Some(localisation) = slam.localisation() {
        let reference = reference.map_or_else(String::new, |r| {
            reference_comparison(args, r, sequence, localisation.trajectory())
        });
        print_localise_summary(
            args,
            (sequence, &reference),
            slam,
            localisation,
            (frames, played),
        );
        return;
    }
    let counts = slam.counts();
    let accuracy = if sequence.ground_truth.is_empty() {
        "ATE n/a (no ground truth)".to_string()
    } else {
        match ate(slam.trajectory(), &sequence.ground_truth, MAX_DT) {
            Ok(a) => format!("ATE {} ({} poses)", evaluate::cm(a.rmse_m), a.pairs),
            Err(e) => format!("ATE n/a ({e})"),
        }
    };
    let odometry = odometry_comparison(sequence, slam);
    let reference = reference.map_or_else(String::new, |r| {
        reference_comparison(args, r, sequence, slam.trajectory())
    });
    let warnings = match slam.settings_warnings().len() {
        0 => String::new(),
        n => format!(", {n} camera-settings warning(s) (see above)"),
    };
    println!(
        "{}: {} frames, {} tracked, {} lost, {} recovered, {} held, {} restarted, {failed} unreadable, {} loop closures ({} global), {} surfels, {accuracy}{odometry}{reference}, {mean:.1} ms/frame (median {median:.1}){warnings}",
        args.dataset.display(),
        frames,
        counts.tracked,
        counts.lost,
        counts.recovered,
        counts.held,
        counts.restarted,
        slam.loop_closures(),
        slam.global_loop_closures(),
        slam.map().live_len(),
    );
}

/// The summary's comparison with the recording device's own trajectory
/// (Stray Scanner's ARKit odometry), `""` when the sequence has none: the
/// RMS distance between the two after rigid alignment, as ATE is computed,
/// but not an error: the odometry drifts too.
fn odometry_comparison(sequence: &Sequence, slam: &Pipeline) -> String {
    if sequence.odometry.is_empty() {
        return String::new();
    }
    match ate(slam.trajectory(), &sequence.odometry, MAX_DT) {
        Ok(a) => format!(
            ", difference from the device's odometry {} RMS ({} poses; odometry, not ground truth)",
            evaluate::cm(a.rmse_m),
            a.pairs
        ),
        Err(e) => format!(", difference from the device's odometry n/a ({e})"),
    }
}

/// The summary's comparison with `--reference`: the RMS distance between
/// `poses` and the reference after rigid alignment, scored as ATE (pairs by
/// the sequence's timestamps, the reference's frame numbers turned into
/// them), named as the user's reference.
fn reference_comparison(
    args: &RunArgs,
    reference: &Reference,
    sequence: &Sequence,
    poses: &[(f64, glam::DAffine3)],
) -> String {
    let file = args.reference.as_deref().unwrap_or(Path::new("")).display();
    let stamped = reference.in_sequence_time(&sequence.frames);
    match ate(poses, &stamped, MAX_DT) {
        Ok(a) => format!(
            ", difference from your reference ({file}) {} RMS ({} poses, by {})",
            evaluate::cm(a.rmse_m),
            a.pairs,
            reference.key.name()
        ),
        Err(e) => format!(", difference from your reference ({file}) n/a ({e})"),
    }
}

/// The summary line of a `--localise` run: frames placed (how), unplaced,
/// and the placed frames' ATE in the map's frame: the ground truth aligned
/// to the saved map's trajectory only (when the sequence's ground truth
/// covers the map's frames), never to the localised frames; `reference`:
/// the placed frames' difference from `--reference` (`""` without one).
fn print_localise_summary(
    args: &RunArgs,
    (sequence, reference): (&Sequence, &str),
    slam: &Pipeline,
    localisation: &Localisation,
    (frames, played): (usize, Played),
) {
    let c = localisation.counts();
    let placed = localisation.trajectory();
    let accuracy = match ate(slam.trajectory(), &sequence.ground_truth, MAX_DT) {
        _ if sequence.ground_truth.is_empty() => "ATE n/a (no ground truth)".to_owned(),
        Err(e) => format!("ATE in the map's frame n/a (the map's own frames: {e})"),
        Ok(map) => match ate_in_frame(
            placed,
            &sequence.ground_truth,
            MAX_DT,
            map.ground_truth_from_estimate,
        ) {
            Ok(a) => format!(
                "ATE in the map's frame {} ({} poses)",
                evaluate::cm(a.rmse_m),
                a.pairs
            ),
            Err(e) => format!("ATE in the map's frame n/a ({e})"),
        },
    };
    println!(
        "{}: localised {} frames in {}: {} placed ({} relocalised, {} tracked, {} held), {} unplaced, {} unreadable, map unchanged ({} surfels), {accuracy}{reference}, {:.1} ms/frame (median {:.1})",
        args.dataset.display(),
        frames,
        args.load.as_deref().unwrap_or(Path::new("")).display(),
        placed.len(),
        c.recovered,
        c.tracked,
        c.held,
        c.lost,
        played.failed,
        slam.map().live_len(),
        played.mean_ms,
        played.median_ms,
    );
}
