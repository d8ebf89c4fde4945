//! A hand-held scan with fast swings, and the motion blur they cause: the
//! known trajectory with the camera turned aside and back about the
//! vertical every so often, rendered with each frame's colour averaged over
//! its exposure.
//!
//! Poses are `world_from_camera` (metres) in the room's frame; times are
//! frame numbers (fractional between frames).

use glam::{DAffine3, DMat3, DQuat, DVec3};

use super::loop_path::loop_pose_at;
use super::noise::NoiseModel;
use super::render::{render_into, RenderedFrame};
use super::scene::Scene;
use super::trajectory::trajectory_pose_at;
use crate::camera::Intrinsics;
use crate::portable_math::quat_from_axis_angle;

/// When and how far the camera swings aside from [`trajectory_pose_at`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwingPath {
    /// The first swing starts at this frame.
    pub first_frame: f64,
    /// A swing starts every this many frames.
    pub period_frames: f64,
    /// Frames a turn aside (and the turn back) takes; the turn follows a
    /// smoothstep, so its fastest frame turns 1.5x the average.
    pub swing_frames: f64,
    /// Frames the camera stays turned aside.
    pub hold_frames: f64,
    /// How far the camera turns, degrees; successive swings alternate
    /// sides.
    pub amplitude_deg: f64,
    /// `Some(n)`: the path swung about is the closed loop of
    /// [`loop_pose_at`], `n` frames a turn (a scan that ends where it
    /// began); `None`: the open path of [`trajectory_pose_at`].
    pub loop_frames: Option<f64>,
}

impl Default for SwingPath {
    /// Swings of 60 degrees in 10 frames (6 degrees a frame on average, 9
    /// at the fastest: 270 degrees a second at 30 Hz), held aside for 15
    /// frames, every 70 frames from frame 40.
    fn default() -> Self {
        Self {
            first_frame: 40.0,
            period_frames: 70.0,
            swing_frames: 10.0,
            hold_frames: 15.0,
            amplitude_deg: 60.0,
            loop_frames: None,
        }
    }
}

impl SwingPath {
    /// The swing's turn at time `t` (frames), radians about the world's
    /// vertical.
    #[must_use]
    pub fn yaw(&self, t: f64) -> f64 {
        let since = t - self.first_frame;
        let period = self.period_frames.max(1.0);
        if !since.is_finite() || since < 0.0 {
            return 0.0;
        }
        let turn = libm::floor(since / period);
        let phase = since - turn * period;
        let sign = if libm::fmod(turn, 2.0) == 0.0 {
            1.0
        } else {
            -1.0
        };
        let swing = self.swing_frames.max(1e-6);
        let smooth = |x: f64| {
            let x = x.clamp(0.0, 1.0);
            x * x * (3.0 - 2.0 * x)
        };
        let fraction = if phase < swing {
            smooth(phase / swing)
        } else if phase < swing + self.hold_frames {
            1.0
        } else {
            1.0 - smooth((phase - swing - self.hold_frames) / swing)
        };
        sign * self.amplitude_deg.to_radians() * fraction
    }

    /// Pose at time `t` (frames): the path swung about ([`trajectory_pose_at`]
    /// or [`loop_pose_at`]) turned by [`Self::yaw`] about the vertical
    /// through the camera.
    #[must_use]
    pub fn pose(&self, t: f64) -> DAffine3 {
        let base = match self.loop_frames {
            Some(n) => loop_pose_at(t, n),
            None => trajectory_pose_at(t),
        };
        let turn = DMat3::from_quat(quat_from_axis_angle(DVec3::Y, self.yaw(t)));
        DAffine3 {
            matrix3: turn * base.matrix3,
            translation: base.translation,
        }
    }

    /// `samples` poses evenly spread over the exposure centred on frame
    /// `t` that lasts `exposure` of a frame interval (with an odd count,
    /// the middle one is `t`'s, the pose the frame is stamped with).
    #[must_use]
    pub fn exposure(&self, t: f64, exposure: f64, samples: usize) -> Vec<DAffine3> {
        let n = samples.max(1);
        (0..n)
            .map(|s| {
                let offset = if n == 1 {
                    0.0
                } else {
                    exposure * (s as f64 / (n - 1) as f64 - 0.5)
                };
                self.pose(t + offset)
            })
            .collect()
    }
}

