//! Index map: the surfels of the map projected into a camera, one pixel per
//! surfel centre: the z-buffer behind the model prediction. A first pass
//! keeps each pixel's nearest depth with an atomic `fetch_min` while
//! surfels are projected in parallel; a second keeps, per pixel, the most
//! confident surfel within a depth band of that nearest one. Only the blocks
//! of the map inside the view frustum are visited.
//!
//! Picking the nearest of several overlapping noisy surfels picks the one
//! whose noise pulls it towards the camera, so the predicted surface would
//! sit in front of the true one and tracking against it would drift;
//! confidence is not correlated with that noise.

use crate::camera::Intrinsics;
use crate::fusion::SurfelMap;
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// A rigid transform in f32 for per-point loops (`rotation * p + translation`).
#[derive(Debug, Clone, Copy)]
pub struct RigidF32 {
    /// Rotation.
    pub rotation: Mat3,
    /// Translation, metres.
    pub translation: Vec3,
}

impl RigidF32 {
    /// Converts an f64 pose to f32.
    #[must_use]
    pub fn from_affine(pose: &glam::DAffine3) -> Self {
        Self {
            rotation: Mat3::from_cols(
                pose.matrix3.x_axis.as_vec3(),
                pose.matrix3.y_axis.as_vec3(),
                pose.matrix3.z_axis.as_vec3(),
            ),
            translation: pose.translation.as_vec3(),
        }
    }

    /// Transforms a point.
    #[inline]
    #[must_use]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Rotates a direction.
    #[inline]
    #[must_use]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.rotation * v
    }
}

/// Depth (metres) and pixel index of a camera-frame point, or `None` when it
/// is behind the camera or outside the image.
#[inline]
#[must_use]
pub fn pixel_of(k: &Intrinsics, p: Vec3) -> Option<(f32, usize)> {
    if p.z <= 0.0 {
        return None;
    }
    k.pixel_index(k.project(p)).map(|i| (p.z, i))
}

/// Writes into `out[i]` the pixel index that `positions[i]` (world frame,
/// metres) projects to from `camera_from_world`, or `u32::MAX` when it lies
/// behind the camera or outside the image; the same pixel as [`pixel_of`].
/// Free of branches, so that the loop vectorises: it is the per-surfel
/// part of association that every visible surfel pays.
pub fn project_to_pixels(
    k: &Intrinsics,
    camera_from_world: &RigidF32,
    positions: &[Vec3],
    out: &mut [u32],
) {
    let (w, h) = (k.width as f32, k.height as f32);
    let width = k.width as u32;
    for (p, o) in positions.iter().zip(out.iter_mut()) {
        let q = camera_from_world.point(*p);
        let inv_z = 1.0 / q.z;
        // The arithmetic of `Intrinsics::project` and `pixel_index`, in the same order.
        let u = k.fx * q.x * inv_z + k.cx + 0.5;
        let v = k.fy * q.y * inv_z + k.cy + 0.5;
        let inside = q.z > 0.0 && u >= 0.0 && v >= 0.0 && u < w && v < h;
        // Truncation is floor for the non-negative values kept; others are discarded.
        let pixel = (v as u32).wrapping_mul(width).wrapping_add(u as u32);
        *o = if inside { pixel } else { u32::MAX };
    }
}

/// Calls `f(i)` in parallel for every surfel index in `ranges` (blocks of the map).
pub fn for_each_in(ranges: &[Range<usize>], f: impl Fn(usize) + Sync + Send) {
    ranges.par_iter().for_each(|r| r.clone().for_each(&f));
}

/// Calls `f(i, &mut data[i])` for every `i` in `ranges` (sorted, disjoint),
/// ranges in parallel. Indices past `data` are skipped.
pub fn for_each_in_mut<T: Send>(
    ranges: &[Range<usize>],
    data: &mut [T],
    f: &(impl Fn(usize, &mut T) + Sync),
) {
    for_each_in_mut_from(ranges, data, 0, f);
}

/// [`for_each_in_mut`] where `data[0]` is element `offset`: splits `data`
/// between the ranges, halves in parallel.
fn for_each_in_mut_from<T: Send>(
    ranges: &[Range<usize>],
    data: &mut [T],
    offset: usize,
    f: &(impl Fn(usize, &mut T) + Sync),
) {
    match ranges {
        [] => {}
        [r] => {
            let start = r.start.saturating_sub(offset).min(data.len());
            let end = r.end.saturating_sub(offset).clamp(start, data.len());
            for (j, x) in data[start..end].iter_mut().enumerate() {
                f(offset + start + j, x);
            }
        }
        _ => {
            let (low, high) = ranges.split_at(ranges.len() / 2);
            let split = high[0].start.saturating_sub(offset).min(data.len());
            let (a, b) = data.split_at_mut(split);
            rayon::join(
                || for_each_in_mut_from(low, a, offset, f),
                || for_each_in_mut_from(high, b, offset + split, f),
            );
        }
    }
}

/// Nearest-surfel buffer of a camera view, one cell per pixel.
#[derive(Debug, Default)]
pub struct IndexMap {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Per pixel, the bits of the nearest projected depth (positive floats
    /// order like their bits), `NO_DEPTH` when none.
    nearest: Vec<AtomicU32>,
    /// Per pixel, `(confidence bits << 32) | (surfel index + 1)` of the
    /// chosen surfel, 0 when none.
    chosen: Vec<AtomicU64>,
    /// Per surfel of the visited ranges: `(depth bits << 32) | cell` from the
    /// first pass, `NOT_PROJECTED` when excluded or outside the image; the
    /// second pass reads it instead of projecting again.
    projected: Vec<u64>,
}

/// Marks a surfel the first pass did not put in any cell.
const NOT_PROJECTED: u64 = u64::MAX;

/// Marks a cell no surfel projects into.
const NO_DEPTH: u32 = u32::MAX;

impl IndexMap {
    /// Allocates (or reuses) the buffers for an image of `k`'s size.
    pub fn resize(&mut self, k: &Intrinsics) {
        self.width = k.width;
        self.height = k.height;
        let n = self.width * self.height;
        if self.nearest.len() != n {
            self.nearest = (0..n).map(|_| AtomicU32::new(NO_DEPTH)).collect();
            self.chosen = (0..n).map(|_| AtomicU64::new(0)).collect();
        }
    }

