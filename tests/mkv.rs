//! Azure Kinect `.mkv` structure: the shared sample's tracks, attachment
//! and blocks (values from an independent EBML walk of the file in
//! Python), a cut copy keeping the clusters before the cut with one
//! warning, hostile bytes giving errors, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::io::Cursor;
use std::path::PathBuf;

use surfel_slam::dataset::mkv::{camera, AzureRecording, Block, MkvError, MkvFile, Purpose};

/// A track as compared: number, name, codec, FOURCC, size.
type TrackRow<'a> = (u64, &'a str, &'a str, Option<&'a str>, Option<(u64, u64)>);

const SAMPLE: &str = "recordings/azure_kinect_nfov_720p.mkv";

fn sample() -> Option<Vec<u8>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(SAMPLE);
    if path.is_file() {
        Some(std::fs::read(path).unwrap())
    } else if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{} not found and CI=true", path.display());
    } else {
        eprintln!("skipping: {} not found", path.display());
        None
    }
}

#[test]
fn the_sample_lists_its_tracks_attachment_and_blocks() {
    let Some(bytes) = sample() else {
        return;
    };
    let mkv = MkvFile::read(Cursor::new(bytes.clone())).expect("reads");
    assert_eq!(mkv.timecode_scale_ns, 1000);
    let tracks: Vec<TrackRow<'_>> = mkv
        .tracks
        .iter()
        .map(|t| {
            (
                t.number,
                t.name.as_str(),
                t.codec.as_str(),
                t.fourcc.as_deref(),
                t.size,
            )
        })
        .collect();
    assert_eq!(
        tracks,
        vec![
            (
                1,
                "COLOR",
                "V_MS/VFW/FOURCC",
                Some("MJPG"),
                Some((1280, 720))
            ),
            (
                2,
                "DEPTH",
                "V_MS/VFW/FOURCC",
                Some("b16g"),
                Some((640, 576))
            ),
            (3, "IR", "V_MS/VFW/FOURCC", Some("b16g"), Some((640, 576))),
            (4, "IMU", "S_K4A/IMU", None, None),
        ]
    );
    assert_eq!(mkv.attachments.len(), 1);
    assert_eq!(mkv.attachments[0].0, "calibration.json");
    assert!(mkv.attachments[0]
        .1
        .starts_with(b"{\"CalibrationInformation\""));
    let block = |track: u64| mkv.blocks[&track].as_slice();
    let at = |time_ns, pos, len| Block { time_ns, pos, len };
    assert_eq!(block(4), [at(0, 7503, 40)]);
    assert_eq!(block(1), [at(463_945_000, 7572, 217_095)]);
    assert_eq!(block(2), [at(463_945_000, 224_675, 737_280)]);
    assert_eq!(block(3), [at(463_945_000, 961_963, 737_280)]);
    assert_eq!(
        &bytes[7572..7574],
        [0xff, 0xd8],
        "the colour block is a JPEG"
    );
    assert_eq!(2 * 640 * 576, 737_280, "the depth block is 16-bit 640x576");
    assert!(mkv.cut_off.is_none());
}

#[test]
fn a_cut_file_keeps_the_clusters_before_the_cut() {
    let Some(bytes) = sample() else {
        return;
    };
    // Cut in the IR block of the second cluster: that capture is dropped whole.
    let mkv = MkvFile::read(Cursor::new(bytes[..1_000_000].to_vec())).expect("reads");
    assert_eq!(mkv.blocks.keys().copied().collect::<Vec<_>>(), vec![4]);
    assert!(
        mkv.cut_off
            .as_deref()
            .is_some_and(|w| w.contains("cut short")),
        "{:?}",
        mkv.cut_off
    );
    assert_eq!(mkv.tracks.len(), 4);
    // Every cut, and bytes flipped in the headers: errors, never a panic.
    for cut in (0..bytes.len()).step_by(4999) {
        let _ = MkvFile::read(Cursor::new(bytes[..cut].to_vec()));
    }
    let head = bytes[..8000].to_vec();
    let mut x = 0x9e37_79b9_u32;
    for _ in 0..3000 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        let mut bad = head.clone();
        let at = x as usize % bad.len();
        bad[at] = (x >> 8) as u8;
        let _ = MkvFile::read(Cursor::new(bad));
    }
    assert_eq!(
        MkvFile::read(Cursor::new(b"#ROSBAG V2.0\n".to_vec())),
        Err(MkvError::NotMatroska)
    );
    // The same through the recording: opened and its frames read, or errors.
    let mut x = 0x2545_f491_u32;
    for i in 0..60 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        let mut bad = bytes.clone();
        if i % 3 == 0 {
            bad.truncate(x as usize % bytes.len());
        } else {
            // In the headers and calibration, or in the blocks' heads.
            let at = if i % 3 == 1 {
                x as usize % 8000
            } else {
                7540 + x as usize % 40
            };
            bad[at] = (x >> 8) as u8;
        }
        if let Ok(mut rec) = AzureRecording::open(Cursor::new(bad)) {
            for f in 0..rec.frames.len() {
                let _ = rec.read_frame(f, true);
            }
        }
    }
}

