//! The IMU, where a recording has one (issue #82, item 2): the gyro
//! integrated between frame times against the true rotation of a
//! synthetic path, the IMU's mounting and clock offset found from the
//! recording itself (true poses, then the pipeline's own tracked poses of
//! a rendered run), refused when the motion cannot show them, bad samples
//! refused, and Stray Scanner's `imu.csv` read with its cut-off last row
//! skipped.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use glam::{DAffine3, DMat3, DQuat, DVec3};
use surfel_slam::dataset::DatasetSource;
use surfel_slam::imu::{
    calibrate, integrate_gyro, rotation_vector, CalibrationRefusal, FramePose, ImuError, ImuSample,
};
use surfel_slam::portable_math::quat_from_axis_angle;
use surfel_slam::synthetic::{self, look_at, ImuSimulation, NoiseModel, Scene, SwingPath};
use surfel_slam::{Intrinsics, Pipeline, PipelineError};

/// The closed loop's frames per turn at 30 Hz: 8 s a turn, 45 degrees a
/// second of yaw with pitch, yaw and roll wobbles.
const LOOP_FRAMES: f64 = 240.0;

/// The loop path at `t` seconds (30 frames a second).
fn loop_path(t: f64) -> DAffine3 {
    synthetic::loop_pose_at(t * 30.0, LOOP_FRAMES)
}

/// The loop with a hand's wobble on top: pitch, roll and yaw of 4-6
/// degrees at 0.45-0.9 Hz about the camera (a hand-held scan turns about
/// every axis; the loop alone turns about the vertical almost only).
fn hand_held(t: f64) -> DAffine3 {
    use std::f64::consts::TAU;
    let wobble = quat_from_axis_angle(DVec3::X, 6f64.to_radians() * libm::sin(TAU * 0.7 * t))
        * quat_from_axis_angle(
            DVec3::Z,
            5f64.to_radians() * libm::sin(TAU * 0.45 * t + 1.0),
        )
        * quat_from_axis_angle(DVec3::Y, 4f64.to_radians() * libm::sin(TAU * 0.9 * t + 2.0));
    loop_path(t) * DAffine3::from_quat(wobble)
}

/// The brief's noisier gyro, 0.005 rad/s/sqrt(Hz), 40x the datasheet's.
fn noisy_imu() -> ImuSimulation {
    ImuSimulation {
        gyro_noise_density: 0.005,
        seed: 7,
        ..ImuSimulation::phone()
    }
}

/// A mounting that is no permutation of the camera's axes.
fn tilted_mount() -> DQuat {
    quat_from_axis_angle(DVec3::new(0.3, -0.8, 0.5).normalize(), 2.1)
}

/// `(time, true world_from_camera)` at `rate_hz` over `[0, seconds]`.
fn frames(path: impl Fn(f64) -> DAffine3, rate_hz: f64, seconds: f64) -> Vec<(f64, DAffine3)> {
    let n = (seconds * rate_hz).round() as usize;
    (0..=n)
        .map(|i| {
            let t = i as f64 / rate_hz;
            (t, path(t))
        })
        .collect()
}

fn poses(frames: &[(f64, DAffine3)]) -> Vec<FramePose> {
    frames
        .iter()
        .map(|(t, p)| FramePose {
            time_s: *t,
            world_from_camera: DQuat::from_mat3(&p.matrix3),
            measured: true,
        })
        .collect()
}

/// Each component of the error between the gyro's camera rotation over
/// every frame interval (the simulation's own mounting, offset and bias
/// applied) and the truth, in units of the gyro's noise over the interval.
fn integration_errors(
    sim: &ImuSimulation,
    samples: &[ImuSample],
    truth: &[(f64, DAffine3)],
    allowance_rad: f64,
) -> Vec<f64> {
    let r = sim.camera_from_imu;
    truth
        .windows(2)
        .flat_map(|w| {
            let ((t0, p0), (t1, p1)) = (w[0], w[1]);
            let (a, b) = (t0 + sim.time_offset_s, t1 + sim.time_offset_s);
            let device = integrate_gyro(samples, a, b, sim.gyro_bias_radps).unwrap();
            let camera = r * device * r.inverse();
            let true_turn = DQuat::from_mat3(&(p0.matrix3.transpose() * p1.matrix3));
            let error = rotation_vector(true_turn.inverse() * camera);
            let sigma = sim.gyro_noise_density * (t1 - t0).sqrt();
            [error.x, error.y, error.z].map(|e| e.abs() / (sigma + allowance_rad))
        })
        .collect()
}

fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

#[test]
fn the_gyro_integrated_between_frames_is_the_true_rotation_within_its_noise() {
    // The loop at 60 Hz, the phone's datasheet noise: every component
    // within 5 sigma, and the errors the size the noise says (RMS near 1
    // sigma), so the sigma is neither hiding an error nor inflated.
    let sim = ImuSimulation::phone();
    let truth = frames(loop_path, 60.0, 6.0);
    let samples = sim.simulate(loop_path, -0.2, 6.2);
    let errors = integration_errors(&sim, &samples, &truth, 0.0);
    let worst = errors.iter().copied().fold(0.0, f64::max);
    let spread = rms(&errors);
    println!("loop, phone IMU: worst {worst:.2} sigma, RMS {spread:.2} sigma");
    assert!(worst < 5.0, "worst {worst} sigma");
    assert!((0.75..1.25).contains(&spread), "RMS {spread} sigma");

    // The hand-held swings (60 degrees in a third of a second) at 30 Hz
    // with the noisier gyro. The smoothstep's rate of turn has a kink at
    // each swing's start and end that a straight line between 100 Hz
    // samples cuts: at most (jump in angular acceleration) * h^2 / 8 a
    // frame, allowed for on top of the noise.
    let swing = SwingPath::default();
    let path = |t: f64| swing.pose(t * 30.0);
    let sim = noisy_imu();
    let truth = frames(path, 30.0, 8.0);
    let samples = sim.simulate(path, -0.2, 8.2);
    let turn_s = swing.swing_frames / 30.0;
    let jump = 6.0 * swing.amplitude_deg.to_radians() / (turn_s * turn_s);
    let h = 1.0 / sim.rate_hz;
    let errors = integration_errors(&sim, &samples, &truth, jump * h * h / 8.0);
    let worst = errors.iter().copied().fold(0.0, f64::max);
    println!("swings, noisy IMU: worst {worst:.2} (sigma + kink allowance)");
    assert!(worst < 5.0, "worst {worst}");

    // The mechanism matters: a frame's turn is up to 9 degrees in a swing,
    // which the identity (no IMU) misses by hundreds of sigma.
    let biggest = truth
        .windows(2)
        .map(|w| {
            rotation_vector(DQuat::from_mat3(
                &(w[0].1.matrix3.transpose() * w[1].1.matrix3),
            ))
            .length()
        })
        .fold(0.0, f64::max);
    assert!(biggest > 100.0 * sim.gyro_noise_density * (1.0f64 / 30.0).sqrt());
}

/// Checks a calibration against the simulation's truth: mounting within
/// `max_deg`, offset within `max_ms`.
fn check_calibration(
    found: &surfel_slam::imu::ImuCalibration,
    sim: &ImuSimulation,
    (max_deg, max_ms): (f64, f64),
) {
    let angle = rotation_vector(found.camera_from_imu.inverse() * sim.camera_from_imu)
        .length()
        .to_degrees();
    let offset_ms = (found.time_offset_s - sim.time_offset_s) * 1000.0;
    let bias = (found.gyro_bias_radps - sim.gyro_bias_radps).length();
    println!(
        "mounting off by {angle:.4} deg (sigma {:.4}), offset by {offset_ms:.3} ms (sigma {:.3}), bias by {bias:.5} rad/s; {} pairs, residual {:.5} rad, noise density {:.2e}",
        found.rotation_sigma_rad.to_degrees(),
        found.offset_sigma_s * 1000.0,
        found.pairs,
        found.residual_rms_rad,
        found.gyro_noise_density,
    );
    assert!(angle < max_deg, "mounting off by {angle} deg");
    // The sigma is honest: the error within 4 of them (per axis: the
    // angle is at most sqrt(3) of its largest component).
    assert!(
        angle.to_radians() < 4.0 * 3f64.sqrt() * found.rotation_sigma_rad,
        "mounting off by {angle} deg, sigma {} deg",
        found.rotation_sigma_rad.to_degrees()
    );
    assert!(
        offset_ms.abs() < 4.0 * found.offset_sigma_s * 1000.0,
        "offset off by {offset_ms} ms, sigma {} ms",
        found.offset_sigma_s * 1000.0
    );
    assert!(offset_ms.abs() < max_ms, "offset off by {offset_ms} ms");
}

