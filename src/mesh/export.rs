//! Mesh files: binary PLY (MeshLab, CloudCompare, Open3D, Blender), OBJ
//! with vertex colours (MeshLab's `v x y z r g b` extension) and glTF
//! binary ([`super::glb`]). All in the map's world frame, metres.

use std::fmt::Write as _;

use super::glb::write_glb_mesh;
use super::ply_header::write_ply_header;
use super::TriangleMesh;

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// glTF 2.0 binary (`.glb`).
    Glb,
    /// Binary little-endian PLY (`.ply`).
    Ply,
    /// Wavefront OBJ (`.obj`).
    Obj,
}

impl MeshFormat {
    /// All formats.
    pub const ALL: [MeshFormat; 3] = [MeshFormat::Glb, MeshFormat::Ply, MeshFormat::Obj];

    /// The format's name and file extension: `glb`, `ply` or `obj`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Glb => "glb",
            MeshFormat::Ply => "ply",
            MeshFormat::Obj => "obj",
        }
    }

    /// The format named `name` (case-insensitive), if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// The format of a file name by its extension, if known.
    #[must_use]
    pub fn from_path(path: &std::path::Path) -> Option<Self> {
        Self::from_name(path.extension()?.to_str()?)
    }
}

/// The mesh as a file of `format`.
#[must_use]
pub fn write_mesh(mesh: &TriangleMesh, format: MeshFormat) -> Vec<u8> {
    match format {
        MeshFormat::Glb => write_glb_mesh(mesh),
        MeshFormat::Ply => write_ply_mesh(mesh),
        MeshFormat::Obj => write_obj(mesh),
    }
}

