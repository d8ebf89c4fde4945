//! Tracking with checks, and re-acquisition after a loss: the `track` stage
//! of [`Pipeline::push_frame`].

use super::{Pipeline, Verdict};
use crate::se3;
use crate::track::verify::{free_space_violation, TrackingChecks};
use crate::track::{track, LostReason, TrackResult, TrackerConfig};
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
    fn new(
        verdict: Verdict,
        pose: DAffine3,
        result: Option<TrackResult>,
        checks: TrackingChecks,
    ) -> Self {
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
const RECOVERY_MIN_CONDITIONING: f64 = 2e-3;

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
    /// from `previous` moved on by the last frame-to-frame motion when the
    /// constant-velocity prior is on.
    ///
    /// A dense result is accepted as it stands only when it passed the
    /// tracker's own tests, its points do not land in the model's free
    /// space, and it moved the camera little (where dense tracking is
    /// reliable). Otherwise the sparse feature estimate (this frame against
    /// the last fused one) is asked: the dense result stands if the two
    /// agree; if not, the dense tracker is started again at the sparse
    /// estimate and its result counts only if it passes the same tests and
    /// agrees with the sparse estimate. Without a sparse estimate, the
    /// wider re-acquisition search runs from `previous` against the model
    /// prediction (still the one rendered at `previous`: lost frames do not
    /// touch it); its result counts only if the normal tracker, started
    /// there, accepts it, it does not violate free space, and the motion
    /// since `previous` is plausible for the number of frames lost.
    pub(super) fn track_or_recover(&mut self, previous: &DAffine3) -> Tracked {
        let normal = &self.config.tracker;
        let verify = normal.verify;
        let workspace = &mut self.tracker;
        let was_lost = self.counts.lost_streak > 0;
        let guess = match self.velocity {
            Some(velocity) if verify.constant_velocity && !was_lost => *previous * velocity,
            _ => *previous,
        };
        let mut checks = TrackingChecks::default();
        let first = track(&self.pyramid, &self.prediction, &guess, normal, workspace);
        checks.first_dense = Some(first.world_from_camera);
        // The coarsest level's points (160x120 from 640x480) tell a right
        // pose (violations <= 1 %) from a wrong one (>= 19 %) at a
        // sixteenth of the full resolution's cost.
        let free_space_vertices = self.pyramid.levels.last().map_or(&[][..], |l| &l.vertices);
        let free_space = |pose: &DAffine3| {
            free_space_violation(&self.prediction, free_space_vertices, 1, pose, &verify).0
        };
        let pinned = |r: &TrackResult| !was_lost || r.conditioning >= RECOVERY_MIN_CONDITIONING;
        let passes =
            |r: &TrackResult| r.lost.is_none() && r.world_from_camera.is_finite() && pinned(r);
        let accepted = if was_lost {
            Verdict::Recovered
        } else {
            Verdict::Tracked
        };
        let first_ok = passes(&first);
        checks.free_space_first = if first_ok {
            free_space(&first.world_from_camera)
        } else {
            0.0
        };
        let free_ok = |fraction: f64| fraction <= verify.max_free_space_fraction;
        let moved = |pose: &DAffine3| {
            [previous, &guess].iter().any(|from| {
                let (dt, dr) = se3::motion_magnitude(&(from.inverse() * *pose));
                dt > verify.sparse_above_m || dr.to_degrees() > verify.sparse_above_deg
            })
        };
        let first_clean = first_ok && free_ok(checks.free_space_first);
        if first_clean && !moved(&first.world_from_camera) && !verify.sparse_always {
            checks.free_space_final = checks.free_space_first;
            return Tracked::new(accepted, first.world_from_camera, Some(first), checks);
        }
        // The sparse estimate: this frame against the last fused one, whose
        // pose is `previous`.
        let sparse = if self.sparse.has_reference() {
            checks.sparse_ran = true;
            self.sparse.estimate()
        } else {
            None
        };
        let lost = |result: TrackResult, checks: TrackingChecks| {
            let reason = result.lost.unwrap_or(LostReason::IllConditioned);
            Tracked::new(Verdict::Lost(reason), *previous, Some(result), checks)
        };
        if let Some(estimate) = sparse {
            let sparse_pose = *previous * estimate.reference_from_current;
            checks.sparse = Some((sparse_pose, estimate.inliers));
            checks.sparse_rms_m = estimate.rms_m;
            if first_clean && verify.agree(&first.world_from_camera, &sparse_pose) {
                checks.free_space_final = checks.free_space_first;
                return Tracked::new(accepted, first.world_from_camera, Some(first), checks);
            }
            let second = track(
                &self.pyramid,
                &self.prediction,
                &sparse_pose,
                normal,
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
                    || (first_clean
                        && first.conditioning >= RECOVERY_MIN_CONDITIONING
                        && verify.same_basin(pose, &first.world_from_camera))
            };
            if passes(&second) && landed(&second.world_from_camera) {
                let fraction = free_space(&second.world_from_camera);
                if free_ok(fraction) {
                    checks.free_space_final = fraction;
                    checks.from_sparse = true;
                    return Tracked::new(accepted, second.world_from_camera, Some(second), checks);
                }
            }
            // The dense tracker cannot hold a view that pins the pose poorly
            // (from a start 0.5 cm off it slides 30 cm along the synthetic
            // room's wall and floor); a strong, tight feature estimate that
            // keeps free space clear is then the better answer, unrefined.
            let strong = estimate.inliers >= verify.sparse_only_min_inliers
                && estimate.rms_m <= verify.sparse_only_max_rms_m;
            if strong && second.conditioning < RECOVERY_MIN_CONDITIONING {
                let fraction = free_space(&sparse_pose);
                if free_ok(fraction) {
                    checks.free_space_final = fraction;
                    checks.from_sparse = true;
                    checks.sparse_only = true;
                    return Tracked::new(accepted, sparse_pose, Some(second), checks);
                }
            }
            let mut result = if first_ok { second } else { first };
            if result.lost.is_none() {
                result.lost = Some(LostReason::Inconsistent);
            }
            return lost(result, checks);
        }
        if first_clean {
            // Moved far, and no feature estimate to confirm or refute it:
            // the dense result and free space are all there is.
            checks.free_space_final = checks.free_space_first;
            return Tracked::new(accepted, first.world_from_camera, Some(first), checks);
        }
        let mut first = first;
        if first_ok {
            first.lost = Some(LostReason::Inconsistent);
        }
        // Nothing to search with: skip the (costlier) wide attempt.
        if first.lost == Some(LostReason::TooFewInliers) && first.inliers < normal.min_inliers / 4 {
            return lost(first, checks);
        }
        let wide = track(
            &self.pyramid,
            &self.prediction,
            previous,
            &self.recovery,
            workspace,
        );
        if !wide.world_from_camera.is_finite() {
            return lost(first, checks);
        }
        let check = track(
            &self.pyramid,
            &self.prediction,
            &wide.world_from_camera,
            normal,
            workspace,
        );
        // The camera may have moved for every frame lost since `previous`.
        let frames = f64::from(self.counts.lost_streak.min(10) + 1);
        let (dt, dr) = se3::motion_magnitude(&(previous.inverse() * check.world_from_camera));
        let plausible = dt <= normal.max_translation_m * frames
            && dr.to_degrees() <= (normal.max_rotation_deg * frames).min(90.0);
        if check.lost.is_none()
            && plausible
            && check.conditioning >= RECOVERY_MIN_CONDITIONING
            && check.world_from_camera.is_finite()
        {
            let fraction = free_space(&check.world_from_camera);
            if free_ok(fraction) {
                checks.free_space_final = fraction;
                return Tracked::new(
                    Verdict::Recovered,
                    check.world_from_camera,
                    Some(check),
                    checks,
                );
            }
        }
        lost(first, checks)
    }
}
