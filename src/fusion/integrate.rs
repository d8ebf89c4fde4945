//! Merge and add: fuse one frame's measurements into the surfel map.
//!
//! Association (Keller et al. 2013): a pixel's candidates are the surfels
//! whose centres project into it (Keller's 4x4 super-sampled index map keeps
//! the nearest of them per sub-cell; here all of them are considered) that
//! pass the depth and normal gates; the most confident one is merged with the
//! measurement, the other candidates whose centres lie on its disk are
//! merged into it, and a pixel without one adds a new surfel unless the disk
//! of a neighbouring pixel's surfel already covers it. Every surfel
//! projects into one pixel only, so candidates are found in parallel over the
//! visible blocks of the map with an atomic maximum per pixel, and merges are
//! applied in parallel over the chunks; adds are appended in pixel order.

use super::chunk_bounds::{ChunkBounds, BLOCK, BLOCKS_PER_CHUNK, CHUNK};
use super::depth_tiles::DepthTiles;
use super::frustum::visible_blocks;
use super::index_map::raise_to;
use super::noise_weights::NoiseWeights;
use super::surfel::Surfel;
use super::surfel_map::ChunkMut;
use super::{FusionConfig, SurfelMap};
use crate::camera::project_to_pixels_into;
use crate::camera::Intrinsics;
use crate::portable_math::{at_least, at_most, max_vec3, min_vec3};
use crate::prefetch::prefetch;
use crate::preprocess::{FramePyramid, PyramidLevel};
use crate::se3::RigidF32;
use glam::{DAffine3, Vec3};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// What one fusion step did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionStats {
    /// Measurements merged into existing surfels (or matched to a settled
    /// one, see `FusionConfig::settled_confidence`).
    pub merged: usize,
    /// New surfels added.
    pub added: usize,
    /// Unstable surfels removed.
    pub removed: usize,
    /// Measurements neither merged nor added: a neighbouring pixel's surfel covers them.
    pub covered: usize,
    /// New surfels not added because the map was at `max_surfels`.
    pub skipped: usize,
    /// Surfels merged into a more confident surfel whose disk holds their
    /// centre; they are removed at the next cleanup.
    pub absorbed: usize,
    /// Surfels visited by the association: those of the map blocks in view
    /// and not wholly behind the measurements. It follows what the camera
    /// sees, not the size of the map.
    pub visited: usize,
}

/// Reusable buffers for fusing frames of one resolution.
#[derive(Debug, Default)]
pub struct Integrator {
    /// Per pixel: `(confidence bits << 32) | (surfel index + 1)` of the best
    /// candidate, 0 when none.
    best: Vec<AtomicU64>,
    /// Surfel ranges (map blocks) that may hold candidates: in view and
    /// not wholly behind the measurements (`DepthTiles`).
    visible: Vec<Range<usize>>,
    tiles: DepthTiles,
    chunks: Vec<ChunkUpdate>,
    /// Per surfel: the pixel it is a candidate of this frame, or `NO_PIXEL`.
    pixels: Vec<u32>,
    /// Per image row: the pixels (row-major indices) that add a new
    /// surfel, in pixel order.
    adds: Vec<Vec<u32>>,
    /// The pixels of `adds` within the surfel budget, in pixel order.
    add_pixels: Vec<u32>,
    /// A batch of the new surfels, built in parallel (world frame, metres;
    /// confidence the radial weight), appended in pixel order.
    new_surfels: Vec<Surfel>,
    /// Radial confidence weight per column and per row (it is separable).
    weight_u: Vec<f32>,
    weight_v: Vec<f32>,
}

/// Per map chunk: whether it is in view, and what its merges did.
#[derive(Debug, Clone, Default)]
struct ChunkUpdate {
    visible: bool,
    merged: usize,
    /// Per block of the chunk: whether a surfel of it won its pixel.
    seen: [bool; BLOCKS_PER_CHUNK],
    /// Per block of the chunk, box around the merged surfels' new
    /// positions, world frame, metres.
    min: [Vec3; BLOCKS_PER_CHUNK],
    max: [Vec3; BLOCKS_PER_CHUNK],
    /// Candidates that lost their pixel to a more confident surfel, each
    /// with that surfel: `(loser, winner)`, map indices.
    losers: Vec<(u32, u32)>,
}

