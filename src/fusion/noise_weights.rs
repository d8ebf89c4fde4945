//! Per-pixel sensor-noise weights of a frame's measurements for fusion: a
//! measurement's share in a merge (far, oblique and depth-edge pixels move
//! a surfel seen better before by little). Camera frame, metres.

use super::FusionConfig;
use crate::camera::Intrinsics;
use crate::preprocess::PyramidLevel;
use glam::Vec3;
use rayon::prelude::*;

/// Sensor-noise weight of every pixel of `level0` (0 where no
/// measurement): the inverse variance of its deviation along its normal
/// ([`SensorNoise::along_normal_m`](crate::noise::SensorNoise::along_normal_m)),
/// times `edge_factor^2` less at depth edges, relative to the model's
/// reference and clamped to `min_noise_weight..=1`. It is the
/// measurement's share in a merge, so far, oblique and edge pixels move a
/// surfel seen better before by little; the confidence a merge adds is the
/// radial weight alone (see `FusionConfig::noise`).
pub(super) fn noise_weights_into(
    level0: &PyramidLevel,
    k: &Intrinsics,
    config: &FusionConfig,
    out: &mut Vec<f32>,
) {
    let (w, h) = (k.width, k.height);
    let noise = &config.noise;
    let focal = k.focal_abs();
    let floor = config.min_noise_weight.clamp(0.0, 1.0);
    let edge_weight = 1.0 / (noise.edge_factor * noise.edge_factor).max(1.0);
    out.resize(w * h, 0.0);
    if level0.vertices.len() != w * h || level0.normals.len() != w * h {
        return;
    }
    let vertices = &level0.vertices;
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, weight) in row.iter_mut().enumerate() {
            let i = v * w + u;
            let p = vertices[i];
            let n = level0.normals[i];
            if p.z <= 0.0 || n == Vec3::ZERO {
                *weight = 0.0;
                continue;
            }
            let cos_ray = n.dot(p) / p.length();
            let sigma = noise.along_normal_m(p.z, cos_ray, focal);
            let mut weight_here = noise.weight(sigma);
            if edge_weight < 1.0 && is_depth_edge(vertices, (u, v), (w, h)) {
                weight_here *= edge_weight;
            }
            *weight = weight_here.clamp(floor, 1.0);
        }
    });
}

/// Relative depth jump between 4-neighbours that makes a depth edge.
const EDGE_JUMP: f32 = 0.04;

/// Whether pixel `(u, v)` has a 4-neighbour without depth or more than
/// `EDGE_JUMP` of its depth nearer or farther.
fn is_depth_edge(vertices: &[Vec3], (u, v): (usize, usize), (w, h): (usize, usize)) -> bool {
    let i = v * w + u;
    let z = vertices[i].z;
    let limit = EDGE_JUMP * z;
    let jump = |j: usize| {
        let zn = vertices[j].z;
        zn <= 0.0 || (zn - z).abs() > limit
    };
    (u > 0 && jump(i - 1))
        || (u + 1 < w && jump(i + 1))
        || (v > 0 && jump(i - w))
        || (v + 1 < h && jump(i + w))
}
