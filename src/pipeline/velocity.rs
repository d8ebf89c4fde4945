//! The constant-velocity motion the next frame starts from, and what a
//! held run carries along the directions its frames leave free.
//!
//! A held frame keeps the directions its geometry leaves free at the
//! guess, so a held run moves along them by the velocity it entered with,
//! frame after frame: one wrong step becomes the run's drift. Two kinds of
//! step are not the camera's motion: a step that slid (a frame pinned just
//! well enough to be tracked, then held on the next) and a step that
//! corrects what a held run drifted.

use super::Pipeline;
use glam::{DAffine3, DVec3};

/// Steps whose median is the velocity a held run enters with: the frame
/// that starts the run and the ones before it. A window of 5 outvotes two
/// wrong steps.
const HELD_RUN_ENTRY_STEPS: usize = 5;

impl Pipeline {
    /// The next frame's constant-velocity motion, from the frame just
    /// fused at `pose` (`held_at_guess`: some of its directions were kept
    /// at the constant-velocity guess) and the one before it at `before`:
    /// the step between them, with two exceptions that keep the step's
    /// rotation (which held frames measure) and replace its translation.
    ///
    /// - The first held frame after a measured one: the camera centre's
    ///   per-axis median step (world frame) over the last
    ///   [`HELD_RUN_ENTRY_STEPS`] frames. The last step alone can be a
    ///   slide: the long ICL-NUIM office at an iPhone's 256x192 without
    ///   colour, frame 320, tracked 3.5 cm along a wall (truth 0.6 cm) at
    ///   conditioning 0.0012, then 50 frames held at that step, 170 cm.
    /// - A measured frame after a held run, whose step corrects what the
    ///   run drifted and as a velocity would repeat that correction every
    ///   frame of the next held run (the synthetic room at 256x192 without
    ///   colour: 9.7 cm a frame, 230 cm in 22 frames): the camera centre's
    ///   mean per frame since the last measured frame.
    ///
    /// A held frame `interval_s` seconds after the one before also slows
    /// the translation down, by `exp(-interval_s / tau)` with `tau` =
    /// [`crate::track::MotionPriorConfig::held_velocity_decay_s`]: what a held run
    /// carries along its free directions is a guess, and a hand comes to
    /// rest rather than keeping a velocity for seconds (a phone walking up
    /// to a bare wall held 118 frames at 8.5 cm a frame, 5 m/s).
    pub(super) fn motion_since_measured(
        &self,
        before: DAffine3,
        pose: &DAffine3,
        (held_at_guess, interval_s): (bool, f64),
    ) -> DAffine3 {
        let step = before.inverse() * *pose;
        let translation_world = match self.measured_frame {
            Some(m) if held_at_guess && m == self.placed_frame => self.median_step(pose),
            Some(m) if !held_at_guess && m < self.placed_frame => self.mean_step_since(m, pose),
            _ => None,
        };
        let motion = match translation_world {
            Some(t) => {
                DAffine3::from_mat3_translation(step.matrix3, before.matrix3.transpose() * t)
            }
            None => step,
        };
        let prior = &self.config.tracker.motion_prior;
        let real_interval = interval_s > 0.0 && interval_s <= prior.max_interval_s;
        if held_at_guess && prior.enabled && real_interval && prior.held_velocity_decay_s > 0.0 {
            let keep = libm::exp(-interval_s / prior.held_velocity_decay_s);
            DAffine3::from_mat3_translation(motion.matrix3, motion.translation * keep)
        } else {
            motion
        }
    }

    /// The per-axis median of the camera centre's last
    /// [`HELD_RUN_ENTRY_STEPS`] steps (world frame, metres), the last one
    /// to `pose`; `None` while the trajectory is shorter.
    fn median_step(&self, pose: &DAffine3) -> Option<DVec3> {
        let recent = self
            .trajectory
            .get(self.trajectory.len().checked_sub(HELD_RUN_ENTRY_STEPS)?..)?;
        let next = |i: usize| {
            recent
                .get(i + 1)
                .map_or(pose.translation, |(_, p)| p.translation)
        };
        let steps: [DVec3; HELD_RUN_ENTRY_STEPS] =
            std::array::from_fn(|i| next(i) - recent[i].1.translation);
        let median = |axis: fn(&DVec3) -> f64| {
            let mut values = steps.map(|v| axis(&v));
            values.sort_by(f64::total_cmp);
            values[HELD_RUN_ENTRY_STEPS / 2]
        };
        Some(DVec3::new(
            median(|v| v.x),
            median(|v| v.y),
            median(|v| v.z),
        ))
    }

    /// The camera centre's mean step (world frame, metres) from frame `m`
    /// to `pose`, the current frame's; `None` when `m` is not behind it.
    fn mean_step_since(&self, m: u32, pose: &DAffine3) -> Option<DVec3> {
        let &(_, start) = self.trajectory.get(m as usize)?;
        let frames = self.frame_index.checked_sub(m).filter(|&n| n > 0)?;
        Some((pose.translation - start.translation) / f64::from(frames))
    }
}
