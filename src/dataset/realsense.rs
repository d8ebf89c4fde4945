//! Intel RealSense, as Open3D's `realsense_recorder.py` writes a recording:
//! `color/NNNNNN.jpg` (or `.png`), `depth/NNNNNN.png` (one pair per frame,
//! the same number; 16-bit depth aligned to the colour image, in the
//! camera's depth units: millimetres by default, the preset's scale 1000)
//! and `camera_intrinsic.json`, Open3D's `PinholeCameraIntrinsic`:
//! `{"width": 640, "height": 480, "intrinsic_matrix": [fx, 0, 0, 0, fy, 0,
//! cx, cy, 1]}` (the 3x3 matrix column-major, pixels). `realsense.bag`,
//! `fragments/` and `scene/` beside them (the recorder's and Open3D's
//! reconstruction system's files) are ignored.
//!
//! There are no timestamps: a frame's timestamp is its file number
//! (`000123` -> 123), and there is no ground truth.

use std::collections::{BTreeSet, HashMap, HashSet};

use crate::camera::Intrinsics;

use super::{index_text, numbered_in, CalibratedSize, DatasetError, FrameEntry, Layout};

/// Colour image extensions, in the order preferred when a frame has both.
const COLOUR_EXTENSIONS: [&str; 3] = ["jpg", "png", "jpeg"];

/// Builds the RealSense frame list (frames in number order; a number with
/// only one of its two images keeps its place with `missing` set) and the
/// intrinsics from `camera_intrinsic.json` (`layout.index_files[0]`).
pub(crate) fn parse(
    layout: &Layout,
    listing: &HashSet<&str>,
    texts: &HashMap<String, String>,
) -> Result<(Intrinsics, Vec<FrameEntry>), DatasetError> {
    let Some(json_name) = layout.index_files.first() else {
        return Err(DatasetError::MissingFile {
            path: format!("{}camera_intrinsic.json", layout.root_prefix),
            listed_in: "the RealSense layout".to_owned(),
        });
    };
    let intrinsics = parse_intrinsic_json(index_text(texts, json_name)?, json_name)?;
    let root = &layout.root_prefix;
    let depth = numbered_in(listing, &format!("{root}depth/"), &["png"]);
    let colour = numbered_in(listing, &format!("{root}color/"), &COLOUR_EXTENSIONS);
    let numbers: BTreeSet<u64> = depth.keys().chain(colour.keys()).copied().collect();
    let size = CalibratedSize {
        width: intrinsics.width,
        height: intrinsics.height,
        file: json_name.clone(),
    };
    let frames = numbers
        .into_iter()
        .enumerate()
        .map(|(index, n)| {
            let depth_path = depth
                .get(&n)
                .map_or_else(|| format!("{root}depth/{n:06}.png"), |p| (*p).to_owned());
            let colour_path = colour
                .get(&n)
                .map_or_else(|| format!("{root}color/{n:06}.jpg"), |p| (*p).to_owned());
            let beside = |other: &str| format!("the RealSense layout (beside {other})");
            let missing = if !depth.contains_key(&n) {
                Some(DatasetError::MissingFile {
                    path: depth_path.clone(),
                    listed_in: beside(&colour_path),
                })
            } else if !colour.contains_key(&n) {
                Some(DatasetError::MissingFile {
                    path: colour_path.clone(),
                    listed_in: beside(&depth_path),
                })
            } else {
                None
            };
            FrameEntry {
                index,
                timestamp: n as f64,
                colour: Some(colour_path),
                depth: depth_path,
                confidence: None,
                calibrated_size: Some(size.clone()),
                pose_file: None,
                missing,
            }
        })
        .collect();
    Ok((intrinsics, frames))
}

