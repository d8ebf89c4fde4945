//! The map's state beyond its surfels, read and restored bit for bit when a
//! session is saved and loaded (`crate::session`): the block boxes as they
//! are (conservative between rebuilds; restored rather than rebuilt, so
//! that culling visits the same blocks), the cleanup schedule and the
//! absorbed slots awaiting removal.

use super::chunk_bounds::{BlockBox, BLOCK};
use super::surfel::Surfel;
use super::surfel_map::SurfelMap;

/// The map's cleanup bookkeeping (see `remove_unstable`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MapSchedule {
    /// Frame of the last removal of unstable surfels.
    pub last_cleanup: Option<u32>,
    /// Lowest slot absorbed since that cleanup (the next one compacts from there).
    pub first_absorbed: Option<usize>,
    /// Slots absorbed into another surfel and not yet removed.
    pub absorbed: usize,
}

impl SurfelMap {
    /// The cleanup bookkeeping, for saving a session.
    #[must_use]
    pub fn schedule(&self) -> MapSchedule {
        MapSchedule {
            last_cleanup: self.last_cleanup,
            first_absorbed: self.first_absorbed,
            absorbed: self.absorbed,
        }
    }

    /// Appends a saved surfel with its frames as they were (absorbed ones
    /// included); the boxes and the changed range are left to
    /// [`Self::finish_restore`], which must follow the last one.
    pub fn push_saved(&mut self, surfel: &Surfel, first_seen: u32, last_seen: u32) {
        self.positions.push(surfel.position);
        self.normals.push(surfel.normal);
        self.colours.push(surfel.colour);
        self.radii.push(surfel.radius);
        self.confidences.push(surfel.confidence);
        self.first_seen.push(first_seen);
        self.last_seen.push(last_seen);
    }

    /// Finishes a map filled by [`Self::push_saved`]: its saved block boxes
    /// (one per `BLOCK` surfels, as [`super::chunk_bounds::ChunkBounds::block`]
    /// gave them) and schedule; the whole map counts as changed (a renderer
    /// uploads it). Refuses values that do not fit the surfels, or a
    /// non-finite surfel, naming the problem.
    pub fn finish_restore(
        &mut self,
        blocks: Vec<BlockBox>,
        schedule: MapSchedule,
    ) -> Result<(), String> {
        let len = self.len();
        if self.common_len() != len {
            return Err("surfel arrays of different lengths".into());
        }
        if !self.all_finite() {
            return Err("a surfel holds a non-finite value".into());
        }
        if blocks.len() != len.div_ceil(BLOCK) {
            return Err(format!(
                "{} block boxes for {len} surfels (expected {})",
                blocks.len(),
                len.div_ceil(BLOCK)
            ));
        }
        if schedule.first_absorbed.is_some_and(|i| i >= len) || schedule.absorbed > len {
            return Err(format!(
                "absorbed slots {:?}/{} out of {len} surfels",
                schedule.first_absorbed, schedule.absorbed
            ));
        }
        self.bounds.clear();
        for block in blocks {
            self.bounds.push_block(block);
        }
        self.last_cleanup = schedule.last_cleanup;
        self.first_absorbed = schedule.first_absorbed;
        self.absorbed = schedule.absorbed;
        (self.change_lo, self.change_hi) = (0, len);
        Ok(())
    }
}
