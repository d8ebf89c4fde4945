//! Settings of the fusion stage and the predicates they define.

use super::SurfelMap;
use crate::noise::SensorNoise;
use std::ops::Range;

/// Settings of the fusion stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FusionConfig {
    /// Largest depth difference (m, along the camera's z) for a merge.
    pub depth_gate_m: f32,
    /// Largest angle between normals for a merge, degrees.
    pub normal_gate_deg: f32,
    /// Sigma of the radial confidence weight `exp(-gamma^2 / (2 sigma^2))`.
    pub confidence_sigma: f32,
    /// Confidence at which a surfel becomes stable (used for prediction).
    pub stable_confidence: f32,
    /// Confidence from which a surfel is no longer moved by merges: it still
    /// wins its pixel (so no surfel is added there) and still absorbs
    /// duplicates on its disk, but neither is averaged in. A merge moves a
    /// surfel of confidence `c` by at most
    /// `1 / (c + 1)` of the measurement's offset, under 1 % here
    /// (`docs/performance.md#settled-confidence`).
    pub settled_confidence: f32,
    /// Unstable surfels older than this many frames are removed; 10 rather
    /// than the published ~20 (`docs/performance.md#unstable-max-age`).
    pub unstable_max_age: u32,
    /// Removal runs every this many frames: removing compacts the arrays and
    /// shifts every later surfel, which a renderer must re-upload, so it is
    /// batched (measured: same ATE on ICL-NUIM kt0 and TUM fr3/teddy as 1).
    pub cleanup_interval_frames: u32,
    /// During the first frames all surfels are predicted, stable or not.
    pub warmup_frames: u32,
    /// Cap on a surfel's radius, metres.
    pub max_radius_m: f32,
    /// Depth noise of the sensor: a measurement's share in a merge (the
    /// average of position, normal and colour) is its inverse variance
    /// relative to the model's reference (see `integrate.rs`,
    /// `noise_weights_into`); the confidence it adds stays the radial
    /// weight, so stability still counts observations. Measured on TUM
    /// fr3/teddy (ATE, tracking weighted too): confidence gain weighted as
    /// well 0.830 cm, merge share only 0.710 cm, far surfaces then also
    /// never became stable. Uniform = no weighting.
    pub noise: SensorNoise,
    /// Smallest noise weight of a measurement in a merge, so that a far
    /// surface seen only from far still follows its measurements.
    pub min_noise_weight: f32,
    /// Surfel budget. When the map holds this many, the pipeline first
    /// evicts stale unstable surfels, then new surfels are skipped (counted
    /// in `FusionStats::skipped`) while merges go on. 40 bytes per surfel.
    pub max_surfels: usize,
    /// Surfels not updated for this many frames are inactive: tracking (the
    /// prediction) and fusion (association, merges, absorbed duplicates)
    /// read only the active ones, so per-frame cost follows the recently
    /// seen part of the scene. Inactive surfels stay in the map, are drawn
    /// and exported; loop closure renders them separately. 200 as in
    /// ElasticFusion (Whelan et al. 2015). Counted in pushed frames, lost
    /// ones included; 0 counts as 1.
    pub active_window_frames: u32,
    /// A stable surfel that has lain this many frames on an older stable
    /// surfel of an earlier visit (inactive, or made more than
    /// `active_window_frames` before it; on its disk, normals within
    /// `normal_gate_deg`) is merged into it, which becomes active again:
    /// a return to a place whose surfels went inactive, or whose centres
    /// fall between the pixels, lays a second copy beside the first and the
    /// map grows on every revisit. The delay leaves loop closure the time
    /// to register the two copies first (merged at once, the copies a
    /// closure would have aligned are gone). 0 = never merged. See
    /// `docs/performance.md#revisit-growth`.
    pub merge_copies_after_frames: u32,
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            depth_gate_m: 0.05,
            normal_gate_deg: 20.0,
            confidence_sigma: 0.6,
            stable_confidence: 5.0,
            settled_confidence: 100.0,
            unstable_max_age: 10,
            cleanup_interval_frames: 10,
            warmup_frames: 10,
            max_radius_m: 0.05,
            noise: SensorNoise::default(),
            min_noise_weight: 0.2,
            max_surfels: 4_000_000,
            active_window_frames: 200,
            merge_copies_after_frames: 30,
        }
    }
}

impl FusionConfig {
    /// Whether surfel `i` takes part in the prediction at frame `frame`.
    #[inline]
    #[must_use]
    pub fn predicts(&self, map: &SurfelMap, i: usize, frame: u32) -> bool {
        let c = map.confidences[i];
        c >= self.stable_confidence || (frame < self.warmup_frames && c >= 0.0)
    }

    /// The `last_seen` frames of the surfels active at frame `frame`: those
    /// updated in the last `active_window_frames` frames, `frame` included.
    /// Pass it to [`super::Prediction::render`] for the active model.
    #[inline]
    #[must_use]
    pub fn active_at(&self, frame: u32) -> Range<u32> {
        frame.saturating_sub(self.active_window_frames.max(1) - 1)..u32::MAX
    }

    /// The `last_seen` frames of the surfels inactive at frame `frame`: all
    /// those before [`FusionConfig::active_at`]. Pass it to
    /// [`super::Prediction::render`] for the inactive model (loop closure).
    #[inline]
    #[must_use]
    pub fn inactive_at(&self, frame: u32) -> Range<u32> {
        0..self.active_at(frame).start
    }

    /// Whether a surfel of this confidence is settled: merges and absorbed
    /// duplicates no longer move it (see `settled_confidence`).
    #[inline]
    #[must_use]
    pub fn is_settled(&self, confidence: f32) -> bool {
        confidence >= self.settled_confidence
    }
}
