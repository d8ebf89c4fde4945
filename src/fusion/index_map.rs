//! Index map: which surfel the model prediction shows at each pixel. The
//! surfel centres are projected in parallel, one pixel each, and each pixel
//! keeps with an atomic `fetch_max` the most confident surfel lying at most
//! a depth band behind the point the camera measured there from the same
//! pose; pixels without a measurement show nothing. Only the blocks of the
//! map inside the view frustum are visited.
//!
//! The measurement, not the nearest projected surfel, tells what is hidden:
//! a stale or noisy surfel in front of the surface would otherwise hide the
//! surface's own surfels, and picking the nearest of several overlapping
//! noisy surfels picks the one whose noise pulls it towards the camera
//! (confidence is not correlated with that noise). Measurements:
//! `docs/performance.md#index-map`.

use crate::camera::{pixel_of, Intrinsics};
use crate::fusion::SurfelMap;
use crate::portable_math::at_least;
use crate::prefetch::prefetch;
use crate::se3::RigidF32;
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// Surfels projected and hinted together by [`IndexMap::render`].
const BATCH: usize = 32;

/// Chosen-surfel buffer of a camera view, one cell per pixel.
#[derive(Debug, Default)]
pub struct IndexMap {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Per pixel, `(confidence bits << 32) | (surfel index + 1)` of the
    /// chosen surfel, 0 when none.
    chosen: Vec<AtomicU64>,
}

impl IndexMap {
    /// Allocates (or reuses) the buffers for an image of `k`'s size.
    pub fn resize(&mut self, k: &Intrinsics) {
        self.width = k.width;
        self.height = k.height;
        let n = self.width * self.height;
        if self.chosen.len() != n {
            self.chosen = (0..n).map(|_| AtomicU64::new(0)).collect();
        }
    }

    /// Projects the centres of the surfels in `ranges` selected by `include`
    /// into the view `camera_from_world`, one pixel each; each pixel that
    /// `measured` (camera-frame points taken from this view, metres, `ZERO`
    /// where none) holds ends up with the most confident surfel lying at
    /// most `band_m` (metres) behind the measured point.
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &mut self,
        map: &SurfelMap,
        ranges: &[Range<usize>],
        camera_from_world: &RigidF32,
        k: &Intrinsics,
        measured: &[Vec3],
        band_m: f32,
        include: impl Fn(usize) -> bool + Sync,
    ) {
        // Writes through `&mut` are plain stores: an atomic store is a locked
        // exchange in threaded wasm, whose atomics are sequentially consistent.
        self.chosen.par_iter_mut().for_each(|c| *c.get_mut() = 0);
        let chosen = &self.chosen;
        // A batch of surfels is projected and the measured points and
        // cells at their pixels hinted to the caches before the batch is
        // tested (those reads are random and waited on memory).
        ranges.par_iter().for_each(|range| {
            let mut cells = [(0usize, 0.0f32, 0usize); BATCH];
            let mut start = range.start;
            while start < range.end {
                let end = (start + BATCH).min(range.end);
                let mut count = 0;
                for i in start..end {
                    if !include(i) {
                        continue;
                    }
                    let Some((z, cell)) = pixel_of(k, camera_from_world.point(map.positions[i]))
                    else {
                        continue;
                    };
                    prefetch(measured, cell);
                    prefetch(chosen, cell);
                    cells[count] = (i, z, cell);
                    count += 1;
                }
                for &(i, z, cell) in &cells[..count] {
                    let surface = measured.get(cell).map_or(0.0, |p| p.z);
                    if surface > 0.0 && z <= surface + band_m {
                        // Confidences are positive, so their bit patterns order like the values.
                        let key = (u64::from(at_least(map.confidences[i], 0.0).to_bits()) << 32)
                            | (i as u64 + 1);
                        raise_to(&chosen[cell], key);
                    }
                }
                start = end;
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

/// Raises `cell` to `key` if `key` is larger: an atomic maximum that
/// skips the locked read-modify-write (a compare-exchange loop on x86)
/// when a plain load already shows a key at least as large, as it does for
/// most candidates of a pixel seen before. The maximum does not depend on
/// the order the candidates arrive in.
#[inline]
pub(crate) fn raise_to(cell: &AtomicU64, key: u64) {
    if cell.load(Ordering::Relaxed) < key {
        cell.fetch_max(key, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raise_to_keeps_the_largest_key_whatever_the_order() {
        let keys: Vec<u64> = (0..1000u64).map(|i| (i * 7919) % 1009).collect();
        let largest = keys.iter().copied().max().unwrap_or(0);
        for reversed in [false, true] {
            let cell = AtomicU64::new(0);
            let mut order = keys.clone();
            if reversed {
                order.reverse();
            }
            order.par_iter().for_each(|&k| raise_to(&cell, k));
            assert_eq!(cell.load(Ordering::Relaxed), largest);
        }
        // A smaller key never lowers the cell.
        let cell = AtomicU64::new(50);
        raise_to(&cell, 10);
        assert_eq!(cell.load(Ordering::Relaxed), 50);
    }

    #[test]
    fn each_measured_pixel_shows_its_most_confident_surfel_not_hidden_by_the_measurement() {
        let k = Intrinsics::new(100.0, 100.0, 15.5, 11.5, 32, 24);
        // A wall measured at 2 m, except the right half of row 5.
        let measured: Vec<Vec3> = (0..k.pixel_count())
            .map(|i| {
                let (u, v) = (i % k.width, i / k.width);
                if v == 5 && u >= 16 {
                    Vec3::ZERO
                } else {
                    k.back_project(u as f32, v as f32, 2.0)
                }
            })
            .collect();
        let mut map = SurfelMap::default();
        let mut add = |(u, v): (usize, usize), depth: f32, confidence: f32| {
            let p = k.back_project(u as f32, v as f32, depth);
            map.push(p, Vec3::NEG_Z, [0; 4], 0.01, confidence, 0);
        };
        // Pixel (3, 3): on the wall, 3 cm behind it (within the 5 cm band)
        // and more confident, 10 cm behind it (hidden) and most confident.
        add((3, 3), 2.0, 6.0);
        add((3, 3), 2.03, 20.0);
        add((3, 3), 2.1, 50.0);
        // Pixel (4, 3): 20 cm in front of the wall, and on it.
        add((4, 3), 1.8, 30.0);
        add((4, 3), 2.0, 10.0);
        // Pixel (7, 3): hidden only.
        add((7, 3), 2.5, 90.0);
        // Pixel (20, 5): no measurement there.
        add((20, 5), 2.0, 40.0);
        let mut index = IndexMap::default();
        index.resize(&k);
        let t = RigidF32::from_affine(&glam::DAffine3::IDENTITY);
        let all = vec![Range {
            start: 0,
            end: map.len(),
        }];
        index.render(&map, &all, &t, &k, &measured, 0.05, |_| true);
        assert_eq!(index.surfel_at(3, 3), Some(1));
        assert_eq!(index.surfel_at(4, 3), Some(3));
        assert_eq!(index.surfel_at(7, 3), None);
        assert_eq!(index.surfel_at(20, 5), None);
        let shown = (0..k.height)
            .flat_map(|y| (0..k.width).map(move |x| (x, y)))
            .filter(|&(x, y)| index.surfel_at(x, y).is_some())
            .count();
        assert_eq!(shown, 2);
        // Excluded surfels are not shown.
        index.render(&map, &all, &t, &k, &measured, 0.05, |i| i != 1);
        assert_eq!(index.surfel_at(3, 3), Some(0));
    }
}
