//! The surfel map: structure-of-arrays storage of all surfels, in world frame.
//!
//! Each attribute is one contiguous array so that the renderer can upload it
//! to the GPU as is (positions and normals are tightly packed `[f32; 3]`,
//! colours `[u8; 4]` RGBA with A = 255) and per-surfel loops vectorise.

use super::chunk_bounds::{ChunkBounds, CHUNK};
use super::surfel::Surfel;
use super::ABSORBED;
use crate::prefetch::prefetch;
use glam::Vec3;
use rayon::prelude::*;

/// Keeps the items of `values` before `start` and those from `start` on
/// whose flag in `kept` (one per item from `start`) is true, in order;
/// returns the new length.
fn compact<T: Copy>(values: &mut Vec<T>, start: usize, kept: &[bool]) -> usize {
    let mut write = start;
    for (read, &k) in (start..values.len()).zip(kept) {
        if k {
            values[write] = values[read];
            write += 1;
        }
    }
    values.truncate(write);
    write
}

/// Mutable view of one chunk of surfels (`CHUNK` consecutive indices), for
/// updating disjoint parts of the map in parallel.
pub struct ChunkMut<'a> {
    /// Index of the chunk's first surfel.
    pub first: usize,
    /// Centres, world frame, metres.
    pub positions: &'a mut [Vec3],
    /// Unit normals, world frame.
    pub normals: &'a mut [Vec3],
    /// RGBA8 colours.
    pub colours: &'a mut [[u8; 4]],
    /// Radii, metres.
    pub radii: &'a mut [f32],
    /// Confidences.
    pub confidences: &'a mut [f32],
    /// Frame of each surfel's last update.
    pub last_seen: &'a mut [u32],
}

/// Reusable buffers for [`SurfelMap::reorder`], one per attribute type.
#[derive(Debug, Default)]
pub struct ReorderScratch {
    vectors: Vec<Vec3>,
    colours: Vec<[u8; 4]>,
    floats: Vec<f32>,
    frames: Vec<u32>,
}

impl ReorderScratch {
    /// Makes room for reordering `len` surfels without allocating.
    pub fn reserve(&mut self, len: usize) {
        self.vectors.reserve(len.saturating_sub(self.vectors.len()));
        self.colours.reserve(len.saturating_sub(self.colours.len()));
        self.floats.reserve(len.saturating_sub(self.floats.len()));
        self.frames.reserve(len.saturating_sub(self.frames.len()));
    }
}

/// Reorders `values` so that slot `i` holds the value that was at `source(i)`.
fn gather<T: Copy>(values: &mut [T], source: impl Fn(usize) -> usize, scratch: &mut Vec<T>) {
    scratch.clear();
    scratch.extend((0..values.len()).map(|i| values[source(i)]));
    values.copy_from_slice(scratch);
}

/// All surfels of the model, structure of arrays; index `i` is one surfel.
///
/// The arrays are visible only inside `fusion/`: everyone else reads them
/// through slice getters ([`SurfelMap::positions`], ...) and changes them
/// only through methods ([`SurfelMap::push`], [`SurfelMap::touch`],
/// [`SurfelMap::absorb`], [`SurfelMap::warp`], ...), so every array keeps
/// the same length and the block boxes, the changed range and the
/// counters stay in step with them. The finer-grained methods that leave
/// that bookkeeping to their caller are `fusion`'s own.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelMap {
    /// Centre of each surfel, world frame, metres.
    pub(in crate::fusion) positions: Vec<Vec3>,
    /// Unit normal of each surfel, world frame, pointing towards the cameras that saw it.
    pub(in crate::fusion) normals: Vec<Vec3>,
    /// Colour, RGBA8 (A = 255).
    pub(in crate::fusion) colours: Vec<[u8; 4]>,
    /// Disk radius, metres.
    pub(in crate::fusion) radii: Vec<f32>,
    /// Accumulated confidence (sum of the radial weights of merged measurements).
    pub(in crate::fusion) confidences: Vec<f32>,
    /// Frame index at which the surfel was created.
    pub(in crate::fusion) first_seen: Vec<u32>,
    /// Frame index at which the surfel was last updated (created, merged
    /// with a measurement, or won its pixel as a settled surfel).
    pub(in crate::fusion) last_seen: Vec<u32>,
    /// Lowest index changed since the last `take_changed_range`.
    pub(in crate::fusion) change_lo: usize,
    /// One past the highest index changed since the last `take_changed_range`.
    pub(in crate::fusion) change_hi: usize,
    /// Boxes around blocks of consecutive surfels, for view culling.
    pub(in crate::fusion) bounds: ChunkBounds,
    /// Frame of the last removal of unstable surfels (see `remove_unstable`).
    pub(in crate::fusion) last_cleanup: Option<u32>,
    /// Lowest index of a surfel absorbed into another since the last
    /// cleanup: the next cleanup compacts the map from there.
    pub(in crate::fusion) first_absorbed: Option<usize>,
    /// Slots holding a surfel absorbed into another (see [`SurfelMap::absorb`])
    /// that no cleanup has removed yet.
    pub(in crate::fusion) absorbed: usize,
}

