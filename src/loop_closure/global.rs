//! Global loop closure: a place seen long ago, found by the keyframe ferns
//! when the drift is too large for the local (model-to-model) check.
//!
//! Every few frames the tracked frame is looked up among the keyframes
//! older than the active window; the model as such a keyframe saw it
//! (inactive surfels only: the active ones are the drifted copy of the same
//! place) is registered against the frame exactly as relocalisation does,
//! with every check of [`super::relocalise`] (tracker verdict,
//! conditioning, free space both ways, photometric agreement with the
//! keyframe). An accepted registration gives the correction from the
//! drifted world to the old one and surface constraints for the
//! deformation graph: points of the frame where the tracked pose puts them
//! and where the registered pose puts them.
//!
//! Poses are `world_from_camera` (metres); times are frame indices.

use super::relocalise::{Model, Relocalisation, Relocaliser, Trackers};
use crate::preprocess::FramePyramid;
use crate::se3;
use crate::track::TrackerWorkspace;
use glam::{DAffine3, Vec3};

/// Settings of the global loop check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalConfig {
    /// Look for old places at all.
    pub enabled: bool,
    /// Only keyframes at least this many frames old count (ElasticFusion:
    /// older than the active window, whose places the local check covers).
    pub min_age_frames: u32,
    /// Look every this many frames (a look that finds a candidate costs a
    /// model render and two tracker runs).
    pub every_frames: u32,
    /// A correction smaller than this is no loop to close, metres (the
    /// local check and fusion absorb it) ...
    pub min_correction_m: f64,
    /// ... and this rotation, degrees.
    pub min_correction_deg: f64,
    /// Constraints are taken every this many pixels (each way) of the
    /// frame's coarsest pyramid level.
    pub constraint_step: usize,
}

impl Default for GlobalConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_age_frames: 200,
            every_frames: 10,
            min_correction_m: 0.01,
            min_correction_deg: 1.0,
            constraint_step: 8,
        }
    }
}

/// A verified match of the current frame with a place seen long ago.
#[derive(Debug, Clone, Copy)]
pub struct GlobalMatch {
    /// The registration against the old model (its pose is
    /// `world_from_camera` in the old map's frame).
    pub registration: Relocalisation,
    /// The pose the tracker gave the frame (the drifted one).
    pub tracked: DAffine3,
    /// Maps the drifted world onto the old one:
    /// `registered = correction * tracked`.
    pub correction: DAffine3,
}

impl GlobalMatch {
    /// Translation (metres) and rotation (radians) of the correction.
    #[must_use]
    pub fn magnitude(&self) -> (f64, f64) {
        se3::motion_magnitude(&(self.tracked.inverse() * self.registration.world_from_camera))
    }
}

/// Looks for a place seen before frame `now - config.min_age_frames` in
/// the frame encoded in `relocaliser` (`pyramid`, tracked at `tracked`,
/// frame `now`); `model` should hold the inactive surfels only. `None` on
/// the frames it does not look at, when no old keyframe looks like the
/// frame, when no registration passes, or when the correction is below
/// the minimum.
pub fn find_global_match<F: Fn(usize) -> bool + Sync>(
    relocaliser: &mut Relocaliser,
    pyramid: &FramePyramid,
    model: Model<'_, F>,
    trackers: Trackers<'_>,
    workspace: &mut TrackerWorkspace,
    (tracked, now): (&DAffine3, u32),
    config: &GlobalConfig,
) -> Option<GlobalMatch> {
    let before = now.checked_sub(config.min_age_frames)?;
    if !config.enabled || now % config.every_frames.max(1) != 0 || !tracked.is_finite() {
        return None;
    }
    let registration = relocaliser.place(pyramid, model, trackers, workspace, before)?;
    let found = GlobalMatch {
        registration,
        tracked: *tracked,
        correction: registration.world_from_camera * tracked.inverse(),
    };
    let (dt, dr) = found.magnitude();
    (dt >= config.min_correction_m || dr.to_degrees() >= config.min_correction_deg).then_some(found)
}

/// Surface constraints of a global match: for points of the frame
/// (`vertices`, camera frame, metres, `ZERO` where no depth; `width`
/// pixels a row; every `step`-th pixel each way), where the tracked pose
/// puts them (source) and where the registered pose puts them (target),
/// world frame, metres, appended to `out`.
pub fn constraints_into(
    found: &GlobalMatch,
    vertices: &[Vec3],
    width: usize,
    step: usize,
    out: &mut Vec<(Vec3, Vec3)>,
) {
    let (width, step) = (width.max(1), step.max(1));
    let tracked = found.tracked.as_affine3a();
    let registered = found.registration.world_from_camera.as_affine3a();
    for row in vertices.chunks(width).step_by(step) {
        for p in row.iter().step_by(step) {
            if p.z > 0.0 && p.is_finite() {
                out.push((
                    tracked.transform_point3(*p),
                    registered.transform_point3(*p),
                ));
            }
        }
    }
}
