//! The map's spatial index: an axis-aligned box (world frame, metres) around
//! each block of `BLOCK` consecutive surfels.
//!
//! Consecutive surfels lie close together (settled surfels are sorted in
//! space, see `spatial_order`; young ones were added from one viewpoint), so
//! box tests against the view skip whole blocks, and a frame's cost follows
//! what the camera sees rather than the size of the map. Boxes only grow
//! between rebuilds (merges move a surfel by at most the fusion depth gate),
//! so they stay conservative.
//!
//! Each block also keeps the range of its surfels' `last_seen` frames, so
//! that fusion and prediction, which read only the recently updated
//! (active) surfels, skip whole blocks of inactive ones: per-frame cost
//! follows the active part of the map, not all of it. The newest frame of
//! a block is raised when one of its surfels is updated; the oldest is
//! exact only after a rebuild, and otherwise a lower bound, which is still
//! conservative for "may hold a surfel seen before frame f".

use crate::portable_math::{max_vec3, min_vec3};
use glam::Vec3;
use rayon::prelude::*;
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

/// Per-block bounding boxes of the surfel positions, and the range of
/// frames at which the block's surfels were last updated.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChunkBounds {
    min: Vec<Vec3>,
    max: Vec<Vec3>,
    /// Per block: no surfel of it was last updated after this frame.
    newest: Vec<u32>,
    /// Per block: no surfel of it was last updated before this frame.
    oldest: Vec<u32>,
}

/// One block of [`ChunkBounds`]: its box and its surfels' `last_seen` range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockBox {
    /// Smallest corner, world frame, metres (`+inf` for an empty box).
    pub min: Vec3,
    /// Largest corner, world frame, metres (`-inf` for an empty box).
    pub max: Vec3,
    /// No surfel of the block was last updated after this frame.
    pub newest: u32,
    /// No surfel of the block was last updated before this frame.
    pub oldest: u32,
}

impl ChunkBounds {
    /// Block `b` as it is (conservative, not rebuilt), for saving a session.
    #[must_use]
    pub fn block(&self, b: usize) -> Option<BlockBox> {
        Some(BlockBox {
            min: *self.min.get(b)?,
            max: *self.max.get(b)?,
            newest: *self.newest.get(b)?,
            oldest: *self.oldest.get(b)?,
        })
    }

    /// Appends a block as [`Self::block`] gave it (restoring a session).
    pub fn push_block(&mut self, block: BlockBox) {
        self.min.push(block.min);
        self.max.push(block.max);
        self.newest.push(block.newest);
        self.oldest.push(block.oldest);
    }

    /// Forgets every box.
    pub fn clear(&mut self) {
        self.min.clear();
        self.max.clear();
        self.newest.clear();
        self.oldest.clear();
    }

    /// Makes sure the block of surfel `i` exists (empty box, no frame);
    /// blocks are created in order as `i` grows.
    fn ensure(&mut self, i: usize) -> usize {
        let c = i / BLOCK;
        while self.min.len() <= c {
            self.min.push(Vec3::splat(f32::INFINITY));
            self.max.push(Vec3::splat(f32::NEG_INFINITY));
            self.newest.push(0);
            self.oldest.push(u32::MAX);
        }
        c
    }

    /// Extends the box of surfel `i`'s block to hold `position`.
    #[inline]
    pub fn grow(&mut self, i: usize, position: Vec3) {
        let c = self.ensure(i);
        self.min[c] = min_vec3(self.min[c], position);
        self.max[c] = max_vec3(self.max[c], position);
    }

    /// Records that surfel `i` was last updated at frame `frame` (a new
    /// surfel, or one merged with a measurement).
    #[inline]
    pub fn saw(&mut self, i: usize, frame: u32) {
        let c = self.ensure(i);
        self.newest[c] = self.newest[c].max(frame);
        self.oldest[c] = self.oldest[c].min(frame);
    }

    /// Extends the boxes and frame ranges of the blocks of the surfels
    /// `first..first + positions.len()` to hold `positions`, all updated at
    /// frame `frame`: [`Self::grow`] and [`Self::saw`] of each, a block at a time.
    pub fn grow_all(&mut self, first: usize, positions: &[Vec3], frame: u32) {
        let (mut i, mut rest) = (first, positions);
        while !rest.is_empty() {
            let (piece, tail) = rest.split_at((BLOCK - i % BLOCK).min(rest.len()));
            let c = self.ensure(i);
            (self.min[c], self.max[c]) = piece
                .iter()
                .fold((self.min[c], self.max[c]), |(lo, hi), &p| {
                    (min_vec3(lo, p), max_vec3(hi, p))
                });
            self.newest[c] = self.newest[c].max(frame);
            self.oldest[c] = self.oldest[c].min(frame);
            (i, rest) = (i + piece.len(), tail);
        }
    }

