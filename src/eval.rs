//! Trajectory accuracy: absolute trajectory error (ATE) after a rigid
//! Horn/Umeyama alignment without scale, and relative pose error (RPE) over
//! consecutive frames, as in the TUM RGB-D benchmark tools.
//!
//! Trajectories are `(timestamp, world_from_camera)` with translations in
//! metres; the estimate's world frame may differ from the ground truth's by
//! any rigid motion (ATE aligns it; RPE is invariant to it).

use glam::{DAffine3, DMat3, DQuat, DVec3};
use nalgebra::Matrix3;
use thiserror::Error;

use crate::dataset::tum::associate_timestamps;

/// Why an evaluation could not be computed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum EvalError {
    /// Too few estimate poses could be matched to the ground truth.
    #[error(
        "only {found} estimate pose(s) matched the ground truth in time, need at least {needed}"
    )]
    TooFewPairs {
        /// Matched pairs found.
        found: usize,
        /// Pairs needed.
        needed: usize,
    },
    /// A pose or timestamp holds NaN or infinity.
    #[error("the {which} trajectory holds a non-finite value")]
    NonFinite {
        /// "estimate" or "ground truth".
        which: &'static str,
    },
    /// The alignment's singular value decomposition failed.
    #[error("the alignment is degenerate (SVD did not converge)")]
    Degenerate,
    /// Association by frame id needs whole-number first columns.
    #[error("the {which} trajectory's first column holds {value}, not a whole frame number")]
    NotFrameIds {
        /// "estimate" or "ground truth".
        which: &'static str,
        /// The first value that is not a whole number.
        value: f64,
    },
}

/// How estimate poses are paired with ground-truth poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Association {
    /// Nearest timestamp within `max_dt` (same unit as the files, seconds
    /// for TUM), each pose used once, greedy by |dt| as TUM's
    /// `associate.py`. Frame-number stamps (ICL-NUIM) match exactly.
    Timestamp {
        /// Largest accepted time difference.
        max_dt: f64,
    },
    /// Equal frame ids: the first column read as a whole frame number
    /// (ICL-NUIM's `N tx ty ...`); each id used once.
    FrameId,
    /// Row order: the i-th estimate pose with the i-th ground-truth pose,
    /// whatever their first columns say.
    Order,
}

/// Error of one matched pose after the ATE alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseError {
    /// Index of the pose in the estimate.
    pub estimate_index: usize,
    /// Index of the matched pose in the ground truth.
    pub ground_truth_index: usize,
    /// The estimate pose's timestamp (file units: seconds, or frame number).
    pub timestamp: f64,
    /// The matched ground-truth pose's timestamp (file units).
    pub ground_truth_timestamp: f64,
    /// Camera position of the estimate, mapped into the ground truth's
    /// world by the ATE alignment, metres.
    pub aligned_position: DVec3,
    /// Camera position of the ground truth, metres (its own world).
    pub ground_truth_position: DVec3,
    /// |aligned_position - ground_truth_position|, metres.
    pub position_error_m: f64,
    /// Angle between the aligned estimate's and the ground truth's camera
    /// orientations, radians in [0, pi].
    pub rotation_error_rad: f64,
}

/// ATE statistics and the per-pose errors behind them.
#[derive(Debug, Clone, PartialEq)]
pub struct AteReport {
    /// The statistics, as [`ate`] returns them.
    pub summary: AteResult,
    /// One entry per matched pose, in the association's order (estimate
    /// time order, or row order for [`Association::Order`]).
    pub errors: Vec<PoseError>,
}

/// Absolute trajectory error statistics, metres, after rigid alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AteResult {
    /// Root mean square of the translation errors, metres.
    pub rmse_m: f64,
    /// Mean translation error, metres.
    pub mean_m: f64,
    /// Median translation error, metres.
    pub median_m: f64,
    /// Largest translation error, metres.
    pub max_m: f64,
    /// Number of matched poses used.
    pub pairs: usize,
    /// The rigid alignment applied: maps estimate-world points to
    /// ground-truth-world points.
    pub ground_truth_from_estimate: DAffine3,
}