impl ChunkUpdate {
    /// Resets for a new frame, keeping the allocation of `losers`.
    fn reset(&mut self) {
        self.visible = false;
        self.merged = 0;
        self.seen = [false; BLOCKS_PER_CHUNK];
        self.min = [Vec3::splat(f32::INFINITY); BLOCKS_PER_CHUNK];
        self.max = [Vec3::splat(f32::NEG_INFINITY); BLOCKS_PER_CHUNK];
        self.losers.clear();
    }
}

/// How many surfels (or adds) ahead the per-surfel loops hint the caches
/// to fetch the measurement at a surfel's pixel: the random reads of
/// association and merging waited on memory for most of their time
/// (`docs/performance.md#prefetch`).
const AHEAD: usize = 16;

/// Hints the caches to fetch what merging or adding pixel `i` reads: its
/// winner, vertex, normal and colour.
fn prefetch_measurement(best: &[AtomicU64], view: &FrameView<'_>, i: usize) {
    prefetch(best, i);
    prefetch(&view.level0.vertices, i);
    prefetch(&view.level0.normals, i);
    prefetch(view.rgb, 3 * i);
}

/// Winners merged together after their noise weights are computed together.
const MERGE_BATCH: usize = 32;

/// Winners of a chunk waiting to be merged: local surfel index and pixel.
struct MergeBatch {
    locals: [usize; MERGE_BATCH],
    pixels: [usize; MERGE_BATCH],
    noise_weights: [f32; MERGE_BATCH],
    count: usize,
}

impl Default for MergeBatch {
    fn default() -> Self {
        Self {
            locals: [0; MERGE_BATCH],
            pixels: [0; MERGE_BATCH],
            noise_weights: [0.0; MERGE_BATCH],
            count: 0,
        }
    }
}

impl MergeBatch {
    /// Queues surfel `local` to merge with pixel `pixel`'s measurement;
    /// true when the batch is full.
    fn push(&mut self, local: usize, pixel: usize) -> bool {
        self.locals[self.count] = local;
        self.pixels[self.count] = pixel;
        self.count += 1;
        self.count == MERGE_BATCH
    }

    /// Merges the queued winners (each a different surfel, so the order
    /// changes nothing), grows their blocks' boxes, and empties the batch.
    fn merge_into(
        &mut self,
        chunk: &mut ChunkMut<'_>,
        update: &mut ChunkUpdate,
        (measure, noise): (&Measure<'_>, &NoiseWeights<'_>),
    ) {
        let n = self.count;
        noise.at_each_into(&self.pixels[..n], &mut self.noise_weights[..n]);
        for ((&local, &pixel), &noise_weight) in self
            .locals
            .iter()
            .zip(&self.pixels)
            .zip(&self.noise_weights)
            .take(n)
        {
            let gain = measure.gain(pixel);
            // The noise weight sets the measurement's share in the merge.
            let m = measure.surfel(pixel, gain * noise_weight);
            let p = merge(chunk, local, &m, gain);
            let block = local / BLOCK;
            update.min[block] = min_vec3(update.min[block], p);
            update.max[block] = max_vec3(update.max[block], p);
        }
        self.count = 0;
    }
}

/// New surfels built and appended at a time.
const ADD_BATCH: usize = 16 * 1024;

/// Marks a surfel that is no pixel's candidate this frame.
const NO_PIXEL: u32 = u32::MAX;