#[test]
fn calibration_from_the_true_poses_finds_the_mounting_and_the_offset() {
    // Four seconds of the loop at 60 Hz, the iPhone-like mounting and a
    // 10 ms offset.
    let sim = ImuSimulation::phone();
    let truth = frames(loop_path, 60.0, 4.0);
    let samples = sim.simulate(loop_path, -0.5, 4.5);
    let found = calibrate(&poses(&truth), &samples).unwrap_or_else(|e| panic!("{e}"));
    check_calibration(&found, &sim, (1.0, 5.0));
    // The bias found, taken off, and the noise measured on the samples
    // (which err high: motion adds to them).
    assert!((found.gyro_bias_radps - sim.gyro_bias_radps).length() < 1e-3);
    assert!(found.gyro_noise_density >= sim.gyro_noise_density * 0.8);

    // A tilted mounting, a clock 37 ms behind, the noisier gyro; the
    // hand-held wobble at 30 Hz. (The swings about the open path turn
    // about the vertical almost only: with this gyro the mounting about
    // it is pinned to 1.5 degrees only.)
    let sim = ImuSimulation {
        camera_from_imu: tilted_mount(),
        time_offset_s: -0.037,
        ..noisy_imu()
    };
    let truth = frames(hand_held, 30.0, 5.0);
    let samples = sim.simulate(hand_held, -0.5, 5.5);
    let found = calibrate(&poses(&truth), &samples).unwrap_or_else(|e| panic!("{e}"));
    check_calibration(&found, &sim, (1.0, 5.0));

    // The calibrated prior between two frames: within 4 of its sigmas.
    for w in truth.windows(2).skip(40).take(60) {
        let ((t0, p0), (t1, p1)) = (w[0], w[1]);
        let (q, sigma) = found
            .camera_before_from_camera_after(&samples, t0, t1)
            .unwrap();
        let true_turn = DQuat::from_mat3(&(p0.matrix3.transpose() * p1.matrix3));
        let error = rotation_vector(true_turn.inverse() * q);
        assert!(
            error.abs().max_element() < 4.0 * sigma,
            "{t0}: {error} against sigma {sigma}"
        );
    }
}

#[test]
fn calibration_is_refused_when_the_motion_cannot_show_it() {
    let sim = ImuSimulation::phone();
    // Pure translation: a step and a sway, the camera never turns.
    let slide = |t: f64| {
        let eye = DVec3::new(0.3 * libm::sin(1.3 * t), -1.4, 0.5 * t);
        look_at(DVec3::ZERO, DVec3::new(0.2, 0.5, 2.0)) * DAffine3::from_translation(eye)
    };
    let samples = sim.simulate(slide, -0.5, 4.5);
    let refusal = calibrate(&poses(&frames(slide, 60.0, 4.0)), &samples).unwrap_err();
    println!("pure translation: {refusal}");
    assert!(
        matches!(refusal, CalibrationRefusal::TooLittleRotation { .. }),
        "{refusal}"
    );

    // Panning back and forth about the vertical at a fixed pitch: the
    // rotation about that axis (fixed in the camera) is not seen.
    let pitched = look_at(DVec3::ZERO, DVec3::new(0.0, 0.6, 2.0)).matrix3;
    let pan = |t: f64| DAffine3 {
        matrix3: DMat3::from_quat(quat_from_axis_angle(DVec3::Y, 0.6 * libm::sin(1.7 * t)))
            * pitched,
        translation: DVec3::new(0.0, -1.4, 0.1 * t),
    };
    let samples = sim.simulate(pan, -0.5, 4.5);
    let refusal = calibrate(&poses(&frames(pan, 60.0, 4.0)), &samples).unwrap_err();
    println!("one axis: {refusal}");
    let CalibrationRefusal::OneAxis { axis, .. } = refusal else {
        panic!("{refusal}");
    };
    let vertical_in_camera = pitched.transpose() * DVec3::Y;
    assert!(axis.cross(vertical_in_camera).length() < 0.05, "{axis}");

    // Samples that cover none of the frames.
    let samples = sim.simulate(loop_path, 10.0, 12.0);
    let refusal = calibrate(&poses(&frames(loop_path, 60.0, 4.0)), &samples).unwrap_err();
    assert!(
        matches!(refusal, CalibrationRefusal::TooFewPairs { pairs: 0, .. }),
        "{refusal}"
    );

    // Another recording's gyro (another path): the fit is poor.
    let swing = SwingPath::default();
    let samples = sim.simulate(|t| swing.pose(t * 30.0), -0.5, 4.5);
    let refusal = calibrate(&poses(&frames(loop_path, 60.0, 4.0)), &samples).unwrap_err();
    println!("another path's gyro: {refusal}");
    assert!(
        !matches!(refusal, CalibrationRefusal::TooFewPairs { .. }),
        "{refusal}"
    );
}

