//! Removal of surfels that stayed unstable too long (outliers, moving
//! objects), and of surfels absorbed into others.

use super::spatial_order::SpatialOrder;
use super::{FusionConfig, SurfelMap};

/// Removes surfels with confidence below the stable threshold that were created
/// more than `unstable_max_age` frames before `frame`, and surfels absorbed
/// into others (negative confidence). Returns how many went.
///
/// Confidence only decreases when a surfel is absorbed, and surfels are
/// stored in creation order, so the surfels old enough at the previous call
/// were settled then (removed, or stable until absorbed): only the younger
/// tail is visited. Stable surfels absorbed before the tail stay in place
/// (never a candidate, never predicted) until they make up 5 % of the map:
/// compacting moves every later surfel, which a renderer must upload again,
/// and on a revisit some surfel near the start of the map is absorbed at
/// almost every cleanup (measured on TUM fr3/teddy).
///
/// The surfels that settle at this call (old enough, kept because stable)
/// are then sorted in space by `order` (see `spatial_order`), so the map's
/// blocks stay compact; they lie in the compacted range, which a renderer
/// uploads again anyway.
pub fn remove_unstable(
    map: &mut SurfelMap,
    config: &FusionConfig,
    frame: u32,
    order: &mut SpatialOrder,
) -> usize {
    let before = map.len();
    let settled_before = map
        .last_cleanup
        .map_or(0, |f| f.saturating_sub(config.unstable_max_age));
    let tail = map.first_seen.partition_point(|&f| f < settled_before);
    let start = match map.first_absorbed {
        Some(first) if first < tail => {
            let holes = map.confidences[first..tail]
                .iter()
                .filter(|&&c| c < 0.0)
                .count();
            if holes * 20 >= map.len() {
                map.first_absorbed = None;
                first
            } else {
                tail
            }
        }
        _ => {
            map.first_absorbed = None;
            tail
        }
    };
    let stable = config.stable_confidence;
    let max_age = config.unstable_max_age;
    let keep = |map: &SurfelMap, i: usize| {
        let c = map.confidences[i];
        c >= stable || (c >= 0.0 && frame.saturating_sub(map.first_seen[i]) <= max_age)
    };
    // Runs left from another map (a reset that kept them) would be read
    // past this map's end: then the order starts again.
    order.forget_beyond(map.len());
    order.before_removal(start, |i| !keep(map, i));
    map.retain_from(start, keep);
    // Every surfel before `settled` was settled at an earlier call, and the
    // rest are still in creation order, so both bounds are partition points.
    let settled = map.first_seen.partition_point(|&f| f < settled_before);
    let now_settled = map
        .first_seen
        .partition_point(|&f| f < frame.saturating_sub(max_age));
    order.settle(map, settled, now_settled);
    map.last_cleanup = Some(frame);
    before - map.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn absorbed_surfels_before_the_tail_wait_until_they_are_5_percent() {
        let config = FusionConfig::default();
        let mut order = SpatialOrder::default();
        let mut map = SurfelMap::default();
        for i in 0..100 {
            map.push(Vec3::splat(i as f32), Vec3::Z, [0; 4], 0.01, 10.0, 0);
        }
        // Settle the old surfels: a cleanup long after they were made.
        let frame = 100;
        assert_eq!(remove_unstable(&mut map, &config, frame, &mut order), 0);
        for i in [3, 7] {
            map.absorb(i);
        }
        assert_eq!((map.live_len(), map.absorbed_len()), (98, 2));
        assert_eq!(
            remove_unstable(&mut map, &config, frame + 10, &mut order),
            0
        );
        assert_eq!(map.len(), 100);
        assert_eq!((map.live_len(), map.absorbed_len()), (98, 2));
        for i in [20, 30, 40] {
            map.absorb(i);
        }
        assert_eq!(
            remove_unstable(&mut map, &config, frame + 20, &mut order),
            5
        );
        assert_eq!(map.len(), 95);
        assert_eq!((map.live_len(), map.absorbed_len()), (95, 0));
        assert!(map.confidences.iter().all(|&c| c >= 0.0));
        assert_eq!(map.positions[3], Vec3::splat(4.0), "order kept");
    }

    #[test]
    fn a_cleanup_with_the_sorted_runs_of_a_larger_map_does_not_read_past_the_end() {
        let config = FusionConfig::default();
        let mut order = SpatialOrder::default();
        let mut map = SurfelMap::default();
        for i in 0..3000 {
            map.push(
                Vec3::splat(i as f32 * 1e-3),
                Vec3::Z,
                [0; 4],
                0.01,
                10.0,
                i / 100,
            );
        }
        remove_unstable(&mut map, &config, 40, &mut order);
        remove_unstable(&mut map, &config, 50, &mut order);
        // A new, smaller map with the same order (as a reset that forgot it).
        map.clear();
        for i in 0..500 {
            map.push(
                Vec3::splat(i as f32 * 1e-3),
                Vec3::Z,
                [0; 4],
                0.01,
                10.0,
                i / 100,
            );
        }
        map.absorb(7);
        remove_unstable(&mut map, &config, 30, &mut order);
        assert_eq!(map.len(), 499);
        assert_eq!(map.live_len(), 499);
        remove_unstable(&mut map, &config, 40, &mut order);
        assert_eq!(map.len(), 499);
    }
}