    /// Recomputes the boxes and frame ranges of every block from the one
    /// holding surfel `first` on, after the surfels from `first` on were
    /// moved or removed; `positions` and `last_seen` are the map's arrays
    /// (of one length). The blocks are summed up in parallel.
    pub fn rebuild_from(&mut self, positions: &[Vec3], last_seen: &[u32], first: usize) {
        let c0 = first / BLOCK;
        self.min.truncate(c0);
        self.max.truncate(c0);
        self.newest.truncate(c0);
        self.oldest.truncate(c0);
        if c0 > 0 {
            // The blocks before `first`'s are kept; they exist even if
            // no surfel ever grew the last of them.
            self.ensure(c0 * BLOCK - 1);
        }
        let start = (c0 * BLOCK).min(positions.len()).min(last_seen.len());
        let blocks: Vec<BlockBox> = positions[start..]
            .par_chunks(BLOCK)
            .zip(last_seen[start..].par_chunks(BLOCK))
            .map(|(positions, frames)| {
                let empty = BlockBox {
                    min: Vec3::splat(f32::INFINITY),
                    max: Vec3::splat(f32::NEG_INFINITY),
                    newest: 0,
                    oldest: u32::MAX,
                };
                positions
                    .iter()
                    .zip(frames)
                    .fold(empty, |b, (&p, &f)| BlockBox {
                        min: b.min.min(p),
                        max: b.max.max(p),
                        newest: b.newest.max(f),
                        oldest: b.oldest.min(f),
                    })
            })
            .collect();
        for b in blocks {
            self.min.push(b.min);
            self.max.push(b.max);
            self.newest.push(b.newest);
            self.oldest.push(b.oldest);
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

    /// Surfel index ranges of the blocks that may hold a surfel last
    /// updated at a frame in `seen` and whose box `keep(min, max)` accepts,
    /// written into `out` (cleared first; its allocation is reused) in
    /// increasing order. Adjacent accepted blocks form one range, but no
    /// range crosses a `CHUNK` boundary.
    pub fn select(
        &self,
        surfels: usize,
        seen: &Range<u32>,
        mut keep: impl FnMut(Vec3, Vec3) -> bool,
        out: &mut Vec<Range<usize>>,
    ) {
        out.clear();
        for (c, (&lo, &hi)) in self.min.iter().zip(&self.max).enumerate() {
            let range = c * BLOCK..((c + 1) * BLOCK).min(surfels);
            let in_time = self.newest.get(c).is_some_and(|&n| n >= seen.start)
                && self.oldest.get(c).is_some_and(|&o| o < seen.end);
            if range.is_empty() || !in_time || !keep(lo, hi) {
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

    const ALL: Range<u32> = 0..u32::MAX;

    #[test]
    fn boxes_hold_their_surfels_and_rebuild_shrinks_them() {
        let positions: Vec<Vec3> = (0..2 * BLOCK + 10)
            .map(|i| Vec3::new(i as f32, 0.0, 1.0))
            .collect();
        let seen: Vec<u32> = vec![0; positions.len()];
        let mut b = ChunkBounds::default();
        for (i, &p) in positions.iter().enumerate() {
            b.grow(i, p);
            b.saw(i, 0);
        }
        assert_eq!(b.len(), 3);
        let mut ranges = Vec::new();
        let middle = (BLOCK + BLOCK / 2) as f32;
        b.select(
            positions.len(),
            &ALL,
            |lo, hi| lo.x <= middle && hi.x >= middle,
            &mut ranges,
        );
        assert_eq!(ranges, vec![BLOCK..2 * BLOCK]);
        b.rebuild_from(&positions[..BLOCK + 1], &seen, BLOCK);
        assert_eq!(b.len(), 2);
        b.select(BLOCK + 1, &ALL, |_, hi| hi.x >= BLOCK as f32, &mut ranges);
        assert_eq!(ranges, vec![BLOCK..BLOCK + 1]);
    }

    #[test]
    fn adjacent_blocks_merge_within_a_chunk_only() {
        let n = CHUNK + 2 * BLOCK;
        let mut b = ChunkBounds::default();
        for i in 0..n {
            b.grow(i, Vec3::new(i as f32, 0.0, 1.0));
            b.saw(i, 0);
        }
        let mut ranges = Vec::new();
        // Every block but the second.
        b.select(
            n,
            &ALL,
            |lo, _| !(BLOCK as f32..2.0 * BLOCK as f32).contains(&lo.x),
            &mut ranges,
        );
        assert_eq!(ranges, vec![0..BLOCK, 2 * BLOCK..CHUNK, CHUNK..n]);
        assert_eq!(ChunkBounds::in_chunk(&ranges, 0), &ranges[..2]);
        assert_eq!(ChunkBounds::in_chunk(&ranges, 1), &ranges[2..]);
        assert!(ChunkBounds::in_chunk(&ranges, 2).is_empty());
    }

    #[test]
    fn blocks_are_selected_by_the_frames_their_surfels_were_last_updated() {
        // Block 0 seen at frames 0..=9, block 1 at 100, block 2 at 5 and 300.
        let n = 3 * BLOCK;
        let frame = |i: usize| match i / BLOCK {
            0 => (i % 10) as u32,
            1 => 100,
            _ => [5, 300][i % 2],
        };
        let mut b = ChunkBounds::default();
        for i in 0..n {
            b.grow(i, Vec3::ZERO);
            b.saw(i, frame(i));
        }
        let select = |b: &ChunkBounds, seen: Range<u32>| {
            let mut out: Vec<Range<usize>> = Vec::new();
            b.select(n, &seen, |_, _| true, &mut out);
            out
        };
        assert_eq!(select(&b, 50..u32::MAX), vec![BLOCK..n]);
        assert_eq!(select(&b, 200..u32::MAX), vec![2 * BLOCK..n]);
        assert_eq!(select(&b, 0..50), vec![0..BLOCK, 2 * BLOCK..n]);
        assert_eq!(select(&b, 301..u32::MAX), vec![]);
        // A merge raises the newest frame of its block.
        b.saw(3, 400);
        assert_eq!(select(&b, 301..u32::MAX), vec![0..BLOCK]);
        // A rebuild makes the ranges exact again.
        let positions = vec![Vec3::ZERO; n];
        let seen: Vec<u32> = (0..n).map(|i| frame(i).max(60)).collect();
        b.rebuild_from(&positions, &seen, 0);
        assert_eq!(select(&b, 0..60), vec![]);
        assert_eq!(select(&b, 0..61), vec![0..BLOCK, 2 * BLOCK..n]);
    }
}
