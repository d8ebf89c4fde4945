//! The RealSense (Open3D recorder) and Stray Scanner (iPhone LiDAR) layouts
//! (issue #52): the synthetic room rendered into each layout's files,
//! detected, parsed, decoded and run through `surfel-slam run` with the
//! default settings, near the rendered truth; every malformed file refused
//! with an error naming it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use std::path::Path;
use std::process::Command;

use glam::DAffine3;
use image::{ImageBuffer, Luma, RgbImage};
use surfel_slam::dataset::{read_frame, trajectory, DatasetError, DatasetKind, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::se3::unit_quaternion;
use surfel_slam::synthetic::{self, NoiseModel, Scene, DEPTH_UNITS_PER_METRE};
use surfel_slam::{CameraPreset, Intrinsics};

use common::scratch;

/// Frames rendered into each layout (a short run keeps CI fast).
const FRAMES: usize = 36;
/// Odometry rows of the Stray Scanner export: fewer than its depth frames.
const ODOMETRY_ROWS: usize = 30;
/// Largest ATE (and odometry difference) accepted, metres.
const BOUND_M: f64 = 0.02;

/// The synthetic camera's path from frame 0, so the first pose is the identity.
fn truth(frames: usize) -> Vec<DAffine3> {
    let poses = synthetic::trajectory(frames);
    let origin = poses[0].inverse();
    poses.iter().map(|p| origin * *p).collect()
}

/// The truth stamped as a RealSense folder's frames are: by file number.
fn truth_by_file_number(frames: usize) -> Vec<(f64, DAffine3)> {
    truth(frames)
        .into_iter()
        .enumerate()
        .map(|(i, p)| (i as f64, p))
        .collect()
}

/// Renders frame `i` with `k` (no noise): colour and depth in millimetres.
fn render_mm(scene: &Scene, k: &Intrinsics, i: usize) -> (Vec<u8>, Vec<u16>) {
    let pose = synthetic::trajectory_pose(i);
    let frame = synthetic::render(scene, k, &pose, &NoiseModel::none(), i as u64);
    let per_mm = DEPTH_UNITS_PER_METRE / 1000.0;
    let mm = frame
        .depth_raw
        .iter()
        .map(|&r| (f32::from(r) / per_mm).round() as u16)
        .collect();
    (frame.rgb, mm)
}

fn write_depth(path: &Path, width: usize, height: usize, mm: Vec<u16>) {
    ImageBuffer::<Luma<u16>, _>::from_raw(width as u32, height as u32, mm)
        .unwrap()
        .save(path)
        .unwrap();
}

fn write_colour(path: &Path, width: usize, height: usize, rgb: Vec<u8>) {
    RgbImage::from_raw(width as u32, height as u32, rgb)
        .unwrap()
        .save(path)
        .unwrap();
}

/// Open3D's recorder's folder: colour JPEG (PNG every fifth frame), depth
/// in millimetres, the intrinsics column-major, the files it ignores.
fn write_realsense(dir: &Path, k: &Intrinsics, frames: usize) {
    for sub in ["color", "depth", "fragments", "scene"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let json = format!(
        r#"{{"width": {}, "height": {}, "intrinsic_matrix": [{}, 0.0, 0.0, 0.0, {}, 0.0, {}, {}, 1.0]}}"#,
        k.width, k.height, k.fx, k.fy, k.cx, k.cy
    );
    std::fs::write(dir.join("camera_intrinsic.json"), json).unwrap();
    std::fs::write(dir.join("realsense.bag"), b"not read").unwrap();
    std::fs::write(dir.join("fragments/fragment_000.ply"), b"not read").unwrap();
    let scene = Scene::room();
    for i in 0..frames {
        let (rgb, mm) = render_mm(&scene, k, i);
        let ext = if i % 5 == 4 { "png" } else { "jpg" };
        write_colour(
            &dir.join(format!("color/{i:06}.{ext}")),
            k.width,
            k.height,
            rgb,
        );
        write_depth(
            &dir.join(format!("depth/{i:06}.png")),
            k.width,
            k.height,
            mm,
        );
    }
}

/// The Stray Scanner depth intrinsics the fixture renders with: an iPhone's
/// 1920x1440 colour camera scaled to 256x192.
fn stray_intrinsics() -> Intrinsics {
    let s = 256.0 / 1920.0;
    Intrinsics::new(1597.4 * s, 1597.4 * s, 959.5 * s, 719.5 * s, 256, 192)
}

/// A Stray Scanner export: 256x192 depth (mm) with confidence (0 on a
/// border band, whose depth is garbage), `camera_matrix.csv` at 1920x1440
/// with an odd third row, a 15-column `odometry.csv` with empty last fields
/// and fewer rows than frames, `imu.csv` and `rgb.mp4` beside them; with
/// `rgb`, also `rgb/` frames at 2x the depth's size, numbered from 1 as
/// ffmpeg numbers them.
fn write_stray(dir: &Path, frames: usize, rgb: bool) -> Vec<(f64, DAffine3)> {
    for sub in ["depth", "confidence", "rgb"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let k = stray_intrinsics();
    let s = 1920.0 / 256.0;
    std::fs::write(
        dir.join("camera_matrix.csv"),
        format!(
            "{}, 0.0, {}\n0.0, {}, {}\n0.0, 0.0, 1.0942\n",
            k.fx * s,
            k.cx * s,
            k.fy * s,
            k.cy * s
        ),
    )
    .unwrap();
    let poses = truth(frames);
    let stamps: Vec<f64> = (0..frames).map(|i| 1000.0 + i as f64 / 30.0).collect();
    let mut odometry = String::from(
        "timestamp, frame, x, y, z, qx, qy, qz, qw, fx, fy, cx, cy, distortion_center_x, distortion_center_y\n",
    );
    for i in 0..ODOMETRY_ROWS.min(frames) {
        let p = poses[i].translation;
        let [qx, qy, qz, qw] = unit_quaternion(&poses[i]);
        odometry.push_str(&format!(
            "{:.6}, {i}, {}, {}, {}, {qx}, {qy}, {qz}, {qw}, 1597.4, 1597.4, 959.5, 719.5, ,\n",
            stamps[i], p.x, p.y, p.z
        ));
    }
    std::fs::write(dir.join("odometry.csv"), odometry).unwrap();
    std::fs::write(dir.join("imu.csv"), "timestamp, a_x\n").unwrap();
    std::fs::write(dir.join("rgb.mp4"), b"not read").unwrap();
    let scene = Scene::room();
    for i in 0..frames {
        let (colour, mut mm) = render_mm(&scene, &k, i);
        let mut confidence = vec![2u8; 256 * 192];
        for (j, (c, d)) in confidence.iter_mut().zip(&mut mm).enumerate() {
            let (u, v) = (j % 256, j / 256);
            if u < 6 || v < 6 {
                *c = 0;
                *d = 777; // garbage the confidence removes
            } else if u > 250 {
                *c = 1;
            }
        }
        write_depth(&dir.join(format!("depth/{i:06}.png")), 256, 192, mm);
        ImageBuffer::<Luma<u8>, _>::from_raw(256, 192, confidence)
            .unwrap()
            .save(dir.join(format!("confidence/{i:06}.png")))
            .unwrap();
        if rgb {
            // Twice the depth's size: each pixel repeated 2x2.
            let big: Vec<u8> = (0..384 * 512)
                .flat_map(|j| {
                    let (u, v) = ((j % 512) / 2, (j / 512) / 2);
                    let at = 3 * (v * 256 + u);
                    [colour[at], colour[at + 1], colour[at + 2]]
                })
                .collect();
            write_colour(&dir.join(format!("rgb/{:06}.jpg", i + 1)), 512, 384, big);
        }
    }
    if !rgb {
        std::fs::remove_dir(dir.join("rgb")).unwrap();
    }
    stamps.into_iter().zip(poses).collect()
}

struct Answer {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run_cli(dir: &Path, trajectory_file: &Path) -> Answer {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .arg("run")
        .arg(dir)
        .arg("--quiet")
        .arg("--trajectory")
        .arg(trajectory_file)
        .output()
        .expect("the CLI runs");
    Answer {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// ATE of the trajectory file against `truth`, metres.
fn ate_of(file: &Path, truth: &[(f64, DAffine3)]) -> (f64, usize) {
    let text = std::fs::read_to_string(file).unwrap();
    let estimate = trajectory::parse_tum(&text, "estimate").unwrap();
    let a = ate(&estimate, truth, 0.001).unwrap();
    (a.rmse_m, a.pairs)
}

#[test]
fn realsense_folder_is_detected_parsed_and_run() {
    let dir = scratch("realsense");
    let k = synthetic::default_intrinsics();
    write_realsense(&dir.0, &k, FRAMES);
    let sequence = Sequence::open(&dir.0).expect("opens");
    assert_eq!(sequence.kind, DatasetKind::RealSense);
    assert_eq!(sequence.preset, CameraPreset::RealSenseD400);
    assert_eq!(sequence.intrinsics, Some(k));
    assert_eq!(sequence.frames.len(), FRAMES);
    assert_eq!(sequence.frames[7].timestamp, 7.0);
    assert_eq!(
        sequence.frames[4].colour.as_deref(),
        Some("color/000004.png")
    );
    let frame = read_frame(
        &dir.0,
        &sequence.frames[0],
        &sequence.preset.depth_settings(),
    )
    .expect("decodes");
    assert_eq!((frame.width, frame.height), (640, 480));
    assert!(frame.valid_depth_count() > 200_000);

    let out = dir.0.join("estimate.txt");
    let a = run_cli(&dir.0, &out);
    assert_eq!(a.code, 0, "{}\n{}", a.stdout, a.stderr);
    assert!(
        a.stdout.contains("ATE n/a (no ground truth)"),
        "{}",
        a.stdout
    );
    assert!(!a.stderr.contains("warning"), "{}", a.stderr);
    let truth = truth_by_file_number(FRAMES);
    let (rmse, pairs) = ate_of(&out, &truth);
    eprintln!(
        "RealSense: {}ATE against the rendered truth {rmse} m",
        a.stdout
    );
    assert_eq!(pairs, FRAMES);
    assert!(rmse < BOUND_M, "ATE {rmse} m");
}

#[test]
fn stray_export_runs_on_depth_alone_against_the_odometry() {
    let dir = scratch("stray");
    let truth = write_stray(&dir.0, FRAMES, false);
    let sequence = Sequence::open(&dir.0).expect("opens");
    assert_eq!(sequence.kind, DatasetKind::StrayScanner);
    assert_eq!(sequence.preset, CameraPreset::StrayLidar);
    assert!(sequence.is_depth_only());
    let k = sequence.intrinsics.expect("from camera_matrix.csv");
    let expected = stray_intrinsics();
    assert!((k.fx - expected.fx).abs() < 1e-3 && (k.cy - expected.cy).abs() < 1e-3);
    assert_eq!(sequence.frames.len(), FRAMES);
    assert_eq!(sequence.odometry.len(), ODOMETRY_ROWS);
    assert!(sequence.ground_truth.is_empty());
    // Frames past the last odometry row continue at its interval.
    for (f, (t, _)) in sequence.frames.iter().zip(&truth) {
        assert!((f.timestamp - t).abs() < 1e-5, "{} vs {t}", f.timestamp);
    }
    // Confidence 0 removes the border's garbage depth; the colour is grey.
    let frame = read_frame(
        &dir.0,
        &sequence.frames[0],
        &sequence.preset.depth_settings(),
    )
    .expect("decodes");
    assert_eq!((frame.width, frame.height), (256, 192));
    assert!(frame.depth_m[..256 * 6].iter().all(|&d| d == 0.0));
    assert!(frame.depth_m[256 * 100 + 3] == 0.0 && frame.depth_m[256 * 100 + 100] > 0.0);
    assert!(frame.depth_m[256 * 100 + 253] > 0.0, "confidence 1 kept");
    // ... marked less certain than confidence 2, which keeps the model's deviation.
    assert_eq!(frame.depth_deviation.len(), 256 * 192);
    assert_eq!(
        frame.depth_deviation[256 * 100 + 253],
        surfel_slam::frame::MEDIUM_CONFIDENCE_DEVIATION
    );
    const { assert!(surfel_slam::frame::MEDIUM_CONFIDENCE_DEVIATION > 1.0) };
    assert_eq!(frame.depth_deviation[256 * 100 + 100], 1.0);
    assert!(frame.rgb.iter().all(|&c| c == 128));

    let out = dir.0.join("estimate.txt");
    let a = run_cli(&dir.0, &out);
    assert_eq!(a.code, 0, "{}\n{}", a.stdout, a.stderr);
    assert_eq!(
        a.stderr.matches("no colour images").count(),
        1,
        "{}",
        a.stderr
    );
    assert!(
        a.stdout.contains("ATE n/a (no ground truth)"),
        "{}",
        a.stdout
    );
    let line = a
        .stdout
        .split(", difference from the device's odometry ")
        .nth(1)
        .unwrap_or_else(|| panic!("no odometry comparison: {}", a.stdout));
    assert!(
        line.contains("(30 poses; odometry, not ground truth)"),
        "{line}"
    );
    let cm: f64 = line.split(" cm").next().unwrap().parse().unwrap();
    assert!(cm < 100.0 * BOUND_M, "{line}");
    let (rmse, pairs) = ate_of(&out, &truth);
    eprintln!(
        "Stray Scanner: {}ATE against the rendered truth {rmse} m",
        a.stdout
    );
    assert_eq!(pairs, FRAMES);
    assert!(rmse < BOUND_M, "ATE {rmse} m");
}

#[test]
fn stray_colour_frames_extracted_from_the_video_are_scaled_to_the_depth() {
    let dir = scratch("stray-rgb");
    write_stray(&dir.0, 3, true);
    let sequence = Sequence::open(&dir.0).expect("opens");
    assert!(!sequence.is_depth_only());
    let entry = &sequence.frames[0];
    assert_eq!(entry.colour.as_deref(), Some("rgb/000001.jpg"));
    let frame = read_frame(&dir.0, entry, &sequence.preset.depth_settings()).expect("decodes");
    assert_eq!(frame.rgb.len(), 256 * 192 * 3);
    assert!(frame.rgb.iter().any(|&c| c.abs_diff(128) > 20));
}

/// Frames of the 848x480 and 1280x720 runs: enough motion for their ATE to
/// tell a misread calibration (the room's path moves about 1 cm a frame).
const SIZE_FRAMES: usize = 8;

#[test]
fn realsense_sizes_of_the_d400_run() {
    for (width, height) in [(848, 480), (1280, 720)] {
        let dir = scratch(&format!("realsense-{width}"));
        let f = 0.95 * width as f32 / 1.4;
        let k = Intrinsics::new(
            f,
            f,
            width as f32 / 2.0 - 0.5,
            height as f32 / 2.0 - 0.5,
            width,
            height,
        );
        write_realsense(&dir.0, &k, SIZE_FRAMES);
        let out = dir.0.join("estimate.txt");
        let a = run_cli(&dir.0, &out);
        assert_eq!(a.code, 0, "{width}x{height}: {}\n{}", a.stdout, a.stderr);
        assert!(
            a.stdout
                .contains(&format!(": {SIZE_FRAMES} frames, {SIZE_FRAMES} tracked")),
            "{}",
            a.stdout
        );
        assert!(!a.stderr.contains("warning"), "{}", a.stderr);
        let text = std::fs::read_to_string(&out).unwrap();
        assert_eq!(
            trajectory::parse_tum(&text, "estimate").unwrap().len(),
            SIZE_FRAMES
        );
        let truth = truth_by_file_number(SIZE_FRAMES);
        let (rmse, pairs) = ate_of(&out, &truth);
        eprintln!("{width}x{height}: ATE against the rendered truth {rmse} m");
        assert_eq!(pairs, SIZE_FRAMES);
        assert!(rmse < BOUND_M, "{width}x{height}: ATE {rmse} m");
    }
}

fn open_err(dir: &Path) -> DatasetError {
    Sequence::open(dir).expect_err("refused")
}

fn frame_err(dir: &Path, index: usize) -> DatasetError {
    let sequence = Sequence::open(dir).expect("opens");
    read_frame(
        dir,
        &sequence.frames[index],
        &sequence.preset.depth_settings(),
    )
    .expect_err("refused")
}

#[test]
fn malformed_files_are_refused_naming_the_file() {
    // RealSense: a 4x4 intrinsic matrix; a depth image of another size.
    let dir = scratch("realsense-bad");
    let k = Intrinsics::new(300.0, 300.0, 159.5, 119.5, 320, 240);
    write_realsense(&dir.0, &k, 2);
    let json = dir.0.join("camera_intrinsic.json");
    let good = std::fs::read_to_string(&json).unwrap();
    std::fs::write(
        &json,
        r#"{"width": 320, "height": 240, "intrinsic_matrix": [300,0,0,0, 0,300,0,0, 159.5,119.5,1,0, 0,0,0,1]}"#,
    )
    .unwrap();
    let err = open_err(&dir.0);
    assert!(
        matches!(&err, DatasetError::Calibration { path, .. } if path == "camera_intrinsic.json"),
        "{err:?}"
    );
    assert!(err.to_string().contains("4x4"), "{err}");
    std::fs::write(&json, good.replace("\"width\": 320", "\"width\": 640")).unwrap();
    let err = frame_err(&dir.0, 0);
    assert!(
        matches!(&err, DatasetError::ImageSize { path, width: 320, expected_width: 640, .. } if path == "depth/000000.png"),
        "{err:?}"
    );
    assert!(err.to_string().contains("camera_intrinsic.json"), "{err}");
    std::fs::write(&json, good).unwrap();
    let answer = run_cli(&dir.0, &dir.0.join("t.txt"));
    assert_eq!(answer.code, 0, "{}", answer.stderr);

    // Stray Scanner: a missing odometry column, a non-numeric matrix entry,
    // a missing confidence image, a depth image of another size.
    let dir = scratch("stray-bad");
    write_stray(&dir.0, 2, false);
    let csv = dir.0.join("odometry.csv");
    let good = std::fs::read_to_string(&csv).unwrap();
    let short: String = good
        .lines()
        .enumerate()
        .map(|(i, l)| {
            // A middle row: a cut-off last row is skipped instead (below).
            if i == 1 {
                l.splitn(3, ", ").take(2).collect::<Vec<_>>().join(", ") + ", 0, 0, 0, 0, 0, 1\n"
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(&csv, short).unwrap();
    let err = open_err(&dir.0);
    assert!(
        matches!(&err, DatasetError::MalformedLine { file, line_number: 2, reason, .. } if file == "odometry.csv" && reason.contains("found 8")),
        "{err:?}"
    );
    std::fs::write(&csv, good).unwrap();

    let matrix = dir.0.join("camera_matrix.csv");
    let good = std::fs::read_to_string(&matrix).unwrap();
    std::fs::write(&matrix, good.replacen("0.0,", "zero,", 1)).unwrap();
    let err = open_err(&dir.0);
    assert!(
        matches!(&err, DatasetError::MalformedLine { file, line_number: 1, .. } if file == "camera_matrix.csv"),
        "{err:?}"
    );
    assert!(
        err.to_string().contains("`zero` is not a finite number"),
        "{err}"
    );
    std::fs::write(&matrix, good).unwrap();

    std::fs::remove_file(dir.0.join("confidence/000001.png")).unwrap();
    let err = frame_err(&dir.0, 1);
    assert!(
        matches!(&err, DatasetError::MissingFile { path, .. } if path == "confidence/000001.png"),
        "{err:?}"
    );
    write_depth(
        &dir.0.join("depth/000000.png"),
        128,
        96,
        vec![1000; 128 * 96],
    );
    let err = frame_err(&dir.0, 0);
    assert!(
        matches!(&err, DatasetError::ImageSize { path, width: 128, expected_width: 256, .. } if path == "depth/000000.png"),
        "{err:?}"
    );
    // Neither frame readable: the run stops, naming both problems' files.
    let answer = run_cli(&dir.0, &dir.0.join("t.txt"));
    assert_eq!(answer.code, 1, "{}", answer.stderr);
    assert!(
        !dir.0.join("t.txt").exists(),
        "nothing tracked, yet a trajectory was written"
    );
    assert!(
        answer.stderr.contains("depth/000000.png is 128x96 pixels")
            && answer.stderr.contains("confidence/000001.png is missing"),
        "{}",
        answer.stderr
    );
}

/// Issue #82, item 5: a Stray export whose app stopped mid-write (the last
/// `odometry.csv` row cut off, the last depth image half written) plays
/// every complete frame: one warning for the row naming the file and the
/// line, one for the image, exit 0.
#[test]
fn a_stray_export_cut_short_plays_its_complete_frames() {
    const CUT_FRAMES: usize = 8;
    let dir = scratch("stray-cut");
    write_stray(&dir.0, CUT_FRAMES, false);
    let csv = dir.0.join("odometry.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows = text.lines().count(); // header + one row a frame
    let last = text.lines().last().unwrap();
    let cut = &last[..last.len() / 2];
    let kept = text.len() - last.len() - 1;
    std::fs::write(&csv, format!("{}{cut}", &text[..kept])).unwrap();
    let depth = dir.0.join(format!("depth/{:06}.png", CUT_FRAMES - 1));
    let bytes = std::fs::read(&depth).unwrap();
    std::fs::write(&depth, &bytes[..bytes.len() / 2]).unwrap();

    let sequence = Sequence::open(&dir.0).expect("a cut-off last row does not refuse it");
    assert_eq!(sequence.frames.len(), CUT_FRAMES);
    assert_eq!(sequence.odometry.len(), CUT_FRAMES - 1);
    assert_eq!(sequence.warnings.len(), 1, "{:?}", sequence.warnings);

    let out = dir.0.join("estimate.txt");
    let a = run_cli(&dir.0, &out);
    eprintln!("{}{}", a.stdout, a.stderr);
    assert_eq!(a.code, 0, "{}\n{}", a.stdout, a.stderr);
    let row_warning = format!("warning: odometry.csv, line {rows}: the last line is cut off");
    assert_eq!(a.stderr.matches(&row_warning).count(), 1, "{}", a.stderr);
    let image_warning = format!(
        "warning: frame {} skipped, the recording's last image does not decode",
        CUT_FRAMES - 1
    );
    assert_eq!(a.stderr.matches(&image_warning).count(), 1, "{}", a.stderr);
    assert!(
        a.stderr
            .contains(&format!("depth/{:06}.png", CUT_FRAMES - 1)),
        "{}",
        a.stderr
    );
    assert!(
        a.stdout.contains(&format!("{CUT_FRAMES} frames,"))
            && a.stdout.contains(" 0 lost,")
            && a.stdout.contains(" 0 unreadable,"),
        "{}",
        a.stdout
    );
    let poses = trajectory::parse_tum(&std::fs::read_to_string(&out).unwrap(), "estimate")
        .unwrap()
        .len();
    assert_eq!(poses, CUT_FRAMES - 1, "every complete frame placed");
}

/// `Pipeline::push_decoded` (the page's `Slam.pushFiles`): a Stray frame's
/// files decoded by `decode_frame_bytes` run as the CLI runs them; a
/// refused decode is handed back and leaves no last decoded frame (the
/// page shows no stale depth), and the map as it was.
#[test]
fn decoded_files_push_like_the_cli_and_a_refused_decode_changes_nothing() {
    use surfel_slam::dataset::{decode_frame_bytes, FrameBytes};
    use surfel_slam::{Pipeline, PipelineError, SlamConfig};
    let dir = scratch("stray-push-decoded");
    write_stray(&dir.0, 3, false);
    let sequence = Sequence::open(&dir.0).expect("opens");
    let mut config = SlamConfig::from_preset(sequence.preset);
    config.intrinsics = sequence.intrinsics.expect("from camera_matrix.csv");
    let mut slam = Pipeline::new(config.clone()).expect("valid");
    let read = |name: &Option<String>| name.as_ref().map(|n| std::fs::read(dir.0.join(n)).unwrap());
    let decode = |i: usize, confidence: Option<&[u8]>| {
        let entry = &sequence.frames[i];
        let depth = std::fs::read(dir.0.join(&entry.depth)).unwrap();
        decode_frame_bytes(
            entry,
            &FrameBytes {
                colour: None,
                depth: &depth,
                confidence,
            },
            &config.depth,
        )
        .map_err(|e| e.to_string())
    };
    // The errors' type only has to take the pipeline's.
    #[derive(Debug)]
    struct Refused(String);
    impl From<PipelineError> for Refused {
        fn from(e: PipelineError) -> Self {
            Self(e.to_string())
        }
    }
    for i in 0..2 {
        let confidence = read(&sequence.frames[i].confidence);
        let frame = decode(i, confidence.as_deref()).map_err(Refused);
        let report = slam
            .push_decoded(frame, sequence.frames[i].timestamp)
            .expect("pushed");
        assert!(report.verdict.is_fused(), "{:?}", report.verdict);
        assert!(slam.last_decoded_frame().is_some());
    }
    let surfels = slam.map().live_len();
    // A confidence image of another size: refused by name, nothing changed.
    let small = std::fs::read(dir.0.join(sequence.frames[0].confidence.as_ref().unwrap())).unwrap();
    let truncated = &small[..small.len() / 2];
    let refused = slam
        .push_decoded(
            decode(2, Some(truncated)).map_err(Refused),
            sequence.frames[2].timestamp,
        )
        .expect_err("a broken confidence image");
    assert!(refused.0.contains("confidence"), "{}", refused.0);
    assert!(slam.last_decoded_frame().is_none());
    assert_eq!((slam.frames(), slam.map().live_len()), (2, surfels));
    // A push the pipeline refuses (a NaN timestamp) is handed back too.
    let frame = decode(2, None).map_err(Refused);
    assert!(slam.push_decoded(frame, f64::NAN).is_err());
    assert_eq!(slam.frames(), 2);
}
