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
//! and where the registered pose puts them. A registration that puts the
//! frame back where constant velocity from the last few frames leads
//! ([`undoes_slide`]) corrects a slide of the tracking, not drift of the
//! map: the closer then moves the pose alone.
//!
//! Poses are `world_from_camera` (metres); times are frame indices.

use super::local::to_frame_of_into;
use super::relocalise::{Model, Relocalisation, Relocaliser, Trackers};
use crate::fusion::Prediction;
use crate::preprocess::{FramePyramid, PyramidLevel};
use crate::se3;
use crate::track::{FreeDirections, TrackerWorkspace};
use glam::{DAffine3, Vec3};

/// Settings of the global loop check.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// ... and this rotation, degrees. Above what registering against the
    /// old model gets wrong on real data: on TUM fr3/teddy played back and
    /// forth, a 0.7 cm 2.0 degree match, consistent from both starts, bent
    /// the map and cost ATE (0.86 -> 1.06 cm) where the camera was about
    /// 1 cm off.
    pub min_correction_deg: f64,
    /// The normal tracker, run again from the tracked pose against the
    /// same old-model view, must land within this of the registered pose,
    /// metres ...
    pub max_disagreement_m: f64,
    /// ... and this rotation, degrees, or at least nearer to it than to
    /// the tracked pose; else the old model holds a second answer near the
    /// tracked pose and the match is refused. Right matches land on the
    /// same pose from both starts (0.00 cm on the synthetic loops and
    /// teddy); teddy's ambiguous ones 3-24 cm from the registered pose and
    /// 0.3-2 cm from the tracked one.
    pub max_disagreement_deg: f64,
    /// A correction larger than this is refused, metres: a tracker whose
    /// checks passed every frame does not drift that far between looks ...
    pub max_correction_m: f64,
    /// ... nor this rotation, degrees.
    pub max_correction_deg: f64,
    /// After a global closure, no look for this many frames: the local
    /// check keeps the revisited part aligned, and the old model there,
    /// now a blend of the two copies, would only give small corrections
    /// of its own blending.
    pub cooldown_frames: u32,
    /// The normal tracker's final system against the old model must be at
    /// least this well conditioned (the pipeline's re-acquisition bound:
    /// without a prior pose, ICP on one or two planes slides).
    pub min_conditioning: f64,
    /// Constraints (frame points) and pins (inactive surfels the
    /// keyframe's view shows) are taken every this many pixels, each way,
    /// of the working image.
    pub constraint_step: usize,
    /// A registered pose nearer a constant-velocity guess than this
    /// fraction of its distance from the tracked pose corrects the last
    /// frames alone: tracking slid off the motion prior on them, the map
    /// did not drift, so the pose is moved and the map is not bent. The
    /// guesses carry the motion into each of the last `slide_frames`
    /// frames on to this one, each only where constant velocity over that
    /// many frames missed the 10 frames before by less than the same
    /// fraction of the correction (a hand-held camera's 8-frame guess
    /// misses by centimetres: the 7-Scenes kitchen 4.5 cm median). On the synthetic room circled ten times under
    /// Kinect-v1 noise every global match was such a slide (4-5 cm on one
    /// frame at a circle's start, the frames before within 0.2 cm of the
    /// truth); bending the map by it laid the right recent map 4.6 cm off
    /// and the later local closures followed (ATE 0.39 cm without loop
    /// closure, 1.5 cm with). 0 in sessions saved before it existed.
    #[serde(default)]
    pub slide_fraction: f64,
    /// How many frames back a slide may have begun (0 = always bend).
    #[serde(default)]
    pub slide_frames: u32,
    /// The part of a match's correction along a direction the old model's
    /// view leaves free (information per point above its normals' noise
    /// floor below this, as [`super::LoopClosureConfig::hold_below_eigenvalue`]
    /// measures the local registration's) is not measured, only where the
    /// search from the keyframe's pose ended: it is taken out before the
    /// correction is judged. On the synthetic closed loop swung 60 degrees
    /// in 10 frames under RealSense-like noise, a match on a keyframe of a
    /// floor and a wall (7.4e-4 along their join) registered the camera
    /// 5.3 cm off where it was tracked 1.3 cm off, 4.6 of the 4.7 cm
    /// correction along the join. 0 (off) in sessions saved before it
    /// existed.
    #[serde(default)]
    pub hold_below_eigenvalue: f64,
}

impl Default for GlobalConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_age_frames: 200,
            every_frames: 10,
            min_correction_m: 0.03,
            min_correction_deg: 3.0,
            max_disagreement_m: 0.005,
            max_disagreement_deg: 0.5,
            cooldown_frames: 200,
            max_correction_m: 1.0,
            max_correction_deg: 30.0,
            min_conditioning: 2e-3,
            constraint_step: 8,
            slide_fraction: 0.25,
            slide_frames: 8,
            hold_below_eigenvalue: 1e-3,
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