/// Renders a frame whose colour is the mean of `scene` seen from each pose
/// of `exposure` (motion blur) and whose depth is the middle pose's, with
/// a hole wherever the poses see depths more than 2 % apart (a depth
/// sensor loses what moves across its pattern or baseline during the
/// exposure: the edges of objects swept past). `noise` and `seed` as in
/// [`render_into`]; an empty `exposure` gives an empty frame.
#[must_use]
pub fn render_blurred(
    scene: &Scene,
    intrinsics: &Intrinsics,
    exposure: &[DAffine3],
    noise: &NoiseModel,
    seed: u64,
) -> RenderedFrame {
    let Some(middle) = exposure.get(exposure.len() / 2) else {
        return RenderedFrame::default();
    };
    let mut out = RenderedFrame::default();
    render_into(&mut out, scene, intrinsics, middle, noise, seed);
    let mut colour_sum: Vec<u32> = out.rgb.iter().map(|&c| u32::from(c)).collect();
    let mut sub = RenderedFrame::default();
    let mut counted = 1u32;
    for (i, pose) in exposure.iter().enumerate() {
        if i == exposure.len() / 2 {
            continue;
        }
        render_into(&mut sub, scene, intrinsics, pose, noise, seed);
        for (sum, &c) in colour_sum.iter_mut().zip(&sub.rgb) {
            *sum += u32::from(c);
        }
        for ((raw, &z), &z_sub) in out.depth_raw.iter_mut().zip(&out.depth_m).zip(&sub.depth_m) {
            if (z - z_sub).abs() > 0.02 * z {
                *raw = 0;
            }
        }
        counted += 1;
    }
    for (c, sum) in out.rgb.iter_mut().zip(colour_sum) {
        *c = ((sum + counted / 2) / counted).min(255) as u8;
    }
    out
}

/// The rotation, degrees, from pose `a` to pose `b` (for tests and
/// reports of how fast a path turns).
#[must_use]
pub fn turn_between_deg(a: &DAffine3, b: &DAffine3) -> f64 {
    let relative = DQuat::from_mat3(&(a.matrix3.transpose() * b.matrix3));
    crate::portable_math::axis_angle(relative).1.to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::test_support::small;

    #[test]
    fn swings_about_the_closed_loop_end_where_they_began() {
        let path = SwingPath {
            loop_frames: Some(600.0),
            ..SwingPath::default()
        };
        // Frame 600 is a turn later and between swings (560 frames after
        // the first, a whole number of periods).
        let (dt, dr) = crate::se3::motion_magnitude(&(path.pose(0.0).inverse() * path.pose(600.0)));
        assert!(dt < 1e-9 && dr < 1e-9, "{dt} m, {dr} rad");
        let (dt, dr) = crate::se3::motion_magnitude(
            &(super::super::loop_pose(50, 600).inverse() * path.pose(50.0)),
        );
        assert!(dt < 1e-12, "{dt} m: the loop's own position");
        assert!(
            (dr.to_degrees() - 60.0).abs() < 1e-6,
            "{} deg: turned aside",
            dr.to_degrees()
        );
    }

    #[test]
    fn swings_turn_aside_and_back_at_the_stated_speed() {
        let path = SwingPath::default();
        assert_eq!(path.yaw(0.0), 0.0);
        assert_eq!(path.yaw(39.0), 0.0);
        assert!((path.yaw(55.0).to_degrees() - 60.0).abs() < 1e-9);
        assert!(
            (path.yaw(125.0).to_degrees() + 60.0).abs() < 1e-9,
            "other side"
        );
        assert!(path.yaw(100.0).abs() < 1e-12, "back on the path");
        let fastest = (40..50)
            .map(|i| turn_between_deg(&path.pose(i as f64), &path.pose(i as f64 + 1.0)))
            .fold(0.0, f64::max);
        assert!((8.0..11.0).contains(&fastest), "{fastest} degrees a frame");
        assert_eq!(path.pose(10.0), trajectory_pose_at(10.0));
        assert_eq!(path.exposure(45.0, 0.5, 3)[1], path.pose(45.0));
    }

    #[test]
    fn blur_averages_colour_and_opens_holes_at_swept_edges() {
        let scene = Scene::room();
        let k = small();
        let path = SwingPath::default();
        let still = render_blurred(
            &scene,
            &k,
            &path.exposure(10.0, 0.5, 5),
            &NoiseModel::none(),
            0,
        );
        let fast = render_blurred(
            &scene,
            &k,
            &path.exposure(45.0, 0.5, 5),
            &NoiseModel::none(),
            0,
        );
        assert_eq!(still.rgb.len(), 3 * k.pixel_count());
        let gradient = |f: &RenderedFrame| -> f64 {
            f.rgb
                .chunks_exact(3)
                .collect::<Vec<_>>()
                .windows(2)
                .map(|p| f64::from(p[0][1].abs_diff(p[1][1])))
                .sum::<f64>()
        };
        assert!(gradient(&fast) < 0.7 * gradient(&still), "blur smooths");
        assert!(fast.valid_depth_count() < still.valid_depth_count());
        assert!(fast.valid_depth_count() > k.pixel_count() / 2);
        assert!(render_blurred(&scene, &k, &[], &NoiseModel::none(), 0)
            .rgb
            .is_empty());
    }
}
