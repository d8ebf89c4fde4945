//! Tracking with checks, and re-acquisition after a loss: the `track` stage
//! of [`Pipeline::push_frame`].

use super::{Pipeline, Verdict};
use crate::features::SparseEstimate;
use crate::fusion::Prediction;
use crate::loop_closure::relocalise::{Model, Relocalisation, Trackers};
use crate::preprocess::FramePyramid;
use crate::se3;
use crate::track::verify::{free_space_violation, TrackingChecks, VerifyConfig};
use crate::track::{
    track, track_with_prior, FreeDirections, LostReason, MotionPrior, TrackResult, TrackerConfig,
    TrackerWorkspace,
};
use glam::DAffine3;

/// The `track` stage's answer for one frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tracked {
    /// Tracked, recovered, lost or initialised.
    pub verdict: Verdict,
    /// `world_from_camera` (metres): the tracked pose, or the last good one
    /// when lost.
    pub pose: DAffine3,
    /// The tracker run whose statistics are reported (`None` for the first frame).
    pub result: Option<TrackResult>,
    /// What the independent checks said.
    pub checks: TrackingChecks,
}

impl Tracked {
    /// A frame placed by relocalisation (`found`) as
    /// [`Verdict::Recovered`], with the tracker's `checks` and the
    /// placement's.
    pub(super) fn relocalised(mut checks: TrackingChecks, found: Relocalisation) -> Self {
        checks.free_space_final = found.free_space;
        checks.relocalised_from = Some(found.keyframe_frame);
        Self::new(
            Verdict::Recovered,
            found.world_from_camera,
            Some(found.result),
            checks,
        )
    }

    /// A `Tracked` verdict becomes `Held` when `result` held directions
    /// (not when the pose is the sparse estimate alone, which pins all six).
    fn new(
        verdict: Verdict,
        pose: DAffine3,
        result: Option<TrackResult>,
        checks: TrackingChecks,
    ) -> Self {
        let held = result.is_some_and(|r| r.held_directions > 0) && !checks.sparse_only;
        let verdict = match verdict {
            Verdict::Tracked if held => Verdict::Held,
            other => other,
        };
        Self {
            verdict,
            pose,
            result,
            checks,
        }
    }
}

/// Re-acquisition accepts a pose only from a view that pins all six degrees
/// of freedom well: without the previous frame's pose as a prior, ICP on a
/// view dominated by one or two planes slides along them to a wrong pose with
/// a tiny residual. Measured (conditioning of the final 6x6 system): every
/// tracked frame of TUM fr3/teddy >= 0.0079; a synthetic view of a wall and
/// the floor that slid 22 cm on re-acquisition: 0.0005.
pub(super) const RECOVERY_MIN_CONDITIONING: f64 = 2e-3;

/// Whether `result` pins all six degrees of freedom well enough to be
/// trusted without the previous pose as a prior: well conditioned, and no
/// direction held at its start.
pub(super) fn pins_pose(result: &TrackResult) -> bool {
    result.conditioning >= RECOVERY_MIN_CONDITIONING && result.held_directions == 0
}

/// Whether `motion` (`previous_from_current`) is one the camera can make
/// in `frames` frames: the tracker's per-frame bounds times the frames (at
/// most 11: ten lost and this one), rotation at most 90 degrees.
fn plausible_motion(normal: &TrackerConfig, frames: u32, motion: &DAffine3) -> bool {
    let frames = f64::from(frames.clamp(1, 11));
    let (dt, dr) = se3::motion_magnitude(motion);
    dt <= normal.max_translation_m * frames
        && dr.to_degrees() <= (normal.max_rotation_deg * frames).min(90.0)
}

/// Misses of the prior (frames back) a slide is judged against.
const PRIOR_HISTORY: usize = 10;

/// Misses of the prior needed before a slide is judged against them.
const MIN_PRIOR_HISTORY: usize = 3;

/// A result slid along a poorly pinned direction when it left the guess by
/// more than this times the prior's largest recent miss along it. The
/// synthetic swings without colour hold the same with 1.5 or 3; with 5 the
/// 30-degree swing slides again.
const SLIDE_OVER_MISS: f64 = 2.0;

