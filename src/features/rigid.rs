//! Rigid 3D-3D alignment: the closed-form least-squares fit (Horn /
//! Umeyama, without scale) and RANSAC over 3-point samples, refined on the
//! inliers.

use crate::random::SplitMix;
use glam::{DAffine3, DVec3, Vec3};
use nalgebra::Matrix3;

/// Settings of [`ransac_rigid`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RansacConfig {
    /// Most 3-point samples drawn.
    pub max_iterations: usize,
    /// Stop sampling once a sample free of outliers has been drawn with
    /// this probability (given the best inlier ratio so far).
    pub confidence: f64,
    /// A pair is an inlier when `|a - T b|` is below this, metres. 4 cm:
    /// about three times a Kinect's depth noise at 3 m, and well below the
    /// errors a wrong match gives (a wrong match lands anywhere in the room).
    pub inlier_m: f64,
    /// Fewer inliers than this: no estimate.
    pub min_inliers: usize,
    /// Seed of the sampler (results are deterministic).
    pub seed: u64,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            max_iterations: 1000,
            confidence: 0.999,
            inlier_m: 0.04,
            min_inliers: 12,
            seed: 0x5eed,
        }
    }
}

/// A rigid transform fitted to pairs of points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidFit {
    /// Maps the `b` points onto the `a` points (`a ~ a_from_b * b`), metres.
    pub a_from_b: DAffine3,
    /// Pairs within the inlier distance of the final fit.
    pub inliers: usize,
    /// RMS distance of the inliers after the fit, metres.
    pub rms_m: f64,
}

/// Least-squares rigid transform with `a[i] ~ T * b[i]` (Horn 1987 /
/// Umeyama 1991, no scale): `None` for fewer than 3 pairs or a degenerate
/// (collinear) set.
#[must_use]
pub fn fit_rigid(pairs: impl Iterator<Item = (DVec3, DVec3)> + Clone) -> Option<DAffine3> {
    let (mut ca, mut cb, mut n) = (DVec3::ZERO, DVec3::ZERO, 0usize);
    for (a, b) in pairs.clone() {
        ca += a;
        cb += b;
        n += 1;
    }
    if n < 3 {
        return None;
    }
    ca /= n as f64;
    cb /= n as f64;
    // Cross-covariance H = sum (b - cb)(a - ca)^T.
    let mut h = Matrix3::<f64>::zeros();
    for (a, b) in pairs {
        let (a, b) = (a - ca, b - cb);
        for r in 0..3 {
            for c in 0..3 {
                h[(r, c)] += b[r] * a[c];
            }
        }
    }
    let svd = h.try_svd(true, true, 1e-12, 100)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let s = svd.singular_values;
    // Collinear (or coincident) points leave a rotation about their line free.
    if !(s.iter().all(|x| x.is_finite())) || s[1] <= 1e-9 * s[0].max(1e-12) {
        return None;
    }
    let v = v_t.transpose();
    let mut d = Matrix3::<f64>::identity();
    // A reflection is never a camera motion: flip the weakest axis.
    if (v * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v * d * u.transpose();
    let rotation = crate::se3::dmat3_from_nalgebra(&r);
    let translation = ca - rotation * cb;
    let t = DAffine3::from_mat3_translation(rotation, translation);
    t.is_finite().then_some(t)
}

/// RANSAC over 3-point samples for `a[i] ~ T * b[i]`, then the closed-form
/// fit refined on the inliers (three rounds of fit and re-selection).
/// `inlier` receives, per pair, whether it is an inlier of the result.
/// `None` when fewer than `min_inliers` agree on any transform.
pub fn ransac_rigid(
    a: &[Vec3],
    b: &[Vec3],
    config: &RansacConfig,
    inlier: &mut Vec<bool>,
) -> Option<RigidFit> {
    let n = a.len().min(b.len());
    inlier.clear();
    inlier.resize(n, false);
    if n < config.min_inliers.max(3) {
        return None;
    }
    let threshold2 = config.inlier_m * config.inlier_m;
    let pair = |i: usize| (a[i].as_dvec3(), b[i].as_dvec3());
    let count = |t: &DAffine3| {
        (0..n)
            .filter(|&i| {
                let (p, q) = pair(i);
                (p - t.transform_point3(q)).length_squared() < threshold2
            })
            .count()
    };
    let mut rng = SplitMix::new(config.seed);
    let mut best: Option<(usize, DAffine3)> = None;
    let mut needed = config.max_iterations;
    let mut iteration = 0;
    while iteration < needed.min(config.max_iterations) {
        iteration += 1;
        let i = rng.below(n);
        let j = rng.below(n);
        let k = rng.below(n);
        if i == j || j == k || i == k {
            continue;
        }
        // A rigid motion keeps distances: most wrong samples fail here,
        // before any fit.
        let consistent = [(i, j), (j, k), (i, k)].iter().all(|&(x, y)| {
            let da = (a[x] - a[y]).length();
            let db = (b[x] - b[y]).length();
            (da - db).abs() < 2.0 * config.inlier_m as f32 && da > 2.0 * config.inlier_m as f32
        });
        if !consistent {
            continue;
        }
        let Some(t) = fit_rigid([i, j, k].into_iter().map(pair)) else {
            continue;
        };
        let c = count(&t);
        if best.is_none_or(|(b, _)| c > b) {
            best = Some((c, t));
            let w = c as f64 / n as f64;
            let p_good = w.powi(3);
            if p_good >= 1.0 {
                needed = iteration;
            } else if p_good > 0.0 {
                let k = libm::log(1.0 - config.confidence) / libm::log(1.0 - p_good);
                needed = if k.is_finite() {
                    k.ceil() as usize
                } else {
                    needed
                };
            }
        }
    }
    let (_, mut t) = best?;
    // Refine: fit on the inliers, re-select, three times (the set settles).
    for _ in 0..3 {
        let selected = (0..n).filter(|&i| {
            let (p, q) = pair(i);
            (p - t.transform_point3(q)).length_squared() < threshold2
        });
        if selected.clone().count() < config.min_inliers.max(3) {
            return None;
        }
        t = fit_rigid(selected.map(pair))?;
    }
    let mut sum2 = 0.0;
    let mut inliers = 0;
    for (i, flag) in inlier.iter_mut().enumerate() {
        let (p, q) = pair(i);
        let d2 = (p - t.transform_point3(q)).length_squared();
        *flag = d2 < threshold2;
        if *flag {
            sum2 += d2;
            inliers += 1;
        }
    }
    (inliers >= config.min_inliers.max(3)).then(|| RigidFit {
        a_from_b: t,
        inliers,
        rms_m: (sum2 / inliers.max(1) as f64).sqrt(),
    })
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn fit_recovers_a_transform_exactly() {
        let t = DAffine3::from_rotation_translation(
            DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 1.2),
            DVec3::new(0.4, -1.0, 2.0),
        );
        let b = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.2, 2.0),
            DVec3::new(-0.5, 0.7, 3.0),
            DVec3::new(0.3, -0.9, 1.5),
        ];
        let fit = fit_rigid(b.iter().map(|&q| (t.transform_point3(q), q))).expect("fit");
        assert!((fit.matrix3 - t.matrix3)
            .to_cols_array()
            .iter()
            .all(|x| x.abs() < 1e-9));
        assert!((fit.translation - t.translation).length() < 1e-9);
        // Collinear points do not pin the rotation.
        let line = [0.0, 1.0, 2.0].map(|s| DVec3::new(s, 2.0 * s, 1.0 + s));
        assert!(fit_rigid(line.iter().map(|&q| (q, q))).is_none());
    }
}
