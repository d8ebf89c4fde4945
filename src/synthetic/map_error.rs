//! Map error: how far a reconstructed map's surfels lie from the scene's
//! true surfaces (the ground truth of the map, as the trajectory is of the
//! poses).

use glam::{DAffine3, Vec3};
use rayon::prelude::*;

use super::scene::Scene;

/// Distances of surfel centres from the nearest true surface, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MapError {
    /// Root mean square distance.
    pub rms_m: f64,
    /// Median distance.
    pub median_m: f64,
    /// Fraction of the surfels within 1 cm of a true surface.
    pub within_1cm: f64,
    /// Surfels measured (the finite positions).
    pub surfels: usize,
}

/// The error of `positions` (the map's world frame, metres) against
/// `scene`, where `scene_from_map` places the map's world in the scene's
/// (for a pipeline: the true pose of its first frame). Non-finite
/// positions are skipped.
#[must_use]
pub fn map_error(scene: &Scene, positions: &[Vec3], scene_from_map: &DAffine3) -> MapError {
    let mut distances: Vec<f64> = positions
        .par_iter()
        .filter(|p| p.is_finite())
        .map(|p| scene.distance_to_surface(scene_from_map.transform_point3(p.as_dvec3())))
        .collect();
    let n = distances.len();
    if n == 0 {
        return MapError::default();
    }
    let sum2: f64 = distances.iter().map(|d| d * d).sum();
    let within = distances.iter().filter(|&&d| d <= 0.01).count();
    distances.sort_unstable_by(f64::total_cmp);
    MapError {
        rms_m: (sum2 / n as f64).sqrt(),
        median_m: distances[n / 2],
        within_1cm: within as f64 / n as f64,
        surfels: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn points_on_the_surface_have_no_error_and_moved_ones_do() {
        let scene = Scene::room();
        // Points on the floor (y = 0) away from the boxes, in a map whose
        // world is shifted by 1 m along x.
        let scene_from_map = DAffine3::from_translation(DVec3::new(1.0, 0.0, 0.0));
        let on: Vec<Vec3> = (0..100)
            .map(|i| Vec3::new(-1.5 + 0.01 * i as f32, 0.0, 0.2))
            .collect();
        let e = map_error(&scene, &on, &scene_from_map);
        assert_eq!(e.surfels, 100);
        assert!(e.rms_m < 1e-6 && e.within_1cm == 1.0, "{e:?}");
        let off: Vec<Vec3> = on.iter().map(|p| *p - Vec3::Y * 0.02).collect();
        let e = map_error(&scene, &[off, vec![Vec3::NAN]].concat(), &scene_from_map);
        assert_eq!(e.surfels, 100);
        assert!(
            (e.rms_m - 0.02).abs() < 1e-6 && e.within_1cm == 0.0,
            "{e:?}"
        );
        assert_eq!(map_error(&scene, &[], &scene_from_map), MapError::default());
    }
}
