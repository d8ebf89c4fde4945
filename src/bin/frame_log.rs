//! `run --frame-log FILE`: one CSV row per input frame, the header first:
//! its verdict, the tracker's statistics, the pose as tracked (before any
//! loop closure moved it) and, when the sequence has ground truth, the
//! frame's relative pose error against the truth's motion since the
//! last fused frame (what a `tracked` verdict claims to be right; a lost
//! frame is not fused, so the frame after it is judged from the one before).
//!
//! Columns: `frame` (0-based, in the sequence), `timestamp` (as in the
//! trajectory file), `verdict` (initialised, tracked, held, lost,
//! recovered, unplaced, unreadable), `lost_reason`, `inliers`,
//! `residual_mm`, `conditioning`, `tx ty tz qx qy qz qw` (the online
//! `world_from_camera`, metres), `rpe_cm`, `rpe_deg` (the error of the
//! motion since the last fused frame; empty without truth for both),
//! `dead_reckoned` (1 for a lost frame whose pose the sparse estimate
//! carried on from the frame before, else 0), `camera_fixed_pct` (the
//! percentage of the image whose depth was taken out as something carried
//! with the camera, a hand holding it).

use anyhow::{Context, Result};
use glam::DAffine3;
use std::fmt::Write as _;
use std::path::Path;
use surfel_slam::dataset::{FrameEntry, Sequence};
use surfel_slam::se3::{motion_magnitude, unit_quaternion};
use surfel_slam::{FrameReport, Verdict};

use crate::MAX_DT;

/// The header row.
const HEADER: &str = "frame,timestamp,verdict,lost_reason,inliers,residual_mm,conditioning,\
tx,ty,tz,qx,qy,qz,qw,rpe_cm,rpe_deg,dead_reckoned,camera_fixed_pct";

/// The rows so far, and the previous input frame's pose and truth.
pub struct FrameLog<'a> {
    text: String,
    sequence: &'a Sequence,
    /// The last fused frame's online pose and its truth (if any).
    previous: Option<(DAffine3, Option<DAffine3>)>,
}

impl<'a> FrameLog<'a> {
    /// An empty log of `sequence` (its ground truth fills the error columns).
    pub fn new(sequence: &'a Sequence) -> Self {
        Self {
            text: format!("{HEADER}\n"),
            sequence,
            previous: None,
        }
    }

    /// Adds the row of a pushed frame; `online`: its pose as tracked.
    pub fn record(&mut self, entry: &FrameEntry, report: &FrameReport, online: Option<DAffine3>) {
        let reason = match report.verdict {
            Verdict::Lost(reason) => reason.name(),
            _ => "",
        };
        let _ = write!(
            self.text,
            "{},{},{},{reason},{},{:.3},{:.3e}",
            entry.index,
            entry.timestamp,
            report.verdict.name(),
            report.inliers,
            report.residual_rms_m * 1000.0,
            report.conditioning,
        );
        let truth = self.sequence.ground_truth_for(entry.timestamp, MAX_DT);
        match online {
            Some(pose) => {
                let t = pose.translation;
                let [qx, qy, qz, qw] = unit_quaternion(&pose);
                let _ = write!(
                    self.text,
                    ",{:.6},{:.6},{:.6},{qx:.6},{qy:.6},{qz:.6},{qw:.6}",
                    t.x, t.y, t.z
                );
                let error = match (self.previous, truth) {
                    (Some((before, Some(truth_before))), Some(truth)) => {
                        let ours = before.inverse() * pose;
                        let theirs = truth_before.inverse() * truth;
                        Some(motion_magnitude(&(theirs.inverse() * ours)))
                    }
                    _ => None,
                };
                match error {
                    Some((dt, dr)) => {
                        let _ = write!(self.text, ",{:.4},{:.4}", dt * 100.0, dr.to_degrees());
                    }
                    None => self.text.push_str(",,"),
                }
                if report.verdict.is_fused() {
                    self.previous = Some((pose, truth));
                }
            }
            None => self.text.push_str(",,,,,,,,,"),
        }
        let _ = writeln!(
            self.text,
            ",{},{:.2}",
            u8::from(report.checks.dead_reckoned),
            100.0 * report.camera_fixed_share
        );
    }

    /// Adds the row of a frame that could not be read or was refused.
    pub fn record_unreadable(&mut self, entry: &FrameEntry) {
        let _ = writeln!(
            self.text,
            "{},{},unreadable,,,,,,,,,,,,,,,",
            entry.index, entry.timestamp
        );
    }

    /// Writes the file.
    pub fn write(&self, path: &Path) -> Result<()> {
        std::fs::write(path, &self.text)
            .with_context(|| format!("writing the frame log {}", path.display()))
    }
}