/// The misses of the constant-velocity prior along `poses`
/// (`world_from_camera` as tracked): for three poses in a row, the third
/// against the second moved on by the motion from the first, as a twist
/// (rotation first, radians; then metres). How well the prior predicts at
/// this sequence's frame rate and motion, direction by direction.
fn prior_misses(poses: &[(f64, DAffine3)]) -> impl Iterator<Item = se3::Twist> + '_ {
    poses.windows(3).map(|w| {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        let guess = b * (a.inverse() * b);
        se3::log(&(guess.inverse() * c))
    })
}

/// Re-acquisition search: gates wide enough to pull in a pose several
/// frames' motion away (dropped frames, a fast turn), more iterations at the
/// coarse levels where the wide gate is cheap. Its result is then checked by
/// the normal tracker, so the wide gates never decide alone.
pub(super) fn recovery_tracker(normal: &TrackerConfig) -> TrackerConfig {
    let mut wide = normal.clone();
    wide.gates.distance_gate_m = (normal.gates.distance_gate_m * 3.0).max(0.3);
    wide.gates.normal_gate_deg = normal.gates.normal_gate_deg.max(45.0);
    wide.gates.huber_m = normal.gates.huber_m * 2.0;
    let last = wide.iterations.len().saturating_sub(1);
    for (level, n) in wide.iterations.iter_mut().enumerate() {
        // Finest level unchanged; coarser levels get 3x, the coarsest 4x.
        *n = match level {
            0 => *n,
            l if l == last => *n * 4,
            _ => *n * 3,
        };
    }
    // Motion plausibility is judged against the last good pose by the caller.
    wide.max_translation_m = f64::INFINITY;
    wide.max_rotation_deg = f64::INFINITY;
    wide
}

impl Pipeline {
    /// Tracks the pyramid's frame from `previous` (the last good pose), or
    /// from `previous` moved on by `velocity` (the last frame-to-frame
    /// motion) when the constant-velocity prior is on; `lost_streak` is
    /// the number of frames lost since `previous`.
    ///
    /// A dense result is accepted as it stands only when it passed the
    /// tracker's own tests, its points do not land in the model's free
    /// space, and it moved the camera little (where dense tracking is
    /// reliable). Otherwise the sparse feature estimate (this frame against
    /// the last fused one) is asked: the dense result stands if the two
    /// agree; if not, the dense tracker is started again at the sparse
    /// estimate and its result counts only if it passes the same tests and
    /// agrees with the sparse estimate ([`Judge::with_sparse`]). Without a
    /// sparse estimate, a clean result stands unless it slid along a
    /// direction the geometry pins poorly ([`Judge::without_sparse`]); a
    /// result that is not clean starts the wider re-acquisition search from
    /// `previous`, against the model prediction (still the one rendered at
    /// `previous`: lost frames do not touch it); its result counts only if
    /// the normal tracker, started there, accepts it, it does not violate
    /// free space, and the motion since `previous` is plausible for the
    /// number of frames lost ([`Judge::reacquire`]).
    pub(super) fn track_or_recover(
        &mut self,
        previous: &DAffine3,
        (velocity, interval_s): (Option<DAffine3>, f64),
        lost_streak: u32,
    ) -> Tracked {
        let normal = &self.config.tracker;
        let verify = normal.verify;
        let was_lost = lost_streak > 0;
        let guess = match velocity {
            Some(velocity) if verify.constant_velocity && !was_lost => *previous * velocity,
            _ => *previous,
        };
        // A hand's motion since the last frame, only where the guess is one
        // frame's constant-velocity motion.
        let prior = match velocity {
            Some(_) if verify.constant_velocity && !was_lost => {
                MotionPrior::around(&guess, interval_s, &normal.motion_prior)
            }
            _ => None,
        };
        let judge = Judge {
            prior,
            pyramid: &self.pyramid,
            prediction: &self.prediction,
            normal,
            recovery: &self.recovery,
            verify,
            previous: *previous,
            guess,
            lost_streak,
            recent_poses: {
                let poses = &self.online_trajectory;
                &poses[poses.len().saturating_sub(PRIOR_HISTORY + 2)..]
            },
        };
        let workspace = &mut self.tracker;
        let mut checks = TrackingChecks::default();
        let first = judge.first_attempt(workspace, &mut checks);
        let held = first.result.held_directions > 0;
        if first.clean
            && !held
            && !judge.moved(&first.result.world_from_camera)
            && !verify.sparse_always
        {
            checks.free_space_final = checks.free_space_first;
            return first.accept(&judge, checks);
        }
        // The sparse estimate: this frame against the last fused one, whose
        // pose is `previous`.
        let sparse = if self.sparse.has_reference() {
            checks.sparse_ran = true;
            self.sparse.estimate()
        } else {
            None
        };
        if let Some(estimate) = sparse {
            return judge.with_sparse(&estimate, first, checks, workspace);
        }
        if first.clean {
            return judge.without_sparse(first, checks, workspace);
        }
        judge.reacquire(first, checks, workspace)
    }
}