    /// Projects the centres of the surfels in `ranges` selected by `include`
    /// into the view `camera_from_world`, one pixel each; each pixel ends up
    /// with the most confident surfel within `confidence_band_m` (metres)
    /// of the nearest one.
    pub fn render(
        &mut self,
        map: &SurfelMap,
        ranges: &[Range<usize>],
        camera_from_world: &RigidF32,
        k: &Intrinsics,
        confidence_band_m: f32,
        include: impl Fn(usize) -> bool + Sync,
    ) {
        // Writes through `&mut` are plain stores: an atomic store is a locked
        // exchange in threaded wasm, whose atomics are sequentially consistent.
        self.nearest
            .par_iter_mut()
            .for_each(|c| *c.get_mut() = NO_DEPTH);
        self.chosen.par_iter_mut().for_each(|c| *c.get_mut() = 0);
        if self.projected.len() < map.len() {
            self.projected.resize(map.len(), NOT_PROJECTED);
        }
        let nearest = &self.nearest;
        let include = &include;
        for_each_in_mut(ranges, &mut self.projected, &|i, projected: &mut u64| {
            let entry = if include(i) {
                pixel_of(k, camera_from_world.point(map.positions[i]))
            } else {
                None
            };
            *projected = entry.map_or(NOT_PROJECTED, |(z, cell)| {
                nearest[cell].fetch_min(z.to_bits(), Ordering::Relaxed);
                (u64::from(z.to_bits()) << 32) | cell as u64
            });
        });
        let (projected, chosen) = (&self.projected, &self.chosen);
        for_each_in(ranges, |i| {
            let entry = projected[i];
            if entry == NOT_PROJECTED {
                return;
            }
            let z = f32::from_bits((entry >> 32) as u32);
            let cell = (entry & 0xffff_ffff) as usize;
            let near = f32::from_bits(nearest[cell].load(Ordering::Relaxed));
            if z <= near + confidence_band_m {
                // Confidences are positive, so their bit patterns order like the values.
                let key = (u64::from(map.confidences[i].max(0.0).to_bits()) << 32) | (i as u64 + 1);
                chosen[cell].fetch_max(key, Ordering::Relaxed);
            }
        });
    }

    /// The surfel index chosen for cell (x, y), if any.
    #[inline]
    #[must_use]
    pub fn surfel_at(&self, x: usize, y: usize) -> Option<usize> {
        let key = self.chosen.get(y * self.width + x)?.load(Ordering::Relaxed);
        ((key & 0xffff_ffff) as usize).checked_sub(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DAffine3, DQuat, DVec3};

    #[test]
    fn for_each_in_mut_visits_exactly_the_ranges_with_their_own_element() {
        let ranges = [2..5, 7..8, 9..9, 10..20];
        let mut data = vec![usize::MAX; 15];
        for_each_in_mut(&ranges, &mut data, &|i, x: &mut usize| *x = i);
        let expected: Vec<usize> = (0..15)
            .map(|i| {
                if ranges.iter().any(|r| r.contains(&i)) {
                    i
                } else {
                    usize::MAX
                }
            })
            .collect();
        assert_eq!(data, expected);
        let many: Vec<Range<usize>> = (0..100).map(|b| 10 * b..10 * b + 3).collect();
        let mut data = vec![0_usize; 1000];
        for_each_in_mut(&many, &mut data, &|i, x: &mut usize| *x = i + 1);
        assert!(data
            .iter()
            .enumerate()
            .all(|(i, &x)| x == if i % 10 < 3 { i + 1 } else { 0 }));
    }

    #[test]
    fn batch_projection_gives_the_pixels_of_pixel_of() {
        for fy in [525.0, -525.0] {
            let k = Intrinsics::new(525.0, fy, 319.5, 239.5, 640, 480);
            let pose = DAffine3::from_rotation_translation(
                DQuat::from_euler(glam::EulerRot::XYZ, 0.1, -0.3, 0.05),
                DVec3::new(0.2, -0.1, 0.4),
            );
            let camera_from_world = RigidF32::from_affine(&pose.inverse());
            // A grid through the view, behind the camera and beyond the image edges.
            let mut positions: Vec<Vec3> = (0..4000)
                .map(|i| {
                    let (x, y, z) = ((i % 20) as f32, ((i / 20) % 20) as f32, (i / 400) as f32);
                    Vec3::new(x * 0.2 - 2.0, y * 0.15 - 1.5, z * 0.5 - 1.5)
                })
                .collect();
            positions.push(Vec3::NAN);
            let mut pixels = vec![0; positions.len()];
            project_to_pixels(&k, &camera_from_world, &positions, &mut pixels);
            let mut inside = 0;
            for (p, &pixel) in positions.iter().zip(&pixels) {
                let expected = pixel_of(&k, camera_from_world.point(*p)).map(|(_, i)| i as u32);
                assert_eq!(expected.unwrap_or(u32::MAX), pixel, "at {p}");
                inside += usize::from(expected.is_some());
            }
            assert!(inside > 500 && inside < 3000, "{inside} inside the image");
        }
    }
}
