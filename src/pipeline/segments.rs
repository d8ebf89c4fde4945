//! Segments of the map: a camera lost for long restarts mapping at a
//! guess, and the new segment is moved onto the map before it once one
//! of its frames is placed there.
//!
//! A restarted frame ([`Verdict::Restarted`]) is fused at the last placed
//! pose (`world_from_camera`, metres), where the camera was when it was
//! lost or dead-reckoned to. Surfels last seen before the segment's first
//! frame are inactive from then on (`active_at`): the segment's pose
//! relative to them is a guess, so neither tracking nor fusion reads them.
//! The segment's frames are placed in the map before it as a lost frame
//! is: from where the camera was lost (the last placed frame's view, the
//! wide search and re-acquisition's checks), and by the keyframes from
//! before the segment that look like them (relocalisation's checks); on
//! every frame at first, then less often (see [`Pipeline::join_segment`]).
//! On a match the segment (its surfels, poses and keyframes) moves rigidly
//! by the correction: it was tracked, only where it began was a guess. The
//! boundary then goes: the map is one again.

use super::recovery::{pins_pose, Tracked};
use super::{LastFusedFrame, Pipeline, Verdict};
use crate::fusion::Measured;
use crate::loop_closure::relocalise::{see_through_fraction, Relocalisation};
use crate::loop_closure::SegmentJoin;
use crate::se3;
use crate::track::track;
use crate::track::verify::free_space_violation;
use glam::DAffine3;
use std::ops::Range;

/// The current segment of the map: since the first frame, or since the
/// last restart after a long loss ([`super::SlamConfig::restart_after_lost`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Segment {
    /// Index of its first frame; 0 for the first segment and once a
    /// segment was joined onto the map before it.
    pub start: u32,
    /// Frames fused before it: its own warm-up counts from there.
    pub fused_before: u32,
}

/// A lost frame restarts mapping only when at least this share of its
/// pixels has depth: a frame facing nothing in range would seed a segment
/// no later frame can be tracked against.
const RESTART_MIN_DEPTH_SHARE: f64 = 0.25;

/// Fused frames of a segment not yet joined between two looks among the
/// keyframes from before it, after its first [`JOIN_FROM_LOSS_EVERY_FRAME`].
const JOIN_EVERY_FRAMES: u32 = 4;

/// For its first this many fused frames, a segment not yet joined is also
/// looked for where the camera was lost: on every frame for the first
/// [`JOIN_FROM_LOSS_EVERY_FRAME`], then on every second.
const JOIN_FROM_LOSS_FRAMES: u32 = 60;

/// See [`JOIN_FROM_LOSS_FRAMES`]: as a lost frame is, the frames just after
/// a restart are re-acquired at once when the camera comes back.
const JOIN_FROM_LOSS_EVERY_FRAME: u32 = 10;

impl Pipeline {
    /// The `last_seen` frames of the surfels active at frame `frame`:
    /// [`crate::fusion::FusionConfig::active_at`], from the segment's
    /// first frame at the earliest.
    pub(super) fn active_at(&self, frame: u32) -> Range<u32> {
        let window = self.config.fusion.active_at(frame);
        window.start.max(self.segment.start)..window.end
    }

    /// Frames fused in the current segment: its warm-up's count.
    pub(super) fn fused_in_segment(&self) -> u32 {
        self.counts
            .fused()
            .saturating_sub(self.segment.fused_before)
    }

    /// A frame lost after [`super::SlamConfig::restart_after_lost`] lost
    /// ones in a row, with depth over [`RESTART_MIN_DEPTH_SHARE`] of its
    /// pixels, restarts mapping: it becomes [`Verdict::Restarted`] at its
    /// pose (the last placed one, or dead-reckoned) and begins a new
    /// [`Segment`]. Other frames pass unchanged.
    pub(super) fn restart_if_lost_long(&mut self, tracked: &mut Tracked) {
        let after = self.config.restart_after_lost;
        let lost = matches!(tracked.verdict, Verdict::Lost(_));
        if !lost || after == 0 || self.counts.lost_streak < after {
            return;
        }
        let vertices = self.pyramid.levels.first().map_or(&[][..], |l| &l.vertices);
        let with_depth = vertices.iter().filter(|v| v.z > 0.0).count();
        if (with_depth as f64) < RESTART_MIN_DEPTH_SHARE * vertices.len() as f64 {
            return;
        }
        tracked.verdict = Verdict::Restarted;
        // The estimator's reference is still the last placed frame.
        self.lost_frame = self
            .sparse
            .reference_frame()
            .map(|(rgb, vertices, width, height)| {
                Box::new(LastFusedFrame {
                    rgb: rgb.to_vec(),
                    vertices: vertices.to_vec(),
                    width,
                    height,
                })
            });
        self.segment = Segment {
            start: self.frame_index,
            fused_before: self.counts.fused(),
        };
    }

