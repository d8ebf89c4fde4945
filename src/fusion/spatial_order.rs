//! Spatial ordering of settled surfels, so that map blocks are compact in
//! space and the view tests of `chunk_bounds` can skip them.
//!
//! Surfels are appended in the pixel order of the frame that added them. On a
//! first view that is coherent (a block is a band of image rows), but once
//! the scene is mapped each frame adds a few thousand surfels scattered over
//! the image, and a block of them spans the whole view: its box then passes
//! every test and the map is visited whole (`docs/performance.md#spatial-order`).
//! Sorting the surfels that settle at each cleanup along a Morton (Z-order)
//! curve of their positions makes consecutive surfels neighbours in space;
//! merging the sorted runs now and then (see [`SpatialOrder`]) keeps blocks
//! compact as the map grows.

use super::surfel_map::ReorderScratch;
use super::SurfelMap;
use glam::Vec3;
use std::ops::Range;

/// Longest sorted run, surfels: merging stops there, which bounds the
/// buffers a sort needs (40 bytes per surfel of the run, at most 10.5 MB)
/// while blocks stay compact (a run spans the scene in 512 blocks or
/// more). Capped at 2^17 instead, fusion and prediction took about 1 ms
/// more late in a 1500-frame TUM fr3/teddy run.
const MAX_RUN: usize = 1 << 18;

/// Edge of the finest Morton cell, metres.
const CELL_M: f32 = 0.01;

/// Cells per axis on each side of the world origin (21 bits per axis).
const HALF_SPAN: i32 = 1 << 20;

/// The sorted runs that tile the settled part of the map, and reusable
/// buffers for sorting.
///
/// Sorting only the surfels that settle at one cleanup (a few thousand,
/// spread over the whole view) gives blocks that each span a twentieth of
/// the scene; re-sorting the whole settled part at every cleanup costs
/// O(n log n) each time. So, as in a log-structured merge, each cleanup's
/// surfels form a new sorted run, and the last two runs are sorted together
/// while the newer is at least half as long as the older: every surfel is
/// re-sorted O(log n) times in all, and most of the map lies in a few long
/// runs whose blocks are compact. Runs stop merging at `MAX_RUN` surfels,
/// which bounds the sort's buffers (`docs/performance.md#spatial-order`).
#[derive(Debug, Default)]
pub struct SpatialOrder {
    keys: Vec<(u64, u32)>,
    /// Sorted runs, in index order; the last one ends where the settled
    /// surfels end.
    runs: Vec<Range<usize>>,
    scratch: ReorderScratch,
}

impl SpatialOrder {
    /// Forgets the sorted runs (for an emptied map), keeping the buffers.
    pub fn clear(&mut self) {
        self.runs.clear();
        self.keys.clear();
    }

    /// The sorted runs, in index order (for saving a session: the next
    /// cleanups merge and re-sort them).
    #[must_use]
    pub fn runs(&self) -> &[Range<usize>] {
        &self.runs
    }

    /// Restores runs as [`Self::runs`] gave them for a map of `len`
    /// surfels; refuses runs that overlap, are out of order or empty, or
    /// reach past the map.
    pub fn restore_runs(&mut self, runs: Vec<Range<usize>>, len: usize) -> Result<(), String> {
        let mut end = 0;
        for r in &runs {
            if r.start < end || r.end <= r.start || r.end > len {
                return Err(format!(
                    "sorted run {r:?} does not follow {end} within {len} surfels"
                ));
            }
            end = r.end;
        }
        self.runs = runs;
        self.keys.clear();
        Ok(())
    }

    /// Forgets the runs if they reach past a map of `len` surfels: they were
    /// made for another map (emptied or replaced without [`SpatialOrder::clear`])
    /// and would index surfels that are gone.
    pub fn forget_beyond(&mut self, len: usize) {
        if self.runs.last().is_some_and(|r| r.end > len) {
            self.runs.clear();
        }
    }

    /// Makes room for sorting the longest run `map` can hold now, so that
    /// sorting allocates only when the map itself grew (its memory stays
    /// flat once it is full: tests/node/long_run.test.mjs).
    pub fn reserve_for(&mut self, map: &SurfelMap) {
        let longest = map.capacity().min(MAX_RUN);
        if self.keys.capacity() < longest {
            self.keys.reserve(longest - self.keys.len());
            self.scratch.reserve(longest);
        }
    }

