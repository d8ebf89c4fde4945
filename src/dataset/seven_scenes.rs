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

use std::collections::{BTreeMap, HashSet};

use glam::{DAffine3, DMat3, DVec3};

use super::{base_name, DatasetError, FrameEntry};

/// Frame number of a 7-Scenes colour image name (`frame-000123.color.png` or
/// `.color.jpg`), `None` for any other name.
#[must_use]
pub fn colour_frame_number(file_name: &str) -> Option<u64> {
    let rest = file_name.strip_prefix("frame-")?;
    let digits = rest
        .strip_suffix(".color.png")
        .or_else(|| rest.strip_suffix(".color.jpg"))?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Builds the frame list from the names alone; `pose_file` is set where the
/// `.pose.txt` is listed. Ground truth is read later from those files.
pub(crate) fn parse(listing: &HashSet<&str>) -> Result<Vec<FrameEntry>, DatasetError> {
    // Sequence folder -> (frame number, colour path), sorted.
    let mut sequences: BTreeMap<&str, Vec<(u64, &str)>> = BTreeMap::new();
    for &name in listing {
        if let Some(number) = colour_frame_number(base_name(name)) {
            let folder = &name[..name.len() - base_name(name).len()];
            sequences.entry(folder).or_default().push((number, name));
        }
    }
    let mut frames = Vec::new();
    let mut offset = 0.0_f64;
    for mut colours in sequences.into_values() {
        colours.sort_unstable();
        let mut last = offset;
        for (number, colour) in colours {
            let stem = colour
                .strip_suffix(".color.png")
                .or_else(|| colour.strip_suffix(".color.jpg"))
                .unwrap_or(colour);
            let depth = format!("{stem}.depth.png");
            if !listing.contains(depth.as_str()) {
                return Err(DatasetError::MissingFile {
                    path: depth,
                    listed_in: format!("the 7-Scenes layout (beside {colour})"),
                });
            }
            let pose = format!("{stem}.pose.txt");
            let timestamp = offset + number as f64;
            last = timestamp;
            frames.push(FrameEntry {
                index: frames.len(),
                timestamp,
                colour: colour.to_owned(),
                depth,
                pose_file: listing.contains(pose.as_str()).then_some(pose),
            });
        }
        offset = last + 1.0;
    }
    Ok(frames)
}

/// Parses a 7-Scenes `.pose.txt`: a 4x4 camera-to-world matrix (metres), 4
/// lines of 4 whitespace-separated numbers, bottom row `0 0 0 1`. Errors name
/// `file_name` and the line.
pub fn parse_pose_matrix(text: &str, file_name: &str) -> Result<DAffine3, DatasetError> {
    let mut rows: Vec<[f64; 4]> = Vec::with_capacity(4);
    let mut last_line = (0, String::new());
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        let malformed = |reason: &str| DatasetError::MalformedLine {
            file: file_name.to_owned(),
            line_number: i + 1,
            line: line.to_owned(),
            reason: reason.to_owned(),
        };
        if rows.len() == 4 {
            return Err(malformed("a pose matrix has only 4 rows"));
        }
        let values: Vec<f64> = line
            .split_whitespace()
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| malformed("expected finite numbers"))?;
        let [a, b, c, d] = values[..] else {
            return Err(malformed("expected 4 numbers per row"));
        };
        rows.push([a, b, c, d]);
        last_line = (i + 1, line.to_owned());
    }
    let malformed = |reason: &str| DatasetError::MalformedLine {
        file: file_name.to_owned(),
        line_number: last_line.0,
        line: last_line.1.clone(),
        reason: reason.to_owned(),
    };
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
        assert!(layout.index_files.is_empty());
        let seq = parse_sequence(&layout, &names, &HashMap::new(), None).expect("parses");
        assert_eq!(seq.preset, CameraPreset::SevenScenes);
        assert_eq!(seq.frames.len(), 6);
        assert_eq!(seq.frames[0].colour, "chess/seq-01/frame-000000.color.png");
        assert_eq!(seq.frames[3].colour, "chess/seq-02/frame-000000.color.jpg");
        assert_eq!(seq.frames[3].depth, "chess/seq-02/frame-000000.depth.png");
        let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
        assert_eq!(stamps, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(seq.frames[5].index, 5);
        assert!(seq.frames[1].pose_file.is_none());
        assert_eq!(
            seq.frames[2].pose_file.as_deref(),
            Some("chess/seq-01/frame-000002.pose.txt")
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
        assert!(matches!(err, DatasetError::MissingFile { .. }), "{err:?}");
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
