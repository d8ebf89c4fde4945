//! ICL-NUIM "frei_png" layout: `associations.txt` with lines
//! `N depth/N.png N rgb/N.png` (a TUM-style `t rgb/.. t depth/..` order is
//! also accepted: the image whose path names `depth` is the depth), and an
//! optional `*.gt.freiburg` trajectory in TUM format whose timestamps are
//! frame numbers (camera-to-world, metres).
//!
//! A frame's timestamp is its frame number N; frames are sorted by N.
//!
//! Camera convention: ICL-NUIM's ground truth is expressed for a camera with
//! a negative focal length along y. [`crate::camera::CameraPreset::IclNuim`] has fy = -480,
//! so an estimate computed with it is directly in the ground truth's
//! convention: nothing is flipped here, and the user need not do anything.

use std::collections::{HashMap, HashSet};

use super::lines::{parse_rows, parse_rows_strict, Line};
use super::{check_listed, index_text, trajectory, DatasetError, FrameEntry, Layout, Parsed};

/// Builds the ICL-NUIM frame list and ground truth from the layout's index
/// texts (`index_files[0]` = associations, `[1]` = `*.gt.freiburg` if any);
/// a cut-off last line of either is skipped onto `warnings`.
pub(crate) fn parse(
    layout: &Layout,
    listing: &HashSet<&str>,
    texts: &HashMap<String, String>,
    warnings: &mut Vec<DatasetError>,
) -> Result<Parsed, DatasetError> {
    let Some(assoc_name) = layout.index_files.first() else {
        return Err(DatasetError::MissingFile {
            path: format!("{}associations.txt", layout.root_prefix),
            listed_in: "the ICL-NUIM layout".to_owned(),
        });
    };
    let root = layout.root_prefix.as_str();
    let mut frames = parse_rows(
        index_text(texts, assoc_name)?,
        assoc_name,
        true,
        warnings,
        |_, line| association(&line, root).map(Some),
    )?;
    for frame in &mut frames {
        let colour = frame.colour.as_deref().unwrap_or_default();
        frame.missing = check_listed(listing, colour, assoc_name)
            .or_else(|| check_listed(listing, &frame.depth, assoc_name));
    }
    frames.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
    for (i, frame) in frames.iter_mut().enumerate() {
        frame.index = i;
    }
    let ground_truth = match layout.index_files.get(1) {
        Some(name) => trajectory::read_tum(index_text(texts, name)?, name, warnings)?,
        None => Vec::new(),
    };
    Ok((frames, ground_truth))
}

/// Parses an associations file: `N depth N rgb` (or `t rgb t depth`) lines,
/// `#` comments and blank lines skipped; paths get `root_prefix` prepended.
/// Every line must parse.
pub fn parse_associations(
    text: &str,
    file_name: &str,
    root_prefix: &str,
) -> Result<Vec<FrameEntry>, DatasetError> {
    let mut frames = parse_rows_strict(text, file_name, true, |_, line| {
        association(&line, root_prefix).map(Some)
    })?;
    for (i, frame) in frames.iter_mut().enumerate() {
        frame.index = i;
    }
    Ok(frames)
}

/// One association line as a frame (index 0: the caller numbers them).
fn association(line: &Line<'_>, root_prefix: &str) -> Result<FrameEntry, DatasetError> {
    let malformed = |reason: &str| line.malformed(reason);
    let tokens: Vec<&str> = line.tokens().collect();
    let [t1, p1, t2, p2] = tokens[..] else {
        return Err(malformed("expected `N depth/N.png N rgb/N.png`"));
    };
    let number = |t: &str| t.parse::<f64>().ok().filter(|v| v.is_finite());
    let (Some(t1), Some(_)) = (number(t1), number(t2)) else {
        return Err(malformed("the frame numbers are not finite numbers"));
    };
    // ICL-NUIM lists depth first; associate.py output lists colour first.
    let depth_first = p1.contains("depth") || !p2.contains("depth");
    let (depth, colour) = if depth_first { (p1, p2) } else { (p2, p1) };
    Ok(FrameEntry {
        index: 0,
        timestamp: t1,
        colour: Some(format!("{root_prefix}{colour}")),
        depth: format!("{root_prefix}{depth}"),
        confidence: None,
        calibrated_size: None,
        pose_file: None,
        missing: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraPreset;
    use crate::dataset::{detect_layout, parse_sequence, DatasetKind};

    fn names() -> Vec<String> {
        [
            "associations.txt",
            "traj0.gt.freiburg",
            "rgb/1.png",
            "rgb/2.png",
            "rgb/10.png",
            "depth/1.png",
            "depth/2.png",
            "depth/10.png",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect()
    }

    #[test]
    fn icl_layout_uses_negative_fy_and_frame_numbers() {
        let names = names();
        let layout = detect_layout(&names).expect("ICL layout");
        assert_eq!(layout.kind, DatasetKind::IclNuim);
        assert_eq!(
            layout.index_files,
            vec!["associations.txt", "traj0.gt.freiburg"]
        );
        let mut texts = HashMap::new();
        texts.insert(
            "associations.txt".to_owned(),
            "10 depth/10.png 10 rgb/10.png\n1 depth/1.png 1 rgb/1.png\n2 rgb/2.png 2 depth/2.png\n"
                .to_owned(),
        );
        texts.insert(
            "traj0.gt.freiburg".to_owned(),
            "2 0 0 -2.5 0 0 0 1\n10 0.1 0 -2.5 0 0 0 1\n".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("parses");
        assert_eq!(seq.preset, CameraPreset::IclNuim);
        assert!(seq.preset.intrinsics().fy < 0.0);
        let numbers: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
        assert_eq!(numbers, vec![1.0, 2.0, 10.0]);
        assert_eq!(seq.frames[1].colour.as_deref(), Some("rgb/2.png"));
        assert_eq!(seq.frames[1].depth, "depth/2.png");
        assert_eq!(seq.frames[2].index, 2);
        assert_eq!(seq.ground_truth.len(), 2);
        assert!(seq.ground_truth_for(1.0, 0.0).is_none());
        assert!(seq.ground_truth_for(10.0, 0.0).is_some());
    }

    #[test]
    fn malformed_association_line() {
        let err = parse_associations("1 depth/1.png 1 rgb/1.png\n2 depth/2.png\n", "a.txt", "")
            .expect_err("short line");
        assert!(
            matches!(err, DatasetError::MalformedLine { line_number: 2, .. }),
            "{err:?}"
        );
    }
}
