//! A folder whose layout states no calibration (TUM here) of frames resized
//! from the preset's 640x480: `surfel-slam run` scales the preset's
//! calibration to the frames' size and tracks them near the rendered truth;
//! frames of another aspect ratio run with a warning that the focal
//! lengths are a guess.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use image::{ImageBuffer, Luma, RgbImage};
use surfel_slam::dataset::trajectory;
use surfel_slam::eval::ate;
use surfel_slam::se3::unit_quaternion;
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{CameraPreset, Intrinsics};

use common::scratch;

/// Frames of the resized recording.
const FRAMES: usize = 30;
/// Seconds between frames.
const DT: f64 = 1.0 / 30.0;

/// Writes a TUM folder of `frames` frames of the synthetic room seen
/// through `k` (depth in TUM's 5000 units per metre), with ground truth.
fn write_tum(dir: &Path, k: &Intrinsics, frames: usize) {
    std::fs::create_dir_all(dir.join("rgb")).unwrap();
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let scene = Scene::room();
    let (mut rgb_txt, mut depth_txt, mut truth_txt) = (String::new(), String::new(), String::new());
    let origin = synthetic::trajectory_pose(0).inverse();
    for i in 0..frames {
        let pose = synthetic::trajectory_pose(i);
        let frame = synthetic::render(&scene, k, &pose, &NoiseModel::none(), i as u64);
        let (w, h) = (k.width as u32, k.height as u32);
        let t = i as f64 * DT;
        let name = format!("{t:.6}.png");
        RgbImage::from_raw(w, h, frame.rgb)
            .unwrap()
            .save(dir.join("rgb").join(&name))
            .unwrap();
        ImageBuffer::<Luma<u16>, _>::from_raw(w, h, frame.depth_raw)
            .unwrap()
            .save(dir.join("depth").join(&name))
            .unwrap();
        writeln!(rgb_txt, "{t:.6} rgb/{name}").unwrap();
        writeln!(depth_txt, "{t:.6} depth/{name}").unwrap();
        let p = origin * pose;
        let q = unit_quaternion(&p);
        let c = p.translation;
        writeln!(
            truth_txt,
            "{t:.6} {} {} {} {} {} {} {}",
            c.x, c.y, c.z, q[0], q[1], q[2], q[3]
        )
        .unwrap();
    }
    std::fs::write(dir.join("rgb.txt"), rgb_txt).unwrap();
    std::fs::write(dir.join("depth.txt"), depth_txt).unwrap();
    std::fs::write(dir.join("groundtruth.txt"), truth_txt).unwrap();
}

/// `surfel-slam run DIR`: exit code, stderr, and the ATE of the trajectory
/// written against the folder's ground truth (metres, pairs).
fn run(dir: &Path) -> (i32, String, f64, usize) {
    run_with(dir, &[])
}

/// As [`run`], with more options for `run`.
fn run_with(dir: &Path, options: &[&str]) -> (i32, String, f64, usize) {
    let estimate = dir.join("estimate.txt");
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .arg("run")
        .arg(dir)
        .arg("--quiet")
        .arg("--trajectory")
        .arg(&estimate)
        .args(options)
        .output()
        .expect("the CLI runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let code = out.status.code().unwrap_or(-1);
    assert_eq!(code, 0, "{stderr}");
    let parse = |file: &Path, what| {
        trajectory::parse_tum(&std::fs::read_to_string(file).unwrap(), what).unwrap()
    };
    let a = ate(
        &parse(&estimate, "estimate"),
        &parse(&dir.join("groundtruth.txt"), "truth"),
        0.001,
    )
    .unwrap();
    (code, stderr, a.rmse_m, a.pairs)
}

#[test]
fn a_resized_tum_recording_runs_with_the_preset_scaled_to_its_frames() {
    let tmp = scratch("frame-size");
    // The folder's name picks the fr3 preset, calibrated at 640x480.
    let dir = tmp.0.join("rgbd_dataset_freiburg3_resized");
    let preset = CameraPreset::TumFr3.intrinsics();
    let k = preset.for_image_size(320, 240);
    write_tum(&dir, &k, FRAMES);
    let (_, stderr, rmse, pairs) = run(&dir);
    eprintln!("320x240 fr3 folder: ATE {rmse} m over {pairs} poses\n{stderr}");
    assert!(
        stderr
            .contains("the frames are 320x240: the camera's 640x480 calibration is scaled to them"),
        "{stderr}"
    );
    assert!(!stderr.contains("warning"), "{stderr}");
    assert_eq!(pairs, FRAMES);
    // With the 640x480 calibration kept (the build before), 21 of the 30
    // frames were held and the run ended 10.3 cm off.
    assert!(rmse < 0.01, "ATE {rmse} m");
}

#[test]
fn frames_of_another_aspect_ratio_run_with_a_warning_on_the_focal_lengths() {
    let tmp = scratch("frame-aspect");
    let dir = tmp.0.join("rgbd_dataset_freiburg3_wide");
    let k = CameraPreset::TumFr3.intrinsics().for_image_size(384, 216);
    write_tum(&dir, &k, 4);
    let (_, stderr, _, pairs) = run(&dir);
    assert_eq!(pairs, 4);
    assert!(
        stderr.contains(
            "warning: camera settings: the frames are 384x216, but tum-fr3 is calibrated at 640x480, another aspect ratio"
        ),
        "{stderr}"
    );
    assert!(!stderr.contains("is scaled to them"), "{stderr}");

    // The camera's own calibration given whole: nothing is a guess any more.
    let own = [k.fx, k.fy, k.cx, k.cy].map(|v| (v + 0.25).to_string());
    let options = [
        "--fx", &own[0], "--fy", &own[1], "--cx", &own[2], "--cy", &own[3],
    ];
    let (_, stderr, _, pairs) = run_with(&dir, &options);
    assert_eq!(pairs, 4);
    assert!(!stderr.contains("another aspect ratio"), "{stderr}");
}
