//! RealSense ROS2 recordings (`.db3`, librealsense 2.58 and later): the
//! fixture `tests/data/realsense_teddy_crop.db3`, written by librealsense's
//! own recorder (pyrealsense2 2.59, `scripts/db3-fixture.py`) from TUM fr3
//! teddy's depth frames 4-11 cropped to their 320x240 centre, decodes to
//! exactly the TUM pixels, with the recording's intrinsics, depth units and
//! the frames' own timestamps; a short run on it tracks (ATE against TUM's
//! ground truth); damaged copies (every kind of cut, flipped bytes, a page
//! pointer out of range, a missing table, another compression) are errors,
//! never panics.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DAffine3, DQuat, DVec3};
use surfel_slam::dataset::db3::{Db3Error, RealSenseDb3};
use surfel_slam::dataset::{DatasetKind, DatasetSource, Sequence};
use surfel_slam::frame::{decode_colour, decode_depth_raw};
use surfel_slam::{Pipeline, SlamConfig, Verdict};

const DEPTH: &str = "/device_0/sensor_0/Depth_0/image/data/compressedDepth";
const COLOUR: &str = "/device_0/sensor_1/Color_0/image/data/compressed";
/// The crop's corner and size in the 640x480 TUM images.
const CROP: (usize, usize, usize, usize) = (160, 120, 320, 240);
/// The TUM depth frames written (after association), from..to.
const FRAMES: std::ops::Range<usize> = 4..12;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/realsense_teddy_crop.db3")
}

fn tum_list(path: &Path) -> Vec<(f64, String)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut it = l.split_whitespace();
            (
                it.next().unwrap().parse().unwrap(),
                it.next().unwrap().to_owned(),
            )
        })
        .collect()
}

/// The TUM frames the fixture was made from, as the recording tool
/// associates them (each depth with the nearest colour within 0.02 s):
/// (depth time, depth file, colour time, colour file), and the time the
/// recording counts from (the first frame's earlier stamp).
fn tum_frames(dir: &Path) -> (Vec<(f64, String, f64, String)>, f64) {
    let colour = tum_list(&dir.join("rgb.txt"));
    let all: Vec<_> = tum_list(&dir.join("depth.txt"))
        .into_iter()
        .filter_map(|(td, fd)| {
            let (tc, fc) = colour
                .iter()
                .min_by(|a, b| (a.0 - td).abs().total_cmp(&(b.0 - td).abs()))?;
            ((tc - td).abs() < 0.02).then(|| (td, fd, *tc, fc.clone()))
        })
        .collect();
    let frames = all[FRAMES].to_vec();
    let t0 = frames[0].0.min(frames[0].2);
    (frames, t0)
}

fn crop<T: Copy>(pixels: &[T], width: usize, channels: usize) -> Vec<T> {
    let (x, y, w, h) = CROP;
    (y..y + h)
        .flat_map(|r| {
            let start = channels * (r * width + x);
            pixels[start..start + channels * w].iter().copied()
        })
        .collect()
}

#[test]
fn the_fixture_reads_with_its_calibration_and_units() {
    let mut source = DatasetSource::open(&fixture()).expect("opens");
    let seq = source.sequence().expect("a sequence");
    assert_eq!(seq.kind, DatasetKind::RealSenseDb3);
    assert_eq!(seq.frames.len(), FRAMES.len());
    assert!(seq.warnings.is_empty(), "{:?}", seq.warnings);
    // The tool's intrinsics (the crop moves the principal point), depth
    // units 0.0002 m: 5000 units a metre, as TUM's.
    let k = seq.intrinsics.expect("intrinsics");
    assert_eq!((k.width, k.height), (320, 240));
    for (got, want) in [(k.fx, 535.4), (k.fy, 539.2), (k.cx, 160.1), (k.cy, 127.6)] {
        assert!((got - want).abs() < 1e-4, "{got} vs {want}");
    }
    assert_eq!(seq.depth_scale, Some(5000.0));
    assert!(
        seq.frames.iter().all(|f| f.colour.is_some()),
        "colour paired"
    );
    assert!(seq.frames[0].depth.starts_with(DEPTH));
    let mut db3 = RealSenseDb3::open(std::fs::File::open(fixture()).unwrap()).expect("opens");
    let rec = db3.recording().clone();
    assert_eq!(rec.depth_topic, DEPTH);
    assert_eq!(rec.colour.as_ref().map(|c| c.0.as_str()), Some(COLOUR));
    assert_eq!(rec.depth_units_m, 0.0002);
    let frame = db3.read_frame(7, true).expect("the last frame reads");
    assert_eq!((frame.width, frame.height), (320, 240));
    assert_eq!(frame.rgb.len(), 3 * 320 * 240);
    assert!(frame.depth.iter().filter(|&&d| d > 0).count() > 320 * 240 / 2);
}

