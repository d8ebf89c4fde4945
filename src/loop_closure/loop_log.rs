//! The loop record as text: one line saying what the loop stage decided on
//! a frame (the page shows the last one), and one CSV row per frame it
//! checked (the CLI's `--loop-log`): every registration, every global look,
//! what each found and which check refused it. Tuning loop closure on real
//! data starts from these rows.
//!
//! Distances in the CSV are centimetres, residuals millimetres, angles
//! degrees; an empty field is a check that did not run.

use super::closer::LoopOutcome;
use super::global::GlobalMiss;

/// The CSV header of [`loop_log_row`], without a line end.
pub const LOOP_LOG_HEADER: &str = "frame,decision,\
local_overlap,local_inliers,local_residual_mm,local_start_residual_mm,local_conditioning,local_held,\
local_free_space,local_start_free_space,local_correction_cm,local_correction_deg,local_refused,\
global_candidates,global_keyframe,global_dissimilarity,global_correction_cm,\
global_correction_deg,global_conditioning,global_free_space,global_photometric,global_refused,\
deform_error,deform_max_error_cm,reactivated,truth_error_tracked_cm,truth_error_corrected_cm";

impl LoopOutcome {
    /// Whether the stage checked anything on this frame (a registration
    /// ran or the global check looked): the frames the loop log has a row for.
    #[must_use]
    pub fn checked(&self) -> bool {
        self.registration.is_some() || self.global_looked || self.joined.is_some()
    }

    /// What the closure would make of the tracked pose
    /// (`world_from_camera`, metres): the local registration's correction
    /// applied to it, or the pose the global look's furthest candidate
    /// registered; `None` when neither ran that far.
    #[must_use]
    pub fn corrected_pose(&self) -> Option<glam::DAffine3> {
        if let Some(r) = self.registration.filter(|r| r.inliers > 0) {
            return Some(r.correction * self.tracked);
        }
        self.global_attempt.map(|a| a.world_from_camera)
    }

    /// The decision in one line (`local closure 1.8 cm 0.6 deg`, `local
    /// refused: too-little-overlap`, `global refused: photometric 16.2
    /// (keyframe 120)`, ...); `None` when nothing was checked.
    #[must_use]
    pub fn decision(&self) -> Option<String> {
        if !self.checked() {
            return None;
        }
        let mut parts = Vec::new();
        if let Some(r) = &self.registration {
            let (dt, dr) = r.magnitude();
            let size = format!("{:.1} cm {:.1} deg", dt * 100.0, dr);
            parts.push(match (r.rejected, self.closed, self.aligned) {
                (Some(why), ..) => format!("local refused: {}", why.name()),
                (None, true, _) => format!("local closure {size}"),
                (None, _, true) => format!("local aligned {size}"),
                (None, ..) => match &self.deform_error {
                    Some(e) => format!("local {size}, deformation refused: {e}"),
                    None => format!("local accepted {size}"),
                },
            });
        }
        if self.global_looked {
            let keyframe = self.global_attempt.map_or(String::new(), |a| {
                format!(" (keyframe {})", a.keyframe_frame)
            });
            parts.push(match (&self.global, self.global_miss) {
                (Some(g), _) if g.closed => format!(
                    "global closure {:.1} cm {:.1} deg{keyframe}{}",
                    g.correction_m * 100.0,
                    g.correction_deg,
                    if g.pose_only { ", pose only" } else { "" }
                ),
                (Some(_), _) => match &self.deform_error {
                    Some(e) => format!("global match{keyframe}, deformation refused: {e}"),
                    None => format!("global match{keyframe}"),
                },
                (None, Some(GlobalMiss::Refused)) => {
                    let why = self
                        .global_attempt
                        .and_then(|a| a.refused)
                        .map_or("refused", |r| r.name());
                    format!("global refused: {why}{keyframe}")
                }
                (None, Some(miss)) => format!("global {}{keyframe}", miss.name()),
                (None, None) => "global looked".to_owned(),
            });
        }
        if let Some(j) = &self.joined {
            let from = j.keyframe_frame.map_or_else(
                || "where the camera was lost".to_owned(),
                |k| format!("keyframe {k}"),
            );
            parts.push(format!(
                "segment from frame {} joined {:.1} cm {:.1} deg ({from})",
                j.segment_start,
                j.correction.0 * 100.0,
                j.correction.1,
            ));
        }
        Some(parts.join("; "))
    }