/// Parses Open3D's `PinholeCameraIntrinsic` JSON (`camera_intrinsic.json`):
/// `width`, `height` (pixels) and `intrinsic_matrix`, the 3x3 matrix
/// column-major `[fx, 0, 0, 0, fy, 0, cx, cy, 1]`, pixels. Refused, naming
/// `file_name`: text that is not JSON, a missing or non-numeric field, a
/// matrix of another size (a 4x4), one that is not a pinhole matrix (a
/// row-major matrix is named as such), implausible values.
pub fn parse_intrinsic_json(text: &str, file_name: &str) -> Result<Intrinsics, DatasetError> {
    let bad = |reason: String| DatasetError::Calibration {
        path: file_name.to_owned(),
        reason,
    };
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let size = |key: &str| -> Result<usize, DatasetError> {
        let v = value
            .get(key)
            .ok_or_else(|| bad(format!("no `{key}` (the image {key} in pixels)")))?;
        v.as_u64()
            .filter(|&n| n > 0)
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| bad(format!("`{key}` must be a whole number of pixels, got {v}")))
    };
    let (width, height) = (size("width")?, size("height")?);
    let matrix = value
        .get("intrinsic_matrix")
        .and_then(serde_json::Value::as_array)
        .ok_or_else(|| bad("no `intrinsic_matrix` array (9 numbers, column-major)".to_owned()))?;
    let numbers: Vec<f64> = matrix
        .iter()
        .map(|v| v.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| {
            bad("`intrinsic_matrix` holds a value that is not a finite number".into())
        })?;
    let [fx, m1, m2, m3, fy, m5, cx, cy, m8] = numbers[..] else {
        let side = (numbers.len() as f64).sqrt();
        let shape = if side.fract() == 0.0 {
            format!(" (a {side}x{side} matrix)")
        } else {
            String::new()
        };
        return Err(bad(format!(
            "`intrinsic_matrix` has {} numbers{shape}; a pinhole camera's is 3x3, 9 numbers \
             column-major [fx, 0, 0, 0, fy, 0, cx, cy, 1]",
            numbers.len()
        )));
    };
    let zero = |x: f64| x.abs() < 1e-9;
    if !(zero(m1) && zero(m2) && zero(m3) && zero(m5) && (m8 - 1.0).abs() < 1e-9) {
        let row_major = zero(cx) && zero(cy) && !zero(m2) && !zero(m5);
        let why = if row_major {
            "it looks row-major ([fx, 0, cx, 0, fy, cy, 0, 0, 1]); Open3D writes it column-major \
             [fx, 0, 0, 0, fy, 0, cx, cy, 1]"
        } else {
            "expected [fx, 0, 0, 0, fy, 0, cx, cy, 1] (column-major)"
        };
        return Err(bad(format!(
            "`intrinsic_matrix` is not a pinhole matrix: {why}"
        )));
    }
    let k = Intrinsics::new(fx as f32, fy as f32, cx as f32, cy as f32, width, height);
    match k.problem() {
        Some(problem) => Err(bad(problem)),
        None => Ok(k),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraPreset;
    use crate::dataset::{detect_layout, parse_sequence, DatasetKind};

    const JSON: &str = r#"{"width": 848, "height": 480,
        "intrinsic_matrix": [421.5, 0, 0, 0, 421.0, 0, 424.2, 240.7, 1]}"#;

    fn names() -> Vec<String> {
        [
            "rec/camera_intrinsic.json",
            "rec/realsense.bag",
            "rec/color/000000.jpg",
            "rec/color/000001.jpg",
            "rec/color/000002.png",
            "rec/depth/000000.png",
            "rec/depth/000001.png",
            "rec/depth/000003.png",
            "rec/fragments/fragment_000.ply",
            "rec/scene/integrated.ply",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect()
    }

    #[test]
    fn detected_and_parsed_with_the_file_intrinsics() {
        let names = names();
        let layout = detect_layout(&names).expect("RealSense");
        assert_eq!(layout.kind, DatasetKind::RealSense);
        assert_eq!(layout.index_files, vec!["rec/camera_intrinsic.json"]);
        let texts = HashMap::from([(layout.index_files[0].clone(), JSON.to_owned())]);
        let seq = parse_sequence(&layout, &names, &texts, None).expect("parses");
        assert_eq!(seq.preset, CameraPreset::RealSenseD400);
        let k = seq.intrinsics.expect("from the file");
        assert_eq!((k.fx, k.fy, k.cx, k.cy), (421.5, 421.0, 424.2, 240.7));
        assert_eq!((k.width, k.height), (848, 480));
        let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
        assert_eq!(stamps, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(
            seq.frames[1].colour.as_deref(),
            Some("rec/color/000001.jpg")
        );
        assert_eq!(seq.frames[1].depth, "rec/depth/000001.png");
        assert!(seq.frames[1].missing.is_none());
        assert!(
            matches!(&seq.frames[2].missing, Some(DatasetError::MissingFile { path, .. }) if path == "rec/depth/000002.png")
        );
        assert!(
            matches!(&seq.frames[3].missing, Some(DatasetError::MissingFile { path, .. }) if path == "rec/color/000003.jpg")
        );
        assert!(seq.ground_truth.is_empty() && seq.odometry.is_empty());
    }

    #[test]
    fn malformed_intrinsics_are_named() {
        let cases = [
            ("{", "not JSON"),
            (r#"{"height": 480, "intrinsic_matrix": []}"#, "width"),
            (
                r#"{"width": 640, "height": 480, "intrinsic_matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}"#,
                "4x4",
            ),
            (
                r#"{"width": 640, "height": 480, "intrinsic_matrix": [600, 0, 320, 0, 600, 240, 0, 0, 1]}"#,
                "row-major",
            ),
            (
                r#"{"width": 640, "height": 480, "intrinsic_matrix": [600, 0, 0, 0, "a", 0, 320, 240, 1]}"#,
                "not a finite number",
            ),
            (
                r#"{"width": 640, "height": 480, "intrinsic_matrix": [0.6, 0, 0, 0, 0.6, 0, 320, 240, 1]}"#,
                "fx",
            ),
        ];
        for (text, needle) in cases {
            let err = parse_intrinsic_json(text, "c.json").expect_err(needle);
            assert!(
                matches!(&err, DatasetError::Calibration { path, reason } if path == "c.json" && reason.contains(needle)),
                "{needle}: {err}"
            );
        }
        for (w, h) in [(640, 480), (848, 480), (1280, 720)] {
            let text = format!(
                r#"{{"width": {w}, "height": {h}, "intrinsic_matrix": [600, 0, 0, 0, 600, 0, {}, {}, 1]}}"#,
                w / 2,
                h / 2
            );
            let k = parse_intrinsic_json(&text, "c.json").expect("every D400 size");
            assert_eq!((k.width, k.height), (w, h));
        }
    }
}
