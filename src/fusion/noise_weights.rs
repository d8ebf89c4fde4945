//! Per-pixel sensor-noise weights of a frame's measurements for fusion: a
//! measurement's share in a merge (far, oblique and depth-edge pixels move
//! a surfel seen better before by little). Camera frame, metres.

use super::FusionConfig;
use crate::camera::Intrinsics;
use crate::noise::SensorNoise;
use crate::prefetch::prefetch;
use crate::preprocess::PyramidLevel;
use glam::Vec3;

/// Sensor-noise weights of the pixels of `level0`, computed per pixel
/// where read: only a measurement merged into a surfel that is not
/// settled, or added, needs one; covered pixels and those whose winner is
/// settled do not (a pass over every pixel computed them all).
pub(super) struct NoiseWeights<'a> {
    level0: &'a PyramidLevel,
    noise: SensorNoise,
    width: usize,
    height: usize,
    focal: f32,
    floor: f32,
    edge_weight: f32,
    /// False for a uniform model (every weight 1).
    weighted: bool,
    /// False when `level0` does not hold the image of `k` (every weight 0).
    complete: bool,
}

impl<'a> NoiseWeights<'a> {
    /// The weights of `level0`, an image of `k`'s size, under `config`'s noise model.
    pub(super) fn new(level0: &'a PyramidLevel, k: &Intrinsics, config: &FusionConfig) -> Self {
        let (w, h) = (k.width, k.height);
        let noise = config.noise;
        Self {
            level0,
            noise,
            width: w,
            height: h,
            focal: k.focal_abs(),
            floor: config.min_noise_weight.clamp(0.0, 1.0),
            edge_weight: 1.0 / (noise.edge_factor * noise.edge_factor).max(1.0),
            weighted: !noise.is_uniform(),
            complete: level0.vertices.len() == w * h && level0.normals.len() == w * h,
        }
    }

    /// Sensor-noise weight of pixel `i` (row-major; 0 where no
    /// measurement, 1 for a uniform model): the inverse variance of its
    /// deviation along its normal
    /// ([`SensorNoise::along_normal_m`](crate::noise::SensorNoise::along_normal_m)),
    /// times `edge_factor^2` less at depth edges, relative to the model's
    /// reference and clamped to `min_noise_weight..=1`. It is the
    /// measurement's share in a merge, so far, oblique and edge pixels move a
    /// surfel seen better before by little; the confidence a merge adds is the
    /// radial weight alone (see `FusionConfig::noise`).
    #[inline]
    pub(super) fn at(&self, i: usize) -> f32 {
        if !self.weighted {
            return 1.0;
        }
        let (w, h) = (self.width, self.height);
        if !self.complete || i >= w * h {
            return 0.0;
        }
        let vertices = &self.level0.vertices;
        let p = vertices[i];
        let n = self.level0.normals[i];
        if p.z <= 0.0 || n == Vec3::ZERO {
            return 0.0;
        }
        let cos_ray = n.dot(p) / p.length();
        let sigma = self.noise.along_normal_m(p.z, cos_ray, self.focal);
        let mut weight = self.noise.weight(sigma);
        if self.edge_weight < 1.0 && is_depth_edge(vertices, (i % w, i / w), (w, h)) {
            weight *= self.edge_weight;
        }
        weight.clamp(self.floor, 1.0)
    }

    /// Hints the caches to fetch what [`Self::at`] reads beyond the
    /// pixel's own vertex and normal: the depths of the rows above and below.
    #[inline]
    pub(super) fn prefetch(&self, i: usize) {
        if self.weighted && self.edge_weight < 1.0 {
            prefetch(&self.level0.vertices, i.wrapping_sub(self.width));
            prefetch(&self.level0.vertices, i + self.width);
        }
    }
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
