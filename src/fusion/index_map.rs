//! Index map: the surfels of the map projected into a camera, nearest first.
//!
//! At `supersampling = 4` this is Keller et al.'s 4x4 super-sampled index map
//! used for data association (up to 16 candidate surfels per input pixel); at
//! `supersampling = 1` it is the z-buffer behind the model prediction. Each
//! cell holds `(depth bits << 32) | surfel index`, so an atomic `fetch_min`
//! keeps the nearest surfel while all surfels are splatted in parallel.
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

/// Nearest-surfel buffer of a camera view, `supersampling` cells per pixel side.
#[derive(Debug, Default)]
pub struct IndexMap {
    /// Cells per pixel along each axis.
    pub supersampling: usize,
    /// Width in cells.
    pub width: usize,
    /// Height in cells.
    pub height: usize,
    cells: Vec<AtomicU64>,
    confident: Vec<AtomicU64>,
}

/// Depth and cell index of surfel `i`'s centre in the view, or `None` if not visible.
#[inline]
fn cell_of(
    map: &SurfelMap,
    i: usize,
    camera_from_world: &RigidF32,
    k: &Intrinsics,
    s: f32,
    (w, h): (usize, usize),
) -> Option<(f32, usize)> {
    let p = camera_from_world.point(map.positions[i]);
    if p.z <= 0.0 {
        return None;
    }
    let px = k.project(p);
    let cu = ((px.x + 0.5) * s).floor();
    let cv = ((px.y + 0.5) * s).floor();
    if !(cu >= 0.0 && cv >= 0.0 && cu < w as f32 && cv < h as f32) {
        return None;
    }
    Some((p.z, cv as usize * w + cu as usize))
}

impl IndexMap {
    /// Allocates (or reuses) the buffer for an image of `k`'s size.
    pub fn resize(&mut self, k: &Intrinsics, supersampling: usize) {
        self.supersampling = supersampling.max(1);
        self.width = k.width * self.supersampling;
        self.height = k.height * self.supersampling;
        let n = self.width * self.height;
        if self.cells.len() != n {
            self.cells = (0..n).map(|_| AtomicU64::new(EMPTY)).collect();
        }
    }

    /// Projects the centres of the surfels selected by `include` into the view
    /// `camera_from_world`, one cell each. With `confidence_band_m`, each cell
    /// ends up with the most confident surfel within that depth of the
    /// nearest one instead of the nearest.
    pub fn render(
        &mut self,
        map: &SurfelMap,
        camera_from_world: &RigidF32,
        k: &Intrinsics,
        confidence_band_m: Option<f32>,
        include: impl Fn(usize) -> bool + Sync,
    ) {
        self.cells
            .par_iter()
            .for_each(|c| c.store(EMPTY, Ordering::Relaxed));
        let s = self.supersampling as f32;
        let size = (self.width, self.height);
        let cells = &self.cells;
        (0..map.len()).into_par_iter().for_each(|i| {
            if !include(i) {
                return;
            }
            if let Some((z, cell)) = cell_of(map, i, camera_from_world, k, s, size) {
                cells[cell].fetch_min((u64::from(z.to_bits()) << 32) | i as u64, Ordering::Relaxed);
            }
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
        (0..map.len()).into_par_iter().for_each(|i| {
            if !include(i) {
                return;
            }
            let Some((z, cell)) = cell_of(map, i, camera_from_world, k, s, size) else {
                return;
            };
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
