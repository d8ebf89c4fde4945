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
    /// times `edge_factor^2` less at depth edges and the square of the
    /// pixel's [`PyramidLevel::depth_deviation_at`] less, relative to the model's
    /// reference and clamped to `min_noise_weight..=1`. It is the
    /// measurement's share in a merge, so far, oblique and edge pixels move a
    /// surfel seen better before by little; the confidence a merge adds is the
    /// radial weight alone (see `FusionConfig::noise`).
    ///
    /// Only merges read it, through [`Self::at_each_into`], which tests
    /// check against this definition.
    #[cfg(test)]
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
        weight /= self.level0.depth_deviation_at(i).powi(2);
        weight.clamp(self.floor, 1.0)
    }

    /// [`Self::at`] of each pixel of `pixels` into `out` (as many as both
    /// hold): the deviations first, in one loop that the compiler
    /// vectorises, then the pixels without a measurement and the depth
    /// edges. The same values as [`Self::at`], bit for bit.
    pub(super) fn at_each_into(&self, pixels: &[usize], out: &mut [f32]) {
        if !self.weighted || !self.complete {
            out.fill(if self.weighted { 0.0 } else { 1.0 });
            return;
        }
        let (vertices, normals) = (&self.level0.vertices, &self.level0.normals);
        let measured = |i: usize| {
            let p = vertices.get(i).copied().unwrap_or(Vec3::ZERO);
            let n = normals.get(i).copied().unwrap_or(Vec3::ZERO);
            (p, n)
        };
        // Weights past the pixels stay as they are, as `zip` leaves them.
        let len = out.len().min(pixels.len());
        let (out, pixels) = (&mut out[..len], &pixels[..len]);
        // The measurements are gathered first: a loop reading them at
        // random pixels was not vectorised.
        let mut gathered = [(Vec3::ZERO, Vec3::ZERO); PIECE];
        for (out, pixels) in out.chunks_mut(PIECE).zip(pixels.chunks(PIECE)) {
            for (slot, &i) in gathered.iter_mut().zip(pixels) {
                *slot = measured(i);
            }
            for (weight, &(p, n)) in out.iter_mut().zip(&gathered) {
                let cos_ray = n.dot(p) / p.length();
                *weight = self
                    .noise
                    .weight(self.noise.along_normal_m(p.z, cos_ray, self.focal));
            }
        }
        let (w, h) = (self.width, self.height);
        for (weight, &i) in out.iter_mut().zip(pixels) {
            let (p, n) = measured(i);
            if p.z <= 0.0 || n == Vec3::ZERO {
                *weight = 0.0;
                continue;
            }
            if self.edge_weight < 1.0 && is_depth_edge(vertices, (i % w, i / w), (w, h)) {
                *weight *= self.edge_weight;
            }
            *weight /= self.level0.depth_deviation_at(i).powi(2);
            *weight = weight.clamp(self.floor, 1.0);
        }
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

/// Pixels whose deviations [`NoiseWeights::at_each_into`] computes in one
/// vectorised loop (a merge batch's worth).
const PIECE: usize = 32;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::normals_into;

    #[test]
    fn weights_of_a_batch_are_those_of_each_pixel_bit_for_bit() {
        // A slanted, bumpy surface with holes and depth steps: far, oblique,
        // edge and missing pixels all occur.
        let k = Intrinsics::new(500.0, 500.0, 31.5, 23.5, 64, 48);
        let depth = |u: usize, v: usize| {
            if (u * 31 + v * 17) % 23 == 0 {
                0.0
            } else {
                let step = if u > 40 { 0.6 } else { 0.0 };
                0.8 + 0.03 * u as f32 + 0.002 * ((u * v) % 7) as f32 + step
            }
        };
        let vertices: Vec<Vec3> = (0..k.pixel_count())
            .map(|i| {
                let (u, v) = (i % k.width, i / k.width);
                let d = depth(u, v);
                if d > 0.0 {
                    k.back_project(u as f32, v as f32, d)
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let mut normals = vec![Vec3::ZERO; k.pixel_count()];
        normals_into(&vertices, k.width, &mut normals);
        // Every third pixel marked twice as uncertain by the sensor.
        let depth_deviation = (0..k.pixel_count())
            .map(|i| if i % 3 == 0 { 2.0 } else { 1.0 })
            .collect();
        let level0 = PyramidLevel {
            intrinsics: Some(k),
            vertices,
            normals,
            depth_deviation,
            ..PyramidLevel::default()
        };
        let config = FusionConfig {
            noise: SensorNoise::kinect_v1(),
            min_noise_weight: 0.02,
            ..FusionConfig::default()
        };
        let weights = NoiseWeights::new(&level0, &k, &config);
        // Every pixel, and one past the image, in an order unlike the image's.
        let pixels: Vec<usize> = (0..=k.pixel_count())
            .map(|i| (i * 37) % (k.pixel_count() + 1))
            .collect();
        let mut batch = vec![f32::NAN; pixels.len()];
        weights.at_each_into(&pixels, &mut batch);
        let mut distinct = std::collections::BTreeSet::new();
        for (&i, &w) in pixels.iter().zip(&batch) {
            assert_eq!(w.to_bits(), weights.at(i).to_bits(), "pixel {i}");
            distinct.insert(w.to_bits());
        }
        // An output longer than the pixels keeps its extra values.
        let mut longer = vec![f32::NAN; 40];
        weights.at_each_into(&pixels[..35], &mut longer);
        assert!(longer[..35].iter().all(|w| w.is_finite()));
        assert!(longer[35..].iter().all(|w| w.is_nan()));
        // A marked pixel weighs a quarter of what it would unmarked (down
        // to the floor).
        let unmarked_level = PyramidLevel {
            depth_deviation: Vec::new(),
            ..level0.clone()
        };
        let unmarked = NoiseWeights::new(&unmarked_level, &k, &config);
        let mut quartered = 0;
        for i in 0..k.pixel_count() {
            let (marked, plain) = (weights.at(i), unmarked.at(i));
            if i % 3 != 0 || plain == 0.0 {
                assert_eq!(marked.to_bits(), plain.to_bits(), "pixel {i}");
            } else {
                assert_eq!(
                    marked,
                    (plain / 4.0).max(config.min_noise_weight),
                    "pixel {i}"
                );
                quartered += usize::from(plain / 4.0 > config.min_noise_weight);
            }
        }
        assert!(quartered > 100, "{quartered} pixels quartered");
        // The scene gives many different weights, and some zeros.
        assert!(
            distinct.len() > 100 && distinct.contains(&0.0f32.to_bits()),
            "{} distinct weights",
            distinct.len()
        );
    }
}
