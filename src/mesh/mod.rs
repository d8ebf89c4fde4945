//! Triangle meshes from the surfel map, and the files other tools open.
//!
//! The fused surfels define a signed-distance field (an implicit moving
//! least-squares surface, Kolluri 2005: at a point `x`, the kernel-weighted
//! mean of `n_i . (x - p_i)` over the surfels within the kernel's reach),
//! sampled on a sparse voxel grid: only the 8x8x8-voxel blocks that some
//! surfel reaches exist. Surface nets then put one vertex in each voxel cell
//! the zero level crosses and join the cells around each crossed voxel edge
//! with a quad (two triangles). A cell with a corner no surfel reached makes
//! no vertex, so no surface is invented where nothing was measured (a
//! general-purpose surface nets crate such as `fast-surface-nets` has no such
//! mask: an unobserved corner would need a made-up sign, and a wall would
//! appear at the edge of the observed band).
//!
//! Everything is in the map's world frame (the first camera's frame: +x
//! right, +y down, +z forward), metres. Vertex normals point out of the
//! surface, towards the cameras that saw it (as surfel normals do).
//!
//! - [`Mesher`]: the meshing, with buffers reused between calls and a
//!   progress callback.
//! - [`export`]: binary PLY and OBJ writers, [`MeshFormat`].
//! - [`glb`]: glTF 2.0 binary (`.glb`) of a mesh or of the surfel cloud.
//! - [`surfel_ply`]: the surfel map as a PLY file, written and read back
//!   (one header writer for both PLY kinds: `ply_header.rs`).

pub mod export;
pub mod glb;
mod grid;
pub(crate) mod ply_header;
mod surface_nets;
pub mod surfel_ply;

use glam::Vec3;
use thiserror::Error;

use crate::fusion::SurfelMap;
pub use export::{write_mesh, write_obj, write_ply_mesh, MeshFormat};
pub use glb::{write_glb_mesh, write_glb_points};
pub use surfel_ply::{read_surfel_ply, write_surfel_ply, SurfelPlyError};

/// Settings of the meshing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshConfig {
    /// Edge of a voxel, metres. The mesh has about one vertex per voxel of
    /// surface.
    pub voxel_size_m: f32,
    /// Only surfels at least this confident are used; the default is
    /// fusion's stable confidence (`FusionConfig::stable_confidence`).
    pub min_confidence: f32,
    /// Reach of a surfel's kernel along its normal, in voxels: the
    /// distance field at a voxel averages the surfels whose elliptic kernel
    /// reaches it.
    pub support_voxels: f32,
    /// Reach of a surfel's kernel along the surface, in voxels (at least
    /// the surfel's radius).
    pub tangential_voxels: f32,
    /// A cell makes a vertex only if one of its corners lies within this
    /// many voxels of a surfel's centre (a crossing of the zero level far
    /// from every surfel is the kernel's extrapolation).
    pub max_gap_voxels: f32,
    /// A voxel whose summed kernel weight is below this counts as unobserved
    /// (one surfel of full weight contributes at most 1).
    pub min_weight: f32,
    /// Largest number of 8x8x8-voxel blocks (about 6.2 KB each); a map that
    /// needs more is refused with [`MeshError::TooLarge`].
    pub max_blocks: usize,
}

impl Default for MeshConfig {
    fn default() -> Self {
        Self {
            voxel_size_m: 0.01,
            min_confidence: crate::fusion::FusionConfig::default().stable_confidence,
            support_voxels: 2.5,
            tangential_voxels: 1.0,
            max_gap_voxels: 1.0,
            min_weight: 0.25,
            max_blocks: 1 << 16,
        }
    }
}

/// Smallest and largest accepted voxel edge, metres.
pub const VOXEL_SIZE_RANGE_M: (f32, f32) = (0.001, 1.0);

