//! Surfaces mapped twice: a surfel that became stable recently and lies on
//! an older stable surfel (within [`COINCIDE_M`], normals within the
//! fusion's normal gate) is merged into the older one, which takes the
//! later `last_seen`. Fusion associates a measurement only with the active
//! surfels whose centre lands on its pixel, so a return to a place whose
//! surfels went inactive (or whose centres now fall between pixels) lays a
//! second copy beside the first (`docs/performance.md#revisit-growth`).

use super::{FusionConfig, SurfelMap};
use glam::{IVec3, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::Range;

/// Largest distance between two surfels taken for one surface, metres.
pub const COINCIDE_M: f32 = 0.01;

/// Merges the copies due at frame `now` (see
/// [`FusionConfig::merge_copies_after_frames`]): every stable surfel
/// created in the cleanup span that ends `merge_copies_after_frames` before
/// `now` is merged into the nearest older, inactive, stable surfel within
/// [`COINCIDE_M`] with a normal within the fusion's gate, which takes its
/// `last_seen`. Returns how many were merged (marked absorbed, removed at
/// the next cleanup).
pub fn merge_copies(map: &mut SurfelMap, config: &FusionConfig, now: u32) -> usize {
    let delay = config.merge_copies_after_frames;
    if delay == 0 || now < delay {
        return 0;
    }
    // Every surfel still in the map and older than the unstable age was
    // stable at a cleanup, so the span covers each copy more than once.
    let young_to = now - delay;
    let young_from = young_to
        .saturating_sub(3 * config.cleanup_interval_frames.max(1) + config.unstable_max_age);
    let active_from = config.active_at(now).start;
    let stable = config.stable_confidence;
    // Nothing inactive (a run shorter than the window): no work, and no
    // allocation that would raise the wasm memory's high-water mark.
    let n = map.common_len();
    let (positions, normals) = (map.positions(), map.normals());
    let (first_seen, last_seen, confidences) =
        (map.first_seen(), map.last_seen(), map.confidences());
    if !(0..n).any(|b| last_seen[b] < active_from && confidences[b] >= stable) {
        return 0;
    }
    let young: Vec<u32> = (0..n)
        .filter(|&i| (young_from..young_to).contains(&first_seen[i]) && confidences[i] >= stable)
        .map(|i| i as u32)
        .collect();
    if young.is_empty() {
        return 0;
    }
    let cell = |p: Vec3| (p / COINCIDE_M).floor().as_ivec3();
    // The young surfels sorted by cell, and each cell's run of them.
    let mut by_cell: Vec<([i32; 3], u32)> = young
        .iter()
        .map(|&j| (cell(positions[j as usize]).to_array(), j))
        .collect();
    by_cell.sort_unstable();
    let mut grid: HashMap<IVec3, Range<usize>, BuildHasherDefault<CellHasher>> =
        HashMap::with_capacity_and_hasher(by_cell.len(), BuildHasherDefault::default());
    let mut near_young = CellFilter::new();
    let mut start = 0;
    for run in by_cell.chunk_by(|a, b| a.0 == b.0) {
        let c = IVec3::from_array(run[0].0);
        grid.insert(c, start..start + run.len());
        near_young.mark(c);
        start += run.len();
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &j in &young {
        let p = positions[j as usize];
        lo = lo.min(p);
        hi = hi.max(p);
    }
    lo -= Vec3::splat(COINCIDE_M);
    hi += Vec3::splat(COINCIDE_M);
    let cos_gate = libm::cosf(config.normal_gate_deg.to_radians());
    // (young, old, distance) for every coinciding pair, found from the old side.
    let mut pairs: Vec<(u32, u32, f32)> = (0..n)
        .into_par_iter()
        .filter(|&b| {
            first_seen[b] < young_from
                && last_seen[b] < active_from
                && confidences[b] >= stable
                && positions[b].cmpge(lo).all()
                && positions[b].cmple(hi).all()
                && near_young.may_hold(cell(positions[b]))
        })
        .flat_map_iter(|b| {
            let p = positions[b];
            let c = cell(p);
            let mut found = Vec::new();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(js) = grid.get(&c.saturating_add(IVec3::new(dx, dy, dz))) else {
                            continue;
                        };
                        for &(_, j) in &by_cell[js.clone()] {
                            let d = positions[j as usize].distance(p);
                            if d < COINCIDE_M && normals[j as usize].dot(normals[b]) >= cos_gate {
                                found.push((j, b as u32, d));
                            }
                        }
                    }
                }
            }
            found
        })
        .collect();
    // The old surfel's index breaks ties of distance: the pair kept never
    // depends on the order the search found them in.
    pairs.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.2.total_cmp(&b.2)).then(a.1.cmp(&b.1)));
    pairs.dedup_by_key(|p| p.0);
    let mut merged = 0;
    for (j, b, _) in pairs {
        let (j, b) = (j as usize, b as usize);
        if map.confidences()[b] < 0.0 || map.confidences()[j] < 0.0 {
            continue;
        }
        let seen = map.last_seen()[j];
        map.touch(b, seen);
        map.absorb(j);
        merged += 1;
    }
    merged
}

