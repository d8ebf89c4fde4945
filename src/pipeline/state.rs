//! The pipeline's state that decides later frames, taken out to save a
//! session and put back to load one (`crate::session`). Everything else is
//! per-frame scratch, or re-derived here bit for bit: the model prediction
//! is rendered again from the restored map exactly as the last fused frame
//! rendered it (same map, pose, measured points and frame counts), the
//! fern index is rebuilt from the keyframes' codes, the re-acquisition
//! tracker from the configuration.

use super::{Pipeline, PipelineError, Segment, SlamConfig, VerdictCounts};
use crate::fusion::{DepthTiles, Measured, SurfelMap};
use crate::loop_closure::ferns::Keyframe;
use crate::noise::SensorNoise;
use crate::preprocess::camera_fixed::CameraFixedMask;
use crate::track::rgb::{PhotometricReference, ReferencePoint};
use crate::track::TrackerMode;
use crate::RgbdFrame;
use glam::{DAffine3, Vec3};
use std::ops::Range;

/// The pipeline's small values that later frames read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineScalars {
    /// Frames accepted so far (the next frame's index).
    pub frames: u32,
    /// Verdict counts and the lost streak.
    pub counts: VerdictCounts,
    /// Pose of the last placed frame (`world_from_camera`, metres): the
    /// last fused one, or while lost the last one dead-reckoned.
    pub last_good: Option<DAffine3>,
    /// Index of that frame (`None`: the last fused one, as sessions saved
    /// before dead reckoning have it).
    pub placed_frame: Option<u32>,
    /// Index of the last fused frame measured in every direction (not
    /// held; `None` in sessions saved before it was kept).
    pub measured_frame: Option<u32>,
    /// `previous_from_current` of the last two fused frames in a row.
    pub velocity: Option<DAffine3>,
    /// Loop closures, global ones, frame of the last global one.
    pub loop_counters: (u32, u32, Option<u32>),
    /// The first depth image was checked against the depth settings.
    pub depth_checked: bool,
    /// Tracker and fusion noise models as configured, before the first
    /// frame's clean-depth check chose the ones in the configuration.
    pub configured_noise: (SensorNoise, SensorNoise),
    /// The map's current segment (the default: since the first frame).
    pub segment: Segment,
    /// After a thing carried with the camera was first masked, while the
    /// camera is still to be placed again by the map from before it: the
    /// first frame it anchored and the last frame to try (`None` in
    /// sessions saved before it was kept).
    pub anchored: Option<[u32; 2]>,
}

/// The last fused frame as the sparse estimator keeps it: working colour
/// (RGB8) and camera-frame points (metres, `ZERO` where no depth).
#[derive(Debug, Clone, PartialEq)]
pub struct LastFusedFrame<C, V> {
    /// RGB8, `width x height`.
    pub rgb: C,
    /// Camera-frame points, metres.
    pub vertices: V,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
}

/// The pipeline's state, borrowed ([`Pipeline::state`]).
#[derive(Debug)]
pub struct StateView<'a> {
    /// The configuration in use (noise models as chosen at frame 0).
    pub config: &'a SlamConfig,
    /// Counters and poses.
    pub scalars: PipelineScalars,
    /// The surfel map.
    pub map: &'a SurfelMap,
    /// The spatial order's sorted runs.
    pub runs: &'a [Range<usize>],
    /// `(timestamp, world_from_camera)` per frame, as bent by loop closures.
    pub trajectory: &'a [(f64, DAffine3)],
    /// The same as tracked.
    pub online_trajectory: &'a [(f64, DAffine3)],
    /// The fern keyframes, oldest first.
    pub keyframes: &'a [Keyframe],
    /// The last fused frame (none before the first).
    pub last_fused: Option<LastFusedFrame<&'a [u8], &'a [Vec3]>>,
    /// The photometric term's frame memory per level (empty unless the
    /// tracker reads the last frame).
    pub photometric: Vec<&'a [ReferencePoint]>,
    /// What the mask of things carried with the camera remembers.
    pub camera_fixed: &'a CameraFixedMask,
    /// While a restarted segment is not joined: the last frame placed
    /// before the loss.
    pub lost_frame: Option<LastFusedFrame<&'a [u8], &'a [Vec3]>>,
    /// The map's first frame as pushed, while a thing carried with the
    /// camera may still turn out to have been in it.
    pub first_frame: Option<&'a RgbdFrame>,
}

