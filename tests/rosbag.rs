//! RealSense `.bag` recordings (ROS1 bag 2.0): the shared real sample read
//! (values checked against the `rosbags` Python package's reading of the
//! same file), a cut copy (no index, last chunk cut off) playing its
//! complete frames with one warning, bags written here (colour registered
//! through a known extrinsic, IMU, compressions) and hostile bags (every
//! cut and flipped byte: an error, never a panic).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;
mod rosbag_writer;

use std::io::Cursor;
use std::path::PathBuf;
use std::process::Command;

use rosbag_writer::{camera_info, float32, image, imu, transform, Bag};
use surfel_slam::dataset::rosbag::{RealSenseBag, RosbagError};
use surfel_slam::dataset::{DatasetError, DatasetKind, DatasetSource, Sequence};

const SAMPLE: &str = "recordings/realsense_d435_single_depth_color_640x480.bag";
const DEPTH: &str = "/device_0/sensor_0/Depth_0/image/data";
const COLOUR: &str = "/device_0/sensor_1/Color_0/image/data";

/// A shared file under ../shared/data, or `None` (with a message) when
/// absent; panics when absent and `CI=true`.
fn shared_file(name: &str) -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name);
    if path.is_file() {
        Some(path)
    } else if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{} not found and CI=true", path.display());
    } else {
        eprintln!("skipping: {} not found", path.display());
        None
    }
}