/// Why a global look found no loop to close.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GlobalMiss {
    /// Not a frame the check may look at ([`GlobalConfig::may_look_at`]:
    /// off, or too early), or the tracked pose is not finite.
    NotLooked,
    /// No keyframe old enough looks like the frame.
    NoKeyframe,
    /// Every keyframe tried was refused by a check of
    /// [`Relocaliser::place`] (see [`Relocaliser::attempts`]).
    Refused,
    /// The registered pose is within the minimum correction of the tracked
    /// one: no drift to correct.
    TooSmall,
    /// The correction is larger than tracking can drift between looks.
    TooLarge,
    /// The normal tracker, started at the tracked pose, stays near it in
    /// the old model's view: the old model holds two answers.
    SecondAnswer,
}

impl GlobalMiss {
    /// Short kebab-case name (`no-keyframe`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::NotLooked => "not-looked",
            Self::NoKeyframe => "no-keyframe",
            Self::Refused => "refused",
            Self::TooSmall => "too-small",
            Self::TooLarge => "too-large",
            Self::SecondAnswer => "second-answer",
        }
    }
}

/// Looks for a place seen before frame `now - config.min_age_frames` in
/// the frame encoded in `relocaliser` (`pyramid`, tracked at `tracked`,
/// frame `now`); `model` should hold the inactive surfels only. The miss
/// says which step found nothing: a frame it does not look at
/// ([`GlobalConfig::may_look_at`]; the schedule is the caller's), no old keyframe like the frame, no
/// registration passing, a correction below the minimum or above the
/// maximum, or a second answer near the tracked pose.
pub fn find_global_match<F: Fn(usize) -> bool + Sync>(
    relocaliser: &mut Relocaliser,
    pyramid: &FramePyramid,
    model: Model<'_, F>,
    trackers: Trackers<'_>,
    workspace: &mut TrackerWorkspace,
    (tracked, now): (&DAffine3, u32),
    config: &GlobalConfig,
) -> Result<GlobalMatch, GlobalMiss> {
    let before = now.checked_sub(config.min_age_frames);
    let Some(before) = before.filter(|_| config.may_look_at(now) && tracked.is_finite()) else {
        return Err(GlobalMiss::NotLooked);
    };
    let Some(mut registration) = relocaliser.place(pyramid, model, trackers, workspace, 0..before)
    else {
        return Err(if relocaliser.attempts().is_empty() {
            GlobalMiss::NoKeyframe
        } else {
            GlobalMiss::Refused
        });
    };
    registration.world_from_camera = measured_part(
        relocaliser.keyframe_view(),
        tracked,
        &registration.world_from_camera,
        config.hold_below_eigenvalue,
    );
    let found = GlobalMatch {
        registration,
        tracked: *tracked,
        correction: registration.world_from_camera * tracked.inverse(),
    };
    let (dt, dr) = (found.magnitude().0, found.magnitude().1.to_degrees());
    let large = dt >= config.min_correction_m || dr >= config.min_correction_deg;
    let plausible = dt <= config.max_correction_m && dr <= config.max_correction_deg;
    if !large {
        return Err(GlobalMiss::TooSmall);
    }
    if !plausible {
        return Err(GlobalMiss::TooLarge);
    }
    // The old model may hold the frame where it was tracked as well: then
    // it has two answers and neither is a loop to close. TUM fr3/teddy
    // played back and forth (1500 frames) was closed at frame 590 onto
    // keyframe 166, 9 cm and 5 degrees off the truth, from a tracked pose
    // 1.7 cm off; with that refused, at frame 940 onto keyframe 166 again,
    // 3.9 cm 2.3 degrees, with the tracker landing 3.0 cm from the
    // registered pose (tracked 1.4 cm off, registered 2.6 cm).
    // Every such run stayed within 2 cm of the tracked pose; a run that
    // went more than halfway to the registered pose (a drift beyond the
    // tracker's reach, partly corrected) speaks for the match.
    let from_tracked =
        relocaliser.track_in_placed_view(pyramid, tracked, trackers.normal, workspace);
    let landed = from_tracked.world_from_camera.inverse();
    let (at, ar) = se3::motion_magnitude(&(landed * registration.world_from_camera));
    let (stayed, _) = se3::motion_magnitude(&(landed * *tracked));
    let second_answer = from_tracked.lost.is_none()
        && from_tracked.world_from_camera.is_finite()
        && from_tracked.conditioning >= trackers.min_conditioning
        && (at > config.max_disagreement_m || ar.to_degrees() > config.max_disagreement_deg)
        && stayed <= at;
    if second_answer {
        return Err(GlobalMiss::SecondAnswer);
    }
    Ok(found)
}

