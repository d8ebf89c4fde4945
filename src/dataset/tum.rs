//! TUM RGB-D layout: `rgb.txt` and `depth.txt` (`timestamp path` lines,
//! `#` comments), `groundtruth.txt` (`timestamp tx ty tz qx qy qz qw`,
//! camera-to-world, metres, seconds).
//!
//! Colour and depth are associated as the benchmark's `associate.py` does:
//! every candidate pair within [`MAX_ASSOCIATION_DT_S`] is sorted by |dt| and
//! taken greedily, each image used at most once. A frame's timestamp is its
//! colour image's timestamp.

use std::collections::{HashMap, HashSet};

use super::lines::{parse_rows, parse_rows_strict, Line};
use super::{
    base_name, check_listed, index_text, trajectory, DatasetError, FrameEntry, Layout, Parsed,
};
use crate::camera::CameraPreset;

/// Largest colour-depth time difference accepted when associating, seconds.
pub const MAX_ASSOCIATION_DT_S: f64 = 0.02;

/// Parses a TUM file list (`rgb.txt`, `depth.txt`): `(timestamp s, path)` in
/// file order; `#` comments and blank lines skipped; every line must parse.
pub fn parse_file_list(text: &str, file_name: &str) -> Result<Vec<(f64, String)>, DatasetError> {
    parse_rows_strict(text, file_name, true, |_, line| file_row(&line).map(Some))
}

/// [`parse_file_list`] for a recording: a cut-off last line is skipped and
/// pushed onto `warnings` ([`super::lines::parse_rows`]).
fn read_file_list(
    text: &str,
    file_name: &str,
    warnings: &mut Vec<DatasetError>,
) -> Result<Vec<(f64, String)>, DatasetError> {
    parse_rows(text, file_name, true, warnings, |_, line| {
        file_row(&line).map(Some)
    })
}

/// One `timestamp path` line of a file list.
fn file_row(line: &Line<'_>) -> Result<(f64, String), DatasetError> {
    let malformed = |reason: &str| line.malformed(reason);
    let mut tokens = line.tokens();
    let (Some(t), Some(path)) = (tokens.next(), tokens.next()) else {
        return Err(malformed("expected `timestamp path`"));
    };
    let timestamp: f64 = t
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| malformed("the timestamp is not a finite number"))?;
    Ok((timestamp, path.to_owned()))
}

/// Associates two timestamp lists (same unit) as TUM's `associate.py`:
/// candidate pairs with |a - b| <= `max_dt`, sorted by |dt|, taken greedily
/// with each element used at most once. Returns `(index in a, index in b)`
/// sorted by `a`'s timestamp. Non-finite timestamps never match.
#[must_use]
pub fn associate_timestamps(a: &[f64], b: &[f64], max_dt: f64) -> Vec<(usize, usize)> {
    let mut b_sorted: Vec<(f64, usize)> = b
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, t)| t.is_finite())
        .map(|(j, t)| (t, j))
        .collect();
    b_sorted.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
    for (i, &ta) in a.iter().enumerate() {
        if !ta.is_finite() {
            continue;
        }
        let start = b_sorted.partition_point(|(tb, _)| *tb < ta - max_dt);
        for &(tb, j) in b_sorted[start..]
            .iter()
            .take_while(|(tb, _)| *tb <= ta + max_dt)
        {
            let dt = (ta - tb).abs();
            if dt <= max_dt {
                candidates.push((dt, i, j));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut used_a = vec![false; a.len()];
    let mut used_b = vec![false; b.len()];
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !used_a[i] && !used_b[j] {
            used_a[i] = true;
            used_b[j] = true;
            pairs.push((i, j));
        }
    }
    pairs.sort_by(|x, y| a[x.0].total_cmp(&a[y.0]).then(x.0.cmp(&y.0)));
    pairs
}

/// Picks the TUM camera from hints (folder name, bag name in a comment):
/// `freiburg1`/`fr1` -> fr1, `freiburg2`/`fr2` -> fr2, otherwise fr3.
#[must_use]
pub fn preset_from_hints(hints: &[&str]) -> CameraPreset {
    for hint in hints {
        let h = hint.to_ascii_lowercase();
        if h.contains("freiburg1") || h.contains("fr1") {
            return CameraPreset::TumFr1;
        }
        if h.contains("freiburg2") || h.contains("fr2") {
            return CameraPreset::TumFr2;
        }
        if h.contains("freiburg3") || h.contains("fr3") {
            return CameraPreset::TumFr3;
        }
    }
    CameraPreset::TumFr3
}

fn find<'a>(layout: &'a Layout, base: &str) -> Option<&'a str> {
    layout
        .index_files
        .iter()
        .map(String::as_str)
        .find(|f| base_name(f) == base)
}

