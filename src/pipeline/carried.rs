//! What a thing carried with the camera left in the map.
//!
//! A hand at the image's edge is masked only once it stayed put through
//! `PreprocessConfig::camera_fixed_frames` moving frames
//! ([`crate::preprocess::camera_fixed`]). Until then it was tracked and
//! fused: the map holds its surfels, and the frames it anchored placed
//! them where the anchored camera saw them, so they hang in front of the
//! camera's last pose, at the masked pixels and depths. Left there, they
//! are drawn and exported as a blob, and the prediction shows them where
//! the scene should be. And the camera they anchored was placed where it
//! was not: its pose is found again from what the map held before.

use super::recovery::Tracked;
use super::segments::Segment;
use super::Pipeline;
use crate::se3::{self, RigidF32};
use crate::RgbdFrame;
use glam::DAffine3;

/// Frames after a carried thing was first masked in which the camera is
/// placed again by the map from before it: a second, as a segment's join
/// is first tried (a swing's end can leave no view that pins a pose).
const REPLACE_WITHIN_FRAMES: u32 = 30;

/// Frames the map's first frame is kept for, in case a thing carried with
/// the camera was in view from it: two seconds at 30 Hz, well past the
/// mask's 6 moving frames.
pub(super) const FIRST_FRAME_KEPT_FRAMES: u32 = 64;

/// The frames a carried thing anchored, to place the camera again by the
/// map from before them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Anchored {
    /// The first frame it anchored: keyframes and surfels from before it
    /// place the camera.
    pub from: u32,
    /// The last frame tried.
    pub until: u32,
}

impl Pipeline {
    /// On the frame the mask first masks something: absorbs the live
    /// surfels that, seen from the last placed pose, lie on the masked
    /// cells at their depth ([`crate::preprocess::camera_fixed::CameraFixedMask::covers`]),
    /// and those first seen in the frames the masked thing anchored
    /// (placed where an anchored camera saw them). A map left without a
    /// live surfel (the thing was in view since the map began) begins
    /// again from its first frame ([`Self::map_again_from_first`]), or
    /// when that is not kept, with this frame at the last placed pose
    /// ([`super::Verdict::Restarted`]); otherwise the prediction is
    /// rendered again without them, and the camera is to be placed again
    /// ([`Self::place_as_before_carried`]). Returns how many surfels went.
    pub(super) fn forget_what_the_camera_carried(&mut self) -> usize {
        let Some(world_from_camera) = self.last_good else {
            return 0;
        };
        let camera_from_world = RigidF32::from_affine(&world_from_camera.inverse());
        let k = self.config.intrinsics;
        // The anchored frames and the one before them, which the thing's
        // first moving frame was tracked against.
        let anchored_from = self
            .frame_index
            .saturating_sub(u32::from(self.camera_fixed.longest_masked_still()) + 1);
        let map = &self.map;
        let gone: Vec<usize> = (0..map.len())
            .filter(|&i| {
                if map.confidences()[i] < 0.0 {
                    return false;
                }
                if map.first_seen()[i] >= anchored_from {
                    return true;
                }
                let p = camera_from_world.point(map.positions()[i]);
                if p.z <= 0.0 {
                    return false;
                }
                let uv = k.project(p);
                self.camera_fixed.covers(uv.x, uv.y, p.z)
            })
            .collect();
        for &i in &gone {
            self.map.absorb(i);
        }
        if gone.is_empty() {
            return 0;
        }
        if self.map.live_len() == 0 {
            match self.first_frame.take() {
                Some(first) if anchored_from == 0 => {
                    self.map_again_from_first(&first, world_from_camera);
                }
                _ => self.start_map_again(world_from_camera),
            }
        } else {
            // Keyframes the anchored camera took were placed where it was
            // not.
            self.relocaliser.database_mut().forget_from(anchored_from);
            self.anchored = Some(Anchored {
                from: anchored_from,
                until: self.frame_index.saturating_add(REPLACE_WITHIN_FRAMES),
            });
            // This frame is tracked against what is left.
            let dead_reckoned = self.counts.lost_streak > 0;
            self.render_prediction(&world_from_camera, dead_reckoned);
        }
        gone.len()
    }

    /// After a carried thing was first masked, when the map before it
    /// stayed: the camera it anchored moved in the map while it did not in
    /// the room, so the poses since carry that error. Each frame up to
    /// [`REPLACE_WITHIN_FRAMES`] after is placed again by the keyframes
    /// from before the anchored frames, against the surfels made before
    /// them (relocalisation's checks). The first placement replaces
    /// `tracked` as [`super::Verdict::Recovered`]; the surfels made since the
    /// anchored frames began go (placed by the wrong poses), and the next
    /// frame starts from it without the correction as its velocity. Other
    /// frames pass unchanged.
    pub(super) fn place_as_before_carried(&mut self, tracked: Tracked) -> Tracked {
        let Some(anchored) = self.anchored else {
            return tracked;
        };
        let start = self.segment.start;
        if self.frame_index > anchored.until
            || anchored.from <= start
            || !self.relocaliser.config().enabled
        {
            self.anchored = None;
            return tracked;
        }
        let fused = self.fused_in_segment();
        let found = self.place_by_keyframes_of(
            start..anchored.from,
            (start..u32::MAX, anchored.from),
            fused,
        );
        let Some(found) = found else {
            return tracked;
        };
        self.anchored = None;
        self.forget_made_since(anchored.from);
        self.spread_correction(anchored.from, &tracked.pose, &found.world_from_camera);
        self.last_good = Some(found.world_from_camera);
        Tracked::relocalised(tracked.checks, found)
    }

