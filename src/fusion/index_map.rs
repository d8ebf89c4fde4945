//! Index map: the surfels of the map projected into a camera, one pixel per
//! surfel centre, nearest first: the z-buffer behind the model prediction.
//! Each pixel holds `(depth bits << 32) | surfel index`, so an atomic
//! `fetch_min` keeps the nearest surfel while surfels are projected in
//! parallel. Only the blocks of the map inside the view frustum are visited.
//!
//! With a `confidence_band_m`, a second pass keeps, per cell, the most
//! confident surfel within that depth of the nearest one. Picking the nearest
//! of several overlapping noisy surfels picks the one whose noise pulls it
//! towards the camera, so the predicted surface would sit in front of the
//! true one and tracking against it would drift; confidence is not
//! correlated with that noise.

use crate::camera::Intrinsics;
use crate::fusion::SurfelMap;
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// Empty cell marker.
pub const EMPTY: u64 = u64::MAX;

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

/// Calls `f(i)` in parallel for every surfel index in `ranges` (blocks of the map).
pub fn for_each_in(ranges: &[Range<usize>], f: impl Fn(usize) + Sync + Send) {
    ranges.par_iter().for_each(|r| r.clone().for_each(&f));
}

/// Nearest-surfel buffer of a camera view, one cell per pixel.
#[derive(Debug, Default)]
pub struct IndexMap {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    cells: Vec<AtomicU64>,
    confident: Vec<AtomicU64>,
    /// Per surfel of the visited ranges: `(depth bits << 32) | cell` from the
    /// first pass, `NOT_PROJECTED` when excluded or outside the image; the
    /// second pass reads it instead of projecting again.
    projected: Vec<AtomicU64>,
}

/// Marks a surfel the first pass did not put in any cell.
const NOT_PROJECTED: u64 = u64::MAX;

impl IndexMap {
    /// Allocates (or reuses) the buffer for an image of `k`'s size.
    pub fn resize(&mut self, k: &Intrinsics) {
        self.width = k.width;
        self.height = k.height;
        let n = self.width * self.height;
        if self.cells.len() != n {
            self.cells = (0..n).map(|_| AtomicU64::new(EMPTY)).collect();
        }
    }

    /// Projects the centres of the surfels in `ranges` selected by `include`
    /// into the view `camera_from_world`, one pixel each. With
    /// `confidence_band_m`, each pixel ends up with the most confident surfel
    /// within that depth of the nearest one instead of the nearest.
    pub fn render(
        &mut self,
        map: &SurfelMap,
        ranges: &[Range<usize>],
        camera_from_world: &RigidF32,
        k: &Intrinsics,
        confidence_band_m: Option<f32>,
        include: impl Fn(usize) -> bool + Sync,
    ) {
        self.cells
            .par_iter()
            .for_each(|c| c.store(EMPTY, Ordering::Relaxed));
        if self.projected.len() < map.len() {
            self.projected
                .resize_with(map.len(), || AtomicU64::new(NOT_PROJECTED));
        }
        let (cells, projected) = (&self.cells, &self.projected);
        let include = &include;
        for_each_in(ranges, |i| {
            let entry = if include(i) {
                pixel_of(k, camera_from_world.point(map.positions[i]))
            } else {
                None
            };
            let value = entry.map_or(NOT_PROJECTED, |(z, cell)| {
                let depth_bits = u64::from(z.to_bits()) << 32;
                cells[cell].fetch_min(depth_bits | i as u64, Ordering::Relaxed);
                depth_bits | cell as u64
            });
            projected[i].store(value, Ordering::Relaxed);
        });
        let Some(band) = confidence_band_m else {
            return;
        };
        if self.confident.len() != self.cells.len() {
            self.confident = (0..self.cells.len()).map(|_| AtomicU64::new(0)).collect();
        }
        self.confident
            .par_iter()
            .for_each(|c| c.store(0, Ordering::Relaxed));
        let confident = &self.confident;
        for_each_in(ranges, |i| {
            let entry = projected[i].load(Ordering::Relaxed);
            if entry == NOT_PROJECTED {
                return;
            }
            let z = f32::from_bits((entry >> 32) as u32);
            let cell = (entry & 0xffff_ffff) as usize;
            let nearest = f32::from_bits((cells[cell].load(Ordering::Relaxed) >> 32) as u32);
            if z <= nearest + band {
                // Confidences are positive, so their bit patterns order like the values.
                let key = (u64::from(map.confidences[i].max(0.0).to_bits()) << 32) | i as u64;
                confident[cell].fetch_max(key, Ordering::Relaxed);
            }
        });
        // Publish the confident choice as the cell's surfel (depth bits are not used after this).
        self.cells
            .par_iter()
            .zip(self.confident.par_iter())
            .for_each(|(c, f)| {
                if c.load(Ordering::Relaxed) != EMPTY {
                    c.store(f.load(Ordering::Relaxed) & 0xffff_ffff, Ordering::Relaxed);
                }
            });
    }

    /// The surfel index stored in cell (x, y), if any.
    #[inline]
    #[must_use]
    pub fn surfel_at(&self, x: usize, y: usize) -> Option<usize> {
        let key = self.cells.get(y * self.width + x)?.load(Ordering::Relaxed);
        (key != EMPTY).then_some((key & 0xffff_ffff) as usize)
    }
}