/// The frame being fused, as every phase of [`Integrator::integrate`] reads it.
struct FrameView<'a> {
    /// Finest pyramid level: vertices and normals, camera frame, metres.
    level0: &'a PyramidLevel,
    /// Colour, RGB8 interleaved, row-major.
    rgb: &'a [u8],
    k: &'a Intrinsics,
    camera_from_world: RigidF32,
    world_from_camera: RigidF32,
    /// Index of the frame being fused.
    frame: u32,
    /// `last_seen` frames of the surfels fusion reads (the active ones).
    active: Range<u32>,
}

impl Integrator {
    /// Farthest measured depth per tile of the last frame integrated, seen
    /// from its pose (empty before the first frame).
    #[must_use]
    pub fn depth_tiles(&self) -> &DepthTiles {
        &self.tiles
    }

    /// Fuses the frame in `pyramid` seen from `world_from_camera` into `map`
    /// at index `frame`, merging into the surfels whose `last_seen` is in
    /// `active` ([`FusionConfig::active_at`] unless the map was restarted);
    /// `far_m` is the farthest depth the sensor measures.
    ///
    /// Phases, in order (private methods, named for searching):
    /// `reset_frame`, `cull`, `associate`, `weigh`, `merge_winners`,
    /// `absorb_redundant`, `add_uncovered`.
    #[allow(clippy::too_many_arguments)]
    pub fn integrate(
        &mut self,
        map: &mut SurfelMap,
        pyramid: &FramePyramid,
        k: &Intrinsics,
        world_from_camera: &DAffine3,
        (frame, active): (u32, Range<u32>),
        config: &FusionConfig,
        far_m: f32,
    ) -> FusionStats {
        let Some(level0) = pyramid.levels.first() else {
            // No tiles from an earlier pose must outlive this frame.
            self.tiles.build(&[], k.width);
            return FusionStats::default();
        };
        let view = FrameView {
            level0,
            rgb: &pyramid.rgb,
            k,
            camera_from_world: RigidF32::from_affine(&world_from_camera.inverse()),
            world_from_camera: RigidF32::from_affine(world_from_camera),
            frame,
            active,
        };
        self.reset_frame(&view);
        self.cull(map, &view, config, far_m);
        self.associate(map, &view, config);
        self.weigh(&view, config);
        let mut stats = FusionStats {
            merged: self.merge_winners(map, &view, config),
            ..FusionStats::default()
        };
        stats.absorbed = absorb_redundant(&mut self.chunks, map, config);
        stats.visited = self.visible.iter().map(ExactSizeIterator::len).sum();
        self.add_uncovered(map, &view, config, &mut stats);
        stats
    }

    /// Clears the per-pixel best candidates and builds the depth tiles of
    /// the frame's measurements.
    fn reset_frame(&mut self, view: &FrameView<'_>) {
        let n = view.k.pixel_count();
        if self.best.len() != n {
            self.best = (0..n).map(|_| AtomicU64::new(0)).collect();
        } else {
            // Through `&mut`: plain stores. An atomic store is a locked
            // exchange in threaded wasm (its atomics are sequentially consistent).
            self.best.par_iter_mut().for_each(|b| *b.get_mut() = 0);
        }
        self.tiles.build(&view.level0.vertices, view.k.width);
    }

    /// Keeps the map blocks in the view frustum, not wholly behind the
    /// measurements and holding active surfels (`self.visible`), and marks
    /// their chunks visible.
    fn cull(&mut self, map: &SurfelMap, view: &FrameView<'_>, config: &FusionConfig, far_m: f32) {
        let (k, camera_from_world) = (view.k, &view.camera_from_world);
        let tiles = &self.tiles;
        visible_blocks(
            map,
            k,
            (camera_from_world, far_m + config.depth_gate_m),
            &view.active,
            |lo, hi| tiles.may_reach(k, camera_from_world, (lo, hi), config.depth_gate_m),
            &mut self.visible,
        );
        self.chunks
            .resize_with(map.len().div_ceil(CHUNK), ChunkUpdate::default);
        self.chunks.iter_mut().for_each(ChunkUpdate::reset);
        for r in &self.visible {
            if let Some(c) = self.chunks.get_mut(r.start / CHUNK) {
                c.visible = true;
            }
        }
    }