/// What judging the tracking of one frame reads.
struct Judge<'a> {
    pyramid: &'a FramePyramid,
    prediction: &'a Prediction,
    /// The normal tracker.
    normal: &'a TrackerConfig,
    /// The wide re-acquisition search ([`recovery_tracker`]).
    recovery: &'a TrackerConfig,
    verify: VerifyConfig,
    /// The last good pose, `world_from_camera`.
    previous: DAffine3,
    /// Where the first attempt starts: `previous`, moved on by the
    /// constant-velocity prior when on.
    guess: DAffine3,
    /// The hand's motion prior around `guess`, for a frame that follows
    /// a placed one.
    prior: Option<MotionPrior>,
    /// Frames lost in a row before this one.
    lost_streak: u32,
    /// The last poses as tracked, whose [`prior_misses`] scale a slide.
    recent_poses: &'a [(f64, DAffine3)],
}

/// The first dense attempt, from the guess.
struct FirstAttempt {
    result: TrackResult,
    /// It passed the tracker's own tests ([`Judge::passes`]).
    ok: bool,
    /// And its points keep the model's free space clear.
    clean: bool,
}

impl FirstAttempt {
    fn accept(self, judge: &Judge, checks: TrackingChecks) -> Tracked {
        let pose = self.result.world_from_camera;
        Tracked::new(judge.accepted(), pose, Some(self.result), checks)
    }
}

