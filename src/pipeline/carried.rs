//! What a thing carried with the camera left in the map.
//!
//! A hand at the image's edge is masked only once it stayed put through
//! `PreprocessConfig::camera_fixed_frames` moving frames
//! ([`crate::preprocess::camera_fixed`]). Until then it was tracked and
//! fused: the map holds its surfels, and the frames it anchored placed
//! them where the anchored camera saw them, so they hang in front of the
//! camera's last pose, at the masked pixels and depths. Left there, they
//! are drawn and exported as a blob, and the prediction shows them where
//! the scene should be.

use super::segments::Segment;
use super::Pipeline;
use crate::se3::RigidF32;
use glam::DAffine3;

impl Pipeline {
    /// On the frame the mask first masks something: absorbs the live
    /// surfels that, seen from the last placed pose, lie on the masked
    /// cells at their depth ([`crate::preprocess::camera_fixed::CameraFixedMask::covers`]),
    /// and those first seen in the frames the masked thing anchored
    /// (placed where an anchored camera saw them). A map left without a
    /// live surfel (the thing was in view since the map began) starts
    /// again with this frame, at the last placed pose
    /// ([`super::Verdict::Restarted`]); otherwise the prediction is
    /// rendered again without them. Returns how many surfels went.
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
            self.start_map_again(world_from_camera);
        } else {
            // This frame is tracked against what is left.
            let dead_reckoned = self.counts.lost_streak > 0;
            self.render_prediction(&world_from_camera, dead_reckoned);
        }
        gone.len()
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