#[test]
fn bad_samples_are_refused_and_change_nothing() {
    let config = common::synthetic_config(Intrinsics::new(131.25, 131.25, 79.5, 59.5, 160, 120));
    let mut slam = Pipeline::new(config).unwrap();
    let good = ImuSimulation::phone().simulate(loop_path, 0.0, 1.0);
    slam.push_imu(&good[..50]).unwrap();
    let rate = slam.imu_rate_hz();
    let mut nan = good[50];
    nan.accel_mps2.z = f64::NAN;
    let err = slam.push_imu(&[good[50], nan]).unwrap_err();
    println!("{err}");
    assert!(
        matches!(
            err,
            PipelineError::Imu(ImuError::NotFinite { index: 1, .. })
        ),
        "{err}"
    );
    let err = slam.push_imu(&good[10..20]).unwrap_err();
    println!("{err}");
    assert!(
        matches!(
            err,
            PipelineError::Imu(ImuError::OutOfOrder { index: 0, .. })
        ),
        "{err}"
    );
    let mut infinite = good[50];
    infinite.time_s = f64::INFINITY;
    assert!(slam.push_imu(&[infinite]).is_err());
    assert_eq!(slam.imu_rate_hz(), rate, "nothing kept of a refused batch");
    slam.push_imu(&good[50..]).unwrap();
    assert!(
        slam.imu_rotation_prior(0.1, 0.2).is_none(),
        "not calibrated"
    );
    assert!(slam.imu_calibration().is_none());
    slam.reset();
    assert!(slam.imu_rate_hz().is_none(), "reset forgets the samples");
    // After a reset, earlier times are accepted again.
    slam.push_imu(&good[..10]).unwrap();
    slam.push_imu(&[]).unwrap();
}

#[test]
fn the_pipeline_calibrates_from_its_own_tracked_poses() {
    // The hand-held loop rendered at 160x120, 30 Hz, 4 s; the IMU's samples pushed
    // a little ahead of each frame, as the CLI does.
    let k = Intrinsics::new(131.25, 131.25, 79.5, 59.5, 160, 120);
    let config = common::synthetic_config(k);
    let scene = Scene::room();
    let sim = ImuSimulation {
        camera_from_imu: tilted_mount(),
        time_offset_s: 0.023,
        ..ImuSimulation::phone()
    };
    let samples = sim.simulate(hand_held, 0.0, 5.0);
    let mut slam = Pipeline::new(config.clone()).unwrap();
    let mut pushed = 0;
    let mut calibrated_at = None;
    let truth = frames(hand_held, 30.0, 4.0);
    for (i, (t, pose)) in truth.iter().enumerate() {
        let ahead = samples[pushed..].partition_point(|s| s.time_s <= t + 0.2);
        slam.push_imu(&samples[pushed..pushed + ahead]).unwrap();
        pushed += ahead;
        let frame = synthetic::render(&scene, &k, pose, &NoiseModel::kinect(), i as u64)
            .to_frame(&config.depth)
            .unwrap();
        slam.push_frame(&frame, *t).unwrap();
        if calibrated_at.is_none() && slam.imu_calibration().is_some() {
            calibrated_at = Some(i);
        }
    }
    let found = slam.imu_calibration().copied().unwrap_or_else(|| {
        panic!("not calibrated: {:?}", slam.imu_refusal());
    });
    println!(
        "calibrated at frame {calibrated_at:?}: {:?}, {:.2} ms",
        found.rotation_axis_angle_deg(),
        found.time_offset_ms()
    );
    check_calibration(&found, &sim, (1.0, 5.0));
    // The prior between the last two frames against the truth (the world
    // is the first camera's: relative rotations are the same).
    let n = truth.len();
    let ((t0, p0), (t1, p1)) = (truth[n - 2], truth[n - 1]);
    let (q, sigma) = slam.imu_rotation_prior(t0, t1).unwrap();
    let error =
        rotation_vector(DQuat::from_mat3(&(p0.matrix3.transpose() * p1.matrix3)).inverse() * q);
    assert!(
        error.abs().max_element() < 4.0 * sigma,
        "{error} against {sigma}"
    );
    assert!(slam.imu_rotation_prior(t1, t0).is_none());
    slam.reset();
    assert!(slam.imu_calibration().is_none() && slam.imu_rotation_prior(t0, t1).is_none());
}

