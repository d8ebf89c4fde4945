//! Farthest measured depth per image tile, for skipping map blocks that lie
//! wholly behind what the camera measures.
//!
//! Fusion only pairs a surfel with the measurement at its pixel when their
//! depths differ by at most the depth gate, so a block whose box is farther
//! than every measurement it can project onto, plus the gate, has no
//! candidate: skipping it changes nothing. The same holds for the model
//! prediction, which shows at each pixel only surfels at most a band behind
//! the measured point (see `index_map`). On a revisit that is the far
//! side of objects and what they hide (about a fifth of the map on TUM
//! fr3/teddy).

use crate::camera::Intrinsics;
use crate::portable_math::at_least;
use crate::se3::RigidF32;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Tile edge, pixels.
const TILE: usize = 16;

/// Nearest box depth (metres) at which a box is projected; a box reaching
/// closer to the camera plane is kept without a test.
const MIN_PROJECT_DEPTH_M: f32 = 0.01;

/// Per tile of `TILE` x `TILE` pixels, the largest valid depth (metres),
/// or 0 when the tile has no valid measurement.
#[derive(Debug, Default)]
pub struct DepthTiles {
    columns: usize,
    rows: usize,
    far: Vec<f32>,
}

impl DepthTiles {
    /// Fills the tiles from per-pixel camera-frame `vertices` of a
    /// `width`-pixel-wide image (`z <= 0`: no measurement).
    pub fn build(&mut self, vertices: &[Vec3], width: usize) {
        let width = width.max(1);
        self.columns = width.div_ceil(TILE);
        self.rows = (vertices.len() / width).div_ceil(TILE);
        self.far.clear();
        self.far.resize(self.columns * self.rows, 0.0);
        self.far
            .par_chunks_mut(self.columns)
            .zip(vertices.par_chunks(TILE * width))
            .for_each(|(tiles, band)| {
                for row in band.chunks_exact(width) {
                    for (far, run) in tiles.iter_mut().zip(row.chunks(TILE)) {
                        // A compare and select: wasm's f32::max is a call (`portable_math`).
                        *far = run.iter().fold(*far, |m, p| at_least(p.z, m));
                    }
                }
            });
    }

    /// False when the world-frame box `[min, max]`, seen from
    /// `camera_from_world` through `k`, lies more than `gate_m` behind every
    /// measurement it projects onto, or projects outside the image: no
    /// surfel in it can pair with a measurement.
    #[must_use]
    pub fn may_reach(
        &self,
        k: &Intrinsics,
        camera_from_world: &RigidF32,
        (min, max): (Vec3, Vec3),
        gate_m: f32,
    ) -> bool {
        if self.far.is_empty() {
            // Never built (or an empty image): nothing to test against.
            return true;
        }
        let mut near = f32::INFINITY;
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for corner in 0..8 {
            let p = Vec3::new(
                if corner & 1 == 0 { min.x } else { max.x },
                if corner & 2 == 0 { min.y } else { max.y },
                if corner & 4 == 0 { min.z } else { max.z },
            );
            let q = camera_from_world.point(p);
            if q.z < MIN_PROJECT_DEPTH_M {
                return true;
            }
            near = near.min(q.z);
            let uv = k.project(q);
            lo = lo.min(uv);
            hi = hi.max(uv);
        }
        // A surfel's pixel is its projection rounded; one pixel of margin.
        let (u0, u1) = (lo.x - 1.0, hi.x + 1.0);
        let (v0, v1) = (lo.y - 1.0, hi.y + 1.0);
        let (w, h) = ((self.columns * TILE) as f32, (self.rows * TILE) as f32);
        if !(u1 >= 0.0 && v1 >= 0.0 && u0 < w && v0 < h) {
            return false;
        }
        // Truncation is floor for these non-negative values.
        let tile = |x: f32, count: usize| ((x.max(0.0) as usize) / TILE).min(count - 1);
        let (c0, c1) = (tile(u0, self.columns), tile(u1, self.columns));
        let (r0, r1) = (tile(v0, self.rows), tile(v1, self.rows));
        (r0..=r1).any(|r| {
            self.far[r * self.columns + c0..=r * self.columns + c1]
                .iter()
                .any(|&far| far > 0.0 && far + gate_m >= near)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DAffine3;

    #[test]
    fn keeps_boxes_near_the_measured_surface_and_skips_those_behind_or_outside() {
        let k = Intrinsics::new(100.0, 100.0, 31.5, 23.5, 64, 48);
        // A wall at 2 m over the left half of the image; no depth on the right.
        let vertices: Vec<Vec3> = (0..64 * 48)
            .map(|i| {
                if i % 64 < 32 {
                    Vec3::new(0.0, 0.0, 2.0)
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let mut tiles = DepthTiles::default();
        tiles.build(&vertices, 64);
        let t = RigidF32::from_affine(&DAffine3::IDENTITY);
        let cube = |x: f32, z: f32| {
            (
                Vec3::new(x - 0.05, -0.05, z - 0.05),
                Vec3::new(x + 0.05, 0.05, z + 0.05),
            )
        };
        let gate = 0.05;
        // Left of the optical axis: on the wall, in front of it, behind it.
        assert!(tiles.may_reach(&k, &t, cube(-0.4, 2.0), gate));
        assert!(tiles.may_reach(&k, &t, cube(-0.2, 1.0), gate));
        assert!(!tiles.may_reach(&k, &t, cube(-0.4, 3.0), gate));
        // Just beyond the gate is skipped, within it is kept.
        assert!(tiles.may_reach(&k, &t, cube(-0.4, 2.09), gate));
        assert!(!tiles.may_reach(&k, &t, cube(-0.4, 2.11), gate));
        // Right half: no measurement to pair with.
        assert!(!tiles.may_reach(&k, &t, cube(0.4, 2.0), gate));
        // Tiles never built keep every box.
        assert!(DepthTiles::default().may_reach(&k, &t, cube(-0.4, 3.0), gate));
        // Outside the image, and a box reaching the camera plane.
        assert!(!tiles.may_reach(&k, &t, cube(-5.0, 2.0), gate));
        assert!(tiles.may_reach(&k, &t, cube(-0.4, 0.0), gate));
    }
}