    /// Finds each visible active surfel's pixel and keeps it when the surfel
    /// passes the depth and normal gates (`self.pixels`); per pixel the most
    /// confident candidate wins (`self.best`, an atomic maximum). Inactive
    /// surfels are no candidates: a surface seen again after the active
    /// window gets a second copy, which loop closure aligns and fuses.
    fn associate(&mut self, map: &SurfelMap, view: &FrameView<'_>, config: &FusionConfig) {
        let (chunks, visible) = (&self.chunks, &self.visible);
        let cos_gate = libm::cosf(config.normal_gate_deg.to_radians());
        let best = &self.best;
        let (k, camera_from_world, level0) = (view.k, &view.camera_from_world, view.level0);
        // Each candidate surfel's pixel is kept for the merge pass.
        self.pixels.resize(map.len(), NO_PIXEL);
        self.pixels
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, pixels)| {
                if !chunks.get(c).is_some_and(|u| u.visible) {
                    return;
                }
                pixels.fill(NO_PIXEL);
                for range in ChunkBounds::in_chunk(visible, c) {
                    let local = range.start - c * CHUNK..range.end - c * CHUNK;
                    project_to_pixels_into(
                        k,
                        camera_from_world,
                        &map.positions[range.clone()],
                        &mut pixels[local],
                    );
                    for j in range.clone() {
                        // The measurement at a surfel's pixel is a random
                        // read; the pixels ahead are known, so start them.
                        let ahead = pixels.get(j - c * CHUNK + AHEAD).copied();
                        if let Some(a) = ahead.filter(|&a| a != NO_PIXEL) {
                            let a = a as usize;
                            prefetch(&level0.vertices, a);
                            prefetch(&level0.normals, a);
                            prefetch(best, a);
                        }
                        let slot = &mut pixels[j - c * CHUNK];
                        if *slot == NO_PIXEL {
                            continue;
                        }
                        let pixel = *slot as usize;
                        *slot = NO_PIXEL;
                        if map.confidences[j] < 0.0 || !view.active.contains(&map.last_seen[j]) {
                            continue;
                        }
                        // Recomputed rather than stored: the vectorised loop
                        // writes only the pixel, into the buffer the merges read.
                        let z = camera_from_world.point(map.positions[j]).z;
                        let p = level0.vertices[pixel];
                        let n = level0.normals[pixel];
                        if p.z <= 0.0 || n == Vec3::ZERO || (z - p.z).abs() > config.depth_gate_m {
                            continue;
                        }
                        if camera_from_world.vector(map.normals[j]).dot(n) < cos_gate {
                            continue;
                        }
                        *slot = pixel as u32;
                        // Confidences are positive, so their bit patterns order like the values.
                        let key = (u64::from(at_least(map.confidences[j], 0.0).to_bits()) << 32)
                            | (j as u64 + 1);
                        raise_to(&best[pixel], key);
                    }
                }
            });
    }

    /// Fills the radial confidence weight per column and per row (the
    /// sensor-noise weight is computed per pixel where it is read, see
    /// [`NoiseWeights`]).
    fn weigh(&mut self, view: &FrameView<'_>, config: &FusionConfig) {
        let k = view.k;
        // gamma^2 = ((u - cx)^2 + (v - cy)^2) / |c|^2, so the weight
        // exp(-gamma^2 / (2 sigma^2)) is a product of a column and a row factor.
        let scale =
            1.0 / (2.0 * config.confidence_sigma.powi(2) * (k.cx * k.cx + k.cy * k.cy).max(1.0));
        let radial = |d: f32| libm::expf(-(d * d) * scale);
        self.weight_u.clear();
        self.weight_u
            .extend((0..k.width).map(|u| radial(u as f32 - k.cx)));
        self.weight_v.clear();
        self.weight_v
            .extend((0..k.height).map(|v| radial(v as f32 - k.cy)));
    }

    /// Merges each pixel's winning surfel with the pixel's measurement (in
    /// parallel over the chunks; settled surfels are left as they are, but
    /// every winner is marked updated at this frame, so a surface in view
    /// stays active), collects the losers for [`absorb_redundant`], and
    /// grows the blocks' boxes; returns the number of winners.
    fn merge_winners(
        &mut self,
        map: &mut SurfelMap,
        view: &FrameView<'_>,
        config: &FusionConfig,
    ) -> usize {
        let measure = Measure::new(view, (&self.weight_u, &self.weight_v), config);
        let noise = NoiseWeights::new(view.level0, view.k, config);
        let (best, pixels, visible) = (&self.best, &self.pixels, &self.visible);
        map.for_each_chunk_mut(&mut self.chunks, |mut chunk, update| {
            if !update.visible {
                return;
            }
            let c = chunk.first / CHUNK;
            // The winners to merge are taken in batches: a batch's noise
            // weights are computed together (see `NoiseWeights::at_each_into`).
            let mut batch = MergeBatch::default();
            for j in ChunkBounds::in_chunk(visible, c).iter().cloned().flatten() {
                // As in `associate`: the pixel's reads started early.
                if let Some(a) = pixels.get(j + AHEAD).copied().filter(|&a| a != NO_PIXEL) {
                    prefetch_measurement(best, view, a as usize);
                    noise.prefetch(a as usize);
                }
                let local = j - chunk.first;
                let pixel = pixels[j];
                if pixel == NO_PIXEL {
                    continue;
                }
                let key = best[pixel as usize].load(Ordering::Relaxed) & 0xffff_ffff;
                if key != j as u64 + 1 {
                    // A candidate's pixel has a winner: its key is at least the candidate's.
                    if let Some(b) = key.checked_sub(1) {
                        update.losers.push((j as u32, b as u32));
                    }
                    continue;
                }
                update.merged += 1;
                chunk.last_seen[local] = view.frame;
                update.seen[local / BLOCK] = true;
                if config.is_settled(chunk.confidences[local]) {
                    continue;
                }
                if batch.push(local, pixel as usize) {
                    batch.merge_into(&mut chunk, update, (&measure, &noise));
                }
            }
            batch.merge_into(&mut chunk, update, (&measure, &noise));
        });
        let mut merged = 0;
        for (c, update) in self.chunks.iter().enumerate() {
            if update.merged > 0 {
                for (b, (&lo, &hi)) in update.min.iter().zip(&update.max).enumerate() {
                    map.grow_bounds(c * CHUNK + b * BLOCK, lo, hi);
                    if update.seen[b] {
                        map.saw_block(c * CHUNK + b * BLOCK, view.frame);
                    }
                }
                merged += update.merged;
            }
        }
        merged
    }

    /// Adds a surfel for each measured pixel without a candidate whose
    /// surface no neighbouring pixel's surfel covers, up to the budget;
    /// counts `covered`, `added` and `skipped` into `stats`.
    fn add_uncovered(
        &mut self,
        map: &mut SurfelMap,
        view: &FrameView<'_>,
        config: &FusionConfig,
        stats: &mut FusionStats,
    ) {
        let measure = Measure::new(view, (&self.weight_u, &self.weight_v), config);
        let cos_gate = libm::cosf(config.normal_gate_deg.to_radians());
        let (level0, best) = (view.level0, &self.best);
        let (w, h) = (view.k.width, view.k.height);
        // Which pixels add a surfel is decided in parallel (the map is only
        // read); the surfels are appended in pixel order.
        let map_ref = &*map;
        self.adds.resize_with(view.k.height, Vec::new);
        stats.covered = self
            .adds
            .par_iter_mut()
            .enumerate()
            .map(|(v, row)| {
                row.clear();
                let mut covered = 0;
                for u in 0..w {
                    let i = v * w + u;
                    // The winner first: a pixel with one is skipped unread.
                    if best[i].load(Ordering::Relaxed) != 0
                        || level0.vertices[i].z <= 0.0
                        || level0.normals[i] == Vec3::ZERO
                    {
                        continue;
                    }
                    // Only the position and normal are needed to test
                    // the neighbours; most such pixels are covered.
                    let world = &view.world_from_camera;
                    let position = world.point(level0.vertices[i]);
                    let normal = world.vector(level0.normals[i]);
                    if covered_by_neighbour(
                        best,
                        map_ref,
                        (u, v),
                        (w, h),
                        (position, normal),
                        (cos_gate, config.depth_gate_m),
                    ) {
                        covered += 1;
                    } else {
                        row.push(i as u32);
                    }
                }
                covered
            })
            .sum();
        // Appended in pixel order: the same map on any thread count.
        let wanted: usize = self.adds.iter().map(Vec::len).sum();
        let room = config.max_surfels.saturating_sub(map.len());
        stats.added = wanted.min(room);
        stats.skipped = wanted - stats.added;
        self.add_pixels.clear();
        self.add_pixels
            .extend(self.adds.iter().flatten().take(stats.added));
        // In batches, so that a frame adding a surfel at every pixel (a
        // map's first: 11 MB at 640x480) holds only a batch of them at once.
        for batch in self.add_pixels.chunks(ADD_BATCH) {
            self.new_surfels.clear();
            // A new surfel's confidence is the radial weight alone: the
            // noise weight only sets a merge's share.
            self.new_surfels.par_extend(batch.par_iter().map(|&i| {
                let i = i as usize;
                measure.surfel(i, measure.gain(i))
            }));
            map.extend(self.new_surfels.iter(), view.frame);
        }
    }
}

