//! Merge and add: fuse one frame's measurements into the surfel map.
//!
//! Association (Keller et al. 2013): a pixel's candidates are the surfels
//! whose centres project into it (Keller's 4x4 super-sampled index map keeps
//! the nearest of them per sub-cell; here all of them are considered) that
//! pass the depth and normal gates; the most confident one is merged with the
//! measurement, and a pixel without one adds a new surfel. Every surfel
//! projects into one pixel only, so candidates are found in parallel over the
//! visible chunks of the map with an atomic maximum per pixel, then applied.

use super::frustum::visible_chunks;
use super::index_map::{for_each_in, pixel_of, RigidF32};
use super::{FusionConfig, SurfelMap};
use crate::camera::Intrinsics;
use crate::preprocess::FramePyramid;
use glam::{DAffine3, Vec3};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// What one fusion step did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionStats {
    /// Measurements merged into existing surfels.
    pub merged: usize,
    /// New surfels added.
    pub added: usize,
    /// Unstable surfels removed.
    pub removed: usize,
}

/// Reusable buffers for fusing frames of one resolution.
#[derive(Debug, Default)]
pub struct Integrator {
    /// Per pixel: `(confidence bits << 32) | (surfel index + 1)` of the best
    /// candidate, 0 when none.
    best: Vec<AtomicU64>,
    visible: Vec<Range<usize>>,
}

/// One measurement in the world frame, with its weight.
struct Measurement {
    position: Vec3,
    normal: Vec3,
    colour: [u8; 4],
    radius: f32,
    weight: f32,
}

impl Integrator {
    /// Fuses the frame in `pyramid` seen from `world_from_camera` into `map`
    /// at index `frame`; `far_m` is the farthest depth the sensor measures.
    #[allow(clippy::too_many_arguments)]
    pub fn integrate(
        &mut self,
        map: &mut SurfelMap,
        pyramid: &FramePyramid,
        k: &Intrinsics,
        world_from_camera: &DAffine3,
        frame: u32,
        config: &FusionConfig,
        far_m: f32,
    ) -> FusionStats {
        let Some(level0) = pyramid.levels.first() else {
            return FusionStats::default();
        };
        let camera_from_world = RigidF32::from_affine(&world_from_camera.inverse());
        let world_from_camera_f = RigidF32::from_affine(world_from_camera);
        let n = k.pixel_count();
        if self.best.len() != n {
            self.best = (0..n).map(|_| AtomicU64::new(0)).collect();
        } else {
            self.best
                .par_iter()
                .for_each(|b| b.store(0, Ordering::Relaxed));
        }
        visible_chunks(
            map,
            k,
            &camera_from_world,
            far_m + config.depth_gate_m,
            &mut self.visible,
        );
        let cos_gate = config.normal_gate_deg.to_radians().cos();
        let best = &self.best;
        let map_ref = &*map;
        for_each_in(&self.visible, |j| {
            let q = camera_from_world.point(map_ref.positions[j]);
            let Some((z, pixel)) = pixel_of(k, q) else {
                return;
            };
            let p = level0.vertices[pixel];
            let n = level0.normals[pixel];
            if p.z <= 0.0 || n == Vec3::ZERO || (z - p.z).abs() > config.depth_gate_m {
                return;
            }
            if camera_from_world.vector(map_ref.normals[j]).dot(n) < cos_gate {
                return;
            }
            // Confidences are positive, so their bit patterns order like the values.
            let key = (u64::from(map_ref.confidences[j].max(0.0).to_bits()) << 32) | (j as u64 + 1);
            best[pixel].fetch_max(key, Ordering::Relaxed);
        });

        let mut stats = FusionStats::default();
        let w = k.width;
        let centre = glam::Vec2::new(k.cx, k.cy);
        let centre_norm = centre.length().max(1.0);
        let focal = k.focal_abs();
        for (i, best) in self.best.iter().enumerate() {
            let p = level0.vertices[i];
            let n_cam = level0.normals[i];
            if p.z <= 0.0 || n_cam == Vec3::ZERO {
                continue;
            }
            let (u, v) = ((i % w) as f32, (i / w) as f32);
            let gamma = (glam::Vec2::new(u, v) - centre).length() / centre_norm;
            let weight = (-(gamma * gamma) / (2.0 * config.confidence_sigma.powi(2))).exp();
            let radius = (std::f32::consts::SQRT_2 * p.z / focal / n_cam.z.abs().max(0.25))
                .min(config.max_radius_m);
            let c = &pyramid.rgb[3 * i..3 * i + 3];
            let m = Measurement {
                position: world_from_camera_f.point(p),
                normal: world_from_camera_f.vector(n_cam),
                colour: [c[0], c[1], c[2], 255],
                radius,
                weight,
            };
            match best.load(Ordering::Relaxed) & 0xffff_ffff {
                0 => {
                    map.push(m.position, m.normal, m.colour, m.radius, m.weight, frame);
                    stats.added += 1;
                }
                j => {
                    merge(map, j as usize - 1, &m, frame);
                    stats.merged += 1;
                }
            }
        }
        stats
    }
}

/// Confidence-weighted average of surfel `j` and a measurement.
fn merge(map: &mut SurfelMap, j: usize, m: &Measurement, frame: u32) {
    let c = map.confidences[j];
    let total = c + m.weight;
    let (a, b) = (c / total, m.weight / total);
    map.set_position(j, map.positions[j] * a + m.position * b);
    let n = map.normals[j] * a + m.normal * b;
    map.normals[j] = n.try_normalize().unwrap_or(map.normals[j]);
    for (stored, &measured) in map.colours[j].iter_mut().zip(&m.colour).take(3) {
        *stored = (f32::from(*stored) * a + f32::from(measured) * b).round() as u8;
    }
    map.radii[j] = map.radii[j].min(map.radii[j] * a + m.radius * b);
    map.confidences[j] = total;
    // Not marked changed: a merge refines a surfel by less than the sensor
    // noise; renderers refresh merged data in the background (see
    // `SurfelMap::take_changed_range`).
    map.last_seen[j] = frame;
}
