//! The end of a recording: the global loop check once more, on the last
//! frame, whatever its schedule.
//!
//! The global check looks a frame up among the old keyframes every
//! `GlobalConfig::every_frames` frames. A scan that ends where it began is
//! judged by its last frame, and its return to the first view may slide
//! in the last few frames, after the last scheduled look (`docs/design.md`,
//! "A scan that ends where it began"); the last frame is then looked up
//! too.

use super::Pipeline;
use crate::loop_closure::LoopOutcome;

impl Pipeline {
    /// The recording ended: looks the last pushed frame up among the old
    /// keyframes when it was fused and the global check's schedule skipped
    /// it; on a verified match the map, the trajectory and that frame's
    /// pose (`world_from_camera`, metres) are corrected as on any global
    /// closure. Returns what the check did (`LoopOutcome::default()` when
    /// it did not run: no frame, the last one lost, already looked up, in
    /// localise mode, loop closure off). Callable at any time: a second
    /// call does nothing, and frames pushed after it are tracked from the
    /// corrected pose.
    pub fn finish(&mut self) -> LoopOutcome {
        crate::pool::on_pool(|| self.finish_here())
    }

    fn finish_here(&mut self) -> LoopOutcome {
        let Some(index) = self.frame_index.checked_sub(1) else {
            return LoopOutcome::default();
        };
        let Some(&(timestamp, mut pose)) = self.trajectory.last() else {
            return LoopOutcome::default();
        };
        if self.localising.is_some() || self.loop_closer.ran_at() != Some(index) {
            return LoopOutcome::default();
        }
        let outcome = self.run_loop_stage(&mut pose, index, true);
        if outcome.closed {
            if let Some(last) = self.trajectory.last_mut() {
                *last = (timestamp, pose);
            }
            // What the next frame is tracked against, from the corrected pose.
            self.render_prediction(&pose, false);
            self.tracker
                .remember_frame(&self.pyramid, &pose, &self.config.tracker);
            self.last_good = Some(pose);
            // The frame's own keyframe, if it became one, was kept where
            // it was tracked.
            self.relocaliser
                .database_mut()
                .update_poses(|frame, p| if frame == index { pose } else { *p });
        }
        outcome
    }
}
