//! Removal of surfels that stayed unstable too long (outliers, moving objects).

use super::{FusionConfig, SurfelMap};

/// Removes surfels with confidence below the stable threshold that were created
/// more than `unstable_max_age` frames before `frame`. Returns how many went.
pub fn remove_unstable(map: &mut SurfelMap, config: &FusionConfig, frame: u32) -> usize {
    let before = map.len();
    let confidences = map.confidences.clone();
    let first_seen = map.first_seen.clone();
    map.retain_indices(|i| {
        confidences[i] >= config.stable_confidence
            || frame.saturating_sub(first_seen[i]) <= config.unstable_max_age
    });
    before - map.len()
}