/// Turns a pixel's measurement into a surfel in the world frame.
struct Measure<'a> {
    view: &'a FrameView<'a>,
    weight_u: &'a [f32],
    weight_v: &'a [f32],
    focal: f32,
    max_radius_m: f32,
}

impl<'a> Measure<'a> {
    fn new(
        view: &'a FrameView<'a>,
        (weight_u, weight_v): (&'a [f32], &'a [f32]),
        config: &FusionConfig,
    ) -> Self {
        Self {
            view,
            weight_u,
            weight_v,
            focal: view.k.focal_abs(),
            max_radius_m: config.max_radius_m,
        }
    }

    /// Confidence a merge or an add of pixel `i` gives: the radial weight
    /// (the noise weight only sets the merge's share, see `FusionConfig::noise`).
    fn gain(&self, i: usize) -> f32 {
        let w = self.view.k.width;
        self.weight_u[i % w] * self.weight_v[i / w]
    }

    /// The surfel pixel `i` (row-major) measures: world frame, metres, with
    /// confidence `confidence`.
    fn surfel(&self, i: usize, confidence: f32) -> Surfel {
        let p = self.view.level0.vertices[i];
        let n_cam = self.view.level0.normals[i];
        let radius = at_most(
            std::f32::consts::SQRT_2 * p.z / self.focal / at_least(n_cam.z.abs(), 0.25),
            self.max_radius_m,
        );
        let c = &self.view.rgb[3 * i..3 * i + 3];
        Surfel {
            position: self.view.world_from_camera.point(p),
            normal: self.view.world_from_camera.vector(n_cam),
            colour: [c[0], c[1], c[2], 255],
            radius,
            confidence,
        }
    }
}

