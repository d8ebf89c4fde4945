//! The trajectory in a session: `trajectory.txt`, TUM text (`timestamp tx
//! ty tz qx qy qz qw`, `world_from_camera`, metres) for other tools, and
//! `poses.txt`, read back: one line per frame, `timestamp` then the 3x4
//! `world_from_camera` matrix row by row (rotation row, then translation:
//! `r00 r01 r02 tx r10 ... tz`) as the loop closures bent it, then the same
//! as tracked, every number printed so that it reads back to the same bits
//! (a quaternion would not).

use super::binary::alloc;
use super::SessionError;
use glam::{DAffine3, DMat3, DVec3};
use std::io::{BufRead, Write};

/// `world_from_camera` as 12 numbers, row-major 3x4.
#[must_use]
pub fn pose_to_rows(pose: &DAffine3) -> [f64; 12] {
    let (m, t) = (pose.matrix3, pose.translation);
    [
        m.x_axis.x, m.y_axis.x, m.z_axis.x, t.x, //
        m.x_axis.y, m.y_axis.y, m.z_axis.y, t.y, //
        m.x_axis.z, m.y_axis.z, m.z_axis.z, t.z,
    ]
}

/// The inverse of [`pose_to_rows`], bit for bit.
#[must_use]
pub fn pose_from_rows(r: &[f64; 12]) -> DAffine3 {
    DAffine3 {
        matrix3: DMat3::from_cols(
            DVec3::new(r[0], r[4], r[8]),
            DVec3::new(r[1], r[5], r[9]),
            DVec3::new(r[2], r[6], r[10]),
        ),
        translation: DVec3::new(r[3], r[7], r[11]),
    }
}

/// Writes `poses.txt` (see the module documentation).
pub(super) fn write_poses(
    out: &mut dyn Write,
    trajectory: &[(f64, DAffine3)],
    online: &[(f64, DAffine3)],
) -> std::io::Result<()> {
    writeln!(
        out,
        "# timestamp, world_from_camera 3x4 row-major (loop-closed), the same as tracked"
    )?;
    for ((t, bent), (_, tracked)) in trajectory.iter().zip(online) {
        write!(out, "{t}")?;
        for v in pose_to_rows(bent).iter().chain(&pose_to_rows(tracked)) {
            write!(out, " {v}")?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// Loop-closed and tracked trajectories.
pub(super) type Trajectories = (Vec<(f64, DAffine3)>, Vec<(f64, DAffine3)>);

/// Reads `poses.txt` of `frames` frames.
pub(super) fn read_poses(input: impl BufRead, frames: usize) -> Result<Trajectories, SessionError> {
    let corrupt = |line: usize, what: &str| {
        SessionError::Corrupt(format!("poses.txt line {}: {what}", line + 1))
    };
    let mut bent = alloc(frames, "poses.txt")?;
    let mut tracked = alloc(frames, "poses.txt")?;
    for (n, line) in input.lines().enumerate() {
        let line = line.map_err(|e| super::binary::read_error("poses.txt", &e))?;
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let values: Vec<f64> = line
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| corrupt(n, "not a number"))?;
        let [t, rest @ ..] = values.as_slice() else {
            return Err(corrupt(n, "empty"));
        };
        let (Ok(a), Ok(b)) = (
            <[f64; 12]>::try_from(rest.get(..12).unwrap_or(&[])),
            <[f64; 12]>::try_from(rest.get(12..).unwrap_or(&[])),
        ) else {
            return Err(corrupt(n, "expected a timestamp and 24 numbers"));
        };
        if !values.iter().all(|v| v.is_finite()) {
            return Err(corrupt(n, "a number is not finite"));
        }
        if bent.len() == frames {
            return Err(corrupt(
                n,
                &format!("more than the {frames} frames announced"),
            ));
        }
        bent.push((*t, pose_from_rows(&a)));
        tracked.push((*t, pose_from_rows(&b)));
    }
    if bent.len() != frames {
        return Err(SessionError::Corrupt(format!(
            "poses.txt holds {} frames, the manifest {frames}",
            bent.len()
        )));
    }
    Ok((bent, tracked))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_read_back_to_the_same_bits() {
        let pose = DAffine3::from_rotation_translation(
            glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.1, -0.7, 2.9),
            DVec3::new(1.0 / 3.0, -2e-9, 7.25),
        );
        assert_eq!(pose_from_rows(&pose_to_rows(&pose)), pose);
        let traj = vec![(1.5, pose), (1.0 / 7.0, DAffine3::IDENTITY)];
        let online = vec![(1.5, DAffine3::IDENTITY), (1.0 / 7.0, pose)];
        let mut text = Vec::new();
        write_poses(&mut text, &traj, &online).unwrap();
        let (a, b) = read_poses(&text[..], 2).unwrap();
        assert_eq!((a, b), (traj, online));
        assert!(matches!(
            read_poses(&text[..], 3),
            Err(SessionError::Corrupt(m)) if m.contains("holds 2 frames")
        ));
    }
}
