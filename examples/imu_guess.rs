//! What the gyro's rotation is worth as the constant-velocity guess's
//! (`SlamConfig::imu_rotation_guess`): the synthetic room along the
//! hand-held swings of `tests/hand_held_swings.rs` (60 degrees in 6
//! frames at 30 Hz, colour blurred over half a frame, 320x240), with a
//! phone's IMU simulated from the true path (`ImuSimulation::phone`), run
//! with the guess off and on; colour, then depth only. Prints, per run,
//! the verdict counts, the frame the IMU was calibrated at and the ATE.
//!
//! `cargo run --release --example imu_guess [FRAMES]` (default 250)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use glam::DAffine3;
use surfel_slam::eval::ate;
use surfel_slam::synthetic::{self, render_blurred, ImuSimulation, NoiseModel, Scene, SwingPath};
use surfel_slam::{CameraPreset, Intrinsics, Pipeline, RgbdFrame, SlamConfig};

const FPS: f64 = 30.0;

fn main() {
    let frames: usize = std::env::args()
        .nth(1)
        .map_or(250, |s| s.parse().expect("FRAMES: a number"));
    let mut config = SlamConfig::from_preset(CameraPreset::TumFr3);
    config.intrinsics = Intrinsics::new(262.5, 262.5, 159.5, 119.5, 320, 240);
    config.depth = synthetic::depth_settings();
    let path = SwingPath {
        amplitude_deg: 60.0,
        swing_frames: 6.0,
        ..SwingPath::default()
    };
    let scene = Scene::room();
    let origin = path.pose(0.0).inverse();
    let (rendered, truth): (Vec<RgbdFrame>, Vec<(f64, DAffine3)>) = (0..frames)
        .map(|i| {
            let t = i as f64;
            let r = render_blurred(
                &scene,
                &config.intrinsics,
                &path.exposure(t, 0.5, 5),
                &NoiseModel::none(),
                i as u64,
            );
            (
                r.to_frame(&config.depth).expect("frame"),
                (t / FPS, origin * path.pose(t)),
            )
        })
        .unzip();
    let imu =
        ImuSimulation::phone().simulate(|t| path.pose(t * FPS), 0.0, frames as f64 / FPS + 0.5);
    let mut grey = rendered.clone();
    for f in &mut grey {
        f.rgb.fill(surfel_slam::dataset::DEPTH_ONLY_GREY);
    }
    for (name, input) in [("colour", &rendered), ("depth only", &grey)] {
        for guess in [false, true] {
            let mut c = config.clone();
            c.imu_rotation_guess = guess;
            let mut slam = Pipeline::new(c).expect("config");
            let (mut pushed, mut calibrated_at) = (0, None);
            for (i, (frame, (t, _))) in input.iter().zip(&truth).enumerate() {
                let ahead = imu[pushed..].partition_point(|s| s.time_s <= t + 0.25);
                slam.push_imu(&imu[pushed..pushed + ahead])
                    .expect("samples");
                pushed += ahead;
                slam.push_frame(frame, *t).expect("frame");
                if calibrated_at.is_none() && slam.imu_calibration().is_some() {
                    calibrated_at = Some(i);
                }
            }
            let c = slam.counts();
            let ate_cm =
                ate(slam.trajectory(), &truth, 0.001).map_or(f64::NAN, |a| a.rmse_m * 100.0);
            println!(
                "{name}, imu rotation guess {}: {} tracked, {} lost, {} recovered, {} held, {} restarted; imu calibrated at frame {calibrated_at:?}; ATE {ate_cm:.2} cm",
                if guess { "on " } else { "off" },
                c.tracked,
                c.lost,
                c.recovered,
                c.held,
                c.restarted,
            );
        }
    }
}
