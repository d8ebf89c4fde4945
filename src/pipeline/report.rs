//! What the pipeline says about each frame: verdict, counts, timings.

use super::SettingsWarning;
use crate::fusion::FusionStats;
use crate::loop_closure::LoopOutcome;
use crate::track::verify::TrackingChecks;
use crate::track::LostReason;
use glam::DAffine3;

/// Tracking outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// First frame of the map: pose set to identity.
    Initialised,
    /// Tracked against the model and fused.
    Tracked,
    /// Re-acquired against the model and fused: the frame before was lost,
    /// or the normal tracker failed on this frame and the wider
    /// re-acquisition search (see [`Pipeline::push_frame`](super::Pipeline::push_frame)) succeeded.
    Recovered,
    /// Fused, but the geometry left some directions of motion free (a
    /// flat wall, a wall and the floor; see
    /// [`free_directions`](crate::track::free_directions)): the pose is
    /// tracked in the others and held at the motion prior in those.
    Held,
    /// Not tracked; not fused; the pose is held at the last good one.
    Lost(LostReason),
    /// Lost for [`SlamConfig::restart_after_lost`](super::SlamConfig::restart_after_lost)
    /// frames in a row: fused at the last placed pose as the first frame
    /// of a new segment of the map. The map so far is kept, but no longer
    /// tracked against (it is inactive, as if seen long ago) until a loop
    /// closure registers the new segment onto it.
    Restarted,
    /// Localise mode only: the frame could not be placed in the saved map
    /// (neither tracked from the last placed frame nor relocalised from
    /// the keyframes). It has no pose ([`FrameReport::pose`] is `None`);
    /// the next frame is relocalised.
    Unplaced,
}

impl Verdict {
    /// Short name: `initialised`, `tracked`, `recovered`, `held`, `lost`,
    /// `restarted`, `unplaced`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Verdict::Initialised => "initialised",
            Verdict::Tracked => "tracked",
            Verdict::Recovered => "recovered",
            Verdict::Held => "held",
            Verdict::Lost(_) => "lost",
            Verdict::Restarted => "restarted",
            Verdict::Unplaced => "unplaced",
        }
    }

    /// True when the frame was fused (initialised, tracked, recovered,
    /// held or restarted) while mapping. In localise mode nothing is fused: these
    /// verdicts there mean placed in the map.
    #[must_use]
    pub fn is_fused(&self) -> bool {
        !matches!(self, Verdict::Lost(_) | Verdict::Unplaced)
    }
}

/// How many frames got each verdict since creation or the last reset.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VerdictCounts {
    /// Frames tracked normally (the first frame included).
    pub tracked: u32,
    /// Frames lost (not fused).
    pub lost: u32,
    /// Frames re-acquired after a loss.
    pub recovered: u32,
    /// Frames fused with some directions held at the motion prior.
    pub held: u32,
    /// Frames that started a new segment of the map after a long loss.
    pub restarted: u32,
    /// Frames lost in a row up to the last one (0 when tracking).
    pub lost_streak: u32,
}

impl VerdictCounts {
    /// Frames fused: tracked (the first included), recovered, held or
    /// restarted.
    #[must_use]
    pub fn fused(&self) -> u32 {
        self.tracked + self.recovered + self.held + self.restarted
    }
}

/// Milliseconds spent in each stage of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// PNG decoding (0 when the caller passed decoded buffers).
    pub decode_ms: f64,
    /// Bilateral filter, pyramid, vertex and normal maps.
    pub preprocess_ms: f64,
    /// Tracking.
    pub track_ms: f64,
    /// Fusion (index map, merge, add, cleanup).
    pub fuse_ms: f64,
    /// Loop closure: the inactive model's prediction, and on a revisit the
    /// registration, and on a closure the deformation of map and trajectory.
    pub loop_ms: f64,
    /// Model prediction for the next frame.
    pub predict_ms: f64,
    /// Whole frame.
    pub total_ms: f64,
}

/// What happened to one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// Frame index within this run (0-based).
    pub index: u32,
    /// The caller's timestamp (seconds or frame number).
    pub timestamp: f64,
    /// Estimated camera pose (camera to world, metres); the identity, not
    /// a pose, for a [`Verdict::Unplaced`] frame (see [`Self::pose`]).
    pub world_from_camera: DAffine3,
    /// Initialised, tracked, held, recovered or lost (see [`Verdict`]).
    pub verdict: Verdict,
    /// Inlier correspondences at the finest level.
    pub inliers: usize,
    /// Inliers over projected model points.
    pub inlier_ratio: f64,
    /// RMS point-to-plane residual, metres.
    pub residual_rms_m: f64,
    /// Conditioning of the final 6x6 system.
    pub conditioning: f64,
    /// Surfels the map holds after this frame ([`SurfelMap::live_len`](crate::fusion::SurfelMap::live_len): the
    /// PLY export's vertex count).
    pub surfels: usize,
    /// Slots in the map's arrays after this frame ([`SurfelMap::len`](crate::fusion::SurfelMap::len)): the
    /// surfels plus those absorbed into others and not yet compacted away.
    pub surfel_slots: usize,
    /// Fusion counts.
    pub fusion: FusionStats,
    /// Verdict counts of the run so far, this frame included.
    pub counts: VerdictCounts,
    /// What the independent checks of the tracking result said.
    pub checks: TrackingChecks,
    /// Loop closures (the map and trajectory bent) of the run so far, this
    /// frame included.
    pub loop_closures: u32,
    /// Of `loop_closures`, those the global check made.
    pub global_loop_closures: u32,
    /// What the loop-closure stage checked on this frame and what it
    /// decided (its `closed`: every surfel and past pose may have moved).
    pub loop_outcome: LoopOutcome,
    /// A camera-settings warning first reported with this frame (a depth
    /// scale or layout check; all of them: `Pipeline::settings_warnings`).
    pub settings_warning: Option<SettingsWarning>,
    /// Share (0-1) of the pushed image whose depth was taken out as
    /// something carried with the camera, a hand holding it
    /// ([`crate::preprocess::camera_fixed`]); 0 when nothing was.
    pub camera_fixed_share: f64,
    /// Stage timings.
    pub timings: StageTimings,
}

impl FrameReport {
    /// The frame's pose (`world_from_camera`, metres), `None` for a frame
    /// localise mode could not place.
    #[must_use]
    pub fn pose(&self) -> Option<DAffine3> {
        (self.verdict != Verdict::Unplaced).then_some(self.world_from_camera)
    }
}
