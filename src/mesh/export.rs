//! Mesh files: binary PLY (MeshLab, CloudCompare, Open3D, Blender), OBJ
//! with vertex colours (MeshLab's `v x y z r g b` extension) and glTF
//! binary ([`super::glb`]). All in the map's world frame, metres.

use std::fmt::Write as _;

use super::glb::write_glb_mesh;
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
    let header = format!(
        "ply\n\
         format binary_little_endian 1.0\n\
         comment surfel-slam mesh, world frame, metres\n\
         element vertex {nv}\n\
         property float x\n\
         property float y\n\
         property float z\n\
         property float nx\n\
         property float ny\n\
         property float nz\n\
         property uchar red\n\
         property uchar green\n\
         property uchar blue\n\
         element face {}\n\
         property list uchar int vertex_indices\n\
         end_header\n",
        mesh.triangles.len()
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
