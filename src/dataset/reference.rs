//! A reference trajectory the user brings (a T265 or motion capture beside
//! the camera, another tool's output), to score a run against as ground
//! truth is: TUM text (`t tx ty tz qx qy qz qw`, `#` comments), or CSV with
//! a header naming its columns: `x, y, z, qx, qy, qz, qw` and `frame` or
//! `timestamp` (or both), in any order, other columns ignored.
//!
//! Rows are matched to our frames by what the file gives: a `frame` column
//! by frame number (0-based position in the sequence, as the frame log's
//! `frame`), otherwise by timestamp (the sequence's own: seconds for TUM
//! and Stray Scanner, frame numbers for ICL-NUIM, 7-Scenes and RealSense),
//! nearest within the ground truth's tolerance. Poses are
//! `world_from_camera`, metres; the scoring aligns them rigidly, so the
//! reference's world frame is free. A cut-off last row (a recorder stopped
//! mid-write) is skipped with a warning, as in the dataset loaders.

use glam::{DAffine3, DQuat, DVec3};

use super::lines::{content_lines, parse_rows, Line};
use super::trajectory::read_tum;
use super::{DatasetError, FrameEntry};

/// How a reference's rows name the frames they belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReferenceKey {
    /// By timestamp (TUM text, or a CSV with a `timestamp` column and no
    /// `frame` column), in the sequence's own time.
    Timestamp,
    /// By frame number (a CSV with a `frame` column): 0-based position in
    /// the sequence.
    Frame,
}

impl ReferenceKey {
    /// `timestamp` or `frame`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Timestamp => "timestamp",
            Self::Frame => "frame",
        }
    }
}

/// A parsed reference trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// What the first value of each pose is: a timestamp or a frame number.
    pub key: ReferenceKey,
    /// `(timestamp or frame number, world_from_camera)` in file order,
    /// metres.
    pub poses: Vec<(f64, DAffine3)>,
    /// Problems that did not stop the file (a cut-off last row).
    pub warnings: Vec<DatasetError>,
}

impl Reference {
    /// The poses stamped with the sequence's timestamps, as
    /// [`crate::eval::ate`] pairs ground truth: by frame number, the frame's
    /// timestamp (rows naming no frame of `frames` are left out); by
    /// timestamp, as they are.
    #[must_use]
    pub fn in_sequence_time(&self, frames: &[FrameEntry]) -> Vec<(f64, DAffine3)> {
        self.stamped(|n| {
            frames
                .iter()
                .find(|f| f.index as f64 == n)
                .map(|f| f.timestamp)
        })
    }

    /// As [`Self::in_sequence_time`], with the frames' timestamps in
    /// sequence order (`timestamps[i]`: frame i's).
    #[must_use]
    pub fn at_timestamps(&self, timestamps: &[f64]) -> Vec<(f64, DAffine3)> {
        self.stamped(|n| {
            (n >= 0.0 && n.fract() == 0.0 && n < timestamps.len() as f64)
                .then(|| timestamps.get(n as usize).copied())
                .flatten()
        })
    }

    fn stamped(&self, timestamp_of: impl Fn(f64) -> Option<f64>) -> Vec<(f64, DAffine3)> {
        match self.key {
            ReferenceKey::Timestamp => self.poses.clone(),
            ReferenceKey::Frame => self
                .poses
                .iter()
                .filter_map(|(n, pose)| timestamp_of(*n).map(|t| (t, *pose)))
                .collect(),
        }
    }
}