    /// Moves the runs to where they will be once the surfels from `start`
    /// on for which `removed(i)` is true are removed (order preserved).
    /// Call before the removal.
    pub fn before_removal(&mut self, start: usize, removed: impl Fn(usize) -> bool) {
        let mut gone = 0;
        let mut counted = start;
        for run in &mut self.runs {
            let shift_start = gone;
            if run.end > counted {
                gone += (counted.max(run.start)..run.end)
                    .filter(|&i| removed(i))
                    .count();
                counted = run.end;
            }
            *run = run.start - shift_start.min(run.start)..run.end - gone.min(run.end);
        }
        self.runs.retain(|r| !r.is_empty());
    }

    /// Adds the surfels `settled..now_settled`, which settled since the
    /// last call, as a new sorted run and merges runs as described on the
    /// type; the re-sorted range is marked changed and its boxes rebuilt.
    pub fn settle(&mut self, map: &mut SurfelMap, settled: usize, now_settled: usize) {
        let now_settled = now_settled.min(map.len());
        let mut from = settled;
        if self.runs.last().map_or(0, |r| r.end) != settled || settled > now_settled {
            // The map was cleared or changed elsewhere: start again.
            self.runs.clear();
            from = 0;
        }
        for start in (from..now_settled).step_by(MAX_RUN) {
            self.runs.push(start..(start + MAX_RUN).min(now_settled));
            while let [.., older, newer] = self.runs.as_slice() {
                if newer.len() * 2 < older.len() || older.len() + newer.len() > MAX_RUN {
                    break;
                }
                let merged = older.start..newer.end;
                self.runs.truncate(self.runs.len() - 2);
                self.runs.push(merged);
            }
            if let Some(last) = self.runs.last().cloned() {
                self.sort(map, last);
            }
        }
    }

    /// Reorders the surfels of `range` along the Morton curve of their
    /// positions (world frame). Marks the range changed and rebuilds the
    /// chunk boxes from its start.
    pub fn sort(&mut self, map: &mut SurfelMap, range: Range<usize>) {
        let range = range.start..range.end.min(map.len());
        if range.len() < 2 {
            return;
        }
        self.keys.clear();
        self.keys.extend(
            map.positions[range.clone()]
                .iter()
                .enumerate()
                .map(|(i, &p)| (morton_key(p), i as u32)),
        );
        self.keys.sort_unstable();
        let keys = &self.keys;
        map.reorder(
            range.start,
            range.len(),
            |i| keys[i].1 as usize,
            &mut self.scratch,
        );
        map.mark_changed(range.start);
        map.mark_changed(range.end - 1);
        map.rebuild_bounds_from(range.start);
    }
}

/// Z-order key of a world position quantised to `CELL_M` cells.
#[must_use]
fn morton_key(p: Vec3) -> u64 {
    // `as` saturates (NaN gives 0), so any input maps to some cell.
    let cell = |x: f32| {
        ((x / CELL_M) as i32)
            .saturating_add(HALF_SPAN)
            .clamp(0, 2 * HALF_SPAN - 1) as u32
    };
    spread_bits(cell(p.x)) | spread_bits(cell(p.y)) << 1 | spread_bits(cell(p.z)) << 2
}