impl MeshConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`MeshError::InvalidConfig`] naming the setting.
    pub fn validate(&self) -> Result<(), MeshError> {
        let (lo, hi) = VOXEL_SIZE_RANGE_M;
        if !(self.voxel_size_m >= lo && self.voxel_size_m <= hi) {
            return Err(MeshError::InvalidConfig(format!(
                "voxel size must be between {lo} and {hi} m, got {}",
                self.voxel_size_m
            )));
        }
        if !self.min_confidence.is_finite() {
            return Err(MeshError::InvalidConfig(format!(
                "minimum confidence must be finite, got {}",
                self.min_confidence
            )));
        }
        if !(self.support_voxels >= 0.5 && self.support_voxels <= 4.0) {
            return Err(MeshError::InvalidConfig(format!(
                "support must be between 0.5 and 4 voxels, got {}",
                self.support_voxels
            )));
        }
        if !(self.tangential_voxels >= 0.5 && self.tangential_voxels <= 4.0) {
            return Err(MeshError::InvalidConfig(format!(
                "tangential support must be between 0.5 and 4 voxels, got {}",
                self.tangential_voxels
            )));
        }
        if !(self.max_gap_voxels >= 0.0 && self.max_gap_voxels.is_finite()) {
            return Err(MeshError::InvalidConfig(format!(
                "maximum gap must be finite and >= 0 voxels, got {}",
                self.max_gap_voxels
            )));
        }
        if !(self.min_weight > 0.0 && self.min_weight.is_finite()) {
            return Err(MeshError::InvalidConfig(format!(
                "minimum weight must be finite and > 0, got {}",
                self.min_weight
            )));
        }
        Ok(())
    }
}

/// Why a mesh could not be made.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    /// A setting is out of range (the message names it).
    #[error("mesh settings: {0}")]
    InvalidConfig(String),
    /// The map spans more voxel blocks than `MeshConfig::max_blocks`.
    #[error("the map needs {blocks} voxel blocks at {voxel_size_m} m voxels, more than the limit of {max}; use larger voxels")]
    TooLarge {
        /// Blocks the map needs.
        blocks: usize,
        /// The limit.
        max: usize,
        /// Voxel edge asked for, metres.
        voxel_size_m: f32,
    },
}

/// An indexed triangle mesh, world frame, metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions, world frame, metres.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, world frame, pointing out of the surface.
    pub normals: Vec<Vec3>,
    /// Vertex colours, RGBA8 (A = 255).
    pub colours: Vec<[u8; 4]>,
    /// Triangles as vertex indices, counter-clockwise seen from the side the
    /// normals point to.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// True when the mesh has no triangle.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    fn clear(&mut self) {
        self.positions.clear();
        self.normals.clear();
        self.colours.clear();
        self.triangles.clear();
    }
}

/// What one meshing did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeshStats {
    /// Surfels that shaped the distance field.
    pub surfels_used: usize,
    /// Surfels left out: below the confidence, or degenerate (non-finite
    /// values, zero normal, non-positive or non-finite radius, too far out).
    pub surfels_skipped: usize,
    /// Voxel blocks (8x8x8) that existed.
    pub blocks: usize,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Bytes held by the mesher's buffers after the call (the mesh excluded).
    pub scratch_bytes: usize,
}

/// Meshes surfel maps, keeping its buffers between calls.
#[derive(Debug, Default)]
pub struct Mesher {
    grid: grid::Grid,
}

impl Mesher {
    /// A mesher with empty buffers.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Meshes `map` into `mesh` (cleared first). `progress` is called on
    /// the calling thread with the fraction done (0..=1), a few dozen times.
    ///
    /// # Errors
    /// Bad settings, or a map too large for `config.max_blocks`; `mesh` is
    /// then left empty.
    pub fn mesh_into(
        &mut self,
        map: &SurfelMap,
        config: &MeshConfig,
        mesh: &mut TriangleMesh,
        progress: &mut dyn FnMut(f32),
    ) -> Result<MeshStats, MeshError> {
        mesh.clear();
        config.validate()?;
        progress(0.0);
        let (used, skipped) = self.grid.fill(map, config, &mut |f| progress(0.75 * f))?;
        surface_nets::extract(&mut self.grid, mesh, &mut |f| progress(0.75 + 0.25 * f));
        progress(1.0);
        Ok(MeshStats {
            surfels_used: used,
            surfels_skipped: skipped,
            blocks: self.grid.block_count(),
            vertices: mesh.positions.len(),
            triangles: mesh.triangles.len(),
            scratch_bytes: self.grid.heap_bytes(),
        })
    }