#[test]
fn the_fixture_decodes_to_the_tum_pixels_and_times() {
    let Some(tum) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let (frames, t0) = tum_frames(&tum);
    let mut source = DatasetSource::open(&fixture()).expect("opens");
    let seq = source.sequence().expect("a sequence");
    let settings = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3).depth;
    for (entry, (td, fd, tc, fc)) in seq.frames.iter().zip(&frames) {
        // The frames' own timestamps: the TUM stamps from the first one.
        assert!((entry.timestamp - (td - t0)).abs() < 2e-6, "{entry:?}");
        let raw = source.read_raw(entry).expect("reads");
        let (w, _, tum_depth) = decode_depth_raw(&std::fs::read(tum.join(fd)).unwrap()).unwrap();
        assert_eq!(raw.depth, crop(&tum_depth, w, 1), "{fd}: raw depth");
        let (w, _, tum_rgb) = decode_colour(&std::fs::read(tum.join(fc)).unwrap()).unwrap();
        assert_eq!(raw.rgb, crop(&tum_rgb, w, 3), "{fc} (at {tc}): colour");
        // In metres, through the dataset layer, as the TUM folder gives them.
        let frame = source.read_frame(entry, &settings).expect("decodes");
        let metres: Vec<f32> = crop(&tum_depth, 640, 1)
            .into_iter()
            .map(|d| settings.to_metres(d))
            .collect();
        assert_eq!(frame.depth_m, metres, "{fd}: metres");
    }
}

/// The TUM ground truth in the recording's time (from its first stamp).
fn truth(tum: &Path, t0: f64) -> Vec<(f64, DAffine3)> {
    std::fs::read_to_string(tum.join("groundtruth.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            let q = DQuat::from_xyzw(v[4], v[5], v[6], v[7]).normalize();
            (
                v[0] - t0,
                DAffine3::from_rotation_translation(q, DVec3::new(v[1], v[2], v[3])),
            )
        })
        .collect()
}

#[test]
fn a_short_run_on_the_fixture_tracks() {
    let mut source = DatasetSource::open(&fixture()).expect("opens");
    let seq = source.sequence().expect("a sequence");
    // As the CLI sets it up: the preset's settings, the recording's camera
    // and depth units.
    let mut config = SlamConfig::from_preset(seq.preset);
    config.intrinsics = seq.intrinsics.expect("intrinsics");
    config.depth.scale = seq.depth_scale.expect("a depth scale");
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    for entry in &seq.frames {
        let frame = source.read_frame(entry, &config.depth).expect("decodes");
        let report = slam.push_frame(&frame, entry.timestamp).expect("pushed");
        assert!(!matches!(report.verdict, Verdict::Lost(_)), "{report:?}");
    }
    let Some(tum) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let (_, t0) = tum_frames(&tum);
    let ate = surfel_slam::eval::ate(slam.trajectory(), &truth(&tum, t0), 0.02).expect("ATE");
    // Measured 0.17 cm (8 poses; the camera moves about 2 cm).
    assert!(ate.rmse_m < 0.005, "ATE {} m", ate.rmse_m);
    assert_eq!(ate.pairs, 8);
    // The CLI reads it by its bytes too.
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run", fixture().to_str().unwrap(), "-q"])
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("8 frames, 8 tracked"), "{stdout}");
}

/// Opens `bytes` and reads every frame it lists: the first error, if any.
fn read_all(bytes: Vec<u8>) -> Result<usize, Db3Error> {
    let mut db3 = RealSenseDb3::open(Cursor::new(bytes))?;
    let n = db3.recording().frames.len();
    for i in 0..n {
        db3.read_frame(i, true)?;
    }
    Ok(n)
}