#[test]
fn the_sample_calibration_in_its_modes() {
    let Some(bytes) = sample() else {
        return;
    };
    let mkv = MkvFile::read(Cursor::new(bytes)).expect("reads");
    let json = &mkv.attachments[0].1;
    // As the SDK's mode_specific_calibration.c computes them from the
    // file's normalised values (Python, in f64): NFOV unbinned 640x576 is
    // the 1024x1024 sensor cropped at (192, 180); 720p is the 4096x3072
    // sensor binned to 1280x960, cropped at (0, 120).
    let d = camera(json, Purpose::Depth, 640, 576).expect("depth");
    let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
    assert!(
        close(d.fx, 504.607_635_498_046_9) && close(d.fy, 504.732_513_427_734_4),
        "{d:?}"
    );
    assert!(
        close(d.cx, 332.781_066_894_531_25) && close(d.cy, 348.829_711_914_062_5),
        "{d:?}"
    );
    assert!(close(d.distortion[0], 0.547_939_777_374_267_6), "k1");
    assert_eq!(d.from_depth, glam::DAffine3::IDENTITY);
    let c = camera(json, Purpose::Colour, 1280, 720).expect("colour");
    assert!(
        close(c.fx, 611.795_349_121_093_8) && close(c.fy, 611.926_975_250_244_1),
        "{c:?}"
    );
    assert!(
        close(c.cx, 639.304_344_177_246_1) && close(c.cy, 365.852_901_458_740_23),
        "{c:?}"
    );
    let t = c.from_depth.translation;
    assert!(
        close(t.x, -0.032_083_429_396_152_496) && close(t.z, 0.003_883_692_668_750_882),
        "{t}"
    );
    // Row-major in the file: its second entry is row 0, column 1.
    assert!(close(
        c.from_depth.matrix3.y_axis.x,
        0.001_181_757_659_651_339
    ));
    assert!(matches!(
        camera(json, Purpose::Depth, 640, 480),
        Err(MkvError::Calibration(_))
    ));
    assert!(matches!(
        camera(b"{", Purpose::Depth, 640, 576),
        Err(MkvError::Calibration(_))
    ));
}

#[test]
fn the_sample_plays_its_frame_undistorted_and_coloured() {
    let Some(bytes) = sample() else {
        return;
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(SAMPLE);
    let mut source = surfel_slam::dataset::DatasetSource::open(&path).expect("opens");
    let seq = source.sequence().expect("a sequence");
    assert_eq!(seq.kind, surfel_slam::dataset::DatasetKind::AzureKinect);
    assert_eq!(seq.depth_scale, Some(1000.0));
    assert_eq!(seq.frames.len(), 1);
    assert!(
        seq.frames[0].colour.is_some(),
        "the colour of the same capture"
    );
    assert!((seq.frames[0].timestamp - 0.463_945).abs() < 1e-9);
    let k = seq.intrinsics.expect("the depth mode's");
    assert_eq!((k.width, k.height), (640, 576));
    let raw = source.read_raw(&seq.frames[0]).expect("reads");
    // At the principal point (332.8, 348.8) the lens does not move a
    // pixel: (333, 349) keeps its recorded value, 1883 mm big-endian as
    // Python reads the block.
    let recorded = |u: usize, v: usize| {
        let at = 224_675 + 2 * (v * 640 + u);
        u16::from_be_bytes([bytes[at], bytes[at + 1]])
    };
    assert_eq!(raw.depth[349 * 640 + 333], recorded(333, 349));
    assert_eq!(recorded(333, 349), 1883);
    // Away from it, the undistorted image differs from the recorded one.
    let moved = (0..640 * 576)
        .filter(|&i| raw.depth[i] != recorded(i % 640, i / 640))
        .count();
    assert!(moved > 640 * 576 / 10, "{moved} pixels moved");
    // Colour registered: most measured pixels see the colour camera.
    let measured: Vec<usize> = (0..640 * 576).filter(|&i| raw.depth[i] > 0).collect();
    let grey = measured
        .iter()
        .filter(|&&i| raw.rgb[3 * i..3 * i + 3] == [128, 128, 128])
        .count();
    assert!(
        grey * 10 < measured.len(),
        "{grey} of {} grey",
        measured.len()
    );
    // The command line plays it.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run", path.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 frames"));
}

#[test]
fn an_mkv_without_depth_is_refused_naming_the_file() {
    let Some(bytes) = sample() else {
        return;
    };
    // The DEPTH track renamed: no depth track left.
    let mut bad = bytes;
    let at = bad.windows(5).position(|w| w == b"DEPTH").unwrap();
    bad[at..at + 5].copy_from_slice(b"XXXXX");
    let dir = std::env::temp_dir().join(format!("surfel-slam-mkv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("no-depth.mkv");
    std::fs::write(&path, bad).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run", path.to_str().unwrap()])
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("no-depth.mkv") && stderr.contains("no depth track"),
        "{stderr}"
    );
}
