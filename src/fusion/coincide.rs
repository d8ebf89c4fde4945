//! Surfaces mapped twice: a surfel that became stable recently (a copy)
//! and lies on an older stable surfel from an earlier visit is merged into
//! the older one, which takes the later `last_seen`. Fusion associates a
//! measurement only with the active surfels whose centre lands on its
//! pixel, so a return to a place whose surfels went inactive (or whose
//! centres now fall between pixels) lays a second copy beside the first
//! (`docs/performance.md#revisit-growth`).
//!
//! An earlier visit's surfel is one that is inactive, or one made more than
//! the active window before the copy: mostly one a return woke (a merge
//! wakes the old surfel, and the copies due beside it at the next cleanups
//! would otherwise stay for good), else a surface kept in view all that
//! time, long since settled. Surfels made within the active window are this
//! visit's own: a copy beside them is fusion's business, not a revisit's.
//!
//! "On" depends on how the copies lie as a whole. Scattered about the old
//! surfaces (sensor noise, a return along a path tracked right), a copy goes
//! when it lies on an old surfel's disk: within [`COINCIDE_ALONG_M`] of its
//! plane, within its radius and at most [`COINCIDE_ACROSS_M`] from its centre
//! across its normal; normals within the fusion's normal gate. Offset as a
//! whole by more than [`COPIES_DRIFT_M`] (the pose drifted, and the loop
//! checks have yet to close it), only a copy within [`COINCIDE_M`] of an old
//! centre goes: the rest stay inactive surfaces' counterparts for the local
//! check to register.