/// Relative pose error over consecutive matched frames (delta = 1 frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RpeResult {
    /// RMS of the relative translation errors, metres per frame step.
    pub translation_rmse_m: f64,
    /// RMS of the relative rotation errors, radians per frame step.
    pub rotation_rmse_rad: f64,
    /// Number of relative motions compared.
    pub pairs: usize,
}

fn check_finite(poses: &[(f64, DAffine3)], which: &'static str) -> Result<(), EvalError> {
    if poses.iter().all(|(t, p)| t.is_finite() && p.is_finite()) {
        Ok(())
    } else {
        Err(EvalError::NonFinite { which })
    }
}

/// Largest magnitude at which every f64 whole number is exact.
const MAX_EXACT_ID: f64 = 9_007_199_254_740_992.0;

/// The first column of `poses` as whole frame numbers.
fn frame_ids(poses: &[(f64, DAffine3)], which: &'static str) -> Result<Vec<i64>, EvalError> {
    poses
        .iter()
        .map(|&(t, _)| {
            if t.fract() == 0.0 && t.abs() <= MAX_EXACT_ID {
                // Exact: t is a whole number within i64's range.
                Ok(t as i64)
            } else {
                Err(EvalError::NotFrameIds { which, value: t })
            }
        })
        .collect()
}

/// Pairs `(index in estimate, index in ground truth)` under `association`:
/// estimate time order for timestamps and frame ids, row order for
/// [`Association::Order`]. Each pose is used at most once.
pub fn associate_indices(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    association: Association,
) -> Result<Vec<(usize, usize)>, EvalError> {
    match association {
        Association::Timestamp { max_dt } => {
            let te: Vec<f64> = estimate.iter().map(|p| p.0).collect();
            let tg: Vec<f64> = ground_truth.iter().map(|p| p.0).collect();
            Ok(associate_timestamps(&te, &tg, max_dt))
        }
        Association::FrameId => {
            let ie = frame_ids(estimate, "estimate")?;
            let ig = frame_ids(ground_truth, "ground truth")?;
            let mut by_id = std::collections::HashMap::new();
            for (j, id) in ig.iter().enumerate() {
                by_id.entry(*id).or_insert(j);
            }
            let mut pairs: Vec<(usize, usize)> = ie
                .iter()
                .enumerate()
                // remove(): a repeated estimate id does not reuse its match.
                .filter_map(|(i, id)| by_id.remove(id).map(|j| (i, j)))
                .collect();
            pairs.sort_by_key(|&(i, _)| (ie[i], i));
            Ok(pairs)
        }
        Association::Order => Ok((0..estimate.len().min(ground_truth.len()))
            .map(|i| (i, i))
            .collect()),
    }
}

/// The matched `(estimate, ground truth)` poses, in [`associate_indices`]'s order.
fn associate_poses(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    association: Association,
) -> Result<Vec<(DAffine3, DAffine3)>, EvalError> {
    Ok(associate_indices(estimate, ground_truth, association)?
        .into_iter()
        .map(|(i, j)| (estimate[i].1, ground_truth[j].1))
        .collect())
}

/// Matches estimate and ground-truth poses by nearest timestamp within
/// `max_dt` (0.02 s for TUM; frame-number timestamps match exactly) and
/// returns their camera positions `(estimate, ground truth)`, metres.
#[must_use]
pub fn associate(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    max_dt: f64,
) -> Vec<(DVec3, DVec3)> {
    let te: Vec<f64> = estimate.iter().map(|p| p.0).collect();
    let tg: Vec<f64> = ground_truth.iter().map(|p| p.0).collect();
    associate_timestamps(&te, &tg, max_dt)
        .into_iter()
        .map(|(i, j)| (estimate[i].1.translation, ground_truth[j].1.translation))
        .collect()
}

