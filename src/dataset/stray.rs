//! iPhone / iPad LiDAR recordings as the Stray Scanner app exports them:
//!
//! - `depth/NNNNNN.png`: 16-bit depth, 256x192, millimetres;
//! - `confidence/NNNNNN.png`: 8-bit, 256x192, ARKit's confidence 0 (low),
//!   1 (medium), 2 (high); depth whose confidence is 0 is dropped at decode
//!   (1 and 2 are both kept: the frame carries no per-pixel weight);
//! - `camera_matrix.csv`: the colour camera's 3x3 intrinsics at its
//!   1920x1440 resolution, three comma-separated rows; fx, cx (first row)
//!   and fy, cy (second) are scaled by 256 / 1920 to the depth images; the
//!   third row is not read (exports hold rows like `0.0, 0.0, 1.0942`);
//! - `odometry.csv`: a header line, then `timestamp, frame, x, y, z, qx,
//!   qy, qz, qw` (seconds, frame number, camera-to-world in metres with our
//!   camera axes: x right, y down, z forward); newer versions add `fx, fy,
//!   cx, cy, distortion_center_x, distortion_center_y` (15 columns, the
//!   last ones possibly empty, not read). This is ARKit's own trajectory,
//!   not ground truth: [`crate::dataset::Sequence::odometry`];
//! - `rgb.mp4`, the colour video: not read natively. An `rgb/` folder of
//!   frames extracted from it (`rgb/NNNNNN.jpg` or `.png`, any size: scaled
//!   to the depth's at decode) gives the frames colour; ffmpeg numbers the
//!   frames from 1 unless told `-start_number 0`, so an `rgb/` folder that
//!   starts at `000001` is matched one number up. Without `rgb/` the
//!   sequence is depth only.
//! - `imu.csv` (optional): a header line, then `timestamp, a_x, a_y, a_z,
//!   alpha_x, alpha_y, alpha_z` at 100 Hz (seconds on ARKit's clock, the
//!   accelerometer in m/s² with gravity, the gyro in rad/s, the phone's
//!   own axes): [`crate::dataset::Sequence::imu`]. A last row cut off (the
//!   app stopped mid-write) is skipped with a warning naming the line.
//!
//! A cut-off last row of `odometry.csv` (the app stopped while writing it)
//! is skipped with a warning ([`crate::dataset::Sequence::warnings`]).
//!
//! Frames are the depth images, in number order. A frame's timestamp is its
//! odometry row's; exports often hold more depth images than odometry rows
//! (942 against 854): a frame without a row gets a timestamp between its
//! neighbours' rows, or beyond the last (before the first) one at the mean
//! frame interval of the rows (1/60 s when there are fewer than two rows).

use std::collections::{BTreeMap, HashMap, HashSet};

use glam::{DAffine3, DQuat, DVec3};

use crate::camera::Intrinsics;
use crate::imu::ImuSample;

use super::lines::{parse_rows, parse_rows_strict, strictly, Line};
use super::{index_text, numbered_in, CalibratedSize, DatasetError, FrameEntry, Layout};

/// Width of the colour images `camera_matrix.csv` is calibrated for, pixels.
pub const COLOUR_WIDTH: usize = 1920;
/// Height of the colour images, pixels.
pub const COLOUR_HEIGHT: usize = 1440;
/// Width of Stray Scanner's depth and confidence images, pixels.
pub const DEPTH_WIDTH: usize = 256;
/// Height of the depth and confidence images, pixels.
pub const DEPTH_HEIGHT: usize = 192;
/// Frame interval when the odometry has fewer than two rows, seconds
/// (the app records at 60 Hz).
const DEFAULT_FRAME_INTERVAL_S: f64 = 1.0 / 60.0;

/// One row of `odometry.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryRow {
    /// Seconds (ARKit's clock).
    pub timestamp: f64,
    /// The frame number (of `depth/NNNNNN.png`).
    pub frame: u64,
    /// Camera-to-world, metres.
    pub world_from_camera: DAffine3,
}