impl ChunkMut<'_> {
    /// The values of surfel `local` (index within the chunk).
    #[must_use]
    pub fn surfel(&self, local: usize) -> Surfel {
        Surfel {
            position: self.positions[local],
            normal: self.normals[local],
            colour: self.colours[local],
            radius: self.radii[local],
            confidence: self.confidences[local],
        }
    }

    /// Overwrites the values of surfel `local` (index within the chunk).
    pub fn set_surfel(&mut self, local: usize, s: &Surfel) {
        self.positions[local] = s.position;
        self.normals[local] = s.normal;
        self.colours[local] = s.colour;
        self.radii[local] = s.radius;
        self.confidences[local] = s.confidence;
    }
}

impl SurfelMap {
    /// Centre of each surfel, world frame, metres.
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Unit normal of each surfel, world frame, pointing towards the cameras
    /// that saw it.
    #[must_use]
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Colour of each surfel, RGBA8 (A = 255).
    #[must_use]
    pub fn colours(&self) -> &[[u8; 4]] {
        &self.colours
    }

    /// Disk radius of each surfel, metres.
    #[must_use]
    pub fn radii(&self) -> &[f32] {
        &self.radii
    }

    /// Accumulated confidence of each surfel (sum of the radial weights of
    /// the merged measurements); [`super::ABSORBED`] (negative) for a surfel
    /// absorbed into another and awaiting removal.
    #[must_use]
    pub fn confidences(&self) -> &[f32] {
        &self.confidences
    }

    /// Frame index (0-based, frames pushed since the last reset) at which
    /// each surfel was created.
    #[must_use]
    pub fn first_seen(&self) -> &[u32] {
        &self.first_seen
    }

    /// Frame index at which each surfel was last updated: created, merged
    /// with a measurement, or matched by one as a settled surfel. A surfel
    /// not updated for `FusionConfig::active_window_frames` is inactive
    /// (see [`super::FusionConfig::active_at`]): tracking and fusion no
    /// longer read it, but it stays in the map, drawn and exported.
    #[must_use]
    pub fn last_seen(&self) -> &[u32] {
        &self.last_seen
    }

    /// Records that surfel `i` was updated at frame `frame` (never moves
    /// its `last_seen` back). Does nothing if `i` is out of range.
    pub fn touch(&mut self, i: usize, frame: u32) {
        if let Some(f) = self.last_seen.get_mut(i) {
            *f = (*f).max(frame);
            self.bounds.saw(i, frame);
        }
    }

    /// The values of surfel `i`.
    #[must_use]
    pub fn surfel(&self, i: usize) -> Surfel {
        Surfel {
            position: self.positions[i],
            normal: self.normals[i],
            colour: self.colours[i],
            radius: self.radii[i],
            confidence: self.confidences[i],
        }
    }

    /// Hints the caches to fetch what [`SurfelMap::surfel`] reads of surfel `i`.
    pub(in crate::fusion) fn prefetch(&self, i: usize) {
        prefetch(&self.positions, i);
        prefetch(&self.normals, i);
        prefetch(&self.colours, i);
        prefetch(&self.radii, i);
        prefetch(&self.confidences, i);
    }

    /// Overwrites the values of surfel `i` (not its frames); the caller
    /// reports a moved centre with `SurfelMap::grow_bounds`.
    pub fn set_surfel(&mut self, i: usize, s: &Surfel) {
        self.positions[i] = s.position;
        self.normals[i] = s.normal;
        self.colours[i] = s.colour;
        self.radii[i] = s.radius;
        self.confidences[i] = s.confidence;
    }