    /// The short name of the decision for the CSV: `joined` (a restarted
    /// segment moved onto the map), `closed-local`, `closed-global`,
    /// `placed-global` (the pose alone moved), `aligned`,
    /// `deform-refused`, `refused`.
    #[must_use]
    pub fn decision_name(&self) -> &'static str {
        if self.joined.is_some() {
            return "joined";
        }
        match (self.closed, self.global.is_some(), self.aligned) {
            (true, true, _) if self.global.is_some_and(|g| g.pose_only) => "placed-global",
            (true, true, _) => "closed-global",
            (true, false, _) => "closed-local",
            (false, _, true) => "aligned",
            _ if self.deform_error.is_some() => "deform-refused",
            _ => "refused",
        }
    }
}

/// The CSV row (no line end) of frame `frame`'s outcome, columns as
/// [`LOOP_LOG_HEADER`]. `truth`: the tracked and the corrected pose's
/// position errors against the ground truth, metres, when known.
#[must_use]
pub fn loop_log_row(frame: u32, outcome: &LoopOutcome, truth: Option<(f64, f64)>) -> String {
    let mut row = format!("{frame},{}", outcome.decision_name());
    let mut field = |value: Option<String>| {
        row.push(',');
        if let Some(v) = value {
            row.push_str(&v);
        }
    };
    let r = outcome.registration.as_ref();
    field(r.map(|r| r.overlap.to_string()));
    field(r.map(|r| r.inliers.to_string()));
    field(r.map(|r| format!("{:.3}", r.residual_rms_m * 1000.0)));
    field(r.map(|r| format!("{:.3}", r.start_residual_rms_m * 1000.0)));
    field(r.map(|r| format!("{:.2e}", r.conditioning)));
    field(r.map(|r| r.held.to_string()));
    field(r.map(|r| format!("{:.4}", r.free_space)));
    field(r.map(|r| format!("{:.4}", r.start_free_space)));
    field(r.map(|r| format!("{:.3}", r.magnitude().0 * 100.0)));
    field(r.map(|r| format!("{:.3}", r.magnitude().1)));
    field(r.and_then(|r| r.rejected).map(|why| why.name().to_owned()));
    let looked = outcome.global_looked;
    let a = outcome.global_attempt.as_ref();
    let correction =
        a.map(|a| crate::se3::motion_magnitude(&(outcome.tracked.inverse() * a.world_from_camera)));
    field(looked.then(|| outcome.global_candidates.to_string()));
    field(a.map(|a| a.keyframe_frame.to_string()));
    field(a.map(|a| format!("{:.3}", a.dissimilarity)));
    field(correction.map(|(dt, _)| format!("{:.3}", dt * 100.0)));
    field(correction.map(|(_, dr)| format!("{:.3}", dr.to_degrees())));
    field(a.map(|a| format!("{:.2e}", a.conditioning)));
    field(a.map(|a| format!("{:.4}", a.free_space)));
    field(
        a.and_then(|a| a.photometric_error)
            .map(|p| format!("{p:.2}")),
    );
    field(
        looked.then(|| match (outcome.global_miss, a.and_then(|a| a.refused)) {
            (Some(GlobalMiss::Refused), Some(why)) => why.name().to_owned(),
            (Some(miss), _) => miss.name().to_owned(),
            (None, _) => String::new(),
        }),
    );
    field(
        outcome
            .deform_error
            .map(|e| e.to_string().replace(',', ";")),
    );
    field(
        outcome
            .deform
            .map(|d| format!("{:.3}", d.max_constraint_error_m * 100.0)),
    );
    field(Some(outcome.reactivated.to_string()));
    field(truth.map(|(t, _)| format!("{:.3}", t * 100.0)));
    field(truth.map(|(_, c)| format!("{:.3}", c * 100.0)));
    row
}
