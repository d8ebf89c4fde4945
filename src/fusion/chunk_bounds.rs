//! The map's spatial index: an axis-aligned box (world frame, metres) around
//! each run of `CHUNK` consecutive surfels.
//!
//! Surfels are appended frame by frame, so consecutive indices were mostly
//! created from one viewpoint and lie close together; a box test against the
//! view frustum skips whole runs, and a frame's cost follows what the camera
//! sees rather than the size of the map. Boxes only grow between rebuilds
//! (merges move a surfel by at most the fusion depth gate), so they stay
//! conservative.

use glam::Vec3;
use std::ops::Range;

/// Surfels per chunk.
pub const CHUNK: usize = 4096;

/// Per-chunk bounding boxes of the surfel positions.
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

    /// Extends the box of surfel `i`'s chunk to hold `position`; chunks are
    /// created in order as `i` grows.
    #[inline]
    pub fn grow(&mut self, i: usize, position: Vec3) {
        let c = i / CHUNK;
        while self.min.len() <= c {
            self.min.push(Vec3::splat(f32::INFINITY));
            self.max.push(Vec3::splat(f32::NEG_INFINITY));
        }
        self.min[c] = self.min[c].min(position);
        self.max[c] = self.max[c].max(position);
    }

    /// Recomputes the boxes of every chunk from the one holding surfel `first`
    /// on, after the surfels from `first` on were moved or removed.
    pub fn rebuild_from(&mut self, positions: &[Vec3], first: usize) {
        let c0 = first / CHUNK;
        self.min.truncate(c0);
        self.max.truncate(c0);
        for (i, &p) in positions.iter().enumerate().skip(c0 * CHUNK) {
            self.grow(i, p);
        }
    }

    /// Number of chunks.
    #[must_use]
    pub fn len(&self) -> usize {
        self.min.len()
    }

    /// True when there is no chunk.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.is_empty()
    }

    /// Surfel index ranges of the chunks whose box `keep(min, max)` accepts,
    /// written into `out` (cleared first; its allocation is reused).
    pub fn select(
        &self,
        surfels: usize,
        mut keep: impl FnMut(Vec3, Vec3) -> bool,
        out: &mut Vec<Range<usize>>,
    ) {
        out.clear();
        for (c, (&lo, &hi)) in self.min.iter().zip(&self.max).enumerate() {
            let range = c * CHUNK..((c + 1) * CHUNK).min(surfels);
            if !range.is_empty() && keep(lo, hi) {
                out.push(range);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_hold_their_surfels_and_rebuild_shrinks_them() {
        let positions: Vec<Vec3> = (0..2 * CHUNK + 10)
            .map(|i| Vec3::new(i as f32, 0.0, 1.0))
            .collect();
        let mut b = ChunkBounds::default();
        for (i, &p) in positions.iter().enumerate() {
            b.grow(i, p);
        }
        assert_eq!(b.len(), 3);
        let mut ranges = Vec::new();
        b.select(
            positions.len(),
            |lo, hi| lo.x <= 5000.0 && hi.x >= 5000.0,
            &mut ranges,
        );
        assert_eq!(ranges, vec![CHUNK..2 * CHUNK]);
        b.rebuild_from(&positions[..CHUNK + 1], CHUNK);
        assert_eq!(b.len(), 2);
        b.select(CHUNK + 1, |_, hi| hi.x >= CHUNK as f32, &mut ranges);
        assert_eq!(ranges, vec![CHUNK..CHUNK + 1]);
    }
}