fn cli(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(args)
        .output()
        .expect("runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_real_sample_reads_as_rosbags_reads_it() {
    let Some(path) = shared_file(SAMPLE) else {
        return;
    };
    let mut bag = RealSenseBag::open(std::fs::File::open(&path).unwrap()).expect("opens");
    let rec = bag.recording().clone();
    assert_eq!(rec.depth_topic, DEPTH);
    // rosbags: the depth camera_info K, 640x480, "Brown Conrady", D all 0.
    let d = rec.depth;
    assert_eq!((d.width, d.height), (640, 480));
    assert_eq!(
        (d.fx, d.fy),
        (390.431_457_519_531_25, 390.431_457_519_531_25)
    );
    assert_eq!(
        (d.cx, d.cy),
        (331.387_878_417_968_75, 242.187_347_412_109_38)
    );
    // `/device_0/sensor_0/option/Depth Units/value`: Float32 0.001
    // (0.0010000000474974513 as rosbags prints it), taken as the decimal.
    assert_eq!(rec.depth_units_m, 0.001);
    let (topic, reg) = rec.colour.as_ref().expect("a colour stream");
    assert_eq!(topic, COLOUR);
    assert_eq!(
        (reg.colour.fx, reg.colour.fy),
        (613.203_674_316_406_2, 613.419_311_523_437_5)
    );
    assert_eq!(
        (reg.colour.cx, reg.colour.cy),
        (319.938_842_773_437_5, 239.182_998_657_226_56)
    );
    // The colour stream's tf/0 (the depth's is identity): depth to colour.
    let t = reg.colour_from_depth.translation;
    assert!((t.x - 0.014_311_313_629_150_39).abs() < 1e-12, "{t}");
    assert!((t.y - 0.000_602_306_448_854_506).abs() < 1e-12, "{t}");
    // Two depth images (stamps 360.815089 and 360.981765 s), one colour
    // image (360.713523 s): 0.10 s from the nearest depth, more than half
    // the depth's 0.167 s period, so no frame has colour.
    let stamps: Vec<f64> = rec.frames.iter().map(|f| f.time_s).collect();
    assert_eq!(stamps.len(), 2);
    assert!((stamps[0] - 360.815_089).abs() < 1e-6 && (stamps[1] - 360.981_765).abs() < 1e-6);
    assert_eq!(rec.colour_images, 1);
    assert!(rec.frames.iter().all(|f| f.colour.is_none()));
    assert!(rec.imu.is_empty());
    assert!(
        matches!(
            rec.warnings.as_slice(),
            [RosbagError::FramesWithoutColour {
                unpaired: 2,
                frames: 2
            }]
        ),
        "{:?}",
        rec.warnings
    );
    // The centre pixels, as rosbags reads the message's bytes: 1536 and
    // 1540 units (little-endian [0, 6] and [4, 6]).
    for (i, centre) in [(0, 1536u16), (1, 1540)] {
        let frame = bag.read_frame(i, true).expect("reads");
        assert_eq!((frame.width, frame.height), (640, 480));
        assert_eq!(frame.depth[240 * 640 + 320], centre, "frame {i}");
        assert!(frame.rgb.is_empty(), "no colour paired");
    }
    // Through the dataset layer: the kind, the depth scale, the frames' names.
    let seq = Sequence::open(&path).expect("a sequence");
    assert_eq!(seq.kind, DatasetKind::RealSenseBag);
    assert_eq!(seq.depth_scale, Some(1000.0));
    assert_eq!(seq.intrinsics.map(|k| k.fx), Some(390.431_46));
    assert_eq!(seq.frames[1].depth, format!("{DEPTH} at 360.981765 s"));
}

/// The sample cut in its second (last) chunk, with the bag header's index
/// position as a finished bag gives it (past the cut) or as an unfinished
/// one leaves it (0).
fn cut_sample(path: &std::path::Path, zero_index: bool) -> Vec<u8> {
    let mut bytes = std::fs::read(path).unwrap();
    bytes.truncate(900_000); // the chunks start at 4117 and 756751
    if zero_index {
        let at = bytes.windows(10).position(|w| w == b"index_pos=").unwrap() + 10;
        bytes[at..at + 8].fill(0);
    }
    bytes
}

#[test]
fn a_cut_recording_plays_its_complete_frames_with_one_warning() {
    let Some(path) = shared_file(SAMPLE) else {
        return;
    };
    for zero_index in [false, true] {
        let bytes = cut_sample(&path, zero_index);
        let mut bag = RealSenseBag::open(Cursor::new(bytes)).expect("opens");
        let rec = bag.recording().clone();
        assert_eq!(rec.frames.len(), 1, "the first chunk's depth frame");
        let unfinished: Vec<_> = rec
            .warnings
            .iter()
            .filter(|w| matches!(w, RosbagError::Unfinished(_)))
            .collect();
        assert_eq!(unfinished.len(), 1, "{:?}", rec.warnings);
        assert!(unfinished[0].to_string().contains("1 complete chunks"));
        assert_eq!(
            bag.read_frame(0, true).unwrap().depth[240 * 640 + 320],
            1536
        );
    }
    // Cut before its first chunk ends: no frame, refused, both said.
    let err = RealSenseBag::open(Cursor::new(cut_sample(&path, true)[..5000].to_vec()))
        .err()
        .expect("no frame");
    let text = err.to_string();
    assert!(
        text.contains("no depth stream") && text.contains("unfinished"),
        "{text}"
    );
    // The command line plays it: one frame, exit 0, the warning once.
    let dir = common::scratch("rosbag-cut");
    let cut = dir.0.join("cut.bag");
    std::fs::write(&cut, cut_sample(&path, true)).unwrap();
    let (code, stderr) = cli(&["run", cut.to_str().unwrap(), "--quiet"]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(
        stderr.matches("unfinished recording").count(),
        1,
        "{stderr}"
    );
}

fn depth_units_and_calibration(bag: &mut Bag, w: u32, h: u32, colour_fx: f64) {
    let k = |fx: f64| {
        [
            fx,
            fx,
            (f64::from(w) - 1.0) / 2.0,
            (f64::from(h) - 1.0) / 2.0,
        ]
    };
    bag.chunk(&[
        (
            "/device_0/sensor_0/Depth_0/info/camera_info",
            "sensor_msgs/CameraInfo",
            0,
            camera_info(w, h, "Brown Conrady", &[0.0; 5], k(40.0)),
        ),
        (
            "/device_0/sensor_1/Color_0/info/camera_info",
            "sensor_msgs/CameraInfo",
            0,
            camera_info(w, h, "Inverse Brown Conrady", &[0.0; 5], k(colour_fx)),
        ),
        (
            "/device_0/sensor_0/option/Depth Units/value",
            "std_msgs/Float32",
            0,
            float32(0.0002),
        ),
        (
            "/device_0/sensor_0/Depth_0/tf/0",
            "geometry_msgs/Transform",
            0,
            transform([0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        ),
        (
            "/device_0/sensor_1/Color_0/tf/0",
            "geometry_msgs/Transform",
            0,
            transform([-0.05, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
        ),
    ]);
}

/// A bag of `frames` depth frames at 30 Hz (a wall at 1 m, 5000 units per
/// metre), colour 4 ms after each (red = column, green = row) from a
/// camera 5 cm to the right, gyro and accel samples between.
fn written_bag(compression: &'static str, frames: u64, finished: bool) -> Vec<u8> {
    let (w, h) = (32u32, 24u32);
    let mut bag = Bag::new(compression);
    depth_units_and_calibration(&mut bag, w, h, 40.0);
    let depth: Vec<u8> = (0..w * h).flat_map(|_| 5000u16.to_le_bytes()).collect();
    let colour: Vec<u8> = (0..h)
        .flat_map(|v| (0..w).flat_map(move |u| [u as u8 * 4, v as u8 * 4, 9]))
        .collect();
    for i in 0..frames {
        let t = 1_000_000_000 + i * 33_333_333;
        bag.chunk(&[
            (
                DEPTH,
                "sensor_msgs/Image",
                t,
                image(t, w, h, "mono16", &depth),
            ),
            (
                COLOUR,
                "sensor_msgs/Image",
                t,
                image(t + 4_000_000, w, h, "rgb8", &colour),
            ),
            (
                "/device_0/sensor_2/Gyro_0/imu/data",
                "sensor_msgs/Imu",
                t,
                imu(t + 1_000_000, [0.1, 0.2, 0.3], [0.0; 3]),
            ),
            (
                "/device_0/sensor_2/Accel_0/imu/data",
                "sensor_msgs/Imu",
                t,
                imu(t + 2_000_000, [0.0; 3], [0.0, -9.81, 0.0]),
            ),
        ]);
    }
    bag.finish(finished)
}

#[test]
fn written_bags_register_colour_through_the_extrinsics() {
    for compression in ["none", "lz4"] {
        let bytes = written_bag(compression, 3, true);
        let mut bag = RealSenseBag::open(Cursor::new(bytes)).expect(compression);
        let rec = bag.recording().clone();
        assert!(rec.warnings.is_empty(), "{:?}", rec.warnings);
        assert_eq!(rec.depth_units_m, 0.0002);
        assert_eq!(rec.frames.len(), 3);
        assert!(
            rec.frames.iter().all(|f| f.colour.is_some()),
            "4 ms apart: paired"
        );
        assert_eq!(rec.imu.len(), 6);
        assert_eq!(rec.imu[0].gyro_radps, Some([0.1, 0.2, 0.3]));
        assert_eq!(rec.imu[0].accel_mps2, None);
        assert_eq!(rec.imu[1].accel_mps2, Some([0.0, -9.81, 0.0]));
        assert!((rec.imu[1].time_s - 1.002).abs() < 1e-9);
        let frame = bag.read_frame(2, true).expect("reads");
        // Depth pixel u sees x = (u - 15.5) / 40 at 1 m; the colour camera,
        // 5 cm to the right, sees it at column (x - 0.05) * 40 + 15.5 = u - 2.
        for (u, v) in [(10usize, 5usize), (31, 23), (3, 12)] {
            let px = &frame.rgb[3 * (v * 32 + u)..][..3];
            assert_eq!(px, [(u as u8 - 2) * 4, v as u8 * 4, 9], "({u}, {v})");
        }
        let edge = &frame.rgb[3 * (5 * 32 + 1)..][..3];
        assert_eq!(edge, [128; 3], "column -1 of the colour camera: grey");
        assert!(bag.read_frame(0, false).unwrap().rgb.is_empty());
    }
}

#[test]
fn unread_compressions_and_encodings_are_named() {
    let mut bag = Bag::new("bz2");
    bag.chunk(&[(
        DEPTH,
        "sensor_msgs/Image",
        1,
        image(1, 2, 2, "mono16", &[0; 8]),
    )]);
    let err = RealSenseBag::open(Cursor::new(bag.finish(true)))
        .err()
        .expect("refused");
    assert!(err.to_string().contains("`bz2`"), "{err}");
    let mut bag = Bag::new("none");
    depth_units_and_calibration(&mut bag, 2, 2, 40.0);
    bag.chunk(&[
        (
            DEPTH,
            "sensor_msgs/Image",
            1,
            image(1, 2, 2, "mono16", &[0; 8]),
        ),
        (
            COLOUR,
            "sensor_msgs/Image",
            1,
            image(1, 2, 2, "yuv422", &[0; 8]),
        ),
    ]);
    let err = RealSenseBag::open(Cursor::new(bag.finish(true)))
        .err()
        .expect("refused");
    assert!(
        err.to_string().contains("yuv422") && err.to_string().contains(COLOUR),
        "{err}"
    );
}

#[test]
fn a_bag_without_depth_is_refused_naming_the_file() {
    let mut bag = Bag::new("lz4");
    bag.chunk(&[(
        COLOUR,
        "sensor_msgs/Image",
        1,
        image(1, 2, 2, "rgb8", &[0; 12]),
    )]);
    let dir = common::scratch("rosbag-no-depth");
    let path = dir.0.join("colour-only.bag");
    std::fs::write(&path, bag.finish(true)).unwrap();
    match DatasetSource::open(&path) {
        Err(DatasetError::Rosbag { path: p, source }) => {
            assert_eq!(p, path.display().to_string());
            assert!(
                matches!(source, RosbagError::NoDepthStream { .. }),
                "{source}"
            );
        }
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("opened"),
    }
    let (code, stderr) = cli(&["run", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("colour-only.bag") && stderr.contains("no depth stream"),
        "{stderr}"
    );
    assert!(stderr.contains(&format!("{COLOUR} (rgb8)")), "{stderr}");
    // Recognised by its bytes, not its name.
    let renamed = dir.0.join("colour-only.dat");
    std::fs::rename(&path, &renamed).unwrap();
    let (_, stderr) = cli(&["run", renamed.to_str().unwrap()]);
    assert!(stderr.contains("no depth stream"), "{stderr}");
}

#[test]
fn hostile_bags_are_errors_never_panics() {
    let bytes = written_bag("lz4", 2, true);
    let finished = RealSenseBag::open(Cursor::new(bytes.clone())).expect("whole");
    assert_eq!(finished.recording().frames.len(), 2);
    // Cut in the index at the end: every chunk is whole, one warning.
    let bag = RealSenseBag::open(Cursor::new(bytes[..bytes.len() - 10].to_vec())).expect("opens");
    assert_eq!(bag.recording().frames.len(), 2);
    let warnings: Vec<String> = bag
        .recording()
        .warnings
        .iter()
        .map(ToString::to_string)
        .collect();
    assert!(
        warnings.len() == 1 && warnings[0].contains("index") && warnings[0].contains("3 chunks"),
        "{warnings:?}"
    );
    // Every cut: an error, or (past the first frame's chunk) fewer frames.
    for cut in (0..bytes.len()).step_by(7) {
        if let Ok(mut bag) = RealSenseBag::open(Cursor::new(bytes[..cut].to_vec())) {
            let n = bag.recording().frames.len();
            assert!(n <= 2);
            for i in 0..n {
                bag.read_frame(i, true).expect("a listed frame reads");
            }
        }
    }
    // Flipped bytes and forged lengths: errors or frames that read or not,
    // never a panic.
    let mut x = 0x2545_f491_u32;
    for _ in 0..3000 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        let mut bad = bytes.clone();
        let at = x as usize % bad.len();
        bad[at] = if x & 0x100 == 0 { 0xff } else { (x >> 9) as u8 };
        if let Ok(mut bag) = RealSenseBag::open(Cursor::new(bad)) {
            for i in 0..bag.recording().frames.len() {
                let _ = bag.read_frame(i, true);
            }
        }
    }
}

/// The bundled TUM clip's first frames written as librealsense writes a
/// recording (depth `mono16` at its own stamps, colour `rgb8` at its own,
/// identity extrinsics to reference stream 1, `Depth_Units` 0.0002, the
/// fr3 intrinsics for both cameras) decode to the very frames the folder
/// gives: the run cannot tell them apart.
#[test]
fn a_bag_of_the_clip_decodes_to_the_folders_frames() {
    let clip = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("www/sample/tum_fr3_teddy_clip");
    let mut folder = DatasetSource::open(&clip).unwrap();
    let seq = folder.sequence().unwrap();
    let frames = &seq.frames[..6];
    let (w, h) = (640u32, 480u32);
    let mut bag = Bag::new("lz4");
    let k = [535.4, 539.2, 320.1, 247.6];
    let info = camera_info(w, h, "Brown Conrady", &[0.0; 5], k);
    let identity = transform([0.0; 3], [0.0, 0.0, 0.0, 1.0]);
    bag.chunk(&[
        (
            "/device_0/sensor_0/Depth_0/info/camera_info",
            "sensor_msgs/CameraInfo",
            0,
            info.clone(),
        ),
        (
            "/device_0/sensor_1/Color_0/info/camera_info",
            "sensor_msgs/CameraInfo",
            0,
            info,
        ),
        (
            "/device_0/sensor_0/option/Depth_Units/value",
            "std_msgs/Float32",
            0,
            float32(0.0002),
        ),
        (
            "/device_0/sensor_0/Depth_0/tf/1",
            "geometry_msgs/Transform",
            0,
            identity.clone(),
        ),
        (
            "/device_0/sensor_1/Color_0/tf/1",
            "geometry_msgs/Transform",
            0,
            identity,
        ),
    ]);
    let ns = |t: f64| (t * 1e9).round() as u64;
    for f in frames {
        // TUM names each image by its stamp: depth/1341841873.290604.png.
        let stem = f.depth.rsplit('/').next().unwrap().trim_end_matches(".png");
        let depth_t: f64 = stem.parse().unwrap();
        let depth = image::open(clip.join(&f.depth)).unwrap().into_luma16();
        let depth: Vec<u8> = depth
            .as_raw()
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let colour = image::open(clip.join(f.colour.as_ref().unwrap()))
            .unwrap()
            .into_rgb8();
        bag.chunk(&[(
            DEPTH,
            "sensor_msgs/Image",
            ns(depth_t),
            image(ns(depth_t), w, h, "mono16", &depth),
        )]);
        bag.chunk(&[(
            COLOUR,
            "sensor_msgs/Image",
            ns(f.timestamp),
            image(ns(f.timestamp), w, h, "rgb8", colour.as_raw()),
        )]);
    }
    let dir = common::scratch("rosbag-clip");
    let path = dir.0.join("clip.bag");
    std::fs::write(&path, bag.finish(true)).unwrap();
    let mut source = DatasetSource::open(&path).unwrap();
    let bag_seq = source.sequence().unwrap();
    assert!(bag_seq.warnings.is_empty(), "{:?}", bag_seq.warnings);
    assert_eq!(bag_seq.depth_scale, Some(5000.0), "the folder's scale");
    assert_eq!(bag_seq.frames.len(), frames.len());
    let settings = surfel_slam::CameraPreset::TumFr3.depth_settings();
    for (a, b) in frames.iter().zip(&bag_seq.frames) {
        assert!(b.colour.is_some(), "paired");
        let from_folder = folder.read_frame(a, &settings).unwrap();
        let from_bag = source.read_frame(b, &settings).unwrap();
        assert!(
            from_folder.depth_m == from_bag.depth_m,
            "depth of {}",
            a.depth
        );
        assert!(from_folder.rgb == from_bag.rgb, "colour of {}", b.depth);
    }
}