/// What [`parse`] builds.
pub(crate) struct Parsed {
    /// The depth images' intrinsics.
    pub intrinsics: Intrinsics,
    /// The frames, in number order.
    pub frames: Vec<FrameEntry>,
    /// The device's odometry `(timestamp, world_from_camera)`.
    pub odometry: Vec<(f64, DAffine3)>,
    /// The IMU's samples from `imu.csv`; empty without one.
    pub imu: Vec<ImuSample>,
}

/// Builds the Stray Scanner frame list, the depth intrinsics, the
/// odometry and the IMU samples from `camera_matrix.csv`
/// (`layout.index_files[0]`), `odometry.csv` (`[1]`) and, when listed and
/// its text given, `imu.csv` (`[2]`); a cut-off last row of the odometry
/// (the app stopped mid-write) is skipped onto `warnings`.
pub(crate) fn parse(
    layout: &Layout,
    listing: &HashSet<&str>,
    texts: &HashMap<String, String>,
    warnings: &mut Vec<DatasetError>,
) -> Result<Parsed, DatasetError> {
    let root = &layout.root_prefix;
    let missing_index = |name: &str| DatasetError::MissingFile {
        path: format!("{root}{name}"),
        listed_in: "the Stray Scanner layout".to_owned(),
    };
    let matrix_name = layout
        .index_files
        .first()
        .ok_or_else(|| missing_index("camera_matrix.csv"))?;
    let odometry_name = layout
        .index_files
        .get(1)
        .ok_or_else(|| missing_index("odometry.csv"))?;
    let intrinsics = read_camera_matrix(index_text(texts, matrix_name)?, matrix_name, warnings)?;
    let rows = parse_rows(
        index_text(texts, odometry_name)?,
        odometry_name,
        true,
        warnings,
        odometry_row,
    )?;
    let (imu, warning) = match layout.index_files.get(2) {
        Some(name) => match texts.get(name) {
            Some(text) => parse_imu(text, name)?,
            None => (Vec::new(), None),
        },
        None => (Vec::new(), None),
    };
    warnings.extend(warning);

    let depth = numbered_in(listing, &format!("{root}depth/"), &["png"]);
    let confidence = numbered_in(listing, &format!("{root}confidence/"), &["png"]);
    let colour = numbered_in(listing, &format!("{root}rgb/"), &["jpg", "png", "jpeg"]);
    // ffmpeg's default numbering starts at 1.
    let shift = u64::from(!colour.contains_key(&0) && colour.contains_key(&1));
    let clock = Clock::new(&rows);
    let size = CalibratedSize {
        width: DEPTH_WIDTH,
        height: DEPTH_HEIGHT,
        file: format!("{matrix_name} (Stray Scanner's depth size)"),
    };
    let frames = depth
        .iter()
        .enumerate()
        .map(|(index, (&n, &depth_path))| {
            let beside = || format!("the Stray Scanner layout (beside {depth_path})");
            let confidence_path = confidence.get(&n).map_or_else(
                || format!("{root}confidence/{n:06}.png"),
                |p| (*p).to_owned(),
            );
            let mut missing = (!confidence.contains_key(&n)).then(|| DatasetError::MissingFile {
                path: confidence_path.clone(),
                listed_in: beside(),
            });
            let colour_path = if colour.is_empty() {
                None
            } else {
                let c = n + shift;
                let path = colour
                    .get(&c)
                    .map_or_else(|| format!("{root}rgb/{c:06}.jpg"), |p| (*p).to_owned());
                if !colour.contains_key(&c) && missing.is_none() {
                    missing = Some(DatasetError::MissingFile {
                        path: path.clone(),
                        listed_in: beside(),
                    });
                }
                Some(path)
            };
            FrameEntry {
                index,
                timestamp: clock.timestamp(n),
                colour: colour_path,
                depth: depth_path.to_owned(),
                confidence: Some(confidence_path),
                calibrated_size: Some(size.clone()),
                pose_file: None,
                missing,
            }
        })
        .collect();
    let odometry = rows
        .iter()
        .map(|r| (r.timestamp, r.world_from_camera))
        .collect();
    Ok(Parsed {
        intrinsics,
        frames,
        odometry,
        imu,
    })
}

