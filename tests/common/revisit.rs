//! The revisit sequence of `tests/determinism.rs` and `tests/session.rs`:
//! the synthetic room's loop path out and back (the return meets an
//! inactive model: local and global loop checks, a deformation), a
//! distorted stretch (drift), frames of noise (lost) and a reappearance
//! (relocalised), at 320x240 with Kinect-like noise.

use surfel_slam::synthetic::{self, loop_pose, NoiseModel, Scene};
use surfel_slam::{RgbdFrame, SlamConfig};

use super::synthetic_config;

/// Frames per turn of the loop path (2.1 cm and 1.5 degrees a frame).
pub const PER_LOOP: usize = 240;
/// Frames played forwards, then backwards to frame 0.
pub const OUT: usize = 50;
/// Frames of the way out taken with a focal length 3 % shorter than the
/// one the pipeline is given: a distorted stretch, the path drifts.
pub const DISTORTED: std::ops::Range<usize> = 10..40;
/// Frames of noise after the return (the camera covered): lost.
pub const COVERED: usize = 2;
/// Where the camera then reappears on its path (relocalised), and how
/// many frames it walks on from there.
pub const REAPPEARS: (usize, usize) = (25, 6);

/// The test's settings: 320x240, a 30-frame active window (the return
/// meets an inactive model), global looks every 5 frames at keyframes at
/// least 30 frames old, copies merged 20 frames after they are made.
pub fn config() -> SlamConfig {
    let mut config = synthetic_config(synthetic::default_intrinsics().half());
    config.fusion.active_window_frames = 30;
    config.fusion.merge_copies_after_frames = 20;
    let g = &mut config.loop_closure.global;
    g.enabled = true;
    g.min_age_frames = 30;
    g.every_frames = 5;
    g.cooldown_frames = 30;
    config
}

/// A frame of noise: random colour and random depth in 0.5..4.5 m.
pub fn covered(config: &SlamConfig, seed: u64) -> RgbdFrame {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let n = config.intrinsics.pixel_count();
    RgbdFrame {
        width: config.intrinsics.width,
        height: config.intrinsics.height,
        rgb: (0..3 * n).map(|_| (next() >> 56) as u8).collect(),
        depth_deviation: Vec::new(),
        depth_m: (0..n)
            .map(|_| 0.5 + 4.0 * (next() >> 40) as f32 / (1u64 << 24) as f32)
            .collect(),
    }
}

/// The sequence under Kinect-like noise: the loop path out to frame
/// [`OUT`] (with the [`DISTORTED`] stretch) and back to frame 0 (views
/// last seen more than the active window ago), frames of noise, then
/// [`REAPPEARS`].
pub fn frames(config: &SlamConfig) -> Vec<RgbdFrame> {
    let scene = Scene::room();
    let views = (0..OUT)
        .chain((0..OUT).rev())
        .map(Some)
        .chain(std::iter::repeat_n(None, COVERED))
        .chain((REAPPEARS.0..REAPPEARS.0 + REAPPEARS.1).map(Some));
    views
        .enumerate()
        .map(|(i, view)| {
            let Some(j) = view else {
                return covered(config, i as u64);
            };
            let mut k = config.intrinsics;
            if i < OUT && DISTORTED.contains(&j) {
                k.fx /= 1.03;
                k.fy /= 1.03;
            }
            synthetic::render(
                &scene,
                &k,
                &loop_pose(j, PER_LOOP),
                &NoiseModel::kinect(),
                i as u64,
            )
            .to_frame(&config.depth)
            .expect("synthetic frame")
        })
        .collect()
}