    /// Number of surfels the arrays hold without reallocating.
    #[must_use]
    pub fn capacity(&self) -> usize {
        self.positions.capacity()
    }

    /// Number of slots in the arrays: the surfels the map holds plus those
    /// absorbed into others and not yet removed by a cleanup (negative
    /// confidence). Every array has this length; the surfel budget counts it.
    #[must_use]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Length every array has at least: [`SurfelMap::len`], since the arrays
    /// change only through this type's methods. Readers that index all
    /// arrays by one index stop here anyway, so that a bug in one of those
    /// methods shows as missing surfels rather than a panic.
    #[must_use]
    pub fn common_len(&self) -> usize {
        [
            self.positions.len(),
            self.normals.len(),
            self.colours.len(),
            self.radii.len(),
            self.confidences.len(),
            self.first_seen.len(),
            self.last_seen.len(),
        ]
        .into_iter()
        .min()
        .unwrap_or(0)
    }

    /// Number of surfels the map holds: [`SurfelMap::len`] without the
    /// absorbed ones awaiting removal. The PLY export writes exactly these.
    #[must_use]
    pub fn live_len(&self) -> usize {
        self.len() - self.absorbed_len()
    }

    /// Slots holding a surfel absorbed into another, awaiting removal by a
    /// cleanup (which compacts them only when they are many, see
    /// `remove_unstable`).
    #[must_use]
    pub fn absorbed_len(&self) -> usize {
        self.absorbed.min(self.len())
    }

    /// Marks surfel `i` as absorbed into another: confidence [`ABSORBED`],
    /// no longer a candidate nor predicted, removed by a later cleanup.
    /// Does nothing if `i` is out of range or already absorbed.
    pub fn absorb(&mut self, i: usize) {
        let Some(c) = self.confidences.get_mut(i) else {
            return;
        };
        if *c < 0.0 {
            return;
        }
        *c = ABSORBED;
        self.absorbed += 1;
        self.first_absorbed = Some(self.first_absorbed.map_or(i, |a| a.min(i)));
    }

    /// True when the map holds no surfel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Records that surfel `i` was modified (for incremental GPU uploads).
    #[inline]
    pub(in crate::fusion) fn mark_changed(&mut self, i: usize) {
        if self.change_lo >= self.change_hi {
            self.change_lo = i;
            self.change_hi = i + 1;
        } else {
            self.change_lo = self.change_lo.min(i);
            self.change_hi = self.change_hi.max(i + 1);
        }
    }

    /// The index range whose slots were filled by new surfels, or by surfels
    /// moved when others were removed or when settled surfels were sorted in
    /// space, since the last call, clamped to the current length; resets it.
    /// Merges (and absorptions) are not included: they refine a
    /// surfel's position, normal and colour by less than the sensor noise, so
    /// a renderer that uploads this range every frame, draws `len()` surfels
    /// and refreshes the rest in a rolling window shows the map correctly
    /// while uploading a small fraction of it per frame.
    pub fn take_changed_range(&mut self) -> std::ops::Range<usize> {
        let hi = self.change_hi.min(self.len());
        let lo = self.change_lo.min(hi);
        self.change_lo = 0;
        self.change_hi = 0;
        lo..hi
    }

    /// Removes every surfel, keeping the allocations.
    pub fn clear(&mut self) {
        self.change_lo = 0;
        self.change_hi = 0;
        self.bounds.clear();
        self.last_cleanup = None;
        self.first_absorbed = None;
        self.absorbed = 0;
        self.positions.clear();
        self.normals.clear();
        self.colours.clear();
        self.radii.clear();
        self.confidences.clear();
        self.first_seen.clear();
        self.last_seen.clear();
    }

    /// Reserves room for `additional` more surfels in every array.
    pub fn reserve(&mut self, additional: usize) {
        self.positions.reserve(additional);
        self.normals.reserve(additional);
        self.colours.reserve(additional);
        self.radii.reserve(additional);
        self.confidences.reserve(additional);
        self.first_seen.reserve(additional);
        self.last_seen.reserve(additional);
    }