use super::{FusionConfig, SurfelMap};
use glam::{DMat3, DVec3, IVec3, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// Largest offset of a copy from the old surfel along the old surfel's
/// normal, metres: the two lie on one surface.
pub const COINCIDE_ALONG_M: f32 = 0.01;

/// Largest offset of a copy from the old surfel's centre across its normal,
/// metres; within the old surfel's radius too, so the copy lies on its
/// disk. A return to a place lays its copies between the old centres, not
/// on them: on the synthetic room circled ten times (`examples/ten_circles.rs`)
/// most copies of circle 2 lie 1-1.5 cm from the nearest old centre, 1 cm
/// or less off its plane and within its radius
/// (`docs/performance.md#revisit-growth`).
pub const COINCIDE_ACROSS_M: f32 = 0.02;

/// Whether a copy `offset` (copy minus old, metres) from an old surfel with
/// unit normal `normal` and radius `radius` lies on the old surfel's disk.
fn on_disk(offset: Vec3, normal: Vec3, radius: f32) -> bool {
    let along = offset.dot(normal);
    let across = (offset - normal * along).length();
    along.abs() < COINCIDE_ALONG_M && across < radius.min(COINCIDE_ACROSS_M)
}

/// Largest distance between a copy's centre and the old surfel's taken for
/// one surface when the copies lie offset as a whole, metres.
pub const COINCIDE_M: f32 = 0.01;

/// Offset of a cleanup's copies as a whole from the old surfaces
/// ([`copies_offset`]) beyond which they count as drifted, metres. The
/// synthetic room circled ten times under Kinect-v1 noise, tracked within
/// 0.3 cm of the truth, gives 0-0.3 cm over its first three circles; the
/// drifting synthetic loop
/// (`tests/loop_closure.rs`) 0.7-1.2 cm where it returns, and with every
/// copy on a disk merged there, its local closures found nothing to close
/// (ATE 0.97 -> 2.07 cm).
pub const COPIES_DRIFT_M: f32 = 0.005;

/// The translation (world frame, metres) that best explains how far each
/// copy lies off its nearest old surfel's plane, by least squares over the
/// offsets along the old normals; `pairs` gives each copy (by index) with
/// its nearest old surfel. Directions the normals do not span are damped to
/// zero (a wall alone says nothing of a slide along it).
fn copies_offset(
    pairs: impl Iterator<Item = (usize, usize)>,
    positions: &[Vec3],
    normals: &[Vec3],
) -> DVec3 {
    let (mut a, mut rhs) = (DMat3::ZERO, DVec3::ZERO);
    for (j, b) in pairs {
        let n = normals[b].as_dvec3();
        let along = (positions[j] - positions[b]).as_dvec3().dot(n);
        a += DMat3::from_cols(n * n.x, n * n.y, n * n.z);
        rhs += n * along;
    }
    let damping = 0.05 * (a.x_axis.x + a.y_axis.y + a.z_axis.z) / 3.0;
    if damping <= 0.0 {
        return DVec3::ZERO;
    }
    (a + DMat3::from_diagonal(DVec3::splat(damping))).inverse() * rhs
}

/// A pair's key for an atomic minimum: the distance's bits (metres, not
/// negative, so they order as the distances do) above the old surfel's
/// index, which breaks ties whatever order the search found them in.
fn pair_key(distance: f32, old: usize) -> u64 {
    (u64::from(distance.to_bits()) << 32) | old as u64
}

/// The distance (metres) and old surfel of a [`pair_key`]; `None` for none.
fn from_key(key: u64) -> Option<(f32, usize)> {
    (key != u64::MAX).then(|| {
        (
            f32::from_bits((key >> 32) as u32),
            (key & 0xFFFF_FFFF) as usize,
        )
    })
}

/// Merges the copies due at frame `now` (see
/// [`FusionConfig::merge_copies_after_frames`]): every stable surfel
/// created in the cleanup span that ends `merge_copies_after_frames` before
/// `now` is merged into the nearest stable surfel of an earlier visit it
/// lies on (see the module documentation), which takes its `last_seen`.
/// Whether the copies are offset as a whole is judged against the inactive
/// surfels alone, the surfaces the loop checks register against.
/// Surfels last seen before `active_from` are inactive
/// ([`FusionConfig::active_at`]'s start, or a later restart's).
/// Returns how many were merged (marked absorbed, removed at the next
/// cleanup).
pub fn merge_copies(
    map: &mut SurfelMap,
    config: &FusionConfig,
    (now, active_from): (u32, u32),
) -> usize {
    let delay = config.merge_copies_after_frames;
    if delay == 0 || now < delay {
        return 0;
    }
    // Every surfel still in the map and older than the unstable age was
    // stable at a cleanup, so the span covers each copy more than once.
    let young_to = now - delay;
    let young_from = young_to
        .saturating_sub(3 * config.cleanup_interval_frames.max(1) + config.unstable_max_age);
    let earlier_visit_before = young_from.saturating_sub(config.active_window_frames);
    let stable = config.stable_confidence;
    let n = map.common_len();
    let (positions, normals) = (map.positions(), map.normals());
    let (first_seen, last_seen, confidences, radii) = (
        map.first_seen(),
        map.last_seen(),
        map.confidences(),
        map.radii(),
    );
    let inactive = |b: usize| last_seen[b] < active_from;
    let of_earlier_visit = |b: usize| {
        confidences[b] >= stable
            && first_seen[b] < young_from
            && (inactive(b) || first_seen[b] < earlier_visit_before)
    };
    // No earlier visit (a run shorter than the window): no work, and no
    // allocation that would raise the wasm memory's high-water mark.
    if !(0..n).any(of_earlier_visit) {
        return 0;
    }
    let young: Vec<u32> = (0..n)
        .filter(|&i| (young_from..young_to).contains(&first_seen[i]) && confidences[i] >= stable)
        .map(|i| i as u32)
        .collect();
    if young.is_empty() {
        return 0;
    }
    // Grid cells as wide as the farthest pair: the 27 around a cell hold them all.
    let reach = COINCIDE_ACROSS_M.max(COINCIDE_ALONG_M);
    let cell = |p: Vec3| (p / reach).floor().as_ivec3();
    // The young surfels sorted by cell, and each cell's run of them.
    let mut by_cell: Vec<([i32; 3], u32)> = young
        .iter()
        .enumerate()
        .map(|(y, &j)| (cell(positions[j as usize]).to_array(), y as u32))
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
    lo -= Vec3::splat(reach);
    hi += Vec3::splat(reach);
    let cos_gate = libm::cosf(config.normal_gate_deg.to_radians());
    // Per copy (index into `young`), the nearest inactive old surfel within
    // reach and the nearest old surfel on whose disk it lies, normals within
    // the gate, found from the old side as `pair_key`s.
    let nearest: Vec<AtomicU64> = young.iter().map(|_| AtomicU64::new(u64::MAX)).collect();
    let nearest_on_disk: Vec<AtomicU64> = young.iter().map(|_| AtomicU64::new(u64::MAX)).collect();
    (0..n)
        .into_par_iter()
        .filter(|&b| {
            of_earlier_visit(b)
                && positions[b].cmpge(lo).all()
                && positions[b].cmple(hi).all()
                && near_young.may_hold(cell(positions[b]))
        })
        .for_each(|b| {
            let p = positions[b];
            let c = cell(p);
            for d in (0..27).map(|i| IVec3::new(i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1)) {
                let Some(ys) = grid.get(&c.saturating_add(d)) else {
                    continue;
                };
                for &(_, y) in &by_cell[ys.clone()] {
                    let j = young[y as usize] as usize;
                    let offset = positions[j] - p;
                    let distance = offset.length();
                    if distance < reach && normals[j].dot(normals[b]) >= cos_gate {
                        let key = pair_key(distance, b);
                        if inactive(b) {
                            nearest[y as usize].fetch_min(key, Ordering::Relaxed);
                        }
                        if on_disk(offset, normals[b], radii[b]) {
                            nearest_on_disk[y as usize].fetch_min(key, Ordering::Relaxed);
                        }
                    }
                }
            }
        });
    let nearest_of = |y: usize, keys: &[AtomicU64]| from_key(keys[y].load(Ordering::Relaxed));
    // Copies offset as a whole are a drift the loop checks have yet to
    // close: only those on the old centres go, the rest stay for the checks
    // to register (the drifting synthetic loop, `tests/loop_closure.rs`).
    let pairs = (0..young.len())
        .filter_map(|y| nearest_of(y, &nearest).map(|(_, b)| (young[y] as usize, b)));
    let drifted = copies_offset(pairs, positions, normals).length() > f64::from(COPIES_DRIFT_M);
    let chosen: Vec<(usize, usize)> = (0..young.len())
        .filter_map(|y| {
            let old = if drifted {
                nearest_of(y, &nearest).filter(|&(d, _)| d < COINCIDE_M)
            } else {
                nearest_of(y, &nearest_on_disk)
            };
            old.map(|(_, b)| (young[y] as usize, b))
        })
        .collect();
    let mut merged = 0;
    for (j, b) in chosen {
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

    /// [`merge_copies`] at frame `now`, the active window's surfels active.
    fn merge_due(map: &mut SurfelMap, config: &FusionConfig, now: u32) -> usize {
        merge_copies(map, config, (now, config.active_at(now).start))
    }

    /// A cleanup frame at which copies created at frame 300 are due.
    fn due(config: &FusionConfig) -> u32 {
        300 + config.merge_copies_after_frames + config.cleanup_interval_frames
    }

    /// An old surfel (frame 0, so inactive at [`due`]) and a copy made at
    /// frame 300, `offset` beside it with normal `copy_normal`.
    fn old_and_copy(offset: Vec3, copy_normal: Vec3) -> SurfelMap {
        old_of_radius_and_copy(0.005, offset, copy_normal)
    }

    /// [`old_and_copy`] with the old surfel's radius `radius`, metres.
    fn old_of_radius_and_copy(radius: f32, offset: Vec3, copy_normal: Vec3) -> SurfelMap {
        let mut map = SurfelMap::default();
        map.push(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, [0; 4], radius, 20.0, 0);
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
        assert_eq!(merge_due(&mut map, &config, now), 1);
        assert!(map.confidences()[1] < 0.0, "the copy is absorbed");
        assert_eq!(map.last_seen()[0], 300, "the old surfel is active again");
        // Its geometry stays where it was.
        assert_eq!(map.positions()[0], Vec3::new(0.0, 0.0, 2.0));
    }

    #[test]
    fn a_copy_on_the_old_disk_is_merged_one_off_its_plane_or_disk_is_not() {
        let config = FusionConfig::default();
        let now = due(&config);
        // An old surfel of radius 1.8 cm; copies 1.5 cm from its centre.
        let with_radius = |offset: Vec3| old_of_radius_and_copy(0.018, offset, Vec3::Z);
        let mut beside = with_radius(Vec3::new(0.012, 0.009, 0.002));
        assert_eq!(merge_due(&mut beside, &config, now), 1, "on the disk");
        let mut above = with_radius(Vec3::new(0.009, 0.0, 0.012));
        assert_eq!(merge_due(&mut above, &config, now), 0, "off the plane");
        let mut beyond = with_radius(Vec3::new(0.019, 0.0, 0.0));
        assert_eq!(merge_due(&mut beyond, &config, now), 0, "beyond the radius");
    }

    /// Old surfels (frame 0) on a floor (normal z) and a wall (normal x), 9 x
    /// 9 each, 2 cm apart with radius 1.5 cm, and 8 x 8 copies made at frame
    /// 300, each between four old centres (1 cm along both in-plane axes),
    /// moved by `shift` and `along(i)` more along its normal. Returns the
    /// map and, per copy, its index and the old surfel it was made from.
    fn floor_and_wall_with_copies(
        shift: Vec3,
        along: impl Fn(usize) -> f32,
    ) -> (SurfelMap, Vec<(u32, u32)>) {
        let mut map = SurfelMap::default();
        let planes = [
            (Vec3::Z, Vec3::X, Vec3::Y, Vec3::new(0.1, 0.0, 0.0)),
            (Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.0, 0.0, 0.1)),
        ];
        let at = |(u, v, origin): (Vec3, Vec3, Vec3), i: u32| {
            origin + u * (0.02 * (i % 9) as f32) + v * (0.02 * (i / 9) as f32)
        };
        for &(normal, u, v, origin) in &planes {
            for i in 0..81 {
                map.push(at((u, v, origin), i), normal, [0; 4], 0.015, 20.0, 0);
            }
        }
        let mut made_from = Vec::new();
        for (plane, &(normal, u, v, origin)) in planes.iter().enumerate() {
            for i in (0..81).filter(|i| i % 9 < 8 && i / 9 < 8) {
                let old = at((u, v, origin), i);
                let copy = old + (u + v) * 0.01 + shift + normal * along(made_from.len());
                made_from.push((map.len() as u32, plane as u32 * 81 + i));
                map.push(copy, normal, [0; 4], 0.015, 20.0, 300);
            }
        }
        (map, made_from)
    }

    #[test]
    fn copies_scattered_about_the_old_surface_are_merged_copies_offset_as_a_whole_are_not() {
        let config = FusionConfig::default();
        let now = due(&config);
        // Noise: off the old planes by 3 mm, alternately in front and behind.
        let scatter = |i: usize| if i % 2 == 0 { 0.003 } else { -0.003 };
        let (mut noisy, _) = floor_and_wall_with_copies(Vec3::ZERO, scatter);
        assert_eq!(
            merge_due(&mut noisy, &config, now),
            128,
            "all on the old disks"
        );
        // Drift: every copy 6 mm off both planes (8.5 mm in all). Each still
        // lies on an old disk (1.1 cm across, 6 mm along), none within 1 cm
        // of an old centre.
        let (mut drifted, _) = floor_and_wall_with_copies(Vec3::new(0.006, 0.0, 0.006), |_| 0.0);
        assert_eq!(
            merge_due(&mut drifted, &config, now),
            0,
            "left for the loop checks"
        );
        // A drift of 3 mm is within what noise leaves: merged.
        let (mut small, _) = floor_and_wall_with_copies(Vec3::new(0.003, 0.0, 0.0), |_| 0.0);
        assert_eq!(merge_due(&mut small, &config, now), 128);
    }

    #[test]
    fn the_same_copies_merge_into_the_same_old_surfels_on_any_thread_count() {
        let config = FusionConfig::default();
        let now = due(&config);
        // Each copy lies as far from four old centres: the ties decide.
        let on_threads = |threads: usize| {
            let (mut map, _) = floor_and_wall_with_copies(Vec3::ZERO, |_| 0.0);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let merged = pool.install(|| merge_due(&mut map, &config, now));
            (merged, map.last_seen().to_vec(), map.confidences().to_vec())
        };
        let one = on_threads(1);
        assert_eq!(one.0, 128);
        assert_eq!(on_threads(4), one);
    }

    #[test]
    fn the_copies_offset_is_measured_along_the_normals_they_span() {
        let shift = Vec3::new(0.006, 0.004, 0.006);
        let (map, made_from) = floor_and_wall_with_copies(shift, |_| 0.0);
        let (positions, normals) = (map.positions(), map.normals());
        // Each copy with the old surfel it was made from.
        let pairs = made_from
            .iter()
            .map(|&(copy, old)| (copy as usize, old as usize));
        let offset = copies_offset(pairs, positions, normals);
        // x and z are measured (damped by 1/(1 + 0.05 * 2/3 * 2)); y, along
        // both planes, is not seen at all.
        assert!((offset.x - 0.006 / 1.0333).abs() < 1e-4, "{offset}");
        assert!((offset.z - 0.006 / 1.0333).abs() < 1e-4, "{offset}");
        assert!(offset.y.abs() < 1e-9, "{offset}");
        assert_eq!(
            copies_offset(std::iter::empty(), positions, normals),
            DVec3::ZERO
        );
    }

    #[test]
    fn a_copy_on_a_woken_surfel_of_an_earlier_visit_is_merged_one_beside_this_visits_is_not() {
        let config = FusionConfig::default();
        let now = due(&config);
        // Made at frame 0 and woken at 250 by the return: an earlier visit's.
        let mut woken = old_and_copy(Vec3::new(0.004, 0.0, 0.003), Vec3::Z);
        woken.touch(0, 250);
        assert_eq!(merge_due(&mut woken, &config, now), 1);
        assert!(woken.confidences()[1] < 0.0, "the copy is absorbed");
        // Made at frame 200 and seen since: this visit's, fusion's to merge
        // with. An inactive surfel a metre away gives the cleanup work.
        let mut this_visit = SurfelMap::default();
        this_visit.push(Vec3::new(1.0, 0.0, 2.0), Vec3::Z, [0; 4], 0.005, 20.0, 0);
        this_visit.push(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, [0; 4], 0.005, 20.0, 200);
        this_visit.push(
            Vec3::new(0.004, 0.0, 2.003),
            Vec3::Z,
            [0; 4],
            0.005,
            20.0,
            300,
        );
        assert_eq!(merge_due(&mut this_visit, &config, now), 0);
        // The same surfel made at frame 0 is an earlier visit's.
        this_visit.push(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, [0; 4], 0.005, 20.0, 0);
        this_visit.touch(3, 250);
        assert_eq!(merge_due(&mut this_visit, &config, now), 1);
        assert_eq!(
            this_visit.last_seen()[3],
            300,
            "it takes the copy's last_seen"
        );
    }

    #[test]
    fn far_turned_or_not_yet_due_copies_stay() {
        let config = FusionConfig::default();
        let now = due(&config);
        let mut far = old_and_copy(Vec3::new(0.02, 0.0, 0.0), Vec3::Z);
        assert_eq!(merge_due(&mut far, &config, now), 0);
        let mut turned = old_and_copy(Vec3::ZERO, Vec3::X);
        assert_eq!(merge_due(&mut turned, &config, now), 0);
        let mut early = old_and_copy(Vec3::ZERO, Vec3::Z);
        assert_eq!(merge_due(&mut early, &config, 310), 0);
        let off = FusionConfig {
            merge_copies_after_frames: 0,
            ..config
        };
        let mut never = old_and_copy(Vec3::ZERO, Vec3::Z);
        assert_eq!(merge_due(&mut never, &off, now), 0);
    }

    #[test]
    fn a_copy_across_the_filters_coarse_cells_is_still_found() {
        let config = FusionConfig::default();
        let now = due(&config);
        // 8 cm coarse cells (4 grid cells of COINCIDE_ACROSS_M): the old
        // surfel and its copy lie on either side of a coarse boundary on
        // every axis.
        let mut map = SurfelMap::default();
        let old = Vec3::new(0.0795, -0.0005, 1.9995);
        map.push(old, Vec3::Z, [0; 4], 0.005, 20.0, 0);
        map.push(
            Vec3::new(0.0802, 0.0003, 2.0003),
            Vec3::Z,
            [0; 4],
            0.005,
            20.0,
            300,
        );
        assert_eq!(merge_due(&mut map, &config, now), 1);
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
