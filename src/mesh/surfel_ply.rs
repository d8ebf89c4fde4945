//! The surfel map as a PLY file, readable by MeshLab, CloudCompare, Open3D,
//! and read back from the files written here and from point clouds with
//! normals of other tools (Open3D, CloudCompare).
//!
//! Written: `binary_little_endian 1.0`, one `vertex` element with the
//! standard property names `x y z` (float, world frame, metres), `nx ny nz`
//! (float, unit normal, world frame), `red green blue` (uchar), and two
//! extra float properties `radius` (metres) and `confidence` (accumulated
//! weight).
//!
//! Read: the first element must be `vertex`, with scalar properties; `x y z` and
//! `nx ny nz` are required (world frame, metres; unit normal), `red green
//! blue` (uchar), `radius` (metres) and `confidence` are optional. Points
//! without a confidence count as fully confident; without a radius they get
//! [`DEFAULT_RADIUS_M`]. Points with a non-finite value or a zero normal
//! are dropped.

use glam::Vec3;
use thiserror::Error;

use super::ply_header::write_ply_header;
use crate::fusion::SurfelMap;

/// Radius given to points of a file without a `radius` property, metres.
pub const DEFAULT_RADIUS_M: f32 = 0.005;
/// Confidence given to points of a file without a `confidence` property.
pub const DEFAULT_CONFIDENCE: f32 = 1.0e6;
/// Colour of points of a file without colours.
const DEFAULT_COLOUR: [u8; 4] = [200, 200, 200, 255];
/// Longest header read, bytes.
const MAX_HEADER: usize = 64 * 1024;

/// Why a PLY file could not be read as a surfel map.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SurfelPlyError {
    /// Not a PLY file, or its header is malformed (the message says where).
    #[error("not a readable PLY file: {0}")]
    Header(String),
    /// A format other than binary little-endian.
    #[error("PLY format {0:?} is not supported (only binary_little_endian 1.0)")]
    Format(String),
    /// A required property is missing from the vertex element.
    #[error("PLY vertex element has no {0:?} property")]
    MissingProperty(&'static str),
    /// The data is shorter than the header announces.
    #[error("PLY file is truncated: {expected} bytes of vertex data announced, {found} present")]
    Truncated {
        /// Bytes the header announces.
        expected: u64,
        /// Bytes present after the header.
        found: usize,
    },
}

#[derive(Debug, Clone, Copy)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// The value at the start of `b` (at least `size()` bytes).
    fn read(self, b: &[u8]) -> f64 {
        let a = |n: usize| -> [u8; 8] {
            let mut out = [0u8; 8];
            out[..n].copy_from_slice(&b[..n]);
            out
        };
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Self::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Self::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::F64 => f64::from_le_bytes(a(8)),
        }
    }
}

/// The vertex count and the vertex properties (name, type) of a PLY header
/// (`text`: up to `end_header`).
fn parse_header(text: &str) -> Result<(u64, Vec<(String, Scalar)>), SurfelPlyError> {
    let header_err = |m: &str| SurfelPlyError::Header(m.to_owned());
    let mut lines = text.lines().map(str::trim);
    if lines.next() != Some("ply") {
        return Err(header_err("does not start with \"ply\""));
    }
    let mut count: Option<u64> = None;
    let mut in_vertex = false;
    let mut seen_element = false;
    let mut props: Vec<(String, Scalar)> = Vec::new();
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", format, version] => {
                if *format != "binary_little_endian" || *version != "1.0" {
                    return Err(SurfelPlyError::Format(format!("{format} {version}")));
                }
            }
            ["element", name, n] => {
                if seen_element {
                    // Elements after the vertices are not needed.
                    break;
                }
                if *name != "vertex" {
                    return Err(header_err("the first element is not \"vertex\""));
                }
                seen_element = true;
                in_vertex = true;
                count = Some(n.parse().map_err(|_| header_err("bad vertex count"))?);
            }
            ["property", "list", ..] if in_vertex => {
                return Err(header_err(
                    "list properties in the vertex element are not supported",
                ));
            }
            ["property", ty, name] if in_vertex => {
                let ty = Scalar::parse(ty).ok_or_else(|| header_err("unknown property type"))?;
                props.push(((*name).to_owned(), ty));
            }
            ["property", ..] => return Err(header_err("property outside an element")),
            _ => return Err(header_err("unknown header line")),
        }
    }
    if !text.lines().any(|l| l.trim().starts_with("format ")) {
        return Err(header_err("no format line"));
    }
    let count = count.ok_or_else(|| header_err("no vertex element"))?;
    Ok((count, props))
}