fn replace_all(bytes: &mut [u8], from: &[u8], to: &[u8]) -> usize {
    let mut n = 0;
    let mut at = 0;
    while let Some(i) = bytes[at..].windows(from.len()).position(|w| w == from) {
        bytes[at + i..at + i + to.len()].copy_from_slice(to);
        at += i + from.len();
        n += 1;
    }
    n
}

#[test]
fn damaged_files_are_errors_not_panics() {
    let bytes = std::fs::read(fixture()).unwrap();
    assert_eq!(read_all(bytes.clone()), Ok(8));
    // Cut anywhere: the header declares every page, so a cut file says so.
    for cut in (0..bytes.len())
        .step_by(bytes.len() / 97)
        .chain([99, 100, 4095])
    {
        let err = read_all(bytes[..cut].to_vec()).expect_err("a cut file");
        assert!(
            matches!(err, Db3Error::NotSqlite | Db3Error::Truncated { .. }),
            "cut at {cut}: {err}"
        );
    }
    // Not a database at all, and random bytes behind a valid magic.
    assert_eq!(
        read_all(b"#ROSBAG V2.0\n".to_vec()),
        Err(Db3Error::NotSqlite)
    );
    let mut x = 0x9e37_79b9_u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    let mut random: Vec<u8> = (0..64 * 1024).map(|_| next() as u8).collect();
    random[..100].copy_from_slice(&bytes[..100]);
    assert!(read_all(random).is_err());
    // The messages table's root (page 3, an interior page) pointing past
    // the file: its right-most child out of range.
    let page = 4096;
    assert_eq!(bytes[2 * page], 0x05, "page 3 is an interior table page");
    let mut bad = bytes.clone();
    bad[2 * page + 8..2 * page + 12].copy_from_slice(&0x7fff_ffffu32.to_be_bytes());
    let err = read_all(bad).expect_err("a page out of range");
    assert!(
        matches!(
            err,
            Db3Error::Corrupt {
                page: 2_147_483_647,
                ..
            }
        ),
        "{err}"
    );
    // A database without rosbag2's tables.
    let mut bad = bytes.clone();
    assert!(replace_all(&mut bad[..page], b"messages", b"massages") > 0);
    let err = read_all(bad).expect_err("no messages table");
    assert!(
        matches!(
            err,
            Db3Error::MissingTable {
                table: "messages",
                ..
            }
        ),
        "{err}"
    );
    // Depth compressed otherwise (RVL, as ROS2's compressed_depth_image_transport can).
    let mut bad = bytes.clone();
    assert!(replace_all(&mut bad, b"compressedDepth png", b"compressedDepth rvl") >= 8);
    let err = read_all(bad).expect_err("RVL depth");
    assert!(
        err.to_string().contains("compressedDepth rvl") && err.to_string().contains(DEPTH),
        "{err}"
    );
    // No 16-bit depth stream: refused, naming the image topics found.
    let mut bad = bytes.clone();
    assert!(
        replace_all(
            &mut bad,
            b"16UC1; compressedDepth",
            b"mono8; compressedDepth"
        ) >= 8
    );
    let err = read_all(bad).expect_err("no depth stream");
    assert!(
        err.to_string().starts_with("no depth stream") && err.to_string().contains(COLOUR),
        "{err}"
    );
    // Flipped bytes anywhere: errors or frames, never a panic.
    for _ in 0..300 {
        let mut bad = bytes.clone();
        let at = next() as usize % bad.len();
        bad[at] = next() as u8;
        let _ = read_all(bad);
    }
    // Flipped bytes in the b-tree pages (the schema, the roots, the leaves
    // of the small messages), where a damaged pointer matters most.
    for _ in 0..1000 {
        let mut bad = bytes.clone();
        let at = next() as usize % (8 * page);
        bad[at] = next() as u8;
        let _ = read_all(bad);
    }
}

#[test]
fn the_sequence_opens_by_its_bytes_whatever_its_name() {
    let dir = common::scratch("db3-name");
    std::fs::create_dir_all(&dir.0).unwrap();
    let renamed = dir.0.join("recording.bin");
    std::fs::copy(fixture(), &renamed).unwrap();
    let seq = Sequence::open(&renamed).expect("opens");
    assert_eq!(seq.kind, DatasetKind::RealSenseDb3);
    assert_eq!(seq.frames.len(), 8);
}
