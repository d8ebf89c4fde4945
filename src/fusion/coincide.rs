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
    let mut grid: HashMap<IVec3, Vec<u32>> = HashMap::with_capacity(young.len());
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &j in &young {
        let p = positions[j as usize];
        lo = lo.min(p);
        hi = hi.max(p);
        grid.entry(cell(p)).or_default().push(j);
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
                        for &j in js {
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
}