/// Parses a reference trajectory (see the module documentation); the
/// format is told by its first line that is not a `#` comment: with a comma
/// it is CSV, otherwise TUM text. Errors (and warnings) name `file_name`
/// and the line. A file with no pose is an error: there is nothing to score
/// against.
pub fn parse_reference(text: &str, file_name: &str) -> Result<Reference, DatasetError> {
    let first = content_lines(text, file_name, true).next();
    let mut warnings = Vec::new();
    let (key, poses) = match first {
        Some(line) if line.text.contains(',') => {
            let columns = Columns::from_header(&line)?;
            let poses = parse_rows(text, file_name, true, &mut warnings, |i, line| {
                if i == 0 {
                    return Ok(None);
                }
                columns.row(&line).map(Some)
            })?;
            (columns.key(), poses)
        }
        _ => (
            ReferenceKey::Timestamp,
            read_tum(text, file_name, &mut warnings)?,
        ),
    };
    if poses.is_empty() {
        let last = content_lines(text, file_name, true)
            .last()
            .unwrap_or_else(|| Line::none(file_name));
        return Err(last.malformed(
            "no pose: expected TUM lines `t tx ty tz qx qy qz qw`, or CSV with a header \
             `frame, x, y, z, qx, qy, qz, qw` (or `timestamp, ...`) and rows",
        ));
    }
    Ok(Reference {
        key,
        poses,
        warnings,
    })
}

/// Where each value is in a CSV row, from the header.
struct Columns {
    /// The `frame` column, if any (it wins over `timestamp`).
    frame: Option<usize>,
    /// The `timestamp` column, if any.
    timestamp: Option<usize>,
    /// `x, y, z, qx, qy, qz, qw`.
    pose: [usize; 7],
    /// Fields a row must have: one past the last column read.
    width: usize,
}

/// The pose columns' names, as the header must spell them (`tx` for `x`
/// and so on, and case, are accepted too).
const POSE_COLUMNS: [&str; 7] = ["x", "y", "z", "qx", "qy", "qz", "qw"];

impl Columns {
    fn from_header(line: &Line<'_>) -> Result<Self, DatasetError> {
        let names: Vec<String> = line
            .text
            .trim_start_matches('#')
            .split(',')
            .map(|f| f.trim().to_ascii_lowercase())
            .collect();
        if names.first().is_some_and(|n| n.parse::<f64>().is_ok()) {
            return Err(line.malformed(
                "a CSV reference needs a header naming its columns: \
                 `frame, x, y, z, qx, qy, qz, qw` (or `timestamp, ...`)",
            ));
        }
        let find = |wanted: &[&str]| names.iter().position(|n| wanted.contains(&n.as_str()));
        let frame = find(&["frame", "frame_index", "index", "id"]);
        let timestamp = find(&["timestamp", "t", "time", "#timestamp", "timestamp_s"]);
        if frame.is_none() && timestamp.is_none() {
            return Err(line.malformed("the header names no `frame` or `timestamp` column"));
        }
        let mut pose = [0; 7];
        for (slot, name) in pose.iter_mut().zip(POSE_COLUMNS) {
            let t_name = format!("t{name}");
            *slot = find(&[name, t_name.as_str()]).ok_or_else(|| {
                line.malformed(&format!(
                    "the header has no `{name}` column (needs x, y, z, qx, qy, qz, qw)"
                ))
            })?;
        }
        let width = pose
            .iter()
            .chain(&frame)
            .chain(&timestamp)
            .max()
            .map_or(0, |m| m + 1);
        Ok(Self {
            frame,
            timestamp,
            pose,
            width,
        })
    }

    fn key(&self) -> ReferenceKey {
        if self.frame.is_some() {
            ReferenceKey::Frame
        } else {
            ReferenceKey::Timestamp
        }
    }