/// Frame number -> timestamp, from the odometry rows.
struct Clock {
    /// Frame number -> seconds, one per row (the first row of a number wins).
    known: BTreeMap<u64, f64>,
    /// Mean seconds per frame number over the rows.
    interval: f64,
}

impl Clock {
    fn new(rows: &[OdometryRow]) -> Self {
        let mut known = BTreeMap::new();
        for r in rows {
            known.entry(r.frame).or_insert(r.timestamp);
        }
        let interval = match (known.first_key_value(), known.last_key_value()) {
            (Some((&f0, &t0)), Some((&f1, &t1))) if f1 > f0 && t1 > t0 => {
                (t1 - t0) / (f1 - f0) as f64
            }
            _ => DEFAULT_FRAME_INTERVAL_S,
        };
        Self { known, interval }
    }

    /// The timestamp of frame `n`: its row's; between two rows, on the line
    /// between them; beyond the rows, at the mean interval from the nearest.
    fn timestamp(&self, n: u64) -> f64 {
        let before = self.known.range(..=n).next_back();
        let after = self.known.range(n..).next();
        match (before, after) {
            (Some((&f0, &t0)), Some((&f1, &t1))) if f1 > f0 => {
                t0 + (t1 - t0) * (n - f0) as f64 / (f1 - f0) as f64
            }
            (Some((_, &t)), Some(_)) => t,
            (Some((&f0, &t0)), None) => t0 + (n - f0) as f64 * self.interval,
            (None, Some((&f1, &t1))) => t1 - (f1 - n) as f64 * self.interval,
            (None, None) => n as f64 * self.interval,
        }
    }
}

/// The comma-separated fields of a line, trimmed.
fn fields<'a>(line: &Line<'a>) -> Vec<&'a str> {
    line.text.split(',').map(str::trim).collect()
}

/// A finite number, or the error naming the line and the field.
fn number(line: &Line<'_>, field: &str, what: &str) -> Result<f64, DatasetError> {
    field
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| line.malformed(&format!("{what} `{field}` is not a finite number")))
}

/// Parses `camera_matrix.csv` (the colour camera's 3x3 intrinsics at
/// 1920x1440, three rows of three comma-separated numbers) into the
/// intrinsics of the 256x192 depth images: fx, cx from the first row and
/// fy, cy from the second, scaled by 256 / 1920. The third row must hold
/// three numbers, whatever they are. Errors name `file_name` and the line.
pub fn parse_camera_matrix(text: &str, file_name: &str) -> Result<Intrinsics, DatasetError> {
    let mut warnings = Vec::new();
    let k = read_camera_matrix(text, file_name, &mut warnings)?;
    strictly(k, warnings.pop())
}