/// Reads the surfels of a binary PLY file (see the module docs).
///
/// # Errors
/// A malformed or truncated file, another format, or no positions or
/// normals.
pub fn read_surfel_ply(bytes: &[u8]) -> Result<SurfelMap, SurfelPlyError> {
    let header_err = |m: &str| SurfelPlyError::Header(m.to_owned());
    let search = &bytes[..bytes.len().min(MAX_HEADER)];
    let marker = b"end_header";
    let end = search
        .windows(marker.len())
        .position(|w| w == marker)
        .ok_or_else(|| header_err("no end_header line in the first 64 KiB"))?;
    let mut body = end + marker.len();
    if bytes.get(body) == Some(&b'\r') {
        body += 1;
    }
    if bytes.get(body) != Some(&b'\n') {
        return Err(header_err("end_header is not followed by a newline"));
    }
    body += 1;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| header_err("header is not text"))?;
    let (count, props) = parse_header(text)?;
    let mut offsets = Vec::with_capacity(props.len());
    let mut stride = 0usize;
    for (_, ty) in &props {
        offsets.push(stride);
        stride += ty.size();
    }
    let find = |name: &str| {
        props
            .iter()
            .position(|(n, _)| n == name)
            .map(|i| (offsets[i], props[i].1))
    };
    let need = |name: &'static str| find(name).ok_or(SurfelPlyError::MissingProperty(name));
    let xyz = [need("x")?, need("y")?, need("z")?];
    let normal = [need("nx")?, need("ny")?, need("nz")?];
    let rgb = [find("red"), find("green"), find("blue")];
    let radius = find("radius");
    let confidence = find("confidence");
    let data = &bytes[body..];
    let expected = count.saturating_mul(stride as u64);
    if expected > data.len() as u64 {
        return Err(SurfelPlyError::Truncated {
            expected,
            found: data.len(),
        });
    }
    let mut map = SurfelMap::default();
    // `expected` fits in the data, so the count fits in usize.
    map.reserve(count as usize);
    let get = |rec: &[u8], (off, ty): (usize, Scalar)| ty.read(&rec[off..]);
    for rec in data.chunks_exact(stride.max(1)).take(count as usize) {
        let p = Vec3::from_array(xyz.map(|f| get(rec, f) as f32));
        let Some(n) = Vec3::from_array(normal.map(|f| get(rec, f) as f32)).try_normalize() else {
            continue;
        };
        let colour = match rgb {
            [Some(r), Some(g), Some(b)] => [r, g, b].map(|f| get(rec, f).clamp(0.0, 255.0) as u8),
            _ => [DEFAULT_COLOUR[0], DEFAULT_COLOUR[1], DEFAULT_COLOUR[2]],
        };
        let r = radius.map_or(DEFAULT_RADIUS_M, |f| get(rec, f) as f32);
        let c = confidence.map_or(DEFAULT_CONFIDENCE, |f| get(rec, f) as f32);
        if p.is_finite() && r.is_finite() && c.is_finite() {
            map.push(p, n, [colour[0], colour[1], colour[2], 255], r, c, 0);
        }
    }
    Ok(map)
}

/// Bytes per written vertex: 6 floats, 3 uchars, 2 floats.
const VERTEX_BYTES: usize = 6 * 4 + 3 + 2 * 4;