/// Builds the TUM frame list and ground truth from the layout's index texts;
/// a cut-off last line of any of them is skipped onto `warnings`.
pub(crate) fn parse(
    layout: &Layout,
    listing: &HashSet<&str>,
    texts: &HashMap<String, String>,
    warnings: &mut Vec<DatasetError>,
) -> Result<Parsed, DatasetError> {
    let missing = |name: &str| DatasetError::MissingFile {
        path: format!("{}{name}", layout.root_prefix),
        listed_in: "the TUM layout".to_owned(),
    };
    let rgb_name = find(layout, "rgb.txt").ok_or_else(|| missing("rgb.txt"))?;
    let depth_name = find(layout, "depth.txt").ok_or_else(|| missing("depth.txt"))?;
    let rgb = read_file_list(index_text(texts, rgb_name)?, rgb_name, warnings)?;
    let depth = read_file_list(index_text(texts, depth_name)?, depth_name, warnings)?;
    let rgb_t: Vec<f64> = rgb.iter().map(|r| r.0).collect();
    let depth_t: Vec<f64> = depth.iter().map(|d| d.0).collect();
    let mut frames = Vec::new();
    for (i, j) in associate_timestamps(&rgb_t, &depth_t, MAX_ASSOCIATION_DT_S) {
        let colour = format!("{}{}", layout.root_prefix, rgb[i].1);
        let depth_path = format!("{}{}", layout.root_prefix, depth[j].1);
        let missing = check_listed(listing, &colour, rgb_name)
            .or_else(|| check_listed(listing, &depth_path, depth_name));
        frames.push(FrameEntry {
            index: frames.len(),
            timestamp: rgb[i].0,
            colour: Some(colour),
            depth: depth_path,
            confidence: None,
            calibrated_size: None,
            pose_file: None,
            missing,
        });
    }
    let ground_truth = match find(layout, "groundtruth.txt") {
        Some(name) => trajectory::read_tum(index_text(texts, name)?, name, warnings)?,
        None => Vec::new(),
    };
    Ok((frames, ground_truth))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{detect_layout, parse_sequence, DatasetKind};

    fn listing(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| (*s).to_owned()).collect()
    }

    #[test]
    fn association_is_greedy_and_unique() {
        // Depth 10.005 is nearest to both colour 10.000 and 10.008; the closer
        // pair (10.008, dt 0.003) wins, colour 10.000 falls back to 9.990.
        let rgb = [10.000, 10.008, 10.5];
        let depth = [9.990, 10.005, 10.6];
        let pairs = associate_timestamps(&rgb, &depth, 0.02);
        assert_eq!(pairs, vec![(0, 0), (1, 1)]);
        // Exact frame numbers match with max_dt 0.
        assert_eq!(
            associate_timestamps(&[1.0, 2.0], &[2.0, 1.0], 0.0),
            vec![(0, 1), (1, 0)]
        );
    }

    #[test]
    fn tum_sequence_with_jitter_and_prefix() {
        let names = listing(&[
            "rgbd_dataset_freiburg1_xyz/rgb.txt",
            "rgbd_dataset_freiburg1_xyz/depth.txt",
            "rgbd_dataset_freiburg1_xyz/groundtruth.txt",
            "rgbd_dataset_freiburg1_xyz/rgb/1.00.png",
            "rgbd_dataset_freiburg1_xyz/rgb/1.03.png",
            "rgbd_dataset_freiburg1_xyz/rgb/1.07.png",
            "rgbd_dataset_freiburg1_xyz/depth/1.01.png",
            "rgbd_dataset_freiburg1_xyz/depth/1.035.png",
        ]);
        let layout = detect_layout(&names).expect("TUM layout");
        assert_eq!(layout.kind, DatasetKind::Tum);
        assert_eq!(layout.root_prefix, "rgbd_dataset_freiburg1_xyz/");
        assert_eq!(layout.index_files.len(), 3);
        let mut texts = HashMap::new();
        texts.insert(
            layout.index_files[0].clone(),
            "# colour\n1.00 rgb/1.00.png\n1.03 rgb/1.03.png\n1.07 rgb/1.07.png\n".to_owned(),
        );
        texts.insert(
            layout.index_files[1].clone(),
            "# depth\n1.01 depth/1.01.png\n\n1.035 depth/1.035.png\n".to_owned(),
        );
        texts.insert(
            layout.index_files[2].clone(),
            "# gt\n1.0 0 0 0 0 0 0 1\n1.05 1 2 3 0 0 0 2\n".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("parses");
        assert_eq!(seq.preset, CameraPreset::TumFr1);
        assert_eq!(seq.frames.len(), 2);
        assert_eq!(seq.frames[0].timestamp, 1.00);
        assert_eq!(
            seq.frames[0].colour.as_deref().unwrap_or_default(),
            "rgbd_dataset_freiburg1_xyz/rgb/1.00.png"
        );
        assert_eq!(
            seq.frames[1].depth,
            "rgbd_dataset_freiburg1_xyz/depth/1.035.png"
        );
        assert_eq!(seq.ground_truth.len(), 2);
        let pose = seq.ground_truth_for(1.04, 0.02).expect("nearest pose");
        assert!((pose.translation.y - 2.0).abs() < 1e-12);
        assert!(seq.ground_truth_for(1.2, 0.02).is_none());
    }

    #[test]
    fn a_depth_image_is_used_once() {
        let rgb = [0.0, 0.01];
        let depth = [0.005];
        assert_eq!(associate_timestamps(&rgb, &depth, 0.02).len(), 1);
    }

    #[test]
    fn malformed_groundtruth_names_the_line() {
        let names = listing(&[
            "rgb.txt",
            "depth.txt",
            "groundtruth.txt",
            "rgb/1.png",
            "depth/1.png",
        ]);
        let layout = detect_layout(&names).expect("TUM layout");
        let mut texts = HashMap::new();
        texts.insert("rgb.txt".to_owned(), "1 rgb/1.png\n".to_owned());
        texts.insert("depth.txt".to_owned(), "1 depth/1.png\n".to_owned());
        texts.insert(
            "groundtruth.txt".to_owned(),
            "# header\n1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n3 0 0 0 0 0 0 1\n".to_owned(),
        );
        let err = parse_sequence(&layout, &names, &texts, None).expect_err("bad gt");
        assert!(
            matches!(&err, DatasetError::MalformedLine { line_number: 3, file, .. } if file == "groundtruth.txt"),
            "{err:?}"
        );
        // The same line last: a recording cut short, skipped with a warning.
        texts.insert(
            "groundtruth.txt".to_owned(),
            "# header\n1 0 0 0 0 0 0 1\n2 0 0 zero".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("plays what it has");
        assert_eq!(seq.ground_truth.len(), 1);
        assert!(
            matches!(&seq.warnings[..], [DatasetError::CutOffLine { line_number: 3, file, .. }] if file == "groundtruth.txt"),
            "{:?}",
            seq.warnings
        );
        assert_eq!(
            parse_sequence(&layout, &names, &HashMap::new(), None).expect_err("no texts"),
            DatasetError::MissingFile {
                path: "rgb.txt".into(),
                listed_in: "the index texts given to parse_sequence".into()
            }
        );
    }

    #[test]
    fn missing_image_skips_its_frame_and_no_readable_frame_is_an_error() {
        let names = listing(&[
            "rgb.txt",
            "depth.txt",
            "rgb/1.png",
            "rgb/2.png",
            "depth/2.png",
        ]);
        let layout = detect_layout(&names).expect("TUM layout");
        let mut texts = HashMap::new();
        texts.insert(
            "rgb.txt".to_owned(),
            "1 rgb/1.png\n2 rgb/2.png\n".to_owned(),
        );
        texts.insert(
            "depth.txt".to_owned(),
            "1 depth/1.png\n2 depth/2.png\n".to_owned(),
        );
        let seq = parse_sequence(&layout, &names, &texts, None).expect("one frame readable");
        assert_eq!(seq.frames.len(), 2);
        assert_eq!(
            seq.frames[0].missing,
            Some(DatasetError::MissingFile {
                path: "depth/1.png".into(),
                listed_in: "depth.txt".into()
            })
        );
        assert_eq!(seq.frames[1].missing, None);

        let err = parse_sequence(&layout, &names[..3], &texts, None).expect_err("none readable");
        assert!(
            matches!(&err, DatasetError::NoReadableFrame { frames: 2, first } if matches!(&**first, DatasetError::MissingFile { path, listed_in } if path == "depth/1.png" && listed_in == "depth.txt")),
            "{err:?}"
        );
        assert!(
            err.to_string()
                .contains("depth/1.png is missing (listed in depth.txt)"),
            "{err}"
        );
        texts.insert("depth.txt".to_owned(), "5 depth/1.png\n".to_owned());
        assert_eq!(
            parse_sequence(&layout, &names, &texts, None).expect_err("none paired"),
            DatasetError::NoFrames
        );
    }
}