#[test]
fn a_stray_scan_s_imu_csv_is_read_and_its_cut_off_last_row_skipped_with_a_warning() {
    let scratch = common::scratch("imu-stray");
    let dir = &scratch.0;
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    std::fs::create_dir_all(dir.join("confidence")).unwrap();
    for n in 0..3 {
        std::fs::write(dir.join(format!("depth/{n:06}.png")), b"").unwrap();
        std::fs::write(dir.join(format!("confidence/{n:06}.png")), b"").unwrap();
    }
    std::fs::write(
        dir.join("camera_matrix.csv"),
        "1597.4, 0.0, 959.8\n0.0, 1597.4, 722.2\n0.0, 0.0, 1.0\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("odometry.csv"),
        "timestamp, frame, x, y, z, qx, qy, qz, qw\n10.0, 0, 0, 0, 0, 0, 0, 0, 1\n",
    )
    .unwrap();
    // Without imu.csv: as before.
    let sequence = DatasetSource::open(dir).unwrap().sequence().unwrap();
    assert!(sequence.imu.is_empty() && sequence.warnings.is_empty());

    let mut imu = String::from("timestamp, a_x, a_y, a_z, alpha_x, alpha_y, alpha_z\n");
    for i in 0..20 {
        let t = 10.0 + f64::from(i) * 0.01;
        imu.push_str(&format!(
            "{t:.6}, 0.1, -9.81, 0.05, 0.01, -0.02, {:.4}\n",
            0.001 * f64::from(i)
        ));
    }
    imu.push_str("10.200000, 0.1, -9.8");
    std::fs::write(dir.join("imu.csv"), &imu).unwrap();
    let sequence = DatasetSource::open(dir).unwrap().sequence().unwrap();
    assert_eq!(sequence.imu.len(), 20);
    assert!((sequence.imu[19].gyro_radps.z - 0.019).abs() < 1e-12);
    assert_eq!(sequence.warnings.len(), 1);
    let warning = sequence.warnings[0].to_string();
    println!("{warning}");
    assert!(
        warning.contains("imu.csv, line 22") && warning.contains("cut off"),
        "{warning}"
    );
    // And the pipeline takes the samples as read.
    let config = common::synthetic_config(Intrinsics::new(131.25, 131.25, 79.5, 59.5, 160, 120));
    let mut slam = Pipeline::new(config).unwrap();
    slam.push_imu(&sequence.imu).unwrap();
    assert!((slam.imu_rate_hz().unwrap() - 100.0).abs() < 1e-6);

    // A malformed row before the last one is an error naming the file.
    std::fs::write(
        dir.join("imu.csv"),
        imu.replace("10.050000, 0.1", "10.050000, x"),
    )
    .unwrap();
    let err = DatasetSource::open(dir).unwrap().sequence().unwrap_err();
    assert!(err.to_string().contains("imu.csv, line 7"), "{err}");
}
