//! `surfels.ply`: every slot of the surfel map, absorbed ones included, as
//! binary little-endian PLY that MeshLab, CloudCompare or Open3D open:
//! `x y z nx ny nz` (float; world frame, metres; unit normal), `red green
//! blue alpha` (uchar), `radius` (float, metres), `confidence` (float;
//! negative: absorbed, removed at the next cleanup), `first_seen` and
//! `last_seen` (uint, frame indices). Written and read a row at a time.

use super::binary::{alloc, read_error};
use super::SessionError;
use crate::fusion::{Surfel, SurfelMap};
use crate::mesh::ply_header::write_ply_header;
use glam::Vec3;
use std::io::{Read, Write};

/// Bytes per surfel row.
const ROW: usize = 6 * 4 + 4 + 4 * 4;

/// The header of a file of `surfels` rows.
fn header(surfels: usize) -> String {
    write_ply_header(
        "surfel-slam session surfels, world frame, metres",
        surfels,
        &[
            ("uchar", "alpha"),
            ("float", "radius"),
            ("float", "confidence"),
            ("uint", "first_seen"),
            ("uint", "last_seen"),
        ],
        None,
    )
}

/// Writes every slot of `map`.
pub(super) fn write_surfels(out: &mut dyn Write, map: &SurfelMap) -> std::io::Result<()> {
    let n = map.common_len();
    out.write_all(header(n).as_bytes())?;
    let (p, nr, c) = (map.positions(), map.normals(), map.colours());
    let (r, conf, first, last) = (
        map.radii(),
        map.confidences(),
        map.first_seen(),
        map.last_seen(),
    );
    let mut row = [0u8; ROW];
    for i in 0..n {
        let floats = [p[i].x, p[i].y, p[i].z, nr[i].x, nr[i].y, nr[i].z];
        for (k, v) in floats.iter().enumerate() {
            row[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
        }
        row[24..28].copy_from_slice(&c[i]);
        row[28..32].copy_from_slice(&r[i].to_le_bytes());
        row[32..36].copy_from_slice(&conf[i].to_le_bytes());
        row[36..40].copy_from_slice(&first[i].to_le_bytes());
        row[40..44].copy_from_slice(&last[i].to_le_bytes());
        out.write_all(&row)?;
    }
    Ok(())
}

/// Reads the `surfels` rows the manifest announces into an empty map
/// (its boxes and schedule are restored by the caller).
pub(super) fn read_surfels(
    input: &mut impl Read,
    surfels: usize,
) -> Result<SurfelMap, SessionError> {
    const NAME: &str = "surfels.ply";
    let expected = header(surfels);
    let mut text = vec![0u8; expected.len()];
    input
        .read_exact(&mut text)
        .map_err(|e| read_error(NAME, &e))?;
    if text != expected.as_bytes() {
        return Err(SessionError::Corrupt(format!(
            "{NAME}: the header is not the one for {surfels} surfels"
        )));
    }
    let mut map = SurfelMap::default();
    // Fails early on a count no memory can hold.
    drop(alloc::<[u8; ROW]>(surfels, NAME)?);
    map.reserve(surfels);
    let f = |b: &[u8], at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    let u = |b: &[u8], at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    let mut row = [0u8; ROW];
    for _ in 0..surfels {
        input
            .read_exact(&mut row)
            .map_err(|e| read_error(NAME, &e))?;
        let surfel = Surfel {
            position: Vec3::new(f(&row, 0), f(&row, 4), f(&row, 8)),
            normal: Vec3::new(f(&row, 12), f(&row, 16), f(&row, 20)),
            colour: [row[24], row[25], row[26], row[27]],
            radius: f(&row, 28),
            confidence: f(&row, 32),
        };
        map.push_saved(&surfel, u(&row, 36), u(&row, 40));
    }
    Ok(map)
}
