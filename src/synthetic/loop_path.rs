//! A closed camera path through [`Scene::room`](super::Scene::room) that
//! returns exactly to its start: the revisit that loop closure needs, with
//! known truth.

use glam::{DAffine3, DVec3};
use std::f64::consts::TAU;

use super::trajectory::look_at;

/// Pose `index` (`world_from_camera`, metres) of a closed loop around the
/// room centre that takes `frames_per_loop` frames per turn: pose
/// `index + frames_per_loop` equals pose `index` (to rounding), so a run
/// longer than one turn revisits its first views. A circle of radius 0.8 m,
/// 1.40..1.50 m above the floor, looking ahead along the circle and a little
/// inward (at a point 2 m away, 0.2..0.6 m above the floor), with a pitch
/// and yaw wobble and up to 2 degrees of roll, all periodic in the turn. At
/// 240 frames per turn it moves 2.1 cm and 1.5 degrees per frame; it stays
/// more than 1 m from every surface of the room. `frames_per_loop = 0` is
/// taken as 1.
#[must_use]
pub fn loop_pose(index: usize, frames_per_loop: usize) -> DAffine3 {
    loop_pose_at(index as f64, frames_per_loop.max(1) as f64)
}

/// [`loop_pose`] at time `t` (frames, fractional between frames) of a loop
/// that takes `frames_per_loop` frames a turn (below 1 taken as 1).
#[must_use]
pub fn loop_pose_at(t: f64, frames_per_loop: f64) -> DAffine3 {
    let turn = t / frames_per_loop.max(1.0);
    let theta = 0.2 + TAU * turn;
    let radius = 0.8;
    let height = 1.45 + 0.05 * libm::sin(2.0 * theta);
    let eye = DVec3::new(
        radius * libm::cos(theta),
        -height,
        radius * libm::sin(theta),
    );
    let look = theta + 1.75 + 0.1 * libm::sin(3.0 * theta);
    let target = DVec3::new(
        eye.x + 2.0 * libm::cos(look),
        -0.4 - 0.2 * libm::cos(2.0 * theta),
        eye.z + 2.0 * libm::sin(look),
    );
    let roll = 2f64.to_radians() * libm::sin(4.0 * theta);
    look_at(eye, target) * DAffine3::from_mat3(crate::portable_math::rotation_z(roll))
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;
    use crate::se3::motion_magnitude;
    use crate::synthetic::test_support::{settings, small};
    use crate::synthetic::{render, NoiseModel, Scene};

    #[test]
    fn the_loop_returns_to_its_start_and_stays_in_the_room() {
        let scene = Scene::room();
        let n = 240;
        let (dt, dr) = motion_magnitude(&(loop_pose(0, n).inverse() * loop_pose(n, n)));
        assert!(dt < 1e-9 && dr < 1e-9, "{dt} m, {dr} rad");
        for i in 0..n {
            let (a, b) = (loop_pose(i, n), loop_pose(i + 1, n));
            let (dt, dr) = motion_magnitude(&(a.inverse() * b));
            assert!((0.01..0.03).contains(&dt), "step {i}: {dt} m");
            assert!(dr.to_degrees() < 3.0, "step {i}: {} deg", dr.to_degrees());
            assert!(scene.distance_to_surface(a.translation) > 1.0);
            assert!(scene.is_free(a.translation));
        }
        let k = small();
        for i in (0..n).step_by(20) {
            let f = render(&scene, &k, &loop_pose(i, n), &NoiseModel::none(), 0);
            let frame = f.to_frame(&settings()).expect("valid");
            let valid = frame.valid_depth_count() as f64 / k.pixel_count() as f64;
            assert!(valid >= 0.9, "frame {i}: {valid}");
        }
    }
}