/// [`parse_camera_matrix`] for a recording: a cut-off third row (never
/// read) is skipped onto `warnings`; a cut-off first or second row still
/// leaves too few rows, an error.
fn read_camera_matrix(
    text: &str,
    file_name: &str,
    warnings: &mut Vec<DatasetError>,
) -> Result<Intrinsics, DatasetError> {
    let mut last = Line::none(file_name);
    let warned_before = warnings.len();
    let rows = parse_rows(text, file_name, true, warnings, |i, line| {
        if i == 3 {
            return Err(line.malformed("a 3x3 camera matrix has 3 rows; this is a 4th"));
        }
        let f = fields(&line);
        let [a, b, c] = f[..] else {
            return Err(line.malformed(&format!(
                "expected 3 comma-separated numbers (a row of the 3x3 camera matrix), found {} fields",
                f.len()
            )));
        };
        let what = "matrix entry";
        let row = [
            number(&line, a, what)?,
            number(&line, b, what)?,
            number(&line, c, what)?,
        ];
        last = line;
        Ok(Some(row))
    })?;
    let (r0, r1) = match rows[..] {
        [r0, r1, _] => (r0, r1),
        // The third row cut off: it is not read.
        [r0, r1] if warnings.len() > warned_before => (r0, r1),
        _ => {
            return Err(last.malformed(&format!(
                "expected the 3 rows of a 3x3 camera matrix, found {}",
                rows.len()
            )))
        }
    };
    let s = DEPTH_WIDTH as f64 / COLOUR_WIDTH as f64;
    let k = Intrinsics::new(
        (r0[0] * s) as f32,
        (r1[1] * s) as f32,
        (r0[2] * s) as f32,
        (r1[2] * s) as f32,
        DEPTH_WIDTH,
        DEPTH_HEIGHT,
    );
    match k.problem() {
        Some(problem) => Err(last.malformed(&format!(
            "the matrix scaled from {COLOUR_WIDTH}x{COLOUR_HEIGHT} to the depth's \
             {DEPTH_WIDTH}x{DEPTH_HEIGHT}: {problem}"
        ))),
        None => Ok(k),
    }
}

/// Parses `odometry.csv`: an optional header line (its first field not a
/// number), then rows of 9 (`timestamp, frame, x, y, z, qx, qy, qz, qw`) or
/// 15 comma-separated fields (the 6 more not read and possibly empty).
/// Quaternions are normalised. A row with another number of fields, a
/// non-numeric or non-finite value, a frame that is not a whole number or a
/// zero quaternion is a `MalformedLine` naming `file_name` and the line
/// (the last one too: a sequence skips a cut-off last row, this does not).
pub fn parse_odometry(text: &str, file_name: &str) -> Result<Vec<OdometryRow>, DatasetError> {
    parse_rows_strict(text, file_name, true, odometry_row)
}

/// One row of `odometry.csv` (`i`: its place among the content lines;
/// `None` for the header).
fn odometry_row(i: usize, line: Line<'_>) -> Result<Option<OdometryRow>, DatasetError> {
    let f = fields(&line);
    let header = f.first().is_some_and(|h| h.parse::<f64>().is_err());
    if i == 0 && header {
        return Ok(None);
    }
    if f.len() != 9 && f.len() != 15 {
        return Err(line.malformed(&format!(
            "expected 9 fields `timestamp, frame, x, y, z, qx, qy, qz, qw` (or 15, with \
             `fx, fy, cx, cy, distortion_center_x, distortion_center_y`), found {}",
            f.len()
        )));
    }
    let names = ["timestamp", "frame", "x", "y", "z", "qx", "qy", "qz", "qw"];
    let mut v = [0.0_f64; 9];
    for ((slot, field), name) in v.iter_mut().zip(&f).zip(names) {
        *slot = number(&line, field, name)?;
    }
    let [t, frame, x, y, z, qx, qy, qz, qw] = v;
    if frame < 0.0 || frame.fract() != 0.0 || frame > 1e15 {
        return Err(line.malformed("the frame number is not a whole number >= 0"));
    }
    let q = DQuat::from_xyzw(qx, qy, qz, qw);
    let norm = q.length();
    if norm <= 1e-9 {
        return Err(line.malformed("zero quaternion"));
    }
    Ok(Some(OdometryRow {
        timestamp: t,
        frame: frame as u64,
        world_from_camera: DAffine3::from_rotation_translation(q / norm, DVec3::new(x, y, z)),
    }))
}