/// Writes the map as a binary little-endian PLY file, without the surfels
/// absorbed into others (negative confidence, awaiting removal). If the
/// map's arrays have different lengths (a corrupt map), only the surfels
/// present in every array are written.
#[must_use]
pub fn write_surfel_ply(map: &SurfelMap) -> Vec<u8> {
    let n = map.common_len();
    let (positions, normals, colours) = (map.positions(), map.normals(), map.colours());
    let (radii, confidences) = (map.radii(), map.confidences());
    let kept = || (0..n).filter(|&i| confidences[i] >= 0.0);
    let count = kept().count();
    let header = write_ply_header(
        "surfel-slam surfel map, world frame, metres",
        count,
        &[("float", "radius"), ("float", "confidence")],
        None,
    );
    let mut out = Vec::with_capacity(header.len() + count * VERTEX_BYTES);
    out.extend_from_slice(header.as_bytes());
    for i in kept() {
        let (p, nrm) = (positions[i], normals[i]);
        for v in [p.x, p.y, p.z, nrm.x, nrm.y, nrm.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&colours[i][..3]);
        out.extend_from_slice(&radii[i].to_le_bytes());
        out.extend_from_slice(&confidences[i].to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::Surfel;
    use crate::mesh::tests::sphere_map;
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
        let bytes = write_surfel_ply(&map);
        let parser = Parser::<DefaultElement>::new();
        let ply = parser.read_ply(&mut bytes.as_slice()).expect("valid PLY");
        let vertices = &ply.payload["vertex"];
        assert_eq!(vertices.len(), 2);
        for (i, v) in vertices.iter().enumerate() {
            let p = map.positions()[i];
            let n = map.normals()[i];
            assert_eq!(
                [float(v, "x"), float(v, "y"), float(v, "z")],
                [p.x, p.y, p.z]
            );
            assert_eq!(
                [float(v, "nx"), float(v, "ny"), float(v, "nz")],
                [n.x, n.y, n.z]
            );
            let c = map.colours()[i];
            assert_eq!(
                [uchar(v, "red"), uchar(v, "green"), uchar(v, "blue")],
                [c[0], c[1], c[2]]
            );
            assert_eq!(float(v, "radius"), map.radii()[i]);
            assert_eq!(float(v, "confidence"), map.confidences()[i]);
        }
        // An absorbed surfel (awaiting removal) is not written.
        let mut with_absorbed = map.clone();
        with_absorbed.push(Vec3::ONE, Vec3::Z, [1, 2, 3, 255], 0.01, 2.0, 4);
        with_absorbed.absorb(0);
        let bytes = write_surfel_ply(&with_absorbed);
        let ply = parser.read_ply(&mut bytes.as_slice()).expect("valid PLY");
        let positions: Vec<f32> = ply.payload["vertex"]
            .iter()
            .map(|v| float(v, "x"))
            .collect();
        assert_eq!(positions, [-0.1, 1.0]);
        let empty = write_surfel_ply(&SurfelMap::default());
        let ply = parser
            .read_ply(&mut empty.as_slice())
            .expect("valid empty PLY");
        assert_eq!(ply.payload.get("vertex").map_or(0, Vec::len), 0);
    }

    #[test]
    fn reads_back_what_the_surfel_writer_writes() {
        let mut map = sphere_map(Vec3::new(0.1, 0.2, 1.0), 0.1, 0.02);
        let third = Surfel {
            confidence: 2.5,
            ..map.surfel(3)
        };
        map.set_surfel(3, &third);
        let back = read_surfel_ply(&write_surfel_ply(&map)).expect("reads");
        assert_eq!(back.len(), map.len());
        for i in 0..map.len() {
            assert_eq!(back.positions()[i], map.positions()[i]);
            assert!((back.normals()[i] - map.normals()[i]).length() < 1e-6);
            assert_eq!(back.colours()[i], map.colours()[i]);
            assert_eq!(back.radii()[i], map.radii()[i]);
            assert_eq!(back.confidences()[i], map.confidences()[i]);
        }
    }

    #[test]
    fn bad_files_are_errors() {
        let good = write_surfel_ply(&sphere_map(Vec3::Z, 0.1, 0.02));
        assert!(matches!(
            read_surfel_ply(b""),
            Err(SurfelPlyError::Header(_))
        ));
        assert!(matches!(
            read_surfel_ply(b"not a ply"),
            Err(SurfelPlyError::Header(_))
        ));
        let truncated = &good[..good.len() - 5];
        assert!(matches!(
            read_surfel_ply(truncated),
            Err(SurfelPlyError::Truncated { .. })
        ));
        let text = String::from_utf8_lossy(&good).into_owned();
        let ascii = text.replace("binary_little_endian", "ascii");
        assert!(matches!(
            read_surfel_ply(ascii.as_bytes()),
            Err(SurfelPlyError::Format(_))
        ));
        let no_normals = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0\0\0\0\0\0\0\0\0";
        assert_eq!(
            read_surfel_ply(no_normals),
            Err(SurfelPlyError::MissingProperty("nx"))
        );
        let huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999999999\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n";
        assert!(matches!(
            read_surfel_ply(huge),
            Err(SurfelPlyError::Truncated { .. })
        ));
        // Doubles and no colour, radius or confidence: defaults.
        let mut minimal = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        for v in [[1.0f64, 2.0, 3.0], [f64::NAN, 0.0, 0.0]] {
            for x in v {
                minimal.extend_from_slice(&x.to_le_bytes());
            }
            for n in [0.0f32, 0.0, 2.0] {
                minimal.extend_from_slice(&n.to_le_bytes());
            }
        }
        let m = read_surfel_ply(&minimal).expect("reads");
        assert_eq!(m.len(), 1, "the NaN point is dropped");
        assert_eq!(m.positions()[0], Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(m.normals()[0], Vec3::Z);
        assert_eq!(
            (m.radii()[0], m.confidences()[0]),
            (DEFAULT_RADIUS_M, DEFAULT_CONFIDENCE)
        );
    }
}