    fn row(&self, line: &Line<'_>) -> Result<(f64, DAffine3), DatasetError> {
        let fields: Vec<&str> = line.text.split(',').map(str::trim).collect();
        if fields.len() < self.width {
            return Err(line.malformed(&format!(
                "expected at least {} fields as the header's, found {}",
                self.width,
                fields.len()
            )));
        }
        let value = |i: usize, what: &str| {
            fields
                .get(i)
                .and_then(|f| f.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    line.malformed(&format!(
                        "{what} `{}` is not a finite number",
                        fields.get(i).unwrap_or(&"")
                    ))
                })
        };
        let key = match (self.frame, self.timestamp) {
            (Some(i), _) => {
                let n = value(i, "frame")?;
                if n < 0.0 || n.fract() != 0.0 {
                    return Err(line.malformed("the frame number is not a whole number >= 0"));
                }
                n
            }
            (None, Some(i)) => value(i, "timestamp")?,
            (None, None) => 0.0,
        };
        let mut v = [0.0; 7];
        for ((slot, &i), name) in v.iter_mut().zip(&self.pose).zip(POSE_COLUMNS) {
            *slot = value(i, name)?;
        }
        let [x, y, z, qx, qy, qz, qw] = v;
        let q = DQuat::from_xyzw(qx, qy, qz, qw);
        let norm = q.length();
        if norm <= 1e-9 {
            return Err(line.malformed("zero quaternion"));
        }
        Ok((
            key,
            DAffine3::from_rotation_translation(q / norm, DVec3::new(x, y, z)),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tum_text_is_keyed_by_timestamp() {
        let r =
            parse_reference("# t x\n1.5 1 2 3 0 0 0 1\n1.6 1 2 4 0 0 0 2\n", "r.txt").expect("TUM");
        assert_eq!(r.key, ReferenceKey::Timestamp);
        assert_eq!(r.poses.len(), 2);
        assert!((r.poses[1].1.translation.z - 4.0).abs() < 1e-12);
        assert_eq!(r.at_timestamps(&[9.0]), r.poses);
    }

    #[test]
    fn csv_by_frame_or_timestamp_in_any_column_order() {
        let text =
            "frame, qw, x, y, z, qx, qy, qz\n0, 1, 0.5, 0, 0, 0, 0, 0\n2, 1, 0.7, 0, 0, 0, 0, 0\n";
        let r = parse_reference(text, "r.csv").expect("CSV");
        assert_eq!(r.key, ReferenceKey::Frame);
        let stamped = r.at_timestamps(&[10.0, 10.1, 10.2]);
        assert_eq!(stamped.len(), 2);
        assert_eq!(stamped[1].0, 10.2);
        assert!((stamped[1].1.translation.x - 0.7).abs() < 1e-12);
        // Past the sequence's frames: left out.
        assert_eq!(r.at_timestamps(&[10.0]).len(), 1);

        let text = "timestamp,x,y,z,qx,qy,qz,qw,confidence\n3.25,1,2,3,0,0,0,1,3\n";
        let r = parse_reference(text, "r.csv").expect("CSV");
        assert_eq!(r.key, ReferenceKey::Timestamp);
        assert_eq!(r.poses[0].0, 3.25);
        // Both: the frame number wins.
        let text = "timestamp, frame, x, y, z, qx, qy, qz, qw\n3.25, 7, 1, 2, 3, 0, 0, 0, 1\n";
        assert_eq!(parse_reference(text, "r.csv").expect("CSV").poses[0].0, 7.0);
    }

    #[test]
    fn a_cut_off_last_row_warns_and_bad_files_are_named() {
        let text = "frame, x, y, z, qx, qy, qz, qw\n0, 0, 0, 0, 0, 0, 0, 1\n1, 0, 0";
        let r = parse_reference(text, "r.csv").expect("plays what it has");
        assert_eq!(r.poses.len(), 1);
        assert_eq!(r.warnings.len(), 1);
        assert!(r.warnings[0].to_string().contains("r.csv, line 3"));
        for (text, needle) in [
            ("0, 0, 0, 0, 0, 0, 0, 1\n", "needs a header"),
            ("x, y, z, qx, qy, qz, qw\n0, 0, 0, 0, 0, 0, 1\n", "no `frame` or `timestamp`"),
            ("frame, x, y, z, qx, qy, qw\n0, 0, 0, 0, 0, 0, 1\n", "no `qz` column"),
            ("frame, x, y, z, qx, qy, qz, qw\n0.5, 0, 0, 0, 0, 0, 0, 1\n1, 0, 0, 0, 0, 0, 0, 1\n", "whole number"),
            ("frame, x, y, z, qx, qy, qz, qw\n", "no pose"),
            ("", "no pose"),
            ("1 2 3\n", "expected 8 numbers"),
        ] {
            let err = parse_reference(text, "r.csv").expect_err(needle);
            assert!(
                err.to_string().starts_with("r.csv, line ") && err.to_string().contains(needle),
                "{needle}: {err}"
            );
        }
    }
}