/// Hasher of grid cells: a multiply-rotate over their three coordinates.
/// std's default (SipHash) made building the grid of ~100 k young cells
/// and looking cells up the larger part of the cost; no iteration order of
/// the grid reaches a result (the pairs are sorted).
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u32(u32::from(b));
        }
    }

    fn write_u32(&mut self, x: u32) {
        self.0 = (self.0.rotate_left(5) ^ u64::from(x)).wrapping_mul(0x517C_C1B7_2722_0A95);
    }

    fn write_i32(&mut self, x: i32) {
        self.write_u32(x as u32);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

/// Bits of [`CellFilter`] (128 KiB, fits a core's cache).
const FILTER_BITS: usize = 1 << 20;

/// Cells of the filter, per axis: `2^FILTER_SHIFT` grid cells.
const FILTER_SHIFT: u32 = 2;

/// Which coarse cells (4 x 4 x 4 grid cells) hold a young surfel, as a bit
/// per hashed coarse cell: a false answer is certain, a true one may be a
/// collision. Most old surfels are nowhere near a young one, and a few bit
/// tests spare them the 27 cell look-ups of the grid (those grew with the
/// map: 150-270 ms a cleanup late in the 500-frame 7-Scenes kitchen,
/// `docs/performance.md#merge-copies-filter`). Only skips work: the same
/// pairs are found.
struct CellFilter {
    bits: Vec<u64>,
}

impl CellFilter {
    fn new() -> Self {
        Self {
            bits: vec![0; FILTER_BITS / 64],
        }
    }

    /// Bit of coarse cell `c` (a multiplicative hash of its coordinates).
    fn slot(c: IVec3) -> usize {
        let h = (c.x as u32).wrapping_mul(0x9E37_79B1)
            ^ (c.y as u32).wrapping_mul(0x85EB_CA77)
            ^ (c.z as u32).wrapping_mul(0xC2B2_AE3D);
        (h.wrapping_mul(0x27D4_EB2F) >> (32 - FILTER_BITS.trailing_zeros())) as usize
    }

    /// Marks the coarse cell of grid cell `c`.
    fn mark(&mut self, c: IVec3) {
        let s = Self::slot(c >> FILTER_SHIFT);
        self.bits[s / 64] |= 1 << (s % 64);
    }

    /// False only when no marked grid cell is among the 27 around (and
    /// including) `c`, neighbours taken as `c.saturating_add(d)` like the
    /// grid's look-ups: those fall in at most two coarse cells per axis.
    fn may_hold(&self, c: IVec3) -> bool {
        let lo = c.saturating_add(IVec3::NEG_ONE) >> FILTER_SHIFT;
        let hi = c.saturating_add(IVec3::ONE) >> FILTER_SHIFT;
        (0..8).any(|corner| {
            let coarse = IVec3::new(
                if corner & 1 == 0 { lo.x } else { hi.x },
                if corner & 2 == 0 { lo.y } else { hi.y },
                if corner & 4 == 0 { lo.z } else { hi.z },
            );
            let s = Self::slot(coarse);
            self.bits[s / 64] & (1 << (s % 64)) != 0
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cleanup frame at which copies created at frame 300 are due.
    fn due(config: &FusionConfig) -> u32 {
        300 + config.merge_copies_after_frames + config.cleanup_interval_frames
    }

    /// An old surfel (frame 0, so inactive at [`due`]) and a copy made at
    /// frame 300, `offset` beside it with normal `copy_normal`.
    fn old_and_copy(offset: Vec3, copy_normal: Vec3) -> SurfelMap {
        let mut map = SurfelMap::default();
        map.push(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, [0; 4], 0.005, 20.0, 0);
        map.push(
            Vec3::new(0.0, 0.0, 2.0) + offset,
            copy_normal,
            [0; 4],
            0.005,
            20.0,
            300,
        );
        map
    }

    #[test]
    fn a_copy_on_an_inactive_surfel_is_merged_into_it_and_wakes_it() {
        let config = FusionConfig::default();
        let now = due(&config);
        let mut map = old_and_copy(Vec3::new(0.004, 0.0, 0.003), Vec3::Z);
        assert_eq!(merge_copies(&mut map, &config, now), 1);
        assert!(map.confidences()[1] < 0.0, "the copy is absorbed");
        assert_eq!(map.last_seen()[0], 300, "the old surfel is active again");
        // Its geometry stays where it was.
        assert_eq!(map.positions()[0], Vec3::new(0.0, 0.0, 2.0));
    }

    #[test]
    fn far_turned_active_or_not_yet_due_copies_stay() {
        let config = FusionConfig::default();
        let now = due(&config);
        let mut far = old_and_copy(Vec3::new(0.02, 0.0, 0.0), Vec3::Z);
        assert_eq!(merge_copies(&mut far, &config, now), 0);
        let mut turned = old_and_copy(Vec3::ZERO, Vec3::X);
        assert_eq!(merge_copies(&mut turned, &config, now), 0);
        let mut early = old_and_copy(Vec3::ZERO, Vec3::Z);
        assert_eq!(merge_copies(&mut early, &config, 310), 0);
        // An old surfel still active is fusion's to merge with, not ours.
        let mut active = old_and_copy(Vec3::ZERO, Vec3::Z);
        active.touch(0, 250);
        assert_eq!(merge_copies(&mut active, &config, now), 0);
        let off = FusionConfig {
            merge_copies_after_frames: 0,
            ..config
        };
        let mut never = old_and_copy(Vec3::ZERO, Vec3::Z);
        assert_eq!(merge_copies(&mut never, &off, now), 0);
    }

    #[test]
    fn a_copy_across_the_filters_coarse_cells_is_still_found() {
        let config = FusionConfig::default();
        let now = due(&config);
        // 4 cm coarse cells: the old surfel and its copy lie on either side
        // of a coarse boundary on every axis.
        let mut map = SurfelMap::default();
        let old = Vec3::new(0.0395, -0.0005, 1.9995);
        map.push(old, Vec3::Z, [0; 4], 0.005, 20.0, 0);
        map.push(
            Vec3::new(0.0402, 0.0003, 2.0003),
            Vec3::Z,
            [0; 4],
            0.005,
            20.0,
            300,
        );
        assert_eq!(merge_copies(&mut map, &config, now), 1);
        assert!(map.confidences()[1] < 0.0, "the copy is absorbed");
        assert_eq!(map.positions()[0], old);
    }

    #[test]
    fn the_cell_filter_holds_every_neighbour_of_a_marked_cell() {
        let mut filter = CellFilter::new();
        let marked = [IVec3::new(3, -7, 250), IVec3::new(-1, 0, 0), IVec3::MAX];
        for &c in &marked {
            filter.mark(c);
        }
        for &c in &marked {
            for d in (0..27).map(|i| IVec3::new(i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1)) {
                assert!(filter.may_hold(c.saturating_add(d)), "{c} + {d}");
            }
        }
        // Far from every marked cell, most cells are ruled out.
        let far = (0..1000)
            .filter(|&i| filter.may_hold(IVec3::new(1000 + 5 * i, 40, -90)))
            .count();
        assert!(far < 10, "{far} of 1000 far cells pass");
    }
}