/// The mesh as binary little-endian PLY: `vertex` with `x y z nx ny nz`
/// (float) and `red green blue` (uchar), `face` with a `uchar int` list
/// `vertex_indices`.
#[must_use]
pub fn write_ply_mesh(mesh: &TriangleMesh) -> Vec<u8> {
    let nv = mesh.positions.len();
    let header = write_ply_header(
        "surfel-slam mesh, world frame, metres",
        nv,
        &[],
        Some(mesh.triangles.len()),
    );
    let mut out = Vec::with_capacity(header.len() + nv * 27 + mesh.triangles.len() * 13);
    out.extend_from_slice(header.as_bytes());
    for i in 0..nv {
        let (p, n) = (mesh.positions[i], mesh.normals[i]);
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&mesh.colours[i][..3]);
    }
    for t in &mesh.triangles {
        out.push(3);
        for &i in t {
            // Indices are below the vertex count, which the block budget
            // keeps far below i32::MAX.
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

/// The mesh as Wavefront OBJ: `v x y z r g b` (colour 0..1), `vn`, and
/// `f a//a b//b c//c` (1-based).
#[must_use]
pub fn write_obj(mesh: &TriangleMesh) -> Vec<u8> {
    let mut s = String::with_capacity(mesh.positions.len() * 80 + mesh.triangles.len() * 40);
    s.push_str("# surfel-slam mesh, world frame, metres\n");
    // Writing to a String cannot fail.
    for (p, c) in mesh.positions.iter().zip(&mesh.colours) {
        let _ = writeln!(
            s,
            "v {} {} {} {:.4} {:.4} {:.4}",
            p.x,
            p.y,
            p.z,
            f32::from(c[0]) / 255.0,
            f32::from(c[1]) / 255.0,
            f32::from(c[2]) / 255.0
        );
    }
    for n in &mesh.normals {
        let _ = writeln!(s, "vn {:.5} {:.5} {:.5}", n.x, n.y, n.z);
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| u64::from(i) + 1);
        let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::tests::sphere_map;
    use crate::mesh::{mesh_map, write_glb_points, MeshConfig};
    use glam::Vec3;
    use gltf_json as json;
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};

    fn sphere_mesh() -> TriangleMesh {
        mesh_map(
            &sphere_map(Vec3::new(0.0, 0.0, 1.0), 0.15, 0.004),
            &MeshConfig::default(),
        )
        .expect("meshes")
    }

    #[test]
    fn ply_mesh_reads_back_with_an_independent_reader() {
        let mesh = sphere_mesh();
        assert!(mesh.triangles.len() > 1000);
        let bytes = write_ply_mesh(&mesh);
        let ply = Parser::<DefaultElement>::new()
            .read_ply(&mut bytes.as_slice())
            .expect("valid PLY");
        let vertices = &ply.payload["vertex"];
        let faces = &ply.payload["face"];
        assert_eq!(vertices.len(), mesh.positions.len());
        assert_eq!(faces.len(), mesh.triangles.len());
        let v = &vertices[7];
        let p = mesh.positions[7];
        assert_eq!(v.get("x"), Some(&Property::Float(p.x)));
        assert_eq!(v.get("red"), Some(&Property::UChar(mesh.colours[7][0])));
        match faces[5].get("vertex_indices") {
            Some(Property::ListInt(ix)) => {
                assert_eq!(ix, &mesh.triangles[5].map(|i| i as i32).to_vec());
            }
            other => panic!("{other:?}"),
        }
        let empty = write_ply_mesh(&TriangleMesh::default());
        let ply = Parser::<DefaultElement>::new()
            .read_ply(&mut empty.as_slice())
            .expect("valid empty PLY");
        assert_eq!(ply.payload.get("face").map_or(0, Vec::len), 0);
    }

    #[test]
    fn obj_has_every_vertex_normal_and_face() {
        let mesh = sphere_mesh();
        let text = String::from_utf8(write_obj(&mesh)).expect("utf8");
        let count = |prefix: &str| text.lines().filter(|l| l.starts_with(prefix)).count();
        assert_eq!(count("v "), mesh.positions.len());
        assert_eq!(count("vn "), mesh.positions.len());
        assert_eq!(count("f "), mesh.triangles.len());
        let last = text.lines().last().expect("a face");
        let [a, ..] = mesh.triangles[mesh.triangles.len() - 1];
        assert!(
            last.starts_with(&format!("f {}//{}", a + 1, a + 1)),
            "{last}"
        );
    }

    /// The JSON and the binary chunk of a GLB file.
    fn glb_parts(bytes: &[u8]) -> (json::Root, &[u8]) {
        let word =
            |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes")) as usize;
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(word(4), 2);
        assert_eq!(word(8), bytes.len());
        let json_len = word(12);
        assert_eq!(word(16), 0x4E4F_534A);
        let root: json::Root =
            json::deserialize::from_slice(&bytes[20..20 + json_len]).expect("JSON parses");
        let rest = &bytes[20 + json_len..];
        let bin = if rest.is_empty() {
            rest
        } else {
            &rest[8..8 + word(20 + json_len)]
        };
        (root, bin)
    }

    #[test]
    fn glb_holds_the_mesh_and_the_points() {
        let mesh = sphere_mesh();
        let file = write_mesh(&mesh, MeshFormat::Glb);
        let (root, bin) = glb_parts(&file);
        let counts: Vec<u64> = root.accessors.iter().map(|a| a.count.0).collect();
        let n = mesh.positions.len() as u64;
        assert_eq!(counts, [n, n, n, 3 * mesh.triangles.len() as u64]);
        assert_eq!(root.buffers[0].byte_length.0 as usize, bin.len());
        assert_eq!(
            bin.len(),
            mesh.positions.len() * 28 + mesh.triangles.len() * 12
        );
        // First position, read back from the binary chunk.
        let x = f32::from_le_bytes(bin[..4].try_into().expect("4 bytes"));
        assert_eq!(x, mesh.positions[0].x);

        let map = sphere_map(Vec3::Z, 0.1, 0.01);
        let (root, _) = glb_parts(&write_glb_points(&map, 5.0));
        assert_eq!(root.accessors[0].count.0 as usize, map.len());
        assert_eq!(root.accessors.len(), 3);
        let (root, _) = glb_parts(&write_glb_points(&map, 50.0));
        assert!(root.accessors.is_empty() && root.meshes.is_empty());
        let empty = write_glb_mesh(&TriangleMesh::default());
        let (root, bin) = glb_parts(&empty);
        assert!(root.buffers.is_empty() && bin.is_empty());
    }

    #[test]
    fn formats_by_name_and_path() {
        for f in MeshFormat::ALL {
            assert_eq!(MeshFormat::from_name(f.name()), Some(f));
        }
        let p = std::path::Path::new("out/Mesh.GLB");
        assert_eq!(MeshFormat::from_path(p), Some(MeshFormat::Glb));
        assert_eq!(MeshFormat::from_path(std::path::Path::new("a.stl")), None);
        assert_eq!(MeshFormat::from_path(std::path::Path::new("noext")), None);
    }
}
