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

use crate::fusion::Prediction;
use crate::preprocess::PyramidLevel;
use crate::se3::RigidF32;
use crate::se3::{NormalEquations, RowAccumulator};
use glam::Vec3;
use rayon::prelude::*;

/// Gates and robust weight of one ICP step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpGates {
    /// Largest point distance |p' - q| of a correspondence, metres.
    pub distance_gate_m: f32,
    /// Largest angle between model and frame normals, degrees.
    pub normal_gate_deg: f32,
    /// Huber threshold on the point-to-plane residual, metres.
    pub huber_m: f32,
}

/// Normal equations of one ICP step plus the number of source points tried.
#[derive(Debug, Clone, Copy, Default)]
pub struct IcpStep {
    /// Accumulated system; `count` = inlier correspondences.
    pub system: NormalEquations,
    /// Source points that projected into the image.
    pub candidates: usize,
}

/// Builds the point-to-plane normal equations at one pyramid level.
///
/// Source points are the prediction's pixels on a grid of step `stride`
/// (matching the level's downsampling).
#[must_use]
pub fn icp_step(
    prediction: &Prediction,
    stride: usize,
    target: &PyramidLevel,
    camera_from_world: &RigidF32,
    gates: &IcpGates,
) -> IcpStep {
    let (Some(pk), Some(tk)) = (prediction.intrinsics, target.intrinsics) else {
        return IcpStep::default();
    };
    let cos_gate = gates.normal_gate_deg.to_radians().cos();
    let gate2 = gates.distance_gate_m * gates.distance_gate_m;
    let stride = stride.max(1);
    (0..pk.height.div_ceil(stride))
        .into_par_iter()
        .fold(IcpStep::default, |mut acc, row| {
            let base = row * stride * pk.width;
            let mut sums = RowAccumulator::default();
            for u in (0..pk.width).step_by(stride) {
                let n_model = prediction.normals[base + u];
                if n_model == Vec3::ZERO {
                    continue;
                }
                let p = camera_from_world.point(prediction.vertices[base + u]);
                if p.z <= 0.0 {
                    continue;
                }
                let Some(j) = tk.pixel_index(tk.project(p)) else {
                    continue;
                };
                acc.candidates += 1;
                let q = target.vertices[j];
                let n = target.normals[j];
                if q.z <= 0.0 || n == Vec3::ZERO {
                    continue;
                }
                let d = p - q;
                if d.length_squared() > gate2 {
                    continue;
                }
                if camera_from_world.vector(n_model).dot(n) < cos_gate {
                    continue;
                }
                let r = n.dot(d);
                let c = p.cross(n);
                let w = if r.abs() <= gates.huber_m {
                    1.0
                } else {
                    gates.huber_m / r.abs()
                };
                sums.add(&[c.x, c.y, c.z, n.x, n.y, n.z], r, w);
            }
            sums.flush_into(&mut acc.system);
            acc
        })
        .reduce(IcpStep::default, |a, b| IcpStep {
            system: a.system.merged(&b.system),
            candidates: a.candidates + b.candidates,
        })
}