/// The pipeline's state, owned ([`Pipeline::from_state`]).
#[derive(Debug)]
pub struct PipelineState {
    /// The configuration (noise models as chosen at frame 0).
    pub config: SlamConfig,
    /// Counters and poses.
    pub scalars: PipelineScalars,
    /// The surfel map, its boxes and schedule restored.
    pub map: SurfelMap,
    /// The spatial order's sorted runs.
    pub runs: Vec<Range<usize>>,
    /// `(timestamp, world_from_camera)` per frame, as bent by loop closures.
    pub trajectory: Vec<(f64, DAffine3)>,
    /// The same as tracked.
    pub online_trajectory: Vec<(f64, DAffine3)>,
    /// The fern keyframes, oldest first.
    pub keyframes: Vec<Keyframe>,
    /// The last fused frame (required after the first frame).
    pub last_fused: Option<LastFusedFrame<Vec<u8>, Vec<Vec3>>>,
    /// The photometric term's frame memory per level.
    pub photometric: Vec<Vec<ReferencePoint>>,
    /// What the mask of things carried with the camera remembers.
    pub camera_fixed: CameraFixedMask,
    /// While a restarted segment is not joined: the last frame placed
    /// before the loss (`None` in sessions saved before restarts).
    pub lost_frame: Option<LastFusedFrame<Vec<u8>, Vec<Vec3>>>,
    /// The map's first frame as pushed, while a thing carried with the
    /// camera may still turn out to have been in it (`None` in sessions
    /// saved before it was kept).
    pub first_frame: Option<RgbdFrame>,
}

/// Whether the tracker keeps the last frame for its photometric term.
fn remembers_frames(config: &SlamConfig) -> bool {
    config.tracker.mode != TrackerMode::Icp
        && config.tracker.photometric.reference == PhotometricReference::LastFrame
}