/// Spreads the low 21 bits of `x` to every third bit of the result.
#[must_use]
fn spread_bits(x: u32) -> u64 {
    let mut x = u64::from(x) & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_bits_puts_each_bit_three_apart() {
        for b in 0..21 {
            assert_eq!(spread_bits(1 << b), 1 << (3 * b));
        }
        assert_eq!(spread_bits(u32::MAX), 0x1249_2492_4924_9249);
    }

    /// A map of `n` surfels scattered over a 2 m cube (a fixed LCG), with
    /// `first_seen` = creation index.
    fn scattered(n: u32) -> SurfelMap {
        let mut map = SurfelMap::default();
        let mut state = 12345u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1 << 24) as f32 * 2.0
        };
        for i in 0..n {
            let p = Vec3::new(next(), next(), next());
            map.push(p, Vec3::Z, [0; 4], 0.01, 10.0, i);
        }
        map
    }

    /// Checks that `order`'s runs tile `0..settled` and are each sorted.
    fn assert_sorted_runs(order: &SpatialOrder, map: &SurfelMap, settled: usize) {
        let mut end = 0;
        for run in &order.runs {
            assert_eq!(run.start, end, "runs {:?}", order.runs);
            let keys: Vec<u64> = map.positions[run.clone()]
                .iter()
                .map(|&p| morton_key(p))
                .collect();
            assert!(keys.windows(2).all(|w| w[0] <= w[1]), "run {run:?}");
            end = run.end;
        }
        assert_eq!(end, settled);
    }

    #[test]
    fn each_cleanup_adds_a_run_and_runs_merge_when_the_newer_is_half_as_long() {
        let mut map = scattered(5000);
        let mut order = SpatialOrder::default();
        let mut settled = 0;
        for now_settled in (100..=5000).step_by(100) {
            order.settle(&mut map, settled, now_settled);
            settled = now_settled;
            assert_sorted_runs(&order, &map, settled);
            // Each run is more than twice as long as the next: O(log n) runs.
            for w in order.runs.windows(2) {
                assert!(w[1].len() * 2 < w[0].len(), "runs {:?}", order.runs);
            }
        }
        assert!(order.runs.len() <= 6, "runs {:?}", order.runs);
        let mut seen = map.first_seen.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..5000).collect::<Vec<_>>());
    }

    #[test]
    fn runs_stop_merging_at_the_longest_run() {
        let n = 3 * MAX_RUN + 5000;
        let mut map = scattered(n as u32);
        let mut order = SpatialOrder::default();
        let mut settled = 0;
        for now_settled in (20_000..n).step_by(20_000).chain([n]) {
            order.settle(&mut map, settled, now_settled);
            settled = now_settled;
            assert!(
                order.runs.iter().all(|r| r.len() <= MAX_RUN),
                "runs {:?}",
                order.runs
            );
        }
        assert_sorted_runs(&order, &map, n);
        assert!(order.runs.len() >= 3, "runs {:?}", order.runs);
    }

    #[test]
    fn removing_surfels_moves_the_runs_with_the_surfels_they_hold() {
        let mut map = scattered(3000);
        let mut order = SpatialOrder::default();
        let mut settled = 0;
        for now_settled in [2000, 2600, 2800] {
            order.settle(&mut map, settled, now_settled);
            settled = now_settled;
        }
        assert_eq!(order.runs.len(), 3, "runs {:?}", order.runs);
        // Remove every seventh surfel from index 1000 on, in every run and
        // in the unsettled tail.
        let removed = |map: &SurfelMap, i: usize| i >= 1000 && map.first_seen[i] % 7 == 0;
        let gone_before = |end: usize| (1000..end).filter(|&i| removed(&map, i)).count();
        let expected: Vec<usize> = order
            .runs
            .iter()
            .map(|r| r.end - gone_before(r.end))
            .collect();
        order.before_removal(1000, |i| removed(&map, i));
        let marked: Vec<bool> = (0..map.len()).map(|i| removed(&map, i)).collect();
        map.retain_from(1000, |_, i| !marked[i]);
        let ends: Vec<usize> = order.runs.iter().map(|r| r.end).collect();
        assert_eq!(ends, expected);
        let settled = expected[2];
        assert_sorted_runs(&order, &map, settled);
        // The next cleanup continues from the moved runs instead of starting again.
        order.settle(&mut map, settled, settled + 100);
        assert_eq!(order.runs.first(), Some(&(0..expected[0])));
        assert_sorted_runs(&order, &map, settled + 100);
    }

    #[test]
    fn sorting_groups_neighbours_and_keeps_every_surfel() {
        let mut map = SurfelMap::default();
        // Two clusters 1 m apart, interleaved in creation order.
        for i in 0..200 {
            let x = if i % 2 == 0 { 0.0 } else { 1.0 };
            let p = Vec3::new(x + 0.001 * (i / 2) as f32, 0.2, 1.0);
            map.push(p, Vec3::Z, [i as u8, 0, 0, 255], 0.01, i as f32, i);
        }
        let before: Vec<(u32, f32)> = (0..200)
            .map(|i| (map.first_seen[i], map.confidences[i]))
            .collect();
        let _ = map.take_changed_range();
        // Leave the first 10 surfels where they are.
        SpatialOrder::default().sort(&mut map, 10..200);
        assert_eq!(map.len(), 200);
        for i in 0..10 {
            assert_eq!(map.first_seen[i], i as u32);
        }
        // Each surfel keeps all its attributes together.
        for i in 0..200 {
            let f = map.first_seen[i] as usize;
            assert_eq!(map.confidences[i], before[f].1);
            assert_eq!(map.colours[i][0], f as u8);
        }
        let mut seen: Vec<u32> = map.first_seen.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..200).collect::<Vec<_>>());
        // After the fixed prefix, the clusters are contiguous: one switch.
        let switches = map.positions[10..]
            .windows(2)
            .filter(|w| (w[0].x < 0.5) != (w[1].x < 0.5))
            .count();
        assert_eq!(switches, 1);
        assert_eq!(map.take_changed_range(), 10..200);
    }
}
