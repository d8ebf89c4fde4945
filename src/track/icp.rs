//! Projective point-to-plane ICP, one Gauss-Newton step.
//!
//! The model prediction is the *source*: its points `p` (world frame) are
//! moved by the current estimate `camera_from_world` to `p' = T p` and
//! projected into the frame's pyramid level (the *target*, the only organised
//! image with intrinsics). The projective neighbour `q` with normal `n`
//! (camera frame) is kept if it is valid, within `distance_gate_m` of `p'` and
//! its normal within `normal_gate_deg` of the model normal.
//!
//! Linearising the increment on the left, `exp(xi) p' ~= p' + w x p' + t`,
//! the residual `r = n . (p' - q)` becomes `r + (p' x n) . w + n . t`: each
//! pair adds the row `A_i = [(p' x n)^T, n^T]` with `b_i = n^T (p' - q)`, and
//! the step solves `(sum w_i A_i^T A_i) xi = -(sum w_i A_i^T b_i)` with a
//! Huber weight `w_i` on `r`. The new estimate is `exp(xi) T`.
//!
//! Noise weighting: each residual is divided by its predicted deviation
//! along the normal, `sigma^2 = sigma_q^2 + MODEL_VARIANCE_RATIO sigma_p^2`
//! (the measurement `q` and the model point `p'`, both from the sensor's
//! [`SensorNoise`]), in units of the model's reference deviation at 1 m:
//! the row and residual are scaled by `s = reference / sigma`, and the Huber
//! weight is taken on the scaled residual, so `huber_m` means metres at
//! 1 m facing the surface. Every level uses the same model (coarse levels
//! minimise the same cost as the fine one, on fewer points). A uniform
//! model gives `s = 1`: the unweighted tracker.

use crate::noise::SensorNoise;
use crate::ordered_sum::sum_in_blocks;
use crate::portable_math::at_least;
use crate::prefetch::prefetch;
use crate::preprocess::PyramidLevel;
use crate::se3::RigidF32;
use crate::se3::{NormalEquations, RowAccumulator};
use crate::track::model_points::ModelPoints;
use glam::Vec3;

/// Gates and robust weight of one ICP step.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IcpGates {
    /// Largest point distance |p' - q| of a correspondence, metres.
    pub distance_gate_m: f32,
    /// Largest angle between model and frame normals, degrees.
    pub normal_gate_deg: f32,
    /// Huber threshold on the point-to-plane residual, metres.
    pub huber_m: f32,
}

/// Variance of a predicted model point relative to one measurement at the
/// same depth: stable surfels average at least `stable_confidence` (5)
/// measurements.
pub const MODEL_VARIANCE_RATIO: f32 = 0.2;

/// The sensor noise model and the full-resolution focal length (pixels)
/// its lateral term is given for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseWeights<'a> {
    /// Depth noise of the sensor.
    pub noise: &'a SensorNoise,
    /// Focal length of the finest pyramid level, pixels.
    pub focal_px: f32,
}

impl NoiseWeights<'_> {
    /// Scale `reference / sigma` of a point-to-plane residual between the
    /// measurement `q` and the model point `p` (camera frame, metres) along
    /// the measured normal `n`; `q_deviation` multiplies the model's
    /// deviation of `q` (its pixel's [`PyramidLevel::depth_deviation_at`]).
    #[inline]
    #[must_use]
    pub fn point_to_plane_scale(&self, q: Vec3, p: Vec3, n: Vec3, q_deviation: f32) -> f32 {
        let noise = self.noise;
        let sq = q_deviation
            * noise.along_normal_m(q.z, n.dot(q) / at_least(q.length(), 1e-6), self.focal_px);
        let sp = noise.along_normal_m(p.z, n.dot(p) / at_least(p.length(), 1e-6), self.focal_px);
        // Not divided by (1 + MODEL_VARIANCE_RATIO): that makes a
        // near-uniform model scale by exactly 1 but moved ICL-NUIM kt0 with
        // Kinect noise (tests/sensor_noise.rs) from 0.29 to 0.94 cm ATE;
        // the early frames, tracked against a one-frame model, are
        // sensitive to the ~10 % change of the effective Huber threshold.
        noise.scale((sq * sq + MODEL_VARIANCE_RATIO * sp * sp).sqrt())
    }
}

/// Normal equations of one ICP step plus the number of source points tried.
#[derive(Debug, Clone, Copy, Default)]
pub struct IcpStep {
    /// Accumulated system; `count` = inlier correspondences.
    pub system: NormalEquations,
    /// Source points that projected onto a pixel of the image holding a
    /// measurement (depth and a normal).
    pub candidates: usize,
    /// Sum over those source points of their noise weight (the inverse
    /// axial variance at their depth, relative to the reference; 1 each
    /// without weighting).
    pub candidate_weight: f64,
    /// The same sum over the inliers: far noisy points failing the gates
    /// count little against the inlier ratio.
    pub inlier_weight: f64,
}

