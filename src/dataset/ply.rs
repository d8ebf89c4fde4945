//! PLY export of the surfel map, readable by MeshLab, CloudCompare, Open3D.
//!
//! Format: `binary_little_endian 1.0`, one `vertex` element with the standard
//! property names `x y z` (float, world frame, metres), `nx ny nz` (float,
//! unit normal, world frame), `red green blue` (uchar), and two extra float
//! properties `radius` (metres) and `confidence` (accumulated weight).

use crate::fusion::SurfelMap;

/// Bytes per vertex: 6 floats, 3 uchars, 2 floats.
const VERTEX_BYTES: usize = 6 * 4 + 3 + 2 * 4;

/// Writes the map as a binary little-endian PLY file, without the surfels
/// absorbed into others (negative confidence, awaiting removal). If the
/// map's arrays have different lengths (a corrupt map), only the surfels
/// present in every array are written.
#[must_use]
pub fn write_ply(map: &SurfelMap) -> Vec<u8> {
    let n = map.common_len();
    let kept = || (0..n).filter(|&i| map.confidences[i] >= 0.0);
    let count = kept().count();
    let header = format!(
        "ply\n\
         format binary_little_endian 1.0\n\
         comment surfel-slam surfel map, world frame, metres\n\
         element vertex {count}\n\
         property float x\n\
         property float y\n\
         property float z\n\
         property float nx\n\
         property float ny\n\
         property float nz\n\
         property uchar red\n\
         property uchar green\n\
         property uchar blue\n\
         property float radius\n\
         property float confidence\n\
         end_header\n"
    );
    let mut out = Vec::with_capacity(header.len() + count * VERTEX_BYTES);
    out.extend_from_slice(header.as_bytes());
    for i in kept() {
        let p = map.positions[i];
        let nrm = map.normals[i];
        for v in [p.x, p.y, p.z, nrm.x, nrm.y, nrm.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&map.colours[i][..3]);
        out.extend_from_slice(&map.radii[i].to_le_bytes());
        out.extend_from_slice(&map.confidences[i].to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};

    fn float(e: &DefaultElement, key: &str) -> f32 {
        match e.get(key) {
            Some(Property::Float(v)) => *v,
            other => panic!("{key}: {other:?}"),
        }
    }

    fn uchar(e: &DefaultElement, key: &str) -> u8 {
        match e.get(key) {
            Some(Property::UChar(v)) => *v,
            other => panic!("{key}: {other:?}"),
        }
    }

    #[test]
    fn round_trip_through_an_independent_reader() {
        let mut map = SurfelMap::default();
        map.push(
            Vec3::new(1.0, -2.5, 3.25),
            Vec3::Z,
            [10, 200, 30, 255],
            0.004,
            1.5,
            0,
        );
        map.push(
            Vec3::new(-0.1, 0.2, 0.7),
            Vec3::new(0.6, 0.0, -0.8),
            [255, 0, 7, 255],
            0.01,
            12.0,
            3,
        );
        let bytes = write_ply(&map);
        let parser = Parser::<DefaultElement>::new();
        let ply = parser.read_ply(&mut bytes.as_slice()).expect("valid PLY");
        let vertices = &ply.payload["vertex"];
        assert_eq!(vertices.len(), 2);
        for (i, v) in vertices.iter().enumerate() {
            let p = map.positions[i];
            let n = map.normals[i];
            assert_eq!(
                [float(v, "x"), float(v, "y"), float(v, "z")],
                [p.x, p.y, p.z]
            );
            assert_eq!(
                [float(v, "nx"), float(v, "ny"), float(v, "nz")],
                [n.x, n.y, n.z]
            );
            let c = map.colours[i];
            assert_eq!(
                [uchar(v, "red"), uchar(v, "green"), uchar(v, "blue")],
                [c[0], c[1], c[2]]
            );
            assert_eq!(float(v, "radius"), map.radii[i]);
            assert_eq!(float(v, "confidence"), map.confidences[i]);
        }
        // An absorbed surfel (awaiting removal) is not written.
        let mut with_absorbed = map.clone();
        with_absorbed.push(Vec3::ONE, Vec3::Z, [1, 2, 3, 255], 0.01, 2.0, 4);
        with_absorbed.confidences[0] = crate::fusion::ABSORBED;
        let bytes = write_ply(&with_absorbed);
        let ply = parser.read_ply(&mut bytes.as_slice()).expect("valid PLY");
        let positions: Vec<f32> = ply.payload["vertex"]
            .iter()
            .map(|v| float(v, "x"))
            .collect();
        assert_eq!(positions, [-0.1, 1.0]);
        let empty = write_ply(&SurfelMap::default());
        let ply = parser
            .read_ply(&mut empty.as_slice())
            .expect("valid empty PLY");
        assert_eq!(ply.payload.get("vertex").map_or(0, Vec::len), 0);
    }
}
