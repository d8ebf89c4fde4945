//! The map's spatial index: an axis-aligned box (world frame, metres) around
//! each block of `BLOCK` consecutive surfels.
//!
//! Consecutive surfels lie close together (settled surfels are sorted in
//! space, see `spatial_order`; young ones were added from one viewpoint), so
//! box tests against the view skip whole blocks, and a frame's cost follows
//! what the camera sees rather than the size of the map. Boxes only grow
//! between rebuilds (merges move a surfel by at most the fusion depth gate),
//! so they stay conservative.

use glam::Vec3;
use std::ops::Range;

/// Surfels per chunk, the unit of parallel updates.
pub const CHUNK: usize = 4096;

/// Surfels per block, the unit of view tests. Smaller blocks have tighter
/// boxes but need more tests: on a full turn of the synthetic room fusion
/// visited 68 k surfels with 512 and 88 k with 4096 (the chunk size); on
/// TUM fr3/teddy, whose whole scene stays in view, 128, 256 and 512 cost the
/// same.
pub const BLOCK: usize = 512;

/// Blocks per chunk.
pub const BLOCKS_PER_CHUNK: usize = CHUNK / BLOCK;

/// Per-block bounding boxes of the surfel positions.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChunkBounds {
    min: Vec<Vec3>,
    max: Vec<Vec3>,
}

impl ChunkBounds {
    /// Forgets every box.
    pub fn clear(&mut self) {
        self.min.clear();
        self.max.clear();
    }

    /// Extends the box of surfel `i`'s block to hold `position`; blocks are
    /// created in order as `i` grows.
    #[inline]
    pub fn grow(&mut self, i: usize, position: Vec3) {
        let c = i / BLOCK;
        while self.min.len() <= c {
            self.min.push(Vec3::splat(f32::INFINITY));
            self.max.push(Vec3::splat(f32::NEG_INFINITY));
        }
        self.min[c] = self.min[c].min(position);
        self.max[c] = self.max[c].max(position);
    }

    /// Recomputes the boxes of every block from the one holding surfel `first`
    /// on, after the surfels from `first` on were moved or removed.
    pub fn rebuild_from(&mut self, positions: &[Vec3], first: usize) {
        let c0 = first / BLOCK;
        self.min.truncate(c0);
        self.max.truncate(c0);
        for (i, &p) in positions.iter().enumerate().skip(c0 * BLOCK) {
            self.grow(i, p);
        }
    }

    /// Number of blocks.
    #[must_use]
    pub fn len(&self) -> usize {
        self.min.len()
    }

    /// True when there is no block.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.is_empty()
    }

    /// Surfel index ranges of the blocks whose box `keep(min, max)` accepts,
    /// written into `out` (cleared first; its allocation is reused) in
    /// increasing order. Adjacent accepted blocks form one range, but no
    /// range crosses a `CHUNK` boundary.
    pub fn select(
        &self,
        surfels: usize,
        mut keep: impl FnMut(Vec3, Vec3) -> bool,
        out: &mut Vec<Range<usize>>,
    ) {
        out.clear();
        for (c, (&lo, &hi)) in self.min.iter().zip(&self.max).enumerate() {
            let range = c * BLOCK..((c + 1) * BLOCK).min(surfels);
            if range.is_empty() || !keep(lo, hi) {
                continue;
            }
            match out.last_mut() {
                Some(last) if last.end == range.start && range.start % CHUNK != 0 => {
                    last.end = range.end;
                }
                _ => out.push(range),
            }
        }
    }

    /// The ranges of `selected` (an output of `select`) inside chunk `chunk`.
    #[must_use]
    pub fn in_chunk(selected: &[Range<usize>], chunk: usize) -> &[Range<usize>] {
        let lo = selected.partition_point(|r| r.start < chunk * CHUNK);
        let hi = selected.partition_point(|r| r.start < (chunk + 1) * CHUNK);
        &selected[lo..hi]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_hold_their_surfels_and_rebuild_shrinks_them() {
        let positions: Vec<Vec3> = (0..2 * BLOCK + 10)
            .map(|i| Vec3::new(i as f32, 0.0, 1.0))
            .collect();
        let mut b = ChunkBounds::default();
        for (i, &p) in positions.iter().enumerate() {
            b.grow(i, p);
        }
        assert_eq!(b.len(), 3);
        let mut ranges = Vec::new();
        let middle = (BLOCK + BLOCK / 2) as f32;
        b.select(
            positions.len(),
            |lo, hi| lo.x <= middle && hi.x >= middle,
            &mut ranges,
        );
        assert_eq!(ranges, vec![BLOCK..2 * BLOCK]);
        b.rebuild_from(&positions[..BLOCK + 1], BLOCK);
        assert_eq!(b.len(), 2);
        b.select(BLOCK + 1, |_, hi| hi.x >= BLOCK as f32, &mut ranges);
        assert_eq!(ranges, vec![BLOCK..BLOCK + 1]);
    }

    #[test]
    fn adjacent_blocks_merge_within_a_chunk_only() {
        let n = CHUNK + 2 * BLOCK;
        let mut b = ChunkBounds::default();
        for i in 0..n {
            b.grow(i, Vec3::new(i as f32, 0.0, 1.0));
        }
        let mut ranges = Vec::new();
        // Every block but the second.
        b.select(
            n,
            |lo, _| !(BLOCK as f32..2.0 * BLOCK as f32).contains(&lo.x),
            &mut ranges,
        );
        assert_eq!(ranges, vec![0..BLOCK, 2 * BLOCK..CHUNK, CHUNK..n]);
        assert_eq!(ChunkBounds::in_chunk(&ranges, 0), &ranges[..2]);
        assert_eq!(ChunkBounds::in_chunk(&ranges, 1), &ranges[2..]);
        assert!(ChunkBounds::in_chunk(&ranges, 2).is_empty());
    }
}
