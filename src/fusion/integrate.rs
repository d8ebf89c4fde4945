//! Merge and add: fuse one frame's measurements into the surfel map.
//!
//! Each input pixel owns the 4x4 block of index-map cells under it, so the
//! blocks are disjoint and every surfel is a candidate of at most one pixel:
//! decisions are taken in parallel, then applied.

use super::index_map::{IndexMap, RigidF32};
use super::{FusionConfig, SurfelMap};
use crate::camera::Intrinsics;
use crate::preprocess::FramePyramid;
use glam::{DAffine3, Vec3};
use rayon::prelude::*;

/// What one fusion step did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionStats {
    /// Measurements merged into existing surfels.
    pub merged: usize,
    /// New surfels added.
    pub added: usize,
    /// Unstable surfels removed.
    pub removed: usize,
    /// New surfels not added because the map was at `max_surfels`.
    pub skipped: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Decision {
    Skip,
    Add,
    Merge(u32),
}

/// Reusable buffers for fusing frames of one resolution.
#[derive(Debug, Default)]
pub struct Integrator {
    index: IndexMap,
    decisions: Vec<Decision>,
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
    /// Fuses the frame in `pyramid` seen from `world_from_camera` into `map` at index `frame`.
    pub fn integrate(
        &mut self,
        map: &mut SurfelMap,
        pyramid: &FramePyramid,
        k: &Intrinsics,
        world_from_camera: &DAffine3,
        frame: u32,
        config: &FusionConfig,
    ) -> FusionStats {
        let Some(level0) = pyramid.levels.first() else {
            return FusionStats::default();
        };
        let camera_from_world = RigidF32::from_affine(&world_from_camera.inverse());
        let world_from_camera_f = RigidF32::from_affine(world_from_camera);
        self.index.resize(k, config.index_supersampling);
        self.index
            .render(map, &camera_from_world, k, None, |_| true);

        let w = k.width;
        let s = self.index.supersampling;
        let cos_gate = config.normal_gate_deg.to_radians().cos();
        let index = &self.index;
        let map_ref = &*map;
        self.decisions.resize(k.pixel_count(), Decision::Skip);
        self.decisions
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(v, row)| {
                for (u, decision) in row.iter_mut().enumerate() {
                    let i = v * w + u;
                    let p = level0.vertices[i];
                    let n = level0.normals[i];
                    *decision = if p.z <= 0.0 || n == Vec3::ZERO {
                        Decision::Skip
                    } else {
                        best_candidate(
                            index,
                            map_ref,
                            &camera_from_world,
                            (u * s, v * s),
                            p,
                            world_from_camera_f.vector(n),
                            cos_gate,
                            config.depth_gate_m,
                        )
                        .map_or(Decision::Add, Decision::Merge)
                    };
                }
            });

        let mut stats = FusionStats::default();
        let centre = glam::Vec2::new(k.cx, k.cy);
        let centre_norm = centre.length().max(1.0);
        let focal = k.focal_abs();
        for (i, decision) in self.decisions.iter().enumerate() {
            if *decision == Decision::Skip {
                continue;
            }
            let (u, v) = ((i % w) as f32, (i / w) as f32);
            let p = level0.vertices[i];
            let n_cam = level0.normals[i];
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
            match *decision {
                Decision::Merge(j) => {
                    merge(map, j as usize, &m, frame);
                    stats.merged += 1;
                }
                Decision::Add if map.len() >= config.max_surfels => stats.skipped += 1,
                Decision::Add => {
                    map.push(m.position, m.normal, m.colour, m.radius, m.weight, frame);
                    stats.added += 1;
                }
                Decision::Skip => {}
            }
        }
        stats
    }
}

/// Among the surfels in the pixel's block, the one passing the depth and
/// normal gates with the highest confidence (ties: closest to the ray).
#[allow(clippy::too_many_arguments)]
fn best_candidate(
    index: &IndexMap,
    map: &SurfelMap,
    camera_from_world: &RigidF32,
    (x0, y0): (usize, usize),
    point_in_camera: Vec3,
    normal_in_world: Vec3,
    cos_gate: f32,
    depth_gate: f32,
) -> Option<u32> {
    let s = index.supersampling;
    let ray = point_in_camera.normalize();
    let mut best: Option<(usize, f32, f32)> = None;
    for y in y0..y0 + s {
        for x in x0..x0 + s {
            let Some(j) = index.surfel_at(x, y) else {
                continue;
            };
            let q = camera_from_world.point(map.positions[j]);
            if (q.z - point_in_camera.z).abs() > depth_gate {
                continue;
            }
            if map.normals[j].dot(normal_in_world) < cos_gate {
                continue;
            }
            let conf = map.confidences[j];
            let off_ray = q.cross(ray).length();
            let better = match best {
                None => true,
                Some((_, c, d)) => conf > c || (conf == c && off_ray < d),
            };
            if better {
                best = Some((j, conf, off_ray));
            }
        }
    }
    best.and_then(|(j, _, _)| u32::try_from(j).ok())
}

/// Confidence-weighted average of surfel `j` and a measurement.
fn merge(map: &mut SurfelMap, j: usize, m: &Measurement, frame: u32) {
    let c = map.confidences[j];
    let total = c + m.weight;
    let (a, b) = (c / total, m.weight / total);
    map.positions[j] = map.positions[j] * a + m.position * b;
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
