//! Stage `close_loops`: the loop-closure stage's inputs from the pipeline,
//! after fusion, on every fused frame and once more when a recording ends.

use super::Pipeline;
use crate::fusion::Measured;
use crate::loop_closure::{GlobalLook, LoopFrame, LoopOutcome};
use glam::DAffine3;

impl Pipeline {
    /// Stage `close_loops` ([`LoopCloser`]): where the view overlaps the
    /// inactive model, register the active model onto it; on a closure the
    /// map, the trajectory and `pose` are bent, and so is the last good
    /// pose (the constant-velocity motion is then measured between poses
    /// corrected alike).
    pub(super) fn close_loops(&mut self, pose: &mut DAffine3, index: u32) -> LoopOutcome {
        self.run_loop_stage(pose, index, false)
    }

    /// [`Self::close_loops`] (`finishing` false) or, for the last frame
    /// pushed, once fused, the global check off its schedule (`finishing`
    /// true, see [`Self::finish`]: the trajectory then holds that frame
    /// already, which `pose` stands for).
    pub(super) fn run_loop_stage(
        &mut self,
        pose: &mut DAffine3,
        index: u32,
        finishing: bool,
    ) -> LoopOutcome {
        let k = self.config.working_intrinsics();
        let frame = LoopFrame {
            now: index,
            intrinsics: &k,
            measured: Measured {
                vertices: self.pyramid.levels.first().map_or(&[], |l| &l.vertices),
                tiles: self.integrator.depth_tiles(),
            },
            fusion: &self.config.fusion,
            active_from: self.active_at(index).start,
            far_m: self.config.depth.max_m,
            // During a frame its verdict is not counted yet.
            fused: self.fused_in_segment().saturating_sub(u32::from(finishing)),
            verify: &self.config.tracker.verify,
        };
        let global = GlobalLook {
            relocaliser: &mut self.relocaliser,
            pyramid: &self.pyramid,
            normal: &self.config.tracker,
            wide: &self.recovery,
            workspace: &mut self.tracker,
        };
        let outcome = if finishing {
            let before = self.trajectory.len().saturating_sub(1);
            let trajectory = &mut self.trajectory[..before];
            self.loop_closer
                .look_now(&mut self.map, trajectory, pose, &frame, global)
        } else {
            self.loop_closer.run(
                &mut self.map,
                &mut self.trajectory,
                pose,
                &frame,
                Some(global),
            )
        };
        if outcome.closed {
            // The trajectory's last entry is the last good pose, or (after
            // lost frames) a copy of it held.
            if let Some(&(_, last)) = self.trajectory.last() {
                self.last_good = Some(last);
            }
            // Keyframes are placed in the map they were seen in.
            let closer = &self.loop_closer;
            self.relocaliser
                .database_mut()
                .update_poses(|frame, p| closer.deform_pose(p, frame));
        }
        outcome
    }
}