/// `registered` (`world_from_camera`, metres) with the part of its motion
/// from `tracked` along the directions `view` (the old model as the
/// keyframe saw it) leaves free taken out: what the registration measured.
/// The directions are those below `threshold` in the registered camera's
/// frame ([`FreeDirections::of_model`]); `registered` itself when none.
#[must_use]
pub fn measured_part(
    view: &Prediction,
    tracked: &DAffine3,
    registered: &DAffine3,
    threshold: f64,
) -> DAffine3 {
    let mut level = PyramidLevel::default();
    to_frame_of_into(view, registered, &mut level);
    let free = FreeDirections::of_model(&level, |_| true, threshold, &mut Vec::new());
    if free.count() == 0 {
        return *registered;
    }
    let motion = se3::log(&(tracked.inverse() * *registered));
    *tracked * se3::exp(&free.removed_from(&motion))
}

/// Whether `registered` lies nearer `guess` (the frame's constant-velocity
/// pose) than `fraction` of its distance from `tracked`, the distance being
/// translation plus rotation counted at 1 m: the frame slid off its motion
/// prior and the registration puts it back. Poses are `world_from_camera`,
/// metres.
#[must_use]
pub fn undoes_slide(
    tracked: &DAffine3,
    registered: &DAffine3,
    guess: &DAffine3,
    fraction: f64,
) -> bool {
    let slid = pose_distance(tracked, registered);
    slid > 0.0 && pose_distance(guess, registered) < fraction * slid
}

/// Translation (metres) plus rotation (radians, so counted at 1 m) from
/// `a` to `b`.
#[must_use]
pub fn pose_distance(a: &DAffine3, b: &DAffine3) -> f64 {
    let (t, r) = se3::motion_magnitude(&(a.inverse() * *b));
    t + r
}

impl GlobalConfig {
    /// Whether frame `now` is looked up: the check is on, it is one of
    /// every `every_frames`, and keyframes old enough can exist.
    #[must_use]
    pub fn looks_at(&self, now: u32) -> bool {
        self.may_look_at(now) && now % self.every_frames.max(1) == 0
    }

    /// Whether frame `now` may be looked up off the schedule (the last
    /// frame of a recording): the check is on and keyframes old enough can
    /// exist.
    #[must_use]
    pub fn may_look_at(&self, now: u32) -> bool {
        self.enabled && now >= self.min_age_frames
    }
}

/// A global closure as the frame report shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalClosure {
    /// Frame index of the keyframe whose place the frame was registered in.
    pub keyframe_frame: u32,
    /// The pose the tracker gave the frame (`world_from_camera`, metres,
    /// before the closure).
    pub tracked: DAffine3,
    /// The pose registered against the old model (`world_from_camera`,
    /// metres, in the map as it was before the closure).
    pub registered: DAffine3,
    /// Translation of the correction, metres.
    pub correction_m: f64,
    /// Rotation of the correction, degrees.
    pub correction_deg: f64,
    /// The deformation graph accepted the constraints and the map was
    /// bent, or (with `pose_only`) the pose was moved; `false` when the
    /// graph refused them (nothing moved).
    pub closed: bool,
    /// Only the pose was moved: the correction undid the frame's own slide
    /// off the motion prior ([`GlobalConfig::slide_fraction`]).
    pub pose_only: bool,
}

impl GlobalClosure {
    /// The summary of `found`; `closed` and `pose_only` as given.
    #[must_use]
    pub fn of(found: &GlobalMatch, (closed, pose_only): (bool, bool)) -> Self {
        let (dt, dr) = found.magnitude();
        Self {
            keyframe_frame: found.registration.keyframe_frame,
            tracked: found.tracked,
            registered: found.registration.world_from_camera,
            correction_m: dt,
            correction_deg: dr.to_degrees(),
            closed,
            pose_only,
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn at(x: f64) -> DAffine3 {
        DAffine3::from_translation(DVec3::new(x, 0.0, 0.0))
    }

    #[test]
    fn a_registration_back_on_the_motion_prior_undoes_the_frames_slide() {
        // The prior says 1.00 m; tracking slid to 1.046; the old map says 1.001.
        assert!(undoes_slide(&at(1.046), &at(1.001), &at(1.0), 0.25));
        // Drift: tracked where the prior said, the old map 4.6 cm away.
        assert!(!undoes_slide(&at(1.0), &at(1.046), &at(1.001), 0.25));
        // Halfway between the two: not a slide undone.
        assert!(!undoes_slide(&at(1.046), &at(1.023), &at(1.0), 0.25));
        // No correction at all, or a fraction of 0: never.
        assert!(!undoes_slide(&at(1.0), &at(1.0), &at(1.0), 0.25));
        assert!(!undoes_slide(&at(1.046), &at(1.0), &at(1.0), 0.0));
    }

    #[test]
    fn a_rotation_slide_counts_at_one_metre() {
        let turned = DAffine3::from_rotation_y(0.05);
        // Tracking turned 0.05 rad (5 cm at 1 m) off the prior; registered back.
        assert!(undoes_slide(&turned, &at(0.002), &at(0.0), 0.25));
        assert!(!undoes_slide(&at(0.0), &turned, &at(0.0), 0.25));
    }
}