    /// Appends one surfel created at frame `frame` (its first and last
    /// update).
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        position: Vec3,
        normal: Vec3,
        colour: [u8; 4],
        radius: f32,
        confidence: f32,
        frame: u32,
    ) {
        self.positions.push(position);
        self.normals.push(normal);
        self.colours.push(colour);
        self.radii.push(radius);
        self.confidences.push(confidence);
        self.first_seen.push(frame);
        self.last_seen.push(frame);
        let i = self.positions.len() - 1;
        self.bounds.grow(i, position);
        self.bounds.saw(i, frame);
        self.mark_changed(i);
    }

    /// Appends `surfels` (world frame, metres) in order, created at frame
    /// `frame`, as [`SurfelMap::push`] does one at a time.
    pub fn extend<'a>(&mut self, surfels: impl Iterator<Item = &'a Surfel> + Clone, frame: u32) {
        let n = surfels.clone().count();
        let first = self.len();
        self.positions.extend(surfels.clone().map(|s| s.position));
        self.normals.extend(surfels.clone().map(|s| s.normal));
        self.colours.extend(surfels.clone().map(|s| s.colour));
        self.radii.extend(surfels.clone().map(|s| s.radius));
        self.confidences
            .extend(surfels.clone().map(|s| s.confidence));
        self.first_seen.extend(std::iter::repeat_n(frame, n));
        self.last_seen.extend(std::iter::repeat_n(frame, n));
        self.bounds.grow_all(first, &self.positions[first..], frame);
        if n > 0 {
            self.mark_changed(first);
            self.mark_changed(first + n - 1);
        }
    }

    /// Calls `f` in parallel on every chunk (see [`ChunkMut`]) with the
    /// matching item of `per_chunk` (chunks past its length are skipped).
    /// The caller must report moved surfels with [`SurfelMap::grow_bounds`]
    /// and updated ones with [`SurfelMap::saw_block`].
    pub(in crate::fusion) fn for_each_chunk_mut<T: Send>(
        &mut self,
        per_chunk: &mut [T],
        f: impl Fn(ChunkMut<'_>, &mut T) + Sync + Send,
    ) {
        self.positions
            .par_chunks_mut(CHUNK)
            .zip(self.normals.par_chunks_mut(CHUNK))
            .zip(self.colours.par_chunks_mut(CHUNK))
            .zip(self.radii.par_chunks_mut(CHUNK))
            .zip(self.confidences.par_chunks_mut(CHUNK))
            .zip(self.last_seen.par_chunks_mut(CHUNK))
            .zip(per_chunk.par_iter_mut())
            .enumerate()
            .for_each(|(c, (((attributes, confidences), last_seen), item))| {
                let (((positions, normals), colours), radii) = attributes;
                let chunk = ChunkMut {
                    first: c * CHUNK,
                    positions,
                    normals,
                    colours,
                    radii,
                    confidences,
                    last_seen,
                };
                f(chunk, item);
            });
    }

    /// Extends the box of the block holding surfel `i` by the box
    /// `[min, max]` (world frame, metres) after surfels of it moved there.
    pub(in crate::fusion) fn grow_bounds(&mut self, i: usize, min: Vec3, max: Vec3) {
        if min.cmple(max).all() {
            self.bounds.grow(i, min);
            self.bounds.grow(i, max);
        }
    }

    /// Records that surfels of the block holding surfel `i` were updated at
    /// frame `frame` (after setting their `last_seen` through [`ChunkMut`]).
    pub(in crate::fusion) fn saw_block(&mut self, i: usize, frame: u32) {
        if i < self.len() {
            self.bounds.saw(i, frame);
        }
    }

    /// The spatial index: boxes around blocks of consecutive surfels, with
    /// the frames their surfels were last updated.
    #[must_use]
    pub fn bounds(&self) -> &ChunkBounds {
        &self.bounds
    }

    /// Reorders the `len` surfels from `start` on so that slot `start + i`
    /// receives the surfel that was at `start + source(i)` (`source` is a
    /// permutation of `0..len`); the caller marks them changed and rebuilds
    /// the chunk boxes.
    pub(in crate::fusion) fn reorder(
        &mut self,
        start: usize,
        len: usize,
        source: impl Fn(usize) -> usize + Copy,
        scratch: &mut ReorderScratch,
    ) {
        let r = start..start + len;
        gather(&mut self.positions[r.clone()], source, &mut scratch.vectors);
        gather(&mut self.normals[r.clone()], source, &mut scratch.vectors);
        gather(&mut self.colours[r.clone()], source, &mut scratch.colours);
        gather(&mut self.radii[r.clone()], source, &mut scratch.floats);
        gather(
            &mut self.confidences[r.clone()],
            source,
            &mut scratch.floats,
        );
        gather(&mut self.first_seen[r.clone()], source, &mut scratch.frames);
        gather(&mut self.last_seen[r], source, &mut scratch.frames);
    }

    /// Moves every surfel by `warp`, which receives the centres and normals
    /// (world frame, metres; to change in place) and each surfel's
    /// `last_seen` frame (a deformation graph moves a surfel with the nodes
    /// of its time). Afterwards, whether the warp succeeded or not, the
    /// whole map counts as changed (a renderer re-uploads it) and every
    /// block box is rebuilt. Indices do not change, so the spatial order's
    /// runs still tile the same surfels; a smooth warp keeps them compact.
    pub fn warp<E>(
        &mut self,
        warp: impl FnOnce(&mut [Vec3], &mut [Vec3], &[u32]) -> Result<(), E>,
    ) -> Result<(), E> {
        let result = warp(&mut self.positions, &mut self.normals, &self.last_seen);
        if let Some(last) = self.len().checked_sub(1) {
            self.mark_changed(0);
            self.mark_changed(last);
        }
        self.rebuild_bounds_from(0);
        result
    }

    /// Moves the surfels first seen at frame `created_from` or later by the
    /// rigid `transform` (world to world, metres), centres and normals; the
    /// others stay. As after [`Self::warp`], the whole map counts as
    /// changed and every block box is rebuilt.
    pub fn move_created_since(&mut self, created_from: u32, transform: &glam::DAffine3) {
        let rotation = glam::Mat3::from_cols(
            transform.matrix3.x_axis.as_vec3(),
            transform.matrix3.y_axis.as_vec3(),
            transform.matrix3.z_axis.as_vec3(),
        );
        let translation = transform.translation.as_vec3();
        let created = self.first_seen.iter().map(|&t| t >= created_from);
        for ((p, n), moved) in self
            .positions
            .iter_mut()
            .zip(&mut self.normals)
            .zip(created)
        {
            if moved {
                *p = rotation * *p + translation;
                *n = rotation * *n;
            }
        }
        if let Some(last) = self.len().checked_sub(1) {
            self.mark_changed(0);
            self.mark_changed(last);
        }
        self.rebuild_bounds_from(0);
    }

    /// Recomputes the chunk boxes from the chunk holding surfel `first` on.
    pub(in crate::fusion) fn rebuild_bounds_from(&mut self, first: usize) {
        self.bounds
            .rebuild_from(&self.positions, &self.last_seen, first);
    }

    /// Keeps every surfel before `start` and, from `start` on, those for
    /// which `keep(map, i)` is true, preserving order; `keep` reads the map
    /// as it was (every surfel is judged before any moves). Costs
    /// O(len - start); the judging and each array's compaction run in parallel.
    pub(in crate::fusion) fn retain_from(
        &mut self,
        start: usize,
        keep: impl Fn(&SurfelMap, usize) -> bool + Sync,
    ) {
        let len = self.len();
        let start = start.min(len);
        let map = &*self;
        let kept: Vec<bool> = (start..len).into_par_iter().map(|i| keep(map, i)).collect();
        let Some(first_removed) = kept.iter().position(|&k| !k).map(|i| start + i) else {
            return;
        };
        let absorbed_removed = kept
            .iter()
            .zip(&self.confidences[start..])
            .filter(|&(&k, &c)| !k && c < 0.0)
            .count();
        let kept = &kept;
        let mut write = 0;
        rayon::scope(|s| {
            s.spawn(|_| write = compact(&mut self.positions, start, kept));
            s.spawn(|_| _ = compact(&mut self.normals, start, kept));
            s.spawn(|_| _ = compact(&mut self.colours, start, kept));
            s.spawn(|_| _ = compact(&mut self.radii, start, kept));
            s.spawn(|_| _ = compact(&mut self.confidences, start, kept));
            s.spawn(|_| _ = compact(&mut self.first_seen, start, kept));
            s.spawn(|_| _ = compact(&mut self.last_seen, start, kept));
        });
        // Every slot from the first removed one on now holds another surfel.
        self.mark_changed(first_removed);
        self.mark_changed(len.saturating_sub(1));
        self.absorbed = self.absorbed.saturating_sub(absorbed_removed);
        debug_assert_eq!(write, self.len());
        self.bounds
            .rebuild_from(&self.positions, &self.last_seen, first_removed);
    }

    /// True when every stored value is finite (no NaN or infinity anywhere).
    #[must_use]
    pub fn all_finite(&self) -> bool {
        self.positions.iter().all(|p| p.is_finite())
            && self.normals.iter().all(|n| n.is_finite())
            && self.radii.iter().all(|r| r.is_finite())
            && self.confidences.iter().all(|c| c.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: std::ops::Range<u32> = 0..u32::MAX;

    /// Blocks `select` keeps for the `last_seen` frames `seen`.
    fn blocks_for(map: &SurfelMap, seen: std::ops::Range<u32>) -> Vec<std::ops::Range<usize>> {
        let mut out = Vec::new();
        map.bounds().select(map.len(), &seen, |_, _| true, &mut out);
        out
    }

    #[test]
    fn last_seen_follows_its_surfel_through_touch_reorder_and_removal() {
        let mut map = SurfelMap::default();
        for i in 0..1200u32 {
            map.push(Vec3::splat(i as f32), Vec3::Z, [0; 4], 0.01, 10.0, i / 100);
        }
        assert_eq!(map.first_seen(), map.last_seen());
        // Surfel 5 (block 0) seen again at frame 50.
        map.touch(5, 50);
        map.touch(5, 3);
        assert_eq!(map.last_seen()[5], 50, "touch never moves back");
        assert_eq!(blocks_for(&map, 40..u32::MAX), vec![0..512]);
        // Reversing the first 600 surfels carries the times along.
        let mut scratch = ReorderScratch::default();
        map.reorder(0, 600, |i| 599 - i, &mut scratch);
        map.rebuild_bounds_from(0);
        assert_eq!(map.last_seen()[594], 50);
        assert_eq!(map.first_seen()[594], 0);
        assert_eq!(blocks_for(&map, 40..u32::MAX), vec![512..1024]);
        // Removing every other surfel keeps the pairs together.
        map.retain_from(0, |_, i| i % 2 == 0);
        assert_eq!(map.len(), 600);
        assert_eq!(map.last_seen().len(), 600);
        assert_eq!(map.last_seen()[297], 50);
        assert!(map
            .first_seen()
            .iter()
            .zip(map.last_seen())
            .all(|(f, l)| f <= l));
        assert_eq!(blocks_for(&map, 40..u32::MAX), vec![0..512]);
        assert_eq!(blocks_for(&map, ALL), vec![0..600]);
        map.clear();
        assert!(map.last_seen().is_empty() && blocks_for(&map, ALL).is_empty());
    }

    #[test]
    fn a_warp_moves_every_surfel_and_keeps_the_changed_range_and_boxes_right() {
        let mut map = SurfelMap::default();
        for i in 0..1200u32 {
            map.push(
                Vec3::new(i as f32 * 1e-3, 0.0, 1.0),
                Vec3::Z,
                [0; 4],
                0.01,
                10.0,
                i,
            );
        }
        let _ = map.take_changed_range();
        let far = |min: Vec3, _max: Vec3| min.x >= 10.0;
        let mut out = Vec::new();
        map.bounds().select(map.len(), &ALL, far, &mut out);
        assert!(out.is_empty(), "nothing is beyond x = 10 m yet");
        // Surfels seen from frame 600 on move 10 m along x and turn.
        let moved: Result<(), ()> = map.warp(|positions, normals, times| {
            for ((p, n), &t) in positions.iter_mut().zip(normals.iter_mut()).zip(times) {
                if t >= 600 {
                    *p += Vec3::new(10.0, 0.0, 0.0);
                    *n = Vec3::X;
                }
            }
            Ok(())
        });
        assert_eq!(moved, Ok(()));
        assert!((map.positions()[599].x - 0.599).abs() < 1e-6);
        assert!((map.positions()[600].x - 10.6).abs() < 1e-5);
        assert_eq!(map.normals()[1199], Vec3::X);
        assert_eq!(
            map.take_changed_range(),
            0..1200,
            "the whole map is re-uploaded"
        );
        map.bounds().select(map.len(), &ALL, far, &mut out);
        assert_eq!(
            out,
            vec![1024..1200],
            "only the block wholly moved is beyond 10 m"
        );
        // A failed warp is returned, and the bookkeeping done all the same.
        assert_eq!(map.warp(|_, _, _| Err("refused")), Err("refused"));
        assert_eq!(map.take_changed_range(), 0..1200);
    }
}
