//! The known camera path through the default room, `look_at`, and the
//! default intrinsics.

use glam::{DAffine3, DMat3, DVec3};

use crate::camera::Intrinsics;

/// Default intrinsics: 640x480, fx = fy = 525, cx = 319.5, cy = 239.5 (Kinect-like).
#[must_use]
pub fn default_intrinsics() -> Intrinsics {
    Intrinsics::new(525.0, 525.0, 319.5, 239.5, 640, 480)
}

/// world_from_camera of a camera at `eye` looking at `target`: camera +z points
/// at the target, camera +y points as close to world +y (down; world -y is up)
/// as possible, +x completes a right-handed frame (right). When looking
/// straight up or down, camera +y falls back to world +z; when `eye == target`
/// (or either is not finite) the rotation is the identity.
#[must_use]
pub fn look_at(eye: DVec3, target: DVec3) -> DAffine3 {
    let Some(forward) = (target - eye).try_normalize() else {
        return DAffine3::from_translation(eye);
    };
    let down = if forward.cross(DVec3::Y).length_squared() > 1e-12 {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let right = down.cross(forward).normalize();
    let camera_down = forward.cross(right);
    DAffine3 {
        matrix3: DMat3::from_cols(right, camera_down, forward),
        translation: eye,
    }
}

/// Pose `index` of the known trajectory (see [`trajectory`]).
#[must_use]
pub fn trajectory_pose(index: usize) -> DAffine3 {
    trajectory_pose_at(index as f64)
}

/// The known trajectory at a fractional frame time `t` (frame `i` is
/// `t = i`): the poses between frames, for motion blur.
#[must_use]
pub fn trajectory_pose_at(t: f64) -> DAffine3 {
    // Slow arc around the vertical axis through the room centre.
    let theta = 0.2 + 0.011 * t;
    let radius = 1.1 + 0.15 * libm::sin(0.017 * t);
    let height = 1.45 + 0.12 * libm::sin(0.023 * t);
    let eye = DVec3::new(
        radius * libm::cos(theta),
        -height,
        radius * libm::sin(theta),
    );
    // Looking ahead along the arc and a little inward (100 degrees from the
    // outward radius), at a point 2 m away horizontally and 0.2..0.6 m above
    // the floor, with a gentle yaw / pitch wobble.
    let look = theta + 1.75 + 0.12 * libm::sin(0.031 * t);
    let target = DVec3::new(
        eye.x + 2.0 * libm::cos(look),
        -0.4 - 0.2 * libm::sin(0.019 * t),
        eye.z + 2.0 * libm::sin(look),
    );
    let roll = 3f64.to_radians() * libm::sin(0.05 * t);
    look_at(eye, target) * DAffine3::from_mat3(crate::portable_math::rotation_z(roll))
}

/// The first `frames` poses (world_from_camera) of a known smooth handheld-like
/// path through [`Scene::room`](super::Scene::room): a slow arc of radius 0.95..1.25 m around the
/// room centre, 1.33..1.57 m above the floor, looking ahead along the arc and
/// slightly inward, pitched down 20..35 degrees, with up to 3 degrees of roll
/// and a gentle pitch / yaw wobble. It moves 1.0..1.4 cm and 0.4..0.9 degrees
/// per frame (a handheld Kinect at 30 fps; a full turn takes about 570
/// frames) and stays at least 1.0 m from every surface, so depths lie in about
/// 1.1..4.7 m (about 98 % of them under 4 m). Pose `i` is the same whatever
/// `frames` is.
#[must_use]
pub fn trajectory(frames: usize) -> Vec<DAffine3> {
    (0..frames).map(trajectory_pose).collect()
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use glam::DQuat;

    use super::*;
    use crate::synthetic::test_support::{settings, small};
    use crate::synthetic::{render, NoiseModel, Scene};

    #[test]
    fn trajectory_stays_inside_with_valid_depth() {
        let scene = Scene::room();
        let poses = trajectory(300);
        assert_eq!(poses.len(), 300);
        assert_eq!(trajectory(10)[..], poses[..10]);
        for pair in poses.windows(2) {
            let step = (pair[1].translation - pair[0].translation).length();
            assert!((0.005..0.025).contains(&step), "step {step} m");
            let rel = pair[0].matrix3.transpose() * pair[1].matrix3;
            let angle = DQuat::from_mat3(&rel).to_axis_angle().1.to_degrees();
            assert!((0.2..1.5).contains(&angle), "rotation {angle} deg");
        }
        for pose in trajectory(2000).iter().step_by(7) {
            assert!(scene.is_free(pose.translation));
            assert!(scene.distance_to_surface(pose.translation) >= 0.8);
            assert!((pose.matrix3.determinant() - 1.0).abs() < 1e-9);
        }
        let k = small();
        for (i, pose) in poses.iter().enumerate().step_by(10) {
            let f = render(&scene, &k, pose, &NoiseModel::kinect(), i as u64);
            let frame = f.to_frame(&settings()).expect("valid");
            let valid = frame.valid_depth_count() as f64 / k.pixel_count() as f64;
            assert!(valid >= 0.9, "frame {i}: {valid}");
            let (lo, hi) = f
                .depth_m
                .iter()
                .fold((f32::MAX, 0.0f32), |(lo, hi), &z| (lo.min(z), hi.max(z)));
            assert!(lo > 0.5 && hi < 5.0, "frame {i}: depth {lo}..{hi}");
        }
    }

    #[test]
    fn look_at_conventions() {
        let eye = DVec3::new(0.5, -1.5, -0.2);
        let target = DVec3::new(2.0, -0.5, 1.0);
        let pose = look_at(eye, target);
        let forward = pose.transform_vector3(DVec3::Z);
        assert!((forward - (target - eye).normalize()).length() < 1e-12);
        assert!(
            pose.transform_vector3(DVec3::Y).y > 0.0,
            "camera down is world down"
        );
        assert!(pose.transform_vector3(DVec3::X).y.abs() < 1e-12, "no roll");
        assert!((pose.matrix3.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(pose.transform_point3(DVec3::ZERO), eye);
        // Degenerate inputs do not panic.
        let straight_down = look_at(eye, eye + DVec3::Y);
        assert!((straight_down.matrix3.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(look_at(eye, eye).matrix3, DMat3::IDENTITY);
        let _ = look_at(DVec3::NAN, eye);
    }
}