impl Pipeline {
    /// Everything a session file holds, borrowed.
    #[must_use]
    pub fn state(&self) -> StateView<'_> {
        let photometric = if remembers_frames(&self.config) {
            self.tracker.photometric_memory().collect()
        } else {
            Vec::new()
        };
        let last_fused = (self.frame_index > 0)
            .then(|| self.sparse.reference_frame())
            .flatten()
            .map(|(rgb, vertices, width, height)| LastFusedFrame {
                rgb,
                vertices,
                width,
                height,
            });
        StateView {
            config: &self.config,
            scalars: PipelineScalars {
                frames: self.frame_index,
                counts: self.counts,
                last_good: self.last_good,
                placed_frame: Some(self.placed_frame),
                measured_frame: self.measured_frame,
                velocity: self.velocity,
                loop_counters: self.loop_closer.counters(),
                depth_checked: self.settings_check.depth_checked,
                configured_noise: self.configured_noise,
                segment: self.segment,
                anchored: self.anchored.map(|a| [a.from, a.until]),
            },
            map: &self.map,
            runs: self.order.runs(),
            trajectory: &self.trajectory,
            online_trajectory: &self.online_trajectory,
            keyframes: self.relocaliser.database().keyframes(),
            last_fused,
            photometric,
            camera_fixed: &self.camera_fixed,
            lost_frame: self.lost_frame.as_deref().map(|f| LastFusedFrame {
                rgb: &f.rgb[..],
                vertices: &f.vertices[..],
                width: f.width,
                height: f.height,
            }),
            first_frame: self.first_frame.as_deref(),
        }
    }

    /// A pipeline in `state`, which then continues as the pipeline it was
    /// taken from would have. Refuses a state whose parts do not fit
    /// together (naming the part).
    pub fn from_state(state: PipelineState) -> Result<Self, PipelineError> {
        let bad = |what: String| PipelineError::InvalidConfig(format!("saved state: {what}"));
        let s = state.scalars;
        let mut p = Pipeline::new(state.config)?;
        let frames = s.frames as usize;
        if state.trajectory.len() != frames || state.online_trajectory.len() != frames {
            return Err(bad(format!(
                "{} and {} poses for {frames} frames",
                state.trajectory.len(),
                state.online_trajectory.len()
            )));
        }
        let counted = s.counts.fused() + s.counts.lost;
        if counted != s.frames || s.counts.lost_streak > s.counts.lost {
            return Err(bad(format!(
                "verdict counts {:?} for {frames} frames",
                s.counts
            )));
        }
        let segment = s.segment;
        if segment.fused_before > s.counts.fused() || (s.frames > 0 && segment.start >= s.frames) {
            return Err(bad(format!(
                "segment from frame {} after {} fused frames, for {frames} frames and {} fused",
                segment.start,
                segment.fused_before,
                s.counts.fused()
            )));
        }
        p.order
            .restore_runs(state.runs, state.map.len())
            .map_err(bad)?;
        p.relocaliser
            .database_mut()
            .restore_keyframes(state.keyframes)
            .map_err(|e| bad(e.to_string()))?;
        p.map = state.map;
        p.order.reserve_for(&p.map);
        p.trajectory = state.trajectory;
        p.online_trajectory = state.online_trajectory;
        p.frame_index = s.frames;
        p.counts = s.counts;
        p.last_good = s.last_good;
        let last_fused = s
            .frames
            .saturating_sub(s.counts.lost_streak.saturating_add(1));
        p.placed_frame = s.placed_frame.unwrap_or(last_fused);
        if p.placed_frame < last_fused || (s.frames > 0 && p.placed_frame >= s.frames) {
            return Err(bad(format!(
                "placed frame {} for {frames} frames, the last fused {last_fused}",
                p.placed_frame
            )));
        }
        if let Some(m) = s.measured_frame.filter(|&m| m >= s.frames) {
            return Err(bad(format!("measured frame {m} for {frames} frames")));
        }
        p.measured_frame = s.measured_frame;
        if let Some([from, until]) = s.anchored {
            if from > s.frames || until < from {
                return Err(bad(format!(
                    "anchored frames {from} to {until} for {frames} frames"
                )));
            }
        }
        p.anchored = s
            .anchored
            .map(|[from, until]| super::carried::Anchored { from, until });
        p.velocity = s.velocity;
        p.loop_closer.restore_counters(s.loop_counters);
        p.settings_check.depth_checked = s.depth_checked;
        p.configured_noise = s.configured_noise;
        p.segment = segment;
        if let Some(lost) = &state.lost_frame {
            let pixels = p.config.working_intrinsics().pixel_count();
            let fits = lost.vertices.len() == pixels && lost.rgb.len() == 3 * pixels;
            if !fits || segment.start == 0 {
                return Err(bad(format!(
                    "a frame lost before a restart of {} points, for a segment from frame {} and {pixels} pixels",
                    lost.vertices.len(),
                    segment.start
                )));
            }
        }
        p.lost_frame = state.lost_frame.map(Box::new);
        if let Some(first) = &state.first_frame {
            let k = p.config.intrinsics;
            if (first.width, first.height) != (k.width, k.height) || s.frames == 0 {
                return Err(bad(format!(
                    "a first frame of {}x{} for a {}x{} camera after {frames} frames",
                    first.width, first.height, k.width, k.height
                )));
            }
        }
        p.first_frame = state.first_frame.map(Box::new);
        p.camera_fixed = state.camera_fixed;
        if remembers_frames(&p.config) {
            p.tracker.restore_photometric_memory(state.photometric);
        }
        if s.frames > 0 {
            let last = state
                .last_fused
                .ok_or_else(|| bad("no last fused frame".into()))?;
            p.restore_last_fused(&last).map_err(bad)?;
        }
        Ok(p)
    }

    /// The sparse estimator's reference and the model prediction, as the
    /// last placed frame (`last`) left them.
    fn restore_last_fused(
        &mut self,
        last: &LastFusedFrame<Vec<u8>, Vec<Vec3>>,
    ) -> Result<(), String> {
        let k = self.config.working_intrinsics();
        if (last.width, last.height) != (k.width, k.height) {
            return Err(format!(
                "last frame of {}x{} for a {}x{} camera",
                last.width, last.height, k.width, k.height
            ));
        }
        self.sparse
            .restore_reference(&last.rgb, &last.vertices, last.width, last.height)
            .map_err(|e| e.to_string())?;
        let pose = self.last_good.ok_or("no pose of the last fused frame")?;
        // The frame placed last: fused (the last one before the lost
        // streak, whose warm-up count did not include it yet) or
        // dead-reckoned during the streak.
        let index = self.placed_frame;
        let was_fused = u64::from(index) + 1 + u64::from(self.counts.lost_streak)
            == u64::from(self.frame_index);
        let fused = self.fused_in_segment().saturating_sub(u32::from(was_fused));
        let mut tiles = DepthTiles::default();
        tiles.build(&last.vertices, k.width);
        let fusion_cfg = self.config.fusion;
        let active = self.active_at(index);
        let map = &self.map;
        self.prediction.render(
            map,
            &pose,
            &k,
            (fusion_cfg.depth_gate_m, self.config.depth.max_m),
            Measured {
                vertices: &last.vertices,
                tiles: &tiles,
            },
            active,
            |i| fusion_cfg.predicts(map, i, fused),
        );
        Ok(())
    }
}
