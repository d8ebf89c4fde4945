//! Removal of surfels that stayed unstable too long (outliers, moving
//! objects), and of surfels absorbed into others.

use super::{FusionConfig, SurfelMap};

/// Removes surfels with confidence below the stable threshold that were created
/// more than `unstable_max_age` frames before `frame`, and surfels absorbed
/// into others (negative confidence). Returns how many went.
///
/// Confidence only decreases when a surfel is absorbed, and surfels are
/// stored in creation order, so the surfels old enough at the previous call
/// were settled then (removed, or stable until absorbed): only the younger
/// tail is visited, plus the map from the first surfel absorbed since (a
/// stable one can sit anywhere).
pub fn remove_unstable(map: &mut SurfelMap, config: &FusionConfig, frame: u32) -> usize {
    let before = map.len();
    let settled_before = map
        .last_cleanup
        .map_or(0, |f| f.saturating_sub(config.unstable_max_age));
    let start = map.first_seen.partition_point(|&f| f < settled_before);
    let start = map.first_absorbed.take().map_or(start, |a| a.min(start));
    let stable = config.stable_confidence;
    let max_age = config.unstable_max_age;
    let (confidences, first_seen) = (&map.confidences, &map.first_seen);
    let keep: Vec<bool> = (start..before)
        .map(|i| {
            confidences[i] >= stable
                || (confidences[i] >= 0.0 && frame.saturating_sub(first_seen[i]) <= max_age)
        })
        .collect();
    map.retain_from(start, |i| keep[i - start]);
    map.last_cleanup = Some(frame);
    before - map.len()
}