/// Rigid transform (no scale) minimising sum |R e + t - g|^2 (Horn/Umeyama,
/// SVD with the reflection fix). Needs at least one pair.
fn align_rigid(pairs: &[(DVec3, DVec3)]) -> Result<DAffine3, EvalError> {
    let n = pairs.len() as f64;
    let mu_e = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let mu_g = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    // Cross-covariance H = sum (g - mu_g)(e - mu_e)^T.
    let mut h = Matrix3::<f64>::zeros();
    for (e, g) in pairs {
        let de = *e - mu_e;
        let dg = *g - mu_g;
        for r in 0..3 {
            for c in 0..3 {
                h[(r, c)] += dg[r] * de[c];
            }
        }
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(EvalError::Degenerate);
    };
    // R = U diag(1, 1, d) V^T with d = sign(det(U V^T)) so that det R = +1.
    let d = if (u * v_t).determinant() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let s = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, d));
    let r = u * s * v_t;
    let rotation = DMat3::from_cols(
        DVec3::new(r[(0, 0)], r[(1, 0)], r[(2, 0)]),
        DVec3::new(r[(0, 1)], r[(1, 1)], r[(2, 1)]),
        DVec3::new(r[(0, 2)], r[(1, 2)], r[(2, 2)]),
    );
    if !rotation.is_finite() {
        return Err(EvalError::Degenerate);
    }
    let translation = mu_g - rotation * mu_e;
    Ok(DAffine3::from_mat3_translation(rotation, translation))
}

/// Absolute trajectory error: associates poses within `max_dt`, aligns the
/// estimate's positions to the ground truth's with the best rigid motion
/// (no scale) and reports the position error statistics in metres. Needs at
/// least 3 matched poses.
pub fn ate(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    max_dt: f64,
) -> Result<AteResult, EvalError> {
    ate_report(estimate, ground_truth, Association::Timestamp { max_dt }).map(|r| r.summary)
}

/// [`ate`] under any [`Association`], with the error of every matched pose
/// (metres, radians) after the alignment.
pub fn ate_report(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    association: Association,
) -> Result<AteReport, EvalError> {
    check_finite(estimate, "estimate")?;
    check_finite(ground_truth, "ground truth")?;
    let indices = associate_indices(estimate, ground_truth, association)?;
    if indices.len() < 3 {
        return Err(EvalError::TooFewPairs {
            found: indices.len(),
            needed: 3,
        });
    }
    let pairs: Vec<(DVec3, DVec3)> = indices
        .iter()
        .map(|&(i, j)| (estimate[i].1.translation, ground_truth[j].1.translation))
        .collect();
    let alignment = align_rigid(&pairs)?;
    let per_pose: Vec<PoseError> = indices
        .iter()
        .map(|&(i, j)| {
            let (e, g) = (estimate[i], ground_truth[j]);
            let aligned = alignment * e.1;
            PoseError {
                estimate_index: i,
                ground_truth_index: j,
                timestamp: e.0,
                ground_truth_timestamp: g.0,
                aligned_position: aligned.translation,
                ground_truth_position: g.1.translation,
                position_error_m: (aligned.translation - g.1.translation).length(),
                rotation_error_rad: rotation_angle(g.1.matrix3.transpose() * aligned.matrix3),
            }
        })
        .collect();
    Ok(AteReport {
        summary: statistics(&pairs, alignment),
        errors: per_pose,
    })
}