/// Parses `imu.csv`: an optional header line (its first field not a
/// number), then rows of 7 comma-separated numbers `timestamp, a_x, a_y,
/// a_z, alpha_x, alpha_y, alpha_z` (seconds, m/s² with gravity, rad/s).
/// The last row, when it has fewer fields or a field that is not a number,
/// was cut off by the app stopping mid-write: it is skipped, and the
/// second value is the warning naming `file_name` and its line. Any other
/// malformed row is a `MalformedLine` error.
pub fn parse_imu(
    text: &str,
    file_name: &str,
) -> Result<(Vec<ImuSample>, Option<DatasetError>), DatasetError> {
    let mut warnings = Vec::new();
    let samples = parse_rows(text, file_name, true, &mut warnings, |i, line| {
        let f = fields(&line);
        if i == 0 && f.first().is_some_and(|h| h.parse::<f64>().is_err()) {
            return Ok(None);
        }
        imu_row(&line, &f).map(Some)
    })?;
    Ok((samples, warnings.pop()))
}

/// One row of `imu.csv`.
fn imu_row(line: &Line<'_>, f: &[&str]) -> Result<ImuSample, DatasetError> {
    let [t, ax, ay, az, gx, gy, gz] = f[..] else {
        return Err(line.malformed(&format!(
            "expected 7 fields `timestamp, a_x, a_y, a_z, alpha_x, alpha_y, alpha_z`, found {}",
            f.len()
        )));
    };
    Ok(ImuSample {
        time_s: number(line, t, "timestamp")?,
        accel_mps2: DVec3::new(
            number(line, ax, "a_x")?,
            number(line, ay, "a_y")?,
            number(line, az, "a_z")?,
        ),
        gyro_radps: DVec3::new(
            number(line, gx, "alpha_x")?,
            number(line, gy, "alpha_y")?,
            number(line, gz, "alpha_z")?,
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraPreset;
    use crate::dataset::{detect_layout, parse_sequence, DatasetKind};

    const MATRIX: &str = "1597.4, 0.0, 959.8\n0.0, 1597.4, 722.2\n0.0, 0.0, 1.0942\n";
    const ODOMETRY: &str = "timestamp, frame, x, y, z, qx, qy, qz, qw, fx, fy, cx, cy, distortion_center_x, distortion_center_y\n\
        10.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1597.4, 1597.4, 959.8, 722.2, ,\n\
        10.1, 1, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1597.4, 1597.4, 959.8, 722.2, ,\n\
        10.3, 3, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 1597.4, 1597.4, 959.8, 722.2, ,\n";

    fn names(frames: u64, rgb_from: Option<u64>) -> Vec<String> {
        let mut names: Vec<String> = [
            "s/camera_matrix.csv",
            "s/odometry.csv",
            "s/rgb.mp4",
            "s/imu.csv",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect();
        for n in 0..frames {
            names.push(format!("s/depth/{n:06}.png"));
            names.push(format!("s/confidence/{n:06}.png"));
            if let Some(first) = rgb_from {
                names.push(format!("s/rgb/{:06}.jpg", n + first));
            }
        }
        names
    }

    fn texts() -> HashMap<String, String> {
        HashMap::from([
            ("s/camera_matrix.csv".to_owned(), MATRIX.to_owned()),
            ("s/odometry.csv".to_owned(), ODOMETRY.to_owned()),
        ])
    }

    #[test]
    fn detected_and_parsed_depth_only() {
        let names = names(6, None);
        let layout = detect_layout(&names).expect("Stray");
        assert_eq!(layout.kind, DatasetKind::StrayScanner);
        assert_eq!(
            layout.index_files,
            vec!["s/camera_matrix.csv", "s/odometry.csv", "s/imu.csv"]
        );
        let seq = parse_sequence(&layout, &names, &texts(), None).expect("parses");
        assert_eq!(seq.preset, CameraPreset::StrayLidar);
        let k = seq.intrinsics.expect("from the file");
        assert!((k.fx - 1597.4 * 256.0 / 1920.0).abs() < 1e-3);
        assert!((k.cy - 722.2 * 256.0 / 1920.0).abs() < 1e-3);
        assert_eq!((k.width, k.height), (256, 192));
        assert_eq!(seq.frames.len(), 6);
        assert!(seq
            .frames
            .iter()
            .all(|f| f.colour.is_none() && f.missing.is_none()));
        assert_eq!(
            seq.frames[2].confidence.as_deref(),
            Some("s/confidence/000002.png")
        );
        // Rows at frames 0, 1, 3; frame 2 between them, 4 and 5 beyond at
        // the mean interval (0.1 s).
        let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
        for (t, expected) in stamps.iter().zip([10.0, 10.1, 10.2, 10.3, 10.4, 10.5]) {
            assert!((t - expected).abs() < 1e-9, "{stamps:?}");
        }
        assert_eq!(seq.odometry.len(), 3);
        assert!(seq.ground_truth.is_empty());
        assert!((seq.odometry[2].1.translation.x - 0.3).abs() < 1e-12);
        // imu.csv listed but its text not given (the page before reading
        // it): no samples, no error.
        assert!(seq.imu.is_empty() && seq.warnings.is_empty());
    }

    #[test]
    fn imu_rows_are_read_and_a_cut_off_last_row_is_skipped_with_a_warning() {
        let imu = "timestamp, a_x, a_y, a_z, alpha_x, alpha_y, alpha_z\n\
            10.00, 0.1, -9.8, 0.2, 0.01, 0.02, -0.03\n\
            10.01, 0.1, -9.8, 0.2, 0.01, 0.02, -0.04\n\
            10.02, 0.1, -9.";
        let names = names(3, None);
        let layout = detect_layout(&names).expect("Stray");
        let mut texts = texts();
        texts.insert("s/imu.csv".to_owned(), imu.to_owned());
        let seq = parse_sequence(&layout, &names, &texts, None).expect("parses");
        assert_eq!(seq.imu.len(), 2);
        assert!((seq.imu[1].gyro_radps.z + 0.04).abs() < 1e-12);
        assert!((seq.imu[0].accel_mps2.y + 9.8).abs() < 1e-12);
        assert_eq!(seq.warnings.len(), 1, "{:?}", seq.warnings);
        assert!(
            matches!(&seq.warnings[0], DatasetError::CutOffLine { file, line_number: 4, .. }
                if file == "s/imu.csv"),
            "{}",
            seq.warnings[0]
        );
        // Whole: no warning. A bad row before the last: an error.
        let (whole, warning) =
            parse_imu("10, 0, 0, 0, 0, 0, 0\n10.01, 0, 0, 0, 0, 0, 0\n", "i.csv").unwrap();
        assert_eq!((whole.len(), warning), (2, None));
        let err = parse_imu("10, 0, 0, 0, 0, 0\n10.01, 0, 0, 0, 0, 0, 0\n", "i.csv").unwrap_err();
        assert!(
            matches!(err, DatasetError::MalformedLine { line_number: 1, .. }),
            "{err}"
        );
        let err =
            parse_imu("10, 0, 0, 0, nan, 0, 0\n10.01, 0, 0, 0, 0, 0, 0\n", "i.csv").unwrap_err();
        assert!(err.to_string().contains("alpha_x"), "{err}");
    }

    #[test]
    fn extracted_colour_frames_numbered_from_one() {
        for first in [0, 1] {
            let names = names(3, Some(first));
            let layout = detect_layout(&names).expect("Stray");
            let seq = parse_sequence(&layout, &names, &texts(), None).expect("parses");
            assert_eq!(
                seq.frames[0].colour.as_deref(),
                Some(format!("s/rgb/{first:06}.jpg").as_str())
            );
            assert!(seq.frames.iter().all(|f| f.missing.is_none()));
        }
    }

    #[test]
    fn a_missing_confidence_image_is_named() {
        let mut names = names(3, None);
        names.retain(|n| n != "s/confidence/000001.png");
        let layout = detect_layout(&names).expect("Stray");
        let seq = parse_sequence(&layout, &names, &texts(), None).expect("parses");
        assert!(
            matches!(&seq.frames[1].missing, Some(DatasetError::MissingFile { path, .. }) if path == "s/confidence/000001.png")
        );
    }

    #[test]
    fn malformed_files_are_named() {
        let matrix_cases = [
            ("1,0,0,0\n0,1,0,0\n0,0,1,0\n0,0,0,1\n", 1, "found 4 fields"),
            ("1597, 0, 960\n0, 1597, 720\n0, 0, 1\n0, 0, 1\n", 4, "4th"),
            ("1597, 0, 960\n0, x, 720\n0, 0, 1\n", 2, "`x`"),
            ("1597, 0, 960\n", 1, "found 1"),
        ];
        for (text, line, needle) in matrix_cases {
            let err = parse_camera_matrix(text, "m.csv").expect_err(needle);
            assert!(
                matches!(&err, DatasetError::MalformedLine { file, line_number, reason, .. }
                    if file == "m.csv" && *line_number == line && reason.contains(needle)),
                "{needle}: {err}"
            );
        }
        let odometry_cases = [
            (
                "timestamp, frame, x\n1, 0, 0, 0, 0, 0, 0, 1\n",
                2,
                "found 8",
            ),
            ("1, 0, 0, 0, 0, 0, 0, 0, one\n", 1, "qw `one`"),
            ("1, 0.5, 0, 0, 0, 0, 0, 0, 1\n", 1, "whole number"),
            ("1, 0, 0, 0, 0, 0, 0, 0, 0\n", 1, "zero quaternion"),
        ];
        for (text, line, needle) in odometry_cases {
            let err = parse_odometry(text, "o.csv").expect_err(needle);
            assert!(
                matches!(&err, DatasetError::MalformedLine { file, line_number, reason, .. }
                    if file == "o.csv" && *line_number == line && reason.contains(needle)),
                "{needle}: {err}"
            );
        }
    }

    #[test]
    fn a_cut_off_third_camera_matrix_row_is_not_needed() {
        let mut warnings = Vec::new();
        let k = read_camera_matrix(
            "1597.4, 0.0, 959.8\n0.0, 1597.4, 722.2\n0.0, 0.",
            "m.csv",
            &mut warnings,
        )
        .expect("rows 1 and 2 are read");
        assert!((k.fx - 1597.4 * 256.0 / 1920.0).abs() < 1e-3);
        assert_eq!(warnings.len(), 1);
        let err = read_camera_matrix("1597.4, 0.0, 959.8\n0.0, 1597", "m.csv", &mut warnings)
            .expect_err("the second row is needed");
        assert!(err.to_string().contains("found 1"), "{err}");
    }

    #[test]
    fn a_cut_off_last_odometry_row_is_skipped_with_one_warning() {
        let names = names(6, None);
        let layout = detect_layout(&names).expect("Stray");
        let mut texts = texts();
        // The app stopped mid-row: 8 of the 15 fields, no newline.
        let cut = format!("{ODOMETRY}10.4, 4, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0");
        texts.insert("s/odometry.csv".to_owned(), cut);
        let seq = parse_sequence(&layout, &names, &texts, None).expect("plays what it has");
        assert_eq!(seq.frames.len(), 6);
        assert_eq!(seq.odometry.len(), 3);
        assert_eq!(seq.warnings.len(), 1, "{:?}", seq.warnings);
        let text = seq.warnings[0].to_string();
        assert!(
            text.starts_with("s/odometry.csv, line 5: the last line is cut off"),
            "{text}"
        );
        // The same row in the middle is not a cut-off recording.
        let middle = format!(
            "timestamp, frame\n10.4, 4, 0.4\n{}",
            &ODOMETRY[ODOMETRY.find('\n').unwrap_or(0) + 1..]
        );
        texts.insert("s/odometry.csv".to_owned(), middle);
        let err = parse_sequence(&layout, &names, &texts, None).expect_err("malformed");
        assert!(
            matches!(err, DatasetError::MalformedLine { line_number: 2, .. }),
            "{err}"
        );
    }
}