impl Judge<'_> {
    /// Dense tracking from `from` with `config`.
    fn track(
        &self,
        from: &DAffine3,
        config: &TrackerConfig,
        workspace: &mut TrackerWorkspace,
    ) -> TrackResult {
        track_with_prior(
            self.pyramid,
            self.prediction,
            (from, None),
            self.prior.as_ref(),
            config,
            workspace,
        )
    }

    /// The verdict of a frame whose result is accepted.
    fn accepted(&self) -> Verdict {
        if self.lost_streak > 0 {
            Verdict::Recovered
        } else {
            Verdict::Tracked
        }
    }

    /// Fraction of the frame's points that land in the model's free space
    /// seen from `pose`, sampled on [`FramePyramid::check_level`] (160x120
    /// from 640x480): it tells a right pose (violations <= 1 %) from a
    /// wrong one (>= 19 %) at a sixteenth of the full resolution's cost.
    fn free_space(&self, pose: &DAffine3) -> f64 {
        let vertices = self.pyramid.check_level().map_or(&[][..], |l| &l.vertices);
        free_space_violation(self.prediction, vertices, 1, pose, &self.verify).0
    }

    fn free_ok(&self, fraction: f64) -> bool {
        fraction <= self.verify.max_free_space_fraction
    }

    /// Passed the tracker's own tests, finite, and (after a loss) from a
    /// view that pins all six degrees of freedom.
    fn passes(&self, r: &TrackResult) -> bool {
        let pinned = self.lost_streak == 0 || pins_pose(r);
        r.lost.is_none() && r.world_from_camera.is_finite() && pinned
    }

    /// Moved beyond the sparse check's thresholds from the last good pose
    /// or from the guess.
    fn moved(&self, pose: &DAffine3) -> bool {
        [&self.previous, &self.guess].iter().any(|from| {
            let (dt, dr) = se3::motion_magnitude(&(from.inverse() * *pose));
            dt > self.verify.sparse_above_m || dr.to_degrees() > self.verify.sparse_above_deg
        })
    }

    /// Left the guess along the directions `result`'s final system pins
    /// poorly by more than [`SLIDE_OVER_MISS`] times the prior's largest
    /// recent miss along them (with at least [`MIN_PRIOR_HISTORY`] misses).
    fn slid(&self, result: &TrackResult) -> bool {
        let weak = &result.weak;
        // Three poses make one miss.
        if weak.count() == 0 || self.recent_poses.len() < MIN_PRIOR_HISTORY + 2 {
            return false;
        }
        let slid = weak.length_along(&se3::log(
            &(self.guess.inverse() * result.world_from_camera),
        ));
        let missed = prior_misses(self.recent_poses)
            .map(|miss| weak.length_along(&miss))
            .fold(0.0, f64::max);
        slid > SLIDE_OVER_MISS * missed
    }

    /// A lost frame: the pose held at `previous`, `result`'s statistics.
    fn lost(&self, result: TrackResult, checks: TrackingChecks) -> Tracked {
        let reason = result.lost.unwrap_or(LostReason::IllConditioned);
        Tracked::new(Verdict::Lost(reason), self.previous, Some(result), checks)
    }

    /// Phase 1: dense tracking from the guess, with its free-space check.
    fn first_attempt(
        &self,
        workspace: &mut TrackerWorkspace,
        checks: &mut TrackingChecks,
    ) -> FirstAttempt {
        let result = self.track(&self.guess, self.normal, workspace);
        checks.first_dense = Some(result.world_from_camera);
        let ok = self.passes(&result);
        checks.free_space_first = if ok {
            self.free_space(&result.world_from_camera)
        } else {
            0.0
        };
        let clean = ok && self.free_ok(checks.free_space_first);
        FirstAttempt { result, ok, clean }
    }

    /// Phase 2, with a sparse estimate: the first result if it agrees, else
    /// dense tracking restarted at the estimate, else the estimate alone on
    /// a view that pins the pose poorly; otherwise lost.
    fn with_sparse(
        &self,
        estimate: &SparseEstimate,
        first: FirstAttempt,
        mut checks: TrackingChecks,
        workspace: &mut TrackerWorkspace,
    ) -> Tracked {
        let verify = &self.verify;
        let sparse_pose = self.previous * estimate.reference_from_current;
        checks.sparse = Some((sparse_pose, estimate.inliers));
        checks.sparse_rms_m = estimate.rms_m;
        let held = first.result.held_directions > 0;
        if first.clean && !held && verify.agree(&first.result.world_from_camera, &sparse_pose) {
            checks.free_space_final = checks.free_space_first;
            return first.accept(self, checks);
        }
        // The frame's free directions stay held at the estimate.
        let held = (first.result.held_directions > 0).then_some(&first.result.free);
        let second = track_with_prior(
            self.pyramid,
            self.prediction,
            (&sparse_pose, held),
            self.prior.as_ref(),
            self.normal,
            workspace,
        );
        // Started at the sparse estimate, the dense tracker must land
        // near it, or back on its first result (the sparse estimate is
        // the less accurate of the two: on TUM fr3/teddy at strides 3-8
        // it is up to 4.6 cm / 2.9 degrees from a dense result 1.6 cm
        // from the truth). Not on a view that pins the pose poorly:
        // there both dense runs slide to the same wrong place (the
        // synthetic room's wall-and-floor views, 14 cm).
        let landed = |pose: &DAffine3| {
            verify.landed_near(pose, &sparse_pose)
                || (first.clean
                    && pins_pose(&first.result)
                    && verify.same_basin(pose, &first.result.world_from_camera))
        };
        if self.passes(&second) && landed(&second.world_from_camera) {
            let fraction = self.free_space(&second.world_from_camera);
            if self.free_ok(fraction) {
                checks.free_space_final = fraction;
                checks.from_sparse = true;
                let verdict = self.accepted();
                return Tracked::new(verdict, second.world_from_camera, Some(second), checks);
            }
        }
        // The dense tracker cannot hold a view that pins the pose poorly
        // (from a start 0.5 cm off it slides 30 cm along the synthetic
        // room's wall and floor); a strong, tight feature estimate that
        // keeps free space clear is then the better answer, unrefined.
        let strong = estimate.inliers >= verify.sparse_only_min_inliers
            && estimate.rms_m <= verify.sparse_only_max_rms_m;
        if strong && !pins_pose(&second) {
            let fraction = self.free_space(&sparse_pose);
            if self.free_ok(fraction) {
                checks.free_space_final = fraction;
                checks.from_sparse = true;
                checks.sparse_only = true;
                return Tracked::new(self.accepted(), sparse_pose, Some(second), checks);
            }
        }
        let mut result = if first.ok { second } else { first.result };
        if result.lost.is_none() {
            result.lost = Some(LostReason::Inconsistent);
        }
        self.lost(result, checks)
    }

    /// Phase 2, without a sparse estimate, for a clean first result that
    /// moved far or held directions: the geometry and the motion prior are
    /// all there is. Where the geometry pins the pose, the first result
    /// stands. Along a direction the final system pins poorly, a result
    /// that left the constant-velocity guess by more than
    /// [`SLIDE_OVER_MISS`] times the prior's largest recent miss along that
    /// direction slid: the frame is tracked again from the guess with that
    /// direction held, as with the ones the frame's geometry left free
    /// (verdict `held`). Without it the synthetic room's 20-degree swing
    /// without colour slid 10.6 cm, then 37 cm a frame (294 cm ATE); the
    /// prior's own misses keep a fast real camera, which a constant
    /// velocity predicts poorly, to its measurement (the 7-Scenes kitchen
    /// at every fifth frame misses by up to 7.6 cm).
    fn without_sparse(
        &self,
        first: FirstAttempt,
        mut checks: TrackingChecks,
        workspace: &mut TrackerWorkspace,
    ) -> Tracked {
        checks.free_space_final = checks.free_space_first;
        let weak = if self.slid(&first.result) {
            first.result.weak
        } else {
            FreeDirections::default()
        };
        if weak.count() == 0 {
            // The first attempt already held what the frame leaves free.
            return first.accept(self, checks);
        }
        let hold = first.result.free.with(&weak);
        let second = track_with_prior(
            self.pyramid,
            self.prediction,
            (&self.guess, Some(&hold)),
            self.prior.as_ref(),
            self.normal,
            workspace,
        );
        if self.passes(&second) {
            let fraction = self.free_space(&second.world_from_camera);
            if self.free_ok(fraction) {
                checks.free_space_final = fraction;
                let verdict = self.accepted();
                return Tracked::new(verdict, second.world_from_camera, Some(second), checks);
            }
        }
        first.accept(self, checks)
    }

    /// Phase 2, without a sparse estimate and with a first result that is
    /// not clean: the wide search from `previous`, checked by the normal
    /// tracker, plausible motion for the frames lost, and free space.
    fn reacquire(
        &self,
        first: FirstAttempt,
        checks: TrackingChecks,
        workspace: &mut TrackerWorkspace,
    ) -> Tracked {
        let normal = self.normal;
        let mut first_result = first.result;
        if first.ok {
            first_result.lost = Some(LostReason::Inconsistent);
        }
        // Nothing to search with: skip the (costlier) wide attempt.
        if first_result.lost == Some(LostReason::TooFewInliers)
            && first_result.inliers < normal.min_inliers / 4
        {
            return self.lost(first_result, checks);
        }
        // The wide search and its check judge the data alone: the guess is
        // what the first attempt could not confirm.
        let wide = track(
            self.pyramid,
            self.prediction,
            &self.previous,
            self.recovery,
            workspace,
        );
        if !wide.world_from_camera.is_finite() {
            return self.lost(first_result, checks);
        }
        let check = track(
            self.pyramid,
            self.prediction,
            &wide.world_from_camera,
            normal,
            workspace,
        );
        // The camera may have moved for every frame lost since `previous`.
        let plausible = plausible_motion(
            normal,
            self.lost_streak.saturating_add(1),
            &(self.previous.inverse() * check.world_from_camera),
        );
        if check.lost.is_none()
            && plausible
            && pins_pose(&check)
            && check.world_from_camera.is_finite()
        {
            let fraction = self.free_space(&check.world_from_camera);
            if self.free_ok(fraction) {
                let mut checks = checks;
                checks.free_space_final = fraction;
                let pose = check.world_from_camera;
                return Tracked::new(Verdict::Recovered, pose, Some(check), checks);
            }
        }
        self.lost(first_result, checks)
    }
}