/// Merges every candidate that lost its pixel to a more confident
/// surfel whose disk holds its centre into that surfel (Keller et al.
/// 2013 merge such overlapping points) and marks it [`ABSORBED`].
/// Without this, duplicates win the pixel now and then as the camera
/// moves, become stable, and the map grows on every revisit
/// (`docs/performance.md#absorb-redundant`).
fn absorb_redundant(
    chunks: &mut [ChunkUpdate],
    map: &mut SurfelMap,
    config: &FusionConfig,
) -> usize {
    let cos_gate = libm::cosf(config.normal_gate_deg.to_radians());
    let on_disk = |map: &SurfelMap, b: usize, j: usize| {
        map.normals[b].dot(map.normals[j]) >= cos_gate
            && (map.positions[b] - map.positions[j]).length() < map.radii[b]
    };
    // Most losers are not on the winner's disk; finding the few that are
    // reads the map at random, so it runs in parallel, and only those are
    // merged one by one.
    let map_ref = &*map;
    chunks.par_iter_mut().for_each(|c| {
        c.losers
            .retain(|&(j, b)| on_disk(map_ref, b as usize, j as usize));
    });
    let mut absorbed = 0;
    let mut ahead = chunks.iter().flat_map(|c| &c.losers).skip(ABSORB_AHEAD);
    for &(j, b) in chunks.iter().flat_map(|c| &c.losers) {
        // Both surfels are read at random: start the reads of a later pair.
        if let Some(&(aj, ab)) = ahead.next() {
            map.prefetch(aj as usize);
            map.prefetch(ab as usize);
        }
        let (j, b) = (j as usize, b as usize);
        // Checked again: an earlier merge may have moved the winner.
        if !on_disk(map, b, j) {
            continue;
        }
        if !config.is_settled(map.confidences[b]) {
            let merged = map.surfel(b).merged_with(&map.surfel(j));
            map.set_surfel(b, &merged);
            map.grow_bounds(b, merged.position, merged.position);
        }
        map.absorb(j);
        absorbed += 1;
    }
    absorbed
}

