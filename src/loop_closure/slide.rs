//! Whether a global match undoes a slide of the last frames' tracking
//! rather than drift of the map: judged against where constant velocity,
//! carried on from a few frames back, puts the frame (see
//! [`GlobalConfig::slide_fraction`]).

use super::global::{pose_distance, undoes_slide, GlobalConfig};
use glam::DAffine3;

/// Where constant velocity puts the frame after `trajectory`'s last entry
/// when carried on from `frames` entries back (`world_from_camera`): the
/// motion into the entry `frames` back, repeated `frames` times. `None`
/// without `frames + 1` entries.
fn constant_velocity_guess(trajectory: &[(f64, DAffine3)], frames: usize) -> Option<DAffine3> {
    let start = trajectory.len().checked_sub(frames + 1)?;
    let (_, before) = trajectory.get(start)?;
    let (_, base) = trajectory.get(start + 1)?;
    let step = before.inverse() * *base;
    Some((0..frames).fold(*base, |pose, _| pose * step))
}

/// Frames before the slide on which the guess's own accuracy is judged.
const PRIOR_CHECKED_FRAMES: usize = 10;

/// Whether `registered` undoes a slide of the tracked pose that began on
/// one of the last `config.slide_frames` frames of `trajectory`, judged
/// from a horizon at which constant velocity predicted the frames before
/// it well (see [`GlobalConfig::slide_fraction`]).
pub(super) fn slide_undone(
    trajectory: &[(f64, DAffine3)],
    (tracked, registered): (&DAffine3, &DAffine3),
    config: &GlobalConfig,
) -> bool {
    let slid = pose_distance(tracked, registered);
    let fraction = config.slide_fraction;
    (1..=config.slide_frames as usize).any(|frames| {
        let Some(guess) = constant_velocity_guess(trajectory, frames) else {
            return false;
        };
        // The frames up to the one the guess starts from.
        let before = &trajectory[..trajectory.len() - frames];
        undoes_slide(tracked, registered, &guess, fraction)
            && prior_miss(before, frames, PRIOR_CHECKED_FRAMES)
                .is_some_and(|miss| miss < fraction * slid)
    })
}

/// The largest [`pose_distance`] between each of the last `count` entries
/// of `trajectory` and its [`constant_velocity_guess`] from `frames`
/// entries before it; `None` without enough entries.
fn prior_miss(trajectory: &[(f64, DAffine3)], frames: usize, count: usize) -> Option<f64> {
    let first = trajectory.len().checked_sub(count)?;
    (first..trajectory.len())
        .map(|j| {
            let guess = constant_velocity_guess(trajectory.get(..j)?, frames)?;
            Some(pose_distance(&guess, &trajectory.get(j)?.1))
        })
        .try_fold(0.0, |worst: f64, miss| Some(worst.max(miss?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn at(x: f64) -> (f64, DAffine3) {
        (x, DAffine3::from_translation(DVec3::new(x, 0.0, 0.0)))
    }

    #[test]
    fn the_guess_carries_an_earlier_motion_on_to_the_next_frame() {
        let x = |g: Option<DAffine3>| g.map(|g| g.translation.x);
        assert!(constant_velocity_guess(&[], 1).is_none());
        assert!(constant_velocity_guess(&[at(0.0)], 1).is_none());
        // 0, 1, 2 then a slide to 5: from one frame back, 5 + 3 = 8; from
        // two or three frames back, 4; from four, too few entries.
        let path = [at(0.0), at(1.0), at(2.0), at(5.0)];
        assert_eq!(x(constant_velocity_guess(&path, 1)), Some(8.0));
        assert_eq!(x(constant_velocity_guess(&path, 2)), Some(4.0));
        assert_eq!(x(constant_velocity_guess(&path, 3)), Some(4.0));
        assert!(constant_velocity_guess(&path, 4).is_none());
    }

    #[test]
    fn a_slide_is_undone_only_where_the_prior_predicted_the_frames_before() {
        let config = GlobalConfig::default();
        let x = |x: f64| DAffine3::from_translation(DVec3::new(x, 0.0, 0.0));
        // Steady 1 cm a frame for 20 frames, then a 4 cm slide on the next.
        let mut path: Vec<_> = (0..20).map(|i| at(0.01 * f64::from(i))).collect();
        let (tracked, registered) = (x(0.24), x(0.2005));
        assert!(slide_undone(&path, (&tracked, &registered), &config));
        // Drift: tracked where the steady path leads, the old map 4 cm off.
        assert!(!slide_undone(&path, (&x(0.2), &x(0.16)), &config));
        // A shaky camera (2 cm up and down): its prior judges nothing.
        for (i, p) in path.iter_mut().enumerate() {
            p.1.translation.y = if i % 2 == 0 { 0.02 } else { -0.02 };
        }
        assert!(!slide_undone(&path, (&tracked, &registered), &config));
        // Too few frames to judge the prior.
        assert!(!slide_undone(&path[15..], (&tracked, &registered), &config));
        // Off: always bend.
        let off = GlobalConfig {
            slide_frames: 0,
            ..config
        };
        assert!(!slide_undone(&path, (&tracked, &registered), &off));
    }
}
