//! TUM trajectory format: one pose per line, `timestamp tx ty tz qx qy qz qw`,
//! the pose being `world_from_camera` (camera-to-world), translation in
//! metres, timestamp in seconds (or frame number for ICL-NUIM), unit
//! quaternion. `#` comments and blank lines are allowed.

use glam::{DAffine3, DQuat, DVec3};

use super::lines::{parse_rows, parse_rows_strict, Line};
use super::DatasetError;
use crate::se3::unit_quaternion;

/// Formats poses (`timestamp`, `world_from_camera`) as a TUM trajectory:
/// timestamp with 6 decimals, translation (m) and unit quaternion with 9.
#[must_use]
pub fn format_tum(poses: &[(f64, DAffine3)]) -> String {
    let mut out = String::with_capacity(poses.len() * 96 + 40);
    out.push_str("# timestamp tx ty tz qx qy qz qw\n");
    for (t, pose) in poses {
        let p = pose.translation;
        let [qx, qy, qz, qw] = unit_quaternion(pose);
        out.push_str(&format!(
            "{t:.6} {:.9} {:.9} {:.9} {qx:.9} {qy:.9} {qz:.9} {qw:.9}\n",
            p.x, p.y, p.z
        ));
    }
    out
}

/// Parses a TUM trajectory into `(timestamp, world_from_camera)` in file
/// order. Quaternions are normalised; a zero quaternion, a non-finite number
/// or a line without exactly 8 numbers is a `MalformedLine` naming
/// `file_name` and the 1-based line number.
pub fn parse_tum(text: &str, file_name: &str) -> Result<Vec<(f64, DAffine3)>, DatasetError> {
    parse_rows_strict(text, file_name, true, |_, line| tum_row(&line).map(Some))
}

/// [`parse_tum`] for a recording's trajectory (a dataset's ground truth, a
/// reference written beside a recording): a malformed last line, cut off
/// when the recording stopped, is skipped and pushed onto `warnings` as
/// [`DatasetError::CutOffLine`].
pub fn read_tum(
    text: &str,
    file_name: &str,
    warnings: &mut Vec<DatasetError>,
) -> Result<Vec<(f64, DAffine3)>, DatasetError> {
    parse_rows(text, file_name, true, warnings, |_, line| {
        tum_row(&line).map(Some)
    })
}

/// One `timestamp tx ty tz qx qy qz qw` line.
fn tum_row(line: &Line<'_>) -> Result<(f64, DAffine3), DatasetError> {
    let malformed = |reason: &str| line.malformed(reason);
    let values: Vec<f64> = line
        .tokens()
        .map(|t| t.parse::<f64>().ok())
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| malformed("expected numbers `timestamp tx ty tz qx qy qz qw`"))?;
    let [t, tx, ty, tz, qx, qy, qz, qw] = values[..] else {
        return Err(malformed(&format!(
            "expected 8 numbers `timestamp tx ty tz qx qy qz qw`, found {}",
            values.len()
        )));
    };
    if !values.iter().all(|v| v.is_finite()) {
        return Err(malformed("non-finite number"));
    }
    let q = DQuat::from_xyzw(qx, qy, qz, qw);
    let norm = q.length();
    if norm <= 1e-9 {
        return Err(malformed("zero quaternion"));
    }
    Ok((
        t,
        DAffine3::from_rotation_translation(q / norm, DVec3::new(tx, ty, tz)),
    ))
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let poses = vec![
            (1341841873.273798, DAffine3::IDENTITY),
            (
                1341841873.305888,
                DAffine3::from_rotation_translation(
                    DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -1.2, 2.9),
                    DVec3::new(-2.1837, 0.6821, 1.4854),
                ),
            ),
        ];
        let text = format_tum(&poses);
        let back = parse_tum(&text, "t.txt").expect("parses");
        assert_eq!(back.len(), 2);
        for ((ta, a), (tb, b)) in poses.iter().zip(&back) {
            assert!((ta - tb).abs() < 1e-6);
            assert!(a.abs_diff_eq(*b, 1e-8), "{a:?} vs {b:?}");
        }
        let line = text.lines().nth(2).expect("second pose");
        assert!(
            line.starts_with("1341841873.305888 -2.183700000 "),
            "{line}"
        );
    }

    #[test]
    fn normalises_and_rejects() {
        let poses = parse_tum("# c\n\n5 1 2 3 0 0 0 2\n", "g.txt").expect("parses");
        assert!(poses[0].1.matrix3.abs_diff_eq(glam::DMat3::IDENTITY, 1e-12));
        for (text, line_number) in [
            ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 0\n", 2),
            ("# x\n1 0 0 0 0 0 0\n", 2),
            ("1 0 0 inf 0 0 0 1\n", 1),
            ("1 0 0 NaN 0 0 0 1\n", 1),
            ("1 0 0 0 0 0 0 1 9\n", 1),
            ("1 a 0 0 0 0 0 1\n", 1),
        ] {
            let err = parse_tum(text, "g.txt").expect_err(text);
            assert!(
                matches!(&err, DatasetError::MalformedLine { line_number: n, file, .. } if *n == line_number && file == "g.txt"),
                "{text}: {err:?}"
            );
        }
    }
}