    /// [`Mesher::mesh_into`] into a new mesh, without progress reports.
    ///
    /// # Errors
    /// As [`Mesher::mesh_into`].
    pub fn mesh(
        &mut self,
        map: &SurfelMap,
        config: &MeshConfig,
    ) -> Result<TriangleMesh, MeshError> {
        let mut mesh = TriangleMesh::default();
        self.mesh_into(map, config, &mut mesh, &mut |_| {})?;
        Ok(mesh)
    }
}

/// Meshes `map` with a fresh [`Mesher`].
///
/// # Errors
/// As [`Mesher::mesh_into`].
pub fn mesh_map(map: &SurfelMap, config: &MeshConfig) -> Result<TriangleMesh, MeshError> {
    Mesher::new().mesh(map, config)
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
pub(crate) mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Surfels on a sphere (Fibonacci lattice, about `spacing` apart),
    /// normals pointing out, colour by height.
    pub(crate) fn sphere_map(centre: Vec3, radius: f32, spacing: f32) -> SurfelMap {
        let n = (4.0 * std::f32::consts::PI * radius * radius / (spacing * spacing)) as usize;
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let mut map = SurfelMap::default();
        for i in 0..n {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            let dir = Vec3::new(r * t.cos(), y, r * t.sin());
            let shade = (127.5 * (y + 1.0)) as u8;
            map.push(
                centre + radius * dir,
                dir,
                [shade, 100, 255 - shade, 255],
                spacing,
                10.0,
                0,
            );
        }
        map
    }

    #[test]
    fn a_sphere_gives_a_closed_outward_mesh_on_its_surface() {
        let (centre, radius) = (Vec3::new(0.13, -0.21, 1.52), 0.3);
        let map = sphere_map(centre, radius, 0.004);
        let mut fractions = Vec::new();
        let mut mesh = TriangleMesh::default();
        let stats = Mesher::new()
            .mesh_into(&map, &MeshConfig::default(), &mut mesh, &mut |f| {
                fractions.push(f)
            })
            .expect("meshes");
        assert_eq!(stats.surfels_used, map.len());
        assert_eq!(stats.vertices, mesh.positions.len());
        // About one vertex per cm^2 of the 1.13 m^2 surface.
        let area_cm2 = 4.0 * std::f32::consts::PI * (radius * 100.0).powi(2);
        let ratio = mesh.positions.len() as f32 / area_cm2;
        assert!(
            (0.8..1.6).contains(&ratio),
            "{} vertices",
            mesh.positions.len()
        );
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let off = *p - centre;
            assert!(
                (off.length() - radius).abs() < 0.002,
                "vertex {} m off",
                off.length() - radius
            );
            assert!(n.dot(off.normalize()) > 0.95, "normal {n} at {off}");
        }
        // Closed: every edge is shared by exactly two triangles, in opposite
        // directions (consistent winding), also across block seams.
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        let bad: Vec<_> = edges.iter().filter(|(_, &v)| v != 0).collect();
        for ((a, b), v) in bad.iter().take(5) {
            eprintln!(
                "{v} {} {}",
                mesh.positions[*a as usize] / 0.01,
                mesh.positions[*b as usize] / 0.01
            );
        }
        assert!(
            bad.is_empty(),
            "{} of {} edges open or inconsistently wound",
            bad.len(),
            edges.len()
        );
        // Counter-clockwise seen from outside.
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let face = (b - a).cross(c - a);
            assert!(face.dot((a + b + c) / 3.0 - centre) > 0.0);
        }
        // Colours follow the surfels' (red grows with height, world -y).
        let top = mesh
            .positions
            .iter()
            .zip(&mesh.colours)
            .find(|(p, _)| p.y > centre.y + 0.28);
        assert!(top.is_some_and(|(_, c)| c[0] > 230 && c[2] < 25), "{top:?}");
        assert!(fractions.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(fractions.last(), Some(&1.0));
        assert!(fractions.len() > 10);
    }

    #[test]
    fn an_open_patch_does_not_grow_past_its_edge() {
        // A 30 x 30 cm square of the plane z = 1, normals towards -z.
        let mut map = SurfelMap::default();
        for i in 0..75 {
            for j in 0..75 {
                let p = Vec3::new(i as f32 * 0.004, j as f32 * 0.004, 1.0);
                map.push(p, Vec3::NEG_Z, [9, 9, 9, 255], 0.003, 20.0, 0);
            }
        }
        let mesh = mesh_map(&map, &MeshConfig::default()).expect("meshes");
        assert!(mesh.triangles.len() > 1500);
        for p in &mesh.positions {
            assert!((p.z - 1.0).abs() < 1e-3);
            assert!(
                p.x > -0.02 && p.x < 0.316 && p.y > -0.02 && p.y < 0.316,
                "{p}"
            );
        }
    }

    #[test]
    fn degenerate_maps_give_empty_meshes_or_errors_not_panics() {
        let config = MeshConfig::default();
        let mut mesher = Mesher::new();
        assert!(mesher
            .mesh(&SurfelMap::default(), &config)
            .expect("empty")
            .is_empty());
        let mut bad = SurfelMap::default();
        bad.push(Vec3::new(0.0, 0.0, 1.0), Vec3::Z, [0; 4], 0.0, 50.0, 0);
        bad.push(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, [0; 4], 0.01, 50.0, 0);
        bad.push(
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::Z,
            [0; 4],
            0.01,
            50.0,
            0,
        );
        bad.push(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::Z,
            [0; 4],
            f32::INFINITY,
            50.0,
            0,
        );
        bad.push(Vec3::new(1e30, 0.0, 1.0), Vec3::Z, [0; 4], 0.01, 50.0, 0);
        bad.push(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::Z,
            [0; 4],
            0.01,
            crate::fusion::ABSORBED,
            0,
        );
        let mut mesh = TriangleMesh::default();
        let stats = mesher
            .mesh_into(&bad, &config, &mut mesh, &mut |_| {})
            .expect("meshes");
        assert_eq!((stats.surfels_used, stats.surfels_skipped), (0, 6));
        assert!(mesh.is_empty());
        // A lone surfel: a few voxels of distance field, no closed cell.
        let mut lone = SurfelMap::default();
        lone.push(
            Vec3::new(0.3, 0.2, 1.0),
            Vec3::NEG_Z,
            [1, 2, 3, 255],
            0.004,
            9.0,
            0,
        );
        let m = mesher.mesh(&lone, &config).expect("meshes");
        assert_eq!(m.positions.len(), m.normals.len());
        // Bad settings and maps too large are errors.
        for voxel in [0.0, -0.01, f32::NAN, 2.0] {
            let c = MeshConfig {
                voxel_size_m: voxel,
                ..config
            };
            assert!(matches!(
                mesher.mesh(&lone, &c),
                Err(MeshError::InvalidConfig(_))
            ));
        }
        let mut far = SurfelMap::default();
        for i in 0..200 {
            far.push(
                Vec3::new(i as f32 * 10.0, 0.0, 1.0),
                Vec3::Z,
                [0; 4],
                0.01,
                50.0,
                0,
            );
        }
        let c = MeshConfig {
            max_blocks: 100,
            ..config
        };
        assert!(matches!(
            mesher.mesh(&far, &c),
            Err(MeshError::TooLarge { .. })
        ));
        // The mesher still works after an error.
        let m = mesher
            .mesh(&sphere_map(Vec3::Z, 0.1, 0.004), &config)
            .expect("meshes");
        assert!(!m.is_empty());
    }

    #[test]
    fn the_same_map_gives_the_same_mesh() {
        let map = sphere_map(Vec3::new(-0.5, 0.2, 2.0), 0.2, 0.004);
        let mut mesher = Mesher::new();
        let a = mesher.mesh(&map, &MeshConfig::default()).expect("meshes");
        let b = mesher.mesh(&map, &MeshConfig::default()).expect("meshes");
        assert_eq!(a, b);
        let coarse = MeshConfig {
            voxel_size_m: 0.02,
            ..MeshConfig::default()
        };
        let c = mesher.mesh(&map, &coarse).expect("meshes");
        let ratio = a.positions.len() as f32 / c.positions.len() as f32;
        assert!((3.0..5.0).contains(&ratio), "{ratio}");
    }
}