impl Pipeline {
    /// A lost frame carried on from the last placed one by the sparse
    /// estimate ([`crate::track::verify::VerifyConfig::dead_reckoning`]):
    /// with enough tight inlier matches and a motion the tracker allows in
    /// the frames since the placed one, the frame is placed at the
    /// estimate (still lost, not
    /// fused), and the next frame is tracked from it, against the model
    /// seen from it. Other frames pass unchanged.
    pub(super) fn dead_reckon(&mut self, tracked: &mut Tracked) {
        let verify = self.config.tracker.verify;
        if !verify.dead_reckoning || !matches!(tracked.verdict, Verdict::Lost(_)) {
            return;
        }
        let Some(placed) = self.last_good else {
            return;
        };
        if !tracked.checks.sparse_ran && self.sparse.has_reference() {
            // The track stage did not ask (the dense result failed before
            // any estimate was needed).
            tracked.checks.sparse_ran = true;
            if let Some(estimate) = self.sparse.estimate() {
                tracked.checks.sparse =
                    Some((placed * estimate.reference_from_current, estimate.inliers));
                tracked.checks.sparse_rms_m = estimate.rms_m;
            }
        }
        let Some((pose, inliers)) = tracked.checks.sparse else {
            return;
        };
        // The camera may have moved for every frame since the placed one.
        let frames = self.frame_index.saturating_sub(self.placed_frame);
        let plausible = plausible_motion(&self.config.tracker, frames, &(placed.inverse() * pose));
        if !(pose.is_finite()
            && plausible
            && inliers >= verify.dead_reckoning_min_inliers
            && tracked.checks.sparse_rms_m <= verify.sparse_only_max_rms_m)
        {
            return;
        }
        tracked.pose = pose;
        tracked.checks.dead_reckoned = true;
        let k = self.config.working_intrinsics();
        let vertices = self.pyramid.levels.first().map_or(&[][..], |l| &l.vertices);
        self.lost_tiles.build(vertices, k.width);
        self.render_prediction(&pose, true);
        self.place_current(&pose);
    }
}