/// How many pairs ahead [`absorb_redundant`]'s serial merges hint the caches.
const ABSORB_AHEAD: usize = 8;

/// Confidence that marks a surfel merged into another one: it is no
/// candidate, never predicted, and removed at the next cleanup.
pub const ABSORBED: f32 = -1.0;

/// Whether a surfel merged by one of the 8 neighbouring pixels has a disk
/// that covers the measurement: its centre projects onto the disk, and it
/// lies within the disk's radius of the disk's plane, or within the depth
/// gate with a compatible normal. Surfel centres jitter between pixels as
/// the camera moves, so a pixel often holds no centre though its surface is
/// mapped; adding a surfel there anyway grows the map to about three surfels
/// per pixel footprint (`docs/performance.md#covered-by-neighbour`).
/// Most of the adds the normal gate let through came from noisy normals
/// (teddy's fur) on a surface already mapped. The measurement is not merged
/// into the neighbour, which would smear it along the surface.
/// `(position, normal)`: the measurement at pixel `(u, v)`, world frame, metres.
fn covered_by_neighbour(
    best: &[AtomicU64],
    map: &SurfelMap,
    (u, v): (usize, usize),
    (w, h): (usize, usize),
    (position, normal): (Vec3, Vec3),
    (cos_gate, depth_gate): (f32, f32),
) -> bool {
    (v.saturating_sub(1)..(v + 2).min(h)).any(|y| {
        (u.saturating_sub(1)..(u + 2).min(w)).any(|x| {
            let key = best[y * w + x].load(Ordering::Relaxed) & 0xffff_ffff;
            let Some(j) = (key as usize).checked_sub(1) else {
                return false;
            };
            let d = position - map.positions[j];
            let along = d.dot(map.normals[j]);
            let r = map.radii[j];
            d.length_squared() - along * along < r * r
                && (along.abs() < r
                    || (along.abs() < depth_gate && map.normals[j].dot(normal) >= cos_gate))
        })
    })
}

/// Merges measurement `m` into surfel `local` of `chunk`; returns its new position.
fn merge(chunk: &mut ChunkMut<'_>, local: usize, m: &Surfel, gain: f32) -> Vec3 {
    let old = chunk.surfel(local);
    let mut merged = old.merged_with(m);
    merged.confidence = old.confidence + gain;
    chunk.set_surfel(local, &merged);
    // Not marked changed: a merge refines a surfel by less than the sensor
    // noise; renderers refresh merged data in the background (see
    // `SurfelMap::take_changed_range`).
    merged.position
}