/// The position error statistics of `pairs` (estimate, ground truth;
/// metres) under `alignment`; `pairs` must not be empty.
fn statistics(pairs: &[(DVec3, DVec3)], alignment: DAffine3) -> AteResult {
    let mut errors: Vec<f64> = pairs
        .iter()
        .map(|(e, g)| (alignment.transform_point3(*e) - *g).length())
        .collect();
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let median_m = if n % 2 == 1 {
        errors[n / 2]
    } else {
        0.5 * (errors[n / 2 - 1] + errors[n / 2])
    };
    AteResult {
        rmse_m: (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
        mean_m: errors.iter().sum::<f64>() / n as f64,
        median_m,
        max_m: errors[n - 1],
        pairs: n,
        ground_truth_from_estimate: alignment,
    }
}

/// ATE statistics of `estimate` under a given alignment
/// (`ground_truth_from_estimate`), not one fitted to it: frames localised
/// in a saved map are judged in the map's frame, with the alignment the
/// map's own trajectory got from [`ate`]. Needs one matched pose.
pub fn ate_in_frame(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    max_dt: f64,
    ground_truth_from_estimate: DAffine3,
) -> Result<AteResult, EvalError> {
    check_finite(estimate, "estimate")?;
    check_finite(ground_truth, "ground truth")?;
    let indices = associate_indices(estimate, ground_truth, Association::Timestamp { max_dt })?;
    if indices.is_empty() {
        return Err(EvalError::TooFewPairs {
            found: 0,
            needed: 1,
        });
    }
    let pairs: Vec<(DVec3, DVec3)> = indices
        .iter()
        .map(|&(i, j)| (estimate[i].1.translation, ground_truth[j].1.translation))
        .collect();
    Ok(statistics(&pairs, ground_truth_from_estimate))
}

/// Position errors (metres) of `poses` (`world_from_camera`, all of the
/// frame at `timestamp`) against the ground truth, after aligning the
/// ground truth with the estimate's poses before `aligned_before` only
/// (timestamps within `max_dt`): where the early part of the map says the
/// frame should be. Loop closure's record asks whether a correction moved
/// the current pose toward the truth; an alignment on the whole run would
/// include the drifted part being judged. `None` when the ground truth has
/// no pose within `max_dt` of `timestamp`.
pub fn errors_in_early_alignment(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    max_dt: f64,
    (aligned_before, timestamp): (f64, f64),
    poses: &[DAffine3],
) -> Result<Option<Vec<f64>>, EvalError> {
    let early: Vec<(f64, DAffine3)> = estimate
        .iter()
        .copied()
        .filter(|(t, _)| *t < aligned_before)
        .collect();
    let alignment = ate(&early, ground_truth, max_dt)?.ground_truth_from_estimate;
    let probe = [(timestamp, DAffine3::IDENTITY)];
    let matched = associate_indices(&probe, ground_truth, Association::Timestamp { max_dt })?;
    let Some(truth) = matched.first().map(|&(_, j)| ground_truth[j].1.translation) else {
        return Ok(None);
    };
    Ok(Some(
        poses
            .iter()
            .map(|p| (alignment.transform_point3(p.translation) - truth).length())
            .collect(),
    ))
}

/// Rotation angle of a (near-)rotation matrix, radians in [0, pi].
fn rotation_angle(m: DMat3) -> f64 {
    let q = DQuat::from_mat3(&m).normalize();
    2.0 * libm::atan2(q.xyz().length(), q.w.abs())
}

/// Relative pose error over consecutive matched frames: for each step
/// i -> i+1, error = (G_i^-1 G_{i+1})^-1 (E_i^-1 E_{i+1}); reports the RMS of
/// its translation (metres) and rotation angle (radians). Needs at least 2
/// matched poses.
pub fn rpe(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    max_dt: f64,
) -> Result<RpeResult, EvalError> {
    rpe_with(estimate, ground_truth, Association::Timestamp { max_dt })
}

/// [`rpe`] under any [`Association`]: consecutive steps of the matched
/// sequence, in the association's order.
pub fn rpe_with(
    estimate: &[(f64, DAffine3)],
    ground_truth: &[(f64, DAffine3)],
    association: Association,
) -> Result<RpeResult, EvalError> {
    check_finite(estimate, "estimate")?;
    check_finite(ground_truth, "ground truth")?;
    let pairs = associate_poses(estimate, ground_truth, association)?;
    if pairs.len() < 2 {
        return Err(EvalError::TooFewPairs {
            found: pairs.len(),
            needed: 2,
        });
    }
    let (mut sum_t, mut sum_r) = (0.0, 0.0);
    for w in pairs.windows(2) {
        let (e0, g0) = w[0];
        let (e1, g1) = w[1];
        let delta_e = e0.inverse() * e1;
        let delta_g = g0.inverse() * g1;
        let error = delta_g.inverse() * delta_e;
        sum_t += error.translation.length_squared();
        sum_r += rotation_angle(error.matrix3).powi(2);
    }
    let steps = pairs.len() - 1;
    Ok(RpeResult {
        translation_rmse_m: (sum_t / steps as f64).sqrt(),
        rotation_rmse_rad: (sum_r / steps as f64).sqrt(),
        pairs: steps,
    })
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;
    use glam::EulerRot;

    fn trajectory(n: usize) -> Vec<(f64, DAffine3)> {
        (0..n)
            .map(|i| {
                let s = i as f64 * 0.1;
                let rotation = DQuat::from_euler(EulerRot::XYZ, 0.1 * s, 0.3 * s.sin(), 0.05 * s);
                let position = DVec3::new(s.cos(), 0.5 * (2.0 * s).sin(), 0.2 * s);
                (
                    i as f64 / 30.0,
                    DAffine3::from_rotation_translation(rotation, position),
                )
            })
            .collect()
    }

    #[test]
    fn ate_is_zero_under_a_rigid_change_of_world() {
        let gt = trajectory(60);
        let world = DAffine3::from_rotation_translation(
            DQuat::from_euler(EulerRot::ZYX, 2.0, -0.7, 0.4),
            DVec3::new(3.0, -1.0, 0.5),
        );
        // Slight timestamp jitter: association within 0.02 s must still pair them.
        let est: Vec<_> = gt.iter().map(|(t, p)| (t + 0.004, world * *p)).collect();
        let r = ate(&est, &gt, 0.02).expect("ate");
        assert_eq!(r.pairs, 60);
        assert!(r.rmse_m < 1e-9 && r.max_m < 1e-9, "{r:?}");
        assert!(r
            .ground_truth_from_estimate
            .abs_diff_eq(world.inverse(), 1e-9));
        let rpe = rpe(&est, &gt, 0.02).expect("rpe");
        assert!(
            rpe.translation_rmse_m < 1e-9 && rpe.rotation_rmse_rad < 1e-6,
            "{rpe:?}"
        );
    }

    #[test]
    fn ate_in_frame_uses_the_given_alignment_and_fits_none() {
        let gt = trajectory(60);
        let world = DAffine3::from_rotation_translation(
            DQuat::from_euler(EulerRot::ZYX, 0.3, 0.1, -0.2),
            DVec3::new(1.0, 2.0, -0.5),
        );
        let est: Vec<_> = gt.iter().map(|(t, p)| (*t, world * *p)).collect();
        // The first half gives the alignment; the second half is judged under it.
        let alignment = ate(&est[..30], &gt, 0.02)
            .expect("ate")
            .ground_truth_from_estimate;
        let r = ate_in_frame(&est[30..], &gt, 0.02, alignment).expect("in frame");
        assert_eq!(r.pairs, 30);
        assert!(r.rmse_m < 1e-9, "{r:?}");
        // A second half shifted by 5 cm: a fitted alignment would hide it.
        let shift = DAffine3::from_translation(DVec3::new(0.05, 0.0, 0.0));
        let shifted: Vec<_> = est[30..].iter().map(|(t, p)| (*t, shift * *p)).collect();
        let r = ate_in_frame(&shifted, &gt, 0.02, alignment).expect("in frame");
        assert!(
            (r.rmse_m - 0.05).abs() < 1e-9 && (r.max_m - 0.05).abs() < 1e-9,
            "{r:?}"
        );
        assert!(ate(&shifted, &gt, 0.02).expect("ate").rmse_m < 1e-9);
        assert!(matches!(
            ate_in_frame(&est[..1], &gt[40..], 0.02, alignment),
            Err(EvalError::TooFewPairs { found: 0, .. })
        ));
    }

    #[test]
    fn ate_reports_a_known_offset() {
        // Each position appears twice, shifted by +d and -d along z: the
        // shifts cancel in the centroid and in the cross-covariance, so the
        // best alignment is the identity and every error is exactly d.
        let d = 0.05;
        let gt = trajectory(40);
        let mut est = Vec::new();
        let mut gt2 = Vec::new();
        for (k, (_, p)) in gt.iter().enumerate() {
            for (j, sign) in [1.0, -1.0].into_iter().enumerate() {
                let t = (2 * k + j) as f64;
                gt2.push((t, *p));
                let mut e = *p;
                e.translation.z += sign * d;
                est.push((t, e));
            }
        }
        let r = ate(&est, &gt2, 0.0).expect("ate");
        assert_eq!(r.pairs, 80);
        assert!((r.rmse_m - d).abs() < 1e-9, "{r:?}");
        assert!((r.mean_m - d).abs() < 1e-9 && (r.median_m - d).abs() < 1e-9);
    }

    #[test]
    fn planar_trajectory_gives_a_proper_rotation() {
        let gt: Vec<_> = (0..10)
            .map(|i| {
                let a = i as f64 * 0.6;
                (
                    i as f64,
                    DAffine3::from_translation(DVec3::new(a.cos(), a.sin(), 0.0)),
                )
            })
            .collect();
        let r = ate(&gt, &gt, 0.0).expect("ate");
        assert!(r.rmse_m < 1e-9);
        assert!((r.ground_truth_from_estimate.matrix3.determinant() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn rpe_sees_a_rotation_jump_and_errors_are_reported() {
        let gt = trajectory(10);
        let mut est = gt.clone();
        est[5].1 *= DAffine3::from_rotation_z(0.1);
        let r = rpe(&est, &gt, 0.0).expect("rpe");
        assert_eq!(r.pairs, 9);
        // Two steps (4->5 and 5->6) each carry a 0.1 rad error.
        assert!(
            (r.rotation_rmse_rad - (2.0 * 0.01 / 9.0_f64).sqrt()).abs() < 1e-9,
            "{r:?}"
        );
        assert_eq!(
            ate(&est[..2], &gt, 0.0),
            Err(EvalError::TooFewPairs {
                found: 2,
                needed: 3
            })
        );
        assert_eq!(
            rpe(&est, &gt, -1.0),
            Err(EvalError::TooFewPairs {
                found: 0,
                needed: 2
            })
        );
        let mut bad = gt.clone();
        bad[0].0 = f64::NAN;
        assert_eq!(
            ate(&bad, &gt, 0.02),
            Err(EvalError::NonFinite { which: "estimate" })
        );
    }

    #[test]
    fn frame_ids_and_row_order_pair_differently() {
        // ICL-NUIM style: ground truth for frames 2..=30, estimate for 1..=30.
        let poses = trajectory(31);
        let gt: Vec<_> = (2..=30).map(|k| (k as f64, poses[k].1)).collect();
        let est: Vec<_> = (1..=30).map(|k| (k as f64, poses[k].1)).collect();
        let by_id = ate_report(&est, &gt, Association::FrameId).expect("ate");
        assert_eq!(by_id.errors.len(), 29);
        assert!(by_id.summary.rmse_m < 1e-9, "{:?}", by_id.summary);
        let first = by_id.errors[0];
        assert_eq!((first.estimate_index, first.ground_truth_index), (1, 0));
        assert_eq!((first.timestamp, first.ground_truth_timestamp), (2.0, 2.0));
        assert!(first.rotation_error_rad < 1e-6);
        // Row order pairs frame k with frame k+1: a real error.
        let by_row = ate_report(&est, &gt, Association::Order).expect("ate");
        assert_eq!(by_row.errors.len(), 29);
        assert_eq!(by_row.errors[0].timestamp, 1.0);
        assert!(by_row.summary.rmse_m > 1e-3, "{:?}", by_row.summary);
        // Time association equals id association on whole-number stamps.
        let by_time = ate(&est, &gt, 0.02).expect("ate");
        assert_eq!(by_time, by_id.summary);
        let tum = trajectory(5);
        assert_eq!(
            ate_report(&tum, &tum, Association::FrameId),
            Err(EvalError::NotFrameIds {
                which: "estimate",
                value: 1.0 / 30.0
            })
        );
    }

    #[test]
    fn per_pose_errors_match_known_offsets() {
        // As in ate_reports_a_known_offset, each position twice, shifted by
        // +d and -d along z: every per-pose error is d, in a moved world.
        let d = 0.03;
        let world = DAffine3::from_rotation_translation(
            DQuat::from_rotation_y(1.1),
            DVec3::new(0.2, 0.0, -4.0),
        );
        let gt = trajectory(20);
        let (mut est, mut gt2) = (Vec::new(), Vec::new());
        for (k, (_, p)) in gt.iter().enumerate() {
            for (j, sign) in [1.0, -1.0].into_iter().enumerate() {
                let t = (2 * k + j) as f64 * 0.1;
                gt2.push((t, *p));
                let mut e = *p;
                e.translation.z += sign * d;
                est.push((t + 0.01, world * e));
            }
        }
        let r = ate_report(&est, &gt2, Association::Timestamp { max_dt: 0.02 }).expect("ate");
        assert_eq!(r.errors.len(), 40);
        for (k, e) in r.errors.iter().enumerate() {
            assert_eq!((e.estimate_index, e.ground_truth_index), (k, k));
            assert!((e.position_error_m - d).abs() < 1e-9, "{e:?}");
            assert!(e.rotation_error_rad < 1e-6, "{e:?}");
            assert!(e.ground_truth_position == gt2[k].1.translation);
        }
    }
}