impl Pipeline {
    /// The frame placed by relocalisation against every keyframe and the
    /// map's stable surfels, whenever last seen (as the prediction's, the
    /// warm-up counts the segment's fused frames); `None` when no keyframe
    /// places it. In a segment not yet joined to the map before it, the
    /// segment's keyframes and surfels only: the others are in another
    /// frame.
    pub(super) fn place_in_whole_map(&mut self) -> Option<Relocalisation> {
        let fused = self.fused_in_segment();
        self.place_by_keyframes(self.segment.start..u32::MAX, fused)
    }

    /// The frame placed by relocalisation from the keyframes of frames in
    /// `frames` that look like it, against the stable surfels last seen in
    /// `frames` (the warm-up counting `fused` frames), with
    /// relocalisation's checks.
    pub(super) fn place_by_keyframes(
        &mut self,
        frames: std::ops::Range<u32>,
        fused: u32,
    ) -> Option<Relocalisation> {
        self.place_by_keyframes_of(frames.clone(), (frames, u32::MAX), fused)
    }

    /// As [`Self::place_by_keyframes`], from the keyframes of frames in
    /// `keyframes`, against the stable surfels last seen in `seen.0` and
    /// first seen before frame `seen.1`.
    pub(super) fn place_by_keyframes_of(
        &mut self,
        keyframes: std::ops::Range<u32>,
        (seen, made_before): (std::ops::Range<u32>, u32),
        fused: u32,
    ) -> Option<Relocalisation> {
        let map = &self.map;
        let fusion = self.config.fusion;
        self.relocaliser.place(
            &self.pyramid,
            Model {
                map,
                seen,
                include: |i| {
                    map.first_seen().get(i).is_some_and(|&f| f < made_before)
                        && fusion.predicts(map, i, fused)
                },
                far_m: self.config.depth.max_m,
            },
            Trackers {
                normal: &self.config.tracker,
                wide: &self.recovery,
                min_conditioning: RECOVERY_MIN_CONDITIONING,
            },
            &mut self.tracker,
            keyframes,
        )
    }

    /// A lost frame placed by the keyframes that look like it (see
    /// [`crate::loop_closure::relocalise`]), against the whole model seen
    /// from each keyframe rather than only the view from the last good
    /// pose; reported as [`Verdict::Recovered`] with
    /// `checks.relocalised_from` set. Other frames pass unchanged.
    pub(super) fn relocalise_if_lost(&mut self, tracked: Tracked) -> Tracked {
        if !matches!(tracked.verdict, Verdict::Lost(_)) {
            return tracked;
        }
        if !self.relocaliser.config().enabled {
            return tracked;
        }
        match self.place_in_whole_map() {
            Some(found) => Tracked::relocalised(tracked.checks, found),
            None => tracked,
        }
    }
}
