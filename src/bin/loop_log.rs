//! `run --loop-log FILE`: one CSV row per frame the loop stage checked,
//! with the ground truth's verdict on the correction when the sequence has
//! one (columns: `surfel_slam::loop_closure::loop_log`).

use anyhow::{Context, Result};
use glam::DAffine3;
use std::path::Path;
use surfel_slam::eval::errors_in_early_alignment;
use surfel_slam::loop_closure::loop_log::{loop_log_row, LOOP_LOG_HEADER};
use surfel_slam::{FrameReport, Pipeline};

use crate::MAX_DT;

/// The rows so far and what the truth columns need.
pub struct LoopLog<'a> {
    text: String,
    ground_truth: &'a [(f64, DAffine3)],
}

impl<'a> LoopLog<'a> {
    /// An empty log; `ground_truth` (TUM poses, possibly empty) fills the
    /// truth columns.
    pub fn new(ground_truth: &'a [(f64, DAffine3)]) -> Self {
        Self {
            text: format!("{LOOP_LOG_HEADER}\n"),
            ground_truth,
        }
    }

    /// Adds the row of the frame `report` describes, just pushed into
    /// `slam`, when the loop stage checked anything on it.
    pub fn record(&mut self, slam: &Pipeline, report: &FrameReport) {
        let outcome = &report.loop_outcome;
        if !outcome.checked() {
            return;
        }
        let truth = outcome
            .corrected_pose()
            .and_then(|corrected| self.truth(slam, report, corrected));
        self.text
            .push_str(&loop_log_row(report.index, outcome, truth));
        self.text.push('\n');
    }

    /// The tracked and the corrected pose's errors against the ground
    /// truth aligned on the frames older than the active window (the old
    /// map), metres.
    fn truth(
        &self,
        slam: &Pipeline,
        report: &FrameReport,
        corrected: DAffine3,
    ) -> Option<(f64, f64)> {
        let window = slam.config().fusion.active_window_frames as usize;
        let trajectory = slam.trajectory();
        let old_end = trajectory.len().checked_sub(window + 1)?;
        let aligned_before = trajectory.get(old_end)?.0;
        let poses = [report.loop_outcome.tracked, corrected];
        let errors = errors_in_early_alignment(
            trajectory,
            self.ground_truth,
            MAX_DT,
            (aligned_before, report.timestamp),
            &poses,
        )
        .ok()??;
        Some((*errors.first()?, *errors.get(1)?))
    }

    /// Writes the log to `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        std::fs::write(path, &self.text).with_context(|| format!("writing {}", path.display()))
    }
}