impl IcpStep {
    /// Inliers over candidates, each counted by its noise weight (plain
    /// counts without weighting).
    #[must_use]
    pub fn inlier_ratio(&self) -> f64 {
        if self.candidate_weight > 0.0 {
            self.inlier_weight / self.candidate_weight
        } else {
            0.0
        }
    }
}

/// Builds the point-to-plane normal equations at one pyramid level.
///
/// Source points are the model prediction's pixels (`model`, gathered from
/// it) on a grid of step `stride` (matching the level's downsampling).
/// Residuals are weighted by `noise` (see the module doc), each frame
/// point's deviation multiplied by its pixel's
/// [`PyramidLevel::depth_deviation_at`]; `None` or a uniform model weighs
/// them all 1.
#[must_use]
pub fn icp_step(
    model: &ModelPoints,
    stride: usize,
    target: &PyramidLevel,
    camera_from_world: &RigidF32,
    gates: &IcpGates,
    noise: Option<NoiseWeights<'_>>,
) -> IcpStep {
    let noise = noise.filter(|n| !n.noise.is_uniform());
    let (Some(pk), Some(tk)) = (model.intrinsics, target.intrinsics) else {
        return IcpStep::default();
    };
    let cos_gate = libm::cosf(gates.normal_gate_deg.to_radians());
    let gate2 = gates.distance_gate_m * gates.distance_gate_m;
    let stride = stride.max(1);
    let stride_u32 = u32::try_from(stride).unwrap_or(u32::MAX);
    // Fixed blocks of rows summed in row order: the same bits on any
    // number of threads (see `ordered_sum`).
    let row_sum = |row: usize| {
        let mut acc = IcpStep::default();
        let (columns, vertices, normals) = model.row(row * stride);
        let mut sums = RowAccumulator::default();
        let (mut candidate_weight, mut inlier_weight) = (0.0f32, 0.0f32);
        // The next grid column; columns ascend, so a point left of it is
        // skipped without a division.
        let mut next = 0u32;
        let mut i = 0;
        // Points are taken in batches: a batch's projections are computed
        // and their frame pixels hinted to the caches first, then the
        // batch is summed in order (the reads of the frame at the
        // projections waited on memory).
        let mut points = [Vec3::ZERO; BATCH];
        let mut model_normals = [Vec3::ZERO; BATCH];
        let mut pixels = [NO_PIXEL; BATCH];
        // Model point, frame point and frame normal of each inlier of a
        // batch (camera frame), with its noise weight and scale.
        let mut pairs = [(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO); BATCH];
        let mut deviations = [1.0f32; BATCH];
        let mut weights = [0.0f32; BATCH];
        let mut scales = [1.0f32; BATCH];
        while i < columns.len() {
            let mut count = 0;
            while i < columns.len() && count < BATCH {
                let u = columns[i];
                i += 1;
                if u < next {
                    continue;
                }
                if u != next {
                    next = u.next_multiple_of(stride_u32);
                    if u != next {
                        continue;
                    }
                }
                next = next.saturating_add(stride_u32);
                let p = camera_from_world.point(vertices[i - 1]);
                points[count] = p;
                model_normals[count] = normals[i - 1];
                pixels[count] = if p.z <= 0.0 {
                    NO_PIXEL
                } else {
                    tk.pixel_index(tk.project(p)).unwrap_or(NO_PIXEL)
                };
                prefetch(&target.vertices, pixels[count]);
                prefetch(&target.normals, pixels[count]);
                count += 1;
            }
            // The correspondences that pass the gates, then their noise
            // scales in one loop (the compiler vectorises it), then the sums.
            let mut inliers = 0;
            for ((&p, &n_model), &j) in points.iter().zip(&model_normals).zip(&pixels).take(count) {
                if j == NO_PIXEL {
                    continue;
                }
                let q = target.vertices[j];
                let n = target.normals[j];
                // A pixel without a measurement says nothing for or against
                // the pose: a view whose depth covers a quarter of the
                // image (a desk under two monitors, whose screens return
                // none) is not a quarter inlier.
                if q.z <= 0.0 || n == Vec3::ZERO {
                    continue;
                }
                acc.candidates += 1;
                let wp = noise.map_or(1.0, |w| w.noise.weight(w.noise.axial_m(p.z)));
                candidate_weight += wp;
                let d = p - q;
                if d.length_squared() > gate2 {
                    continue;
                }
                if camera_from_world.vector(n_model).dot(n) < cos_gate {
                    continue;
                }
                pairs[inliers] = (p, q, n);
                deviations[inliers] = target.depth_deviation_at(j);
                weights[inliers] = wp;
                inliers += 1;
            }
            if let Some(w) = noise {
                for ((scale, &(p, q, n)), &f) in
                    scales.iter_mut().zip(&pairs).zip(&deviations).take(inliers)
                {
                    *scale = w.point_to_plane_scale(q, p, n, f);
                }
            }
            for ((&(p, q, n), &scale), &wp) in pairs.iter().zip(&scales).zip(&weights).take(inliers)
            {
                let d = p - q;
                let r = n.dot(d) * scale;
                let c = p.cross(n) * scale;
                let ns = n * scale;
                let w = if r.abs() <= gates.huber_m {
                    1.0
                } else {
                    gates.huber_m / r.abs()
                };
                sums.add(&[c.x, c.y, c.z, ns.x, ns.y, ns.z], r, w);
                inlier_weight += wp;
            }
        }
        sums.flush_into(&mut acc.system);
        acc.candidate_weight += f64::from(candidate_weight);
        acc.inlier_weight += f64::from(inlier_weight);
        acc
    };
    sum_in_blocks(
        pk.height.div_ceil(stride),
        ROWS_PER_BLOCK,
        |rows| rows.map(row_sum).fold(IcpStep::default(), IcpStep::merged),
        IcpStep::merged,
    )
}

