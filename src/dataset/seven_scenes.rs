//! Microsoft 7-Scenes layout: `seq-XX/frame-NNNNNN.color.png` (or `.jpg`),
//! `frame-NNNNNN.depth.png` (millimetres, 65535 = invalid; the preset's
//! `DepthSettings` handle it) and `frame-NNNNNN.pose.txt` (4x4
//! camera-to-world matrix, metres, 4 whitespace-separated lines).
//!
//! The folder may be one `seq-XX` or a scene folder holding several: the
//! sequences are taken in name order and the frame index continues across
//! them. A frame's timestamp is its frame number plus an offset that keeps
//! timestamps increasing across sequences (one past the previous sequence's
//! last timestamp); for a single sequence it is the frame number itself.

use std::collections::{BTreeMap, HashMap, HashSet};

use glam::{DAffine3, DMat3, DVec3};

use super::lines::{content_lines, Line};
use super::{base_name, DatasetError, FrameEntry, Parsed};

/// Frame number in a 7-Scenes file name `frame-NNNNNN<suffix>`.
fn frame_number(file_name: &str, suffixes: &[&str]) -> Option<u64> {
    let rest = file_name.strip_prefix("frame-")?;
    let digits = suffixes.iter().find_map(|s| rest.strip_suffix(s))?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Frame number of a 7-Scenes colour image name (`frame-000123.color.png` or
/// `.color.jpg`), `None` for any other name.
#[must_use]
pub fn colour_frame_number(file_name: &str) -> Option<u64> {
    frame_number(file_name, &[".color.png", ".color.jpg"])
}

/// Frame number of a 7-Scenes pose file name (`frame-000123.pose.txt`).
#[must_use]
pub fn pose_frame_number(file_name: &str) -> Option<u64> {
    frame_number(file_name, &[".pose.txt"])
}

/// Builds the frame list from the names and the ground truth from the pose
/// texts given (each optional). A frame is any frame number with a colour or
/// a depth image; when one of the two is absent the frame is kept with
/// `missing` set (a half-copied folder). The last frame's pose file when
/// malformed (half written: a recording cut short) leaves that frame
/// without ground truth, a [`DatasetError::CutOffLine`] on `warnings`;
/// any other malformed pose file is an error.
pub(crate) fn parse(
    listing: &HashSet<&str>,
    texts: &HashMap<String, String>,
    warnings: &mut Vec<DatasetError>,
) -> Result<Parsed, DatasetError> {
    // Sequence folder -> frame number -> (colour, depth) paths as listed.
    type Images<'a> = (Option<&'a str>, Option<&'a str>);
    let mut sequences: BTreeMap<&str, BTreeMap<u64, Images>> = BTreeMap::new();
    for &name in listing {
        let base = base_name(name);
        let folder = &name[..name.len() - base.len()];
        if let Some(number) = colour_frame_number(base) {
            let slot = sequences
                .entry(folder)
                .or_default()
                .entry(number)
                .or_default();
            slot.0 = Some(name);
        } else if let Some(number) = frame_number(base, &[".depth.png"]) {
            let slot = sequences
                .entry(folder)
                .or_default()
                .entry(number)
                .or_default();
            slot.1 = Some(name);
        }
    }
    let mut frames = Vec::new();
    // (timestamp, pose file, its text), parsed once the last frame is known.
    let mut poses: Vec<(f64, String, &str)> = Vec::new();
    let mut offset = 0.0_f64;
    for numbers in sequences.into_values() {
        let mut last = offset;
        for (number, images) in numbers {
            let stem = match images {
                (Some(c), _) => c
                    .strip_suffix(".color.png")
                    .or_else(|| c.strip_suffix(".color.jpg"))
                    .unwrap_or(c),
                (None, Some(d)) => d.strip_suffix(".depth.png").unwrap_or(d),
                (None, None) => continue,
            };
            let colour = images
                .0
                .map_or_else(|| format!("{stem}.color.png"), str::to_owned);
            let depth = format!("{stem}.depth.png");
            let beside = |other: &str| format!("the 7-Scenes layout (beside {other})");
            let missing = match images {
                (Some(c), None) => Some(DatasetError::MissingFile {
                    path: depth.clone(),
                    listed_in: beside(c),
                }),
                (None, Some(d)) => Some(DatasetError::MissingFile {
                    path: colour.clone(),
                    listed_in: beside(d),
                }),
                _ => None,
            };
            let pose = format!("{stem}.pose.txt");
            let timestamp = offset + number as f64;
            last = timestamp;
            if let Some(text) = texts.get(&pose) {
                poses.push((timestamp, pose.clone(), text));
            }
            frames.push(FrameEntry {
                index: frames.len(),
                timestamp,
                colour: Some(colour),
                depth,
                confidence: None,
                calibrated_size: None,
                pose_file: listing.contains(pose.as_str()).then_some(pose),
                missing,
            });
        }
        offset = last + 1.0;
    }
    let last_frame = frames.last().map(|f: &FrameEntry| f.timestamp);
    let mut ground_truth = Vec::with_capacity(poses.len());
    for (timestamp, file, text) in poses {
        match parse_pose_matrix(text, &file) {
            Ok(pose) => ground_truth.push((timestamp, pose)),
            Err(DatasetError::MalformedLine {
                file,
                line_number,
                line,
                reason,
            }) if Some(timestamp) == last_frame => warnings.push(DatasetError::CutOffLine {
                file,
                line_number,
                line,
                reason,
            }),
            Err(e) => return Err(e),
        }
    }
    Ok((frames, ground_truth))
}

/// Parses a 7-Scenes `.pose.txt`: a 4x4 camera-to-world matrix (metres), 4
/// lines of 4 whitespace-separated numbers, bottom row `0 0 0 1`. Errors name
/// `file_name` and the line.
pub fn parse_pose_matrix(text: &str, file_name: &str) -> Result<DAffine3, DatasetError> {
    let mut rows: Vec<[f64; 4]> = Vec::with_capacity(4);
    let mut last_line = Line::none(file_name);
    // No comments in this format: a `#` line is malformed.
    for line in content_lines(text, file_name, false) {
        let malformed = |reason: &str| line.malformed(reason);
        if rows.len() == 4 {
            return Err(malformed("a pose matrix has only 4 rows"));
        }
        let values: Vec<f64> = line
            .tokens()
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| malformed("expected finite numbers"))?;
        let [a, b, c, d] = values[..] else {
            return Err(malformed("expected 4 numbers per row"));
        };
        rows.push([a, b, c, d]);
        last_line = line;
    }
    let malformed = |reason: &str| last_line.malformed(reason);
    let [r0, r1, r2, r3] = rows[..] else {
        return Err(malformed("expected 4 rows of a 4x4 matrix"));
    };
    let bottom_ok = r3[0].abs() < 1e-6
        && r3[1].abs() < 1e-6
        && r3[2].abs() < 1e-6
        && (r3[3] - 1.0).abs() < 1e-6;
    if !bottom_ok {
        return Err(malformed(
            "the bottom row of a rigid pose must be `0 0 0 1`",
        ));
    }
    let rotation = DMat3::from_cols(
        DVec3::new(r0[0], r1[0], r2[0]),
        DVec3::new(r0[1], r1[1], r2[1]),
        DVec3::new(r0[2], r1[2], r2[2]),
    );
    if (rotation.determinant() - 1.0).abs() > 0.05 {
        return Err(malformed(
            "the 3x3 block is not a rotation (determinant far from 1)",
        ));
    }
    Ok(DAffine3::from_mat3_translation(
        rotation,
        DVec3::new(r0[3], r1[3], r2[3]),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraPreset;
    use crate::dataset::{detect_layout, parse_sequence, DatasetKind};
    use std::collections::HashMap;

    #[test]
    fn scene_with_two_sequences() {
        let mut names = Vec::new();
        for seq in ["seq-02", "seq-01"] {
            for n in 0..3 {
                let ext = if seq == "seq-01" { "png" } else { "jpg" };
                names.push(format!("chess/{seq}/frame-{n:06}.color.{ext}"));
                names.push(format!("chess/{seq}/frame-{n:06}.depth.png"));
                if n != 1 {
                    names.push(format!("chess/{seq}/frame-{n:06}.pose.txt"));
                }
            }
        }
        names.push("chess/TrainSplit.txt".to_owned());
        let layout = detect_layout(&names).expect("7-Scenes layout");
        assert_eq!(layout.kind, DatasetKind::SevenScenes);
        assert_eq!(layout.root_prefix, "chess/");
        assert_eq!(layout.index_files.len(), 4, "{:?}", layout.index_files);
        assert_eq!(layout.index_files[0], "chess/seq-01/frame-000000.pose.txt");
        let seq = parse_sequence(&layout, &names, &HashMap::new(), None).expect("parses");
        assert!(seq.ground_truth.is_empty(), "pose texts not given");
        assert_eq!(seq.preset, CameraPreset::SevenScenes);
        assert_eq!(seq.frames.len(), 6);
        assert_eq!(
            seq.frames[0].colour.as_deref(),
            Some("chess/seq-01/frame-000000.color.png")
        );
        assert_eq!(
            seq.frames[3].colour.as_deref(),
            Some("chess/seq-02/frame-000000.color.jpg")
        );
        assert_eq!(seq.frames[3].depth, "chess/seq-02/frame-000000.depth.png");
        let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
        assert_eq!(stamps, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(seq.frames[5].index, 5);
        assert!(seq.frames[1].pose_file.is_none());
        assert_eq!(
            seq.frames[2].pose_file.as_deref(),
            Some("chess/seq-01/frame-000002.pose.txt")
        );
        // With the pose texts: ground truth at the frames' timestamps.
        let mut texts = HashMap::new();
        texts.insert(
            "chess/seq-01/frame-000002.pose.txt".to_owned(),
            "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n".to_owned(),
        );
        texts.insert(
            "chess/seq-02/frame-000000.pose.txt".to_owned(),
            "1 0 0 0\n0 1 0 2\n0 0 1 0\n0 0 0 1\n".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("parses");
        assert_eq!(seq.ground_truth.len(), 2);
        assert_eq!(seq.ground_truth[0].0, 2.0);
        assert_eq!(seq.ground_truth[0].1.translation.x, 0.5);
        assert_eq!(seq.ground_truth[1].0, 3.0);
        assert_eq!(seq.ground_truth[1].1.translation.y, 2.0);
        texts.insert(
            "chess/seq-01/frame-000000.pose.txt".to_owned(),
            "1 0 0\n".to_owned(),
        );
        let err = parse_sequence(&layout, &names, &texts, None).expect_err("malformed pose");
        assert!(
            matches!(&err, DatasetError::MalformedLine { file, .. } if file == "chess/seq-01/frame-000000.pose.txt"),
            "{err:?}"
        );
        // The last frame's pose file half written: that frame has no
        // ground truth, and a warning names the file.
        texts.remove("chess/seq-01/frame-000000.pose.txt");
        texts.insert(
            "chess/seq-02/frame-000002.pose.txt".to_owned(),
            "1 0 0 0\n0 1 0 2\n0 0".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("plays what it has");
        assert_eq!(seq.ground_truth.len(), 2);
        assert!(
            matches!(&seq.warnings[..], [DatasetError::CutOffLine { file, line_number: 3, .. }] if file == "chess/seq-02/frame-000002.pose.txt"),
            "{:?}",
            seq.warnings
        );
    }

    #[test]
    fn single_sequence_folder_and_missing_depth() {
        let names: Vec<String> = [
            "seq-01/frame-000007.color.png",
            "seq-01/frame-000007.depth.png",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect();
        let layout = detect_layout(&names).expect("layout");
        let seq = parse_sequence(&layout, &names, &HashMap::new(), None).expect("parses");
        assert_eq!(seq.frames[0].timestamp, 7.0);
        let err =
            parse_sequence(&layout, &names[..1], &HashMap::new(), None).expect_err("no depth");
        assert!(
            matches!(err, DatasetError::NoReadableFrame { frames: 1, .. }),
            "{err:?}"
        );
        assert!(
            err.to_string()
                .contains("seq-01/frame-000007.depth.png is missing"),
            "{err}"
        );
        // Half-copied: a frame with only its depth, one with only its colour.
        let mut half = names.clone();
        half.push("seq-01/frame-000008.depth.png".to_owned());
        half.push("seq-01/frame-000009.color.png".to_owned());
        let seq = parse_sequence(&layout, &half, &HashMap::new(), None).expect("parses");
        assert_eq!(seq.frames.len(), 3);
        assert_eq!(seq.frames[0].missing, None);
        assert_eq!(
            seq.frames[1].colour.as_deref(),
            Some("seq-01/frame-000008.color.png")
        );
        assert!(
            matches!(&seq.frames[1].missing, Some(DatasetError::MissingFile { path, .. }) if path == "seq-01/frame-000008.color.png")
        );
        assert!(
            matches!(&seq.frames[2].missing, Some(DatasetError::MissingFile { path, .. }) if path == "seq-01/frame-000009.depth.png")
        );
    }

    #[test]
    fn pose_matrix() {
        let text = "0 -1 0 0.5\n1 0 0 1.5 \n0 0 1 -2\n0 0 0 1\n";
        let pose = parse_pose_matrix(text, "p.txt").expect("valid");
        assert_eq!(pose.translation, DVec3::new(0.5, 1.5, -2.0));
        assert!((pose.transform_vector3(DVec3::X) - DVec3::Y).length() < 1e-12);
        let err =
            parse_pose_matrix("1 0 0 0\n0 1 0 0\n0 0 1 nan\n0 0 0 1\n", "p.txt").expect_err("nan");
        assert!(
            matches!(err, DatasetError::MalformedLine { line_number: 3, .. }),
            "{err:?}"
        );
        assert!(parse_pose_matrix("1 0 0 0\n0 1 0 0\n", "p.txt").is_err());
        assert!(parse_pose_matrix("", "p.txt").is_err());
    }
}