    /// After frame `index` was fused at `pose` in a segment not yet joined:
    /// places the frame in the map before the segment, against the surfels
    /// last seen before it, from where the camera was lost (every frame
    /// for the segment's first [`JOIN_FROM_LOSS_EVERY_FRAME`], then every
    /// second up to [`JOIN_FROM_LOSS_FRAMES`]: a camera swung away and
    /// back) and by the keyframes from before the segment that look like
    /// it (every frame for the first [`JOIN_FROM_LOSS_EVERY_FRAME`], then
    /// every [`JOIN_EVERY_FRAMES`]). On a match moves the segment onto that
    /// map (see the module documentation) and returns what moved it.
    pub(super) fn join_segment(&mut self, pose: &mut DAffine3, index: u32) -> Option<SegmentJoin> {
        let start = self.segment.start;
        let since = index.checked_sub(start)?;
        if start == 0 || since == 0 {
            return None;
        }
        let from_loss = since <= JOIN_FROM_LOSS_EVERY_FRAME
            || (since <= JOIN_FROM_LOSS_FRAMES && since % 2 == 0);
        let mut found = None;
        if from_loss {
            found = self.place_from_loss(start).map(|p| (p, None));
        }
        let by_keyframes = since <= JOIN_FROM_LOSS_EVERY_FRAME || since % JOIN_EVERY_FRAMES == 0;
        if found.is_none() && by_keyframes {
            found = self
                .place_by_keyframes_before(start)
                .map(|r| (r.world_from_camera, Some(r.keyframe_frame)));
        }
        let (placed, keyframe_frame) = found?;
        let correction = placed * pose.inverse();
        if !correction.is_finite() {
            return None;
        }
        let moved = se3::motion_magnitude(&(pose.inverse() * placed));
        self.map.move_created_since(start, &correction);
        for (_, p) in self.trajectory.iter_mut().skip(start as usize) {
            *p = correction * *p;
        }
        *pose = correction * *pose;
        // The frame before this one, in the segment: the velocity is
        // measured from it.
        self.last_good = self.last_good.map(|p| correction * p);
        self.relocaliser.database_mut().update_poses(|frame, p| {
            if frame >= start {
                correction * *p
            } else {
                *p
            }
        });
        self.segment.start = 0;
        self.lost_frame = None;
        Some(SegmentJoin {
            segment_start: start,
            keyframe_frame,
            correction: (moved.0, moved.1.to_degrees()),
        })
    }

    /// The frame placed against the surfels last seen before frame `start`
    /// from the keyframes before it that look like it.
    fn place_by_keyframes_before(&mut self, start: u32) -> Option<Relocalisation> {
        if !self.relocaliser.config().enabled {
            return None;
        }
        let fused = self.counts.fused();
        self.place_by_keyframes(0..start, fused)
    }

    /// The frame placed against the surfels last seen before frame
    /// `start` (the segment's first), as re-acquisition places a lost
    /// frame: the model seen from the pose of the last frame placed before
    /// the loss, down to what that frame measured (`lost_frame`), the wide
    /// search from there, and its checks: the normal tracker started at its
    /// result keeps it, the view pins all six degrees of freedom, and the
    /// frame's points keep the model's free space clear. Renders into the
    /// model prediction, which the `predict` stage renders again.
    fn place_from_loss(&mut self, start: u32) -> Option<DAffine3> {
        // The segment's first frame was placed where the last placed frame was.
        let (_, from) = *self.online_trajectory.get(start as usize)?;
        let lost = self.lost_frame.as_deref()?;
        let k = self.config.working_intrinsics();
        if lost.vertices.len() != k.pixel_count() {
            return None;
        }
        self.lost_tiles.build(&lost.vertices, k.width);
        let fusion = self.config.fusion;
        let fused = self.counts.fused();
        let map = &self.map;
        self.prediction.render(
            map,
            &from,
            &k,
            (fusion.depth_gate_m, self.config.depth.max_m),
            Measured {
                vertices: &lost.vertices,
                tiles: &self.lost_tiles,
            },
            0..start,
            |i| fusion.predicts(map, i, fused),
        );
        let (wide, normal) = (&self.recovery, &self.config.tracker);
        let searched = track(
            &self.pyramid,
            &self.prediction,
            &from,
            wide,
            &mut self.tracker,
        );
        if !searched.world_from_camera.is_finite() {
            return None;
        }
        let check = track(
            &self.pyramid,
            &self.prediction,
            &searched.world_from_camera,
            normal,
            &mut self.tracker,
        );
        let pose = check.world_from_camera;
        if check.lost.is_some() || !pose.is_finite() || !pins_pose(&check) {
            return None;
        }
        // A search that ran far from where the camera was lost found a
        // look-alike, not the place: relocalisation's bound from the
        // keyframe it starts at.
        let reloc = self.relocaliser.config();
        let (dt, dr) = se3::motion_magnitude(&(from.inverse() * pose));
        if dt > reloc.max_from_keyframe_m || dr.to_degrees() > reloc.max_from_keyframe_deg {
            return None;
        }
        let sampled = self.pyramid.check_level()?;
        let verify = &self.config.tracker.verify;
        let (violation, landed) =
            free_space_violation(&self.prediction, &sampled.vertices, 1, &pose, verify);
        // Both ways, as relocalisation checks: the model must not show
        // surfaces where the frame sees through to farther ones.
        let see_through = see_through_fraction(&self.prediction, sampled, &pose, verify);
        let limit = verify.max_free_space_fraction;
        (landed > 0 && violation <= limit && see_through <= limit).then_some(pose)
    }
}