/// Points of a row projected and hinted before they are summed.
const BATCH: usize = 32;

/// Marks a point that projects outside the frame (or lies behind the camera).
const NO_PIXEL: usize = usize::MAX;

/// Rows of source points summed together before the blocks are combined.
const ROWS_PER_BLOCK: usize = 4;

impl IcpStep {
    /// Sum of two partial steps.
    #[must_use]
    fn merged(self, other: Self) -> Self {
        Self {
            system: self.system.merged(&other.system),
            candidates: self.candidates + other.candidates,
            candidate_weight: self.candidate_weight + other.candidate_weight,
            inlier_weight: self.inlier_weight + other.inlier_weight,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::track::model_points::tests::wall_model;
    use glam::DAffine3;

    /// Mean point-to-plane residual along the optical axis that one step's
    /// system holds, metres (`b / a` of the z translation: a wall seen
    /// head-on pins only that translation and two rotations).
    fn mean_axial_residual(step: &IcpStep) -> f64 {
        step.system.b[5] / step.system.a[5][5]
    }

    #[test]
    fn a_frame_pixel_of_larger_deviation_pulls_the_estimate_less() {
        // The model is a wall at 2 m; the frame sees its left half there and
        // its right half 6 cm behind (depth a sensor got wrong).
        let k = Intrinsics::new(60.0, 60.0, 23.5, 17.5, 48, 36);
        let (points, mut target) = wall_model(&k, |_| true);
        for (i, q) in target.vertices.iter_mut().enumerate() {
            if i % k.width >= k.width / 2 {
                *q *= 2.06 / 2.0;
            }
        }
        let gates = IcpGates {
            distance_gate_m: 0.1,
            normal_gate_deg: 20.0,
            huber_m: 0.02,
        };
        let noise = SensorNoise::lidar();
        let weights = NoiseWeights {
            noise: &noise,
            focal_px: k.fx,
        };
        let identity = RigidF32::from_affine(&DAffine3::IDENTITY);
        let step =
            |target: &PyramidLevel| icp_step(&points, 1, target, &identity, &gates, Some(weights));
        let plain = step(&target);
        // The right half marked as four times as uncertain: weighed 1/16.
        target.depth_deviation = (0..k.pixel_count())
            .map(|i| if i % k.width >= k.width / 2 { 4.0 } else { 1.0 })
            .collect();
        let marked = step(&target);
        assert_eq!(plain.system.count, marked.system.count);
        let (plain_m, marked_m) = (mean_axial_residual(&plain), mean_axial_residual(&marked));
        // Unmarked, the Huber weight alone keeps the biased half to about
        // 2.1 cm of pull; marked, about 0.35 cm (6 / 17).
        assert!(plain_m.abs() > 0.015, "plain {plain_m}");
        assert!(marked_m.abs() < 0.006, "marked {marked_m}");
        // Without noise weighting the deviation is not read.
        let unweighted = icp_step(&points, 1, &target, &identity, &gates, None);
        target.depth_deviation.clear();
        let unweighted_plain = icp_step(&points, 1, &target, &identity, &gates, None);
        assert_eq!(unweighted.system.b, unweighted_plain.system.b);
    }

    #[test]
    fn pixels_without_depth_are_not_counted_against_the_pose() {
        // The model is a whole wall; the frame has depth on its bottom
        // fifth only (screens above that return none).
        let k = Intrinsics::new(60.0, 60.0, 23.5, 17.5, 48, 36);
        let (points, mut target) = wall_model(&k, |_| true);
        for (i, (q, n)) in target
            .vertices
            .iter_mut()
            .zip(&mut target.normals)
            .enumerate()
        {
            if i / k.width < k.height * 4 / 5 {
                *q = Vec3::ZERO;
                *n = Vec3::ZERO;
            }
        }
        let gates = IcpGates {
            distance_gate_m: 0.1,
            normal_gate_deg: 20.0,
            huber_m: 0.02,
        };
        let identity = RigidF32::from_affine(&DAffine3::IDENTITY);
        let step = icp_step(&points, 1, &target, &identity, &gates, None);
        assert!(step.system.count > 0);
        assert!(step.inlier_ratio() > 0.99, "{}", step.inlier_ratio());
    }
}