    /// The trajectory's frames from `first` to the last, placed by the
    /// anchored camera, corrected as the frame after them was
    /// (`world_from_camera` from `tracked` to `placed`): a share of the
    /// correction (in the camera's frame) growing linearly to it, as the
    /// anchored error grew frame by frame.
    fn spread_correction(&mut self, first: u32, tracked: &DAffine3, placed: &DAffine3) {
        let correction = se3::log(&(tracked.inverse() * *placed));
        if !correction.iter().all(|c| c.is_finite()) {
            return;
        }
        let frames = self.frame_index.saturating_sub(first) as usize;
        let count = frames.min(self.trajectory.len());
        let steps = (count + 1) as f64;
        let from = self.trajectory.len() - count;
        for (n, (_, pose)) in self.trajectory[from..].iter_mut().enumerate() {
            let share = (n + 1) as f64 / steps;
            *pose *= se3::exp(&correction.map(|c| c * share));
        }
    }

    /// Absorbs the live surfels first seen at frame `first` or later and
    /// forgets the keyframes taken since.
    fn forget_made_since(&mut self, first: u32) {
        let made: Vec<usize> = (0..self.map.len())
            .filter(|&i| self.map.confidences()[i] >= 0.0 && self.map.first_seen()[i] >= first)
            .collect();
        for i in made {
            self.map.absorb(i);
        }
        self.relocaliser.database_mut().forget_from(first);
    }

    /// Keeps the map's first frame (`frame`, as the mask sees it) while
    /// the mask (on after `min_frames` moving frames) has masked nothing,
    /// for at most [`FIRST_FRAME_KEPT_FRAMES`] frames.
    pub(super) fn keep_first_frame(&mut self, frame: &RgbdFrame, min_frames: u8) {
        if self.frame_index == 0 && min_frames > 0 && self.localising.is_none() {
            self.first_frame = Some(Box::new(frame.clone()));
        } else if self.frame_index >= FIRST_FRAME_KEPT_FRAMES
            || self.camera_fixed.masked_count() > 0
        {
            self.first_frame = None;
        }
    }

    /// The map begun again from its first frame (`first`), masked now,
    /// fused where it was placed (the world's origin), and this frame
    /// tracked against it: the frames the thing anchored since are
    /// replaced as this one is placed ([`Self::spread_over_anchored`]),
    /// not carried over as the new map's start (`anchored`: the last
    /// pose they reached).
    fn map_again_from_first(&mut self, first: &RgbdFrame, anchored: DAffine3) {
        let Some(&(_, origin)) = self.trajectory.first() else {
            self.start_map_again(anchored);
            return;
        };
        self.start_map_again(origin);
        self.reseed_at = None;
        let mut masked = RgbdFrame::default();
        self.camera_fixed.apply_into(first, &mut masked);
        // Fused and remembered as frame 0 was.
        let now = self.frame_index;
        self.frame_index = 0;
        self.preprocess(&masked);
        self.keep_for_sparse_and_ferns();
        self.fuse(&origin, 0);
        // No velocity: the step from the anchored pose is not a motion.
        self.last_good = None;
        self.predict(&origin, (false, f64::NAN));
        self.frame_index = now;
        self.anchored_last = Some(anchored);
    }

    /// After [`Self::map_again_from_first`]: once this frame is placed,
    /// the frames since the first take a share of its correction from the
    /// last anchored pose, growing to it frame by frame.
    pub(super) fn spread_over_anchored(&mut self, tracked: &Tracked) {
        let Some(anchored) = self.anchored_last.take() else {
            return;
        };
        if tracked.verdict.is_fused() {
            self.spread_correction(1, &anchored, &tracked.pose);
        }
    }

    /// Empties the map (and what indexes it: the spatial order, the
    /// prediction, the keyframes, loop closure's state), keeping the
    /// trajectory: the frame being pushed is fused first, at
    /// `world_from_camera`, and the warm-up counts from it.
    fn start_map_again(&mut self, world_from_camera: DAffine3) {
        self.map.clear();
        self.order.clear();
        self.prediction.clear();
        self.relocaliser.clear();
        self.loop_closer.reset();
        self.lost_frame = None;
        self.segment = Segment {
            start: 0,
            fused_before: self.counts.fused(),
        };
        self.reseed_at = Some(world_from_camera);
    }
}
