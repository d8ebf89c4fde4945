//! Index map: the surfels of the map projected into a camera, nearest first.
//!
//! At `supersampling = 4` this is Keller et al.'s 4x4 super-sampled index map
//! used for data association (up to 16 candidate surfels per input pixel); at
//! `supersampling = 1` it is the z-buffer behind the model prediction. Each
//! cell holds `(depth bits << 32) | surfel index`, so an atomic `fetch_min`
//! keeps the nearest surfel while all surfels are splatted in parallel.

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

    /// Splats the surfels selected by `include` into the view `camera_from_world`.
    ///
    /// `splat` true covers the surfel's disk (radius projected to pixels, at most
    /// 2 px); false writes only the centre's cell.
    pub fn render(
        &mut self,
        map: &SurfelMap,
        camera_from_world: &RigidF32,
        k: &Intrinsics,
        splat: bool,
        include: impl Fn(usize) -> bool + Sync,
    ) {
        self.cells
            .par_iter()
            .for_each(|c| c.store(EMPTY, Ordering::Relaxed));
        let s = self.supersampling as f32;
        let (w, h) = (self.width as i64, self.height as i64);
        let cells = &self.cells;
        let focal = k.focal_abs();
        (0..map.len()).into_par_iter().for_each(|i| {
            if !include(i) {
                return;
            }
            let p = camera_from_world.point(map.positions[i]);
            if p.z <= 0.0 {
                return;
            }
            let px = k.project(p);
            let cu = ((px.x + 0.5) * s).floor();
            let cv = ((px.y + 0.5) * s).floor();
            if !(cu >= 0.0 && cv >= 0.0 && cu < w as f32 && cv < h as f32) {
                return;
            }
            let key = (u64::from(p.z.to_bits()) << 32) | i as u64;
            let (cu, cv) = (cu as i64, cv as i64);
            let reach = if splat {
                ((map.radii[i] * focal / p.z * s).min(2.0 * s) - 0.5).max(0.0) as i64
            } else {
                0
            };
            for y in (cv - reach).max(0)..=(cv + reach).min(h - 1) {
                for x in (cu - reach).max(0)..=(cu + reach).min(w - 1) {
                    cells[(y * w + x) as usize].fetch_min(key, Ordering::Relaxed);
                }
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
