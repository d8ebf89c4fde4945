//! `surfel-slam mesh`: mesh a saved surfel map (binary PLY); and the mesh
//! writing `run --mesh` shares.

use anyhow::{Context, Result};
use clap::Args;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use surfel_slam::fusion::SurfelMap;
use surfel_slam::mesh::{
    read_surfel_ply, write_mesh, MeshConfig, MeshFormat, Mesher, TriangleMesh,
};

#[derive(Args)]
pub struct MeshArgs {
    /// Surfel map (binary little-endian PLY with x y z nx ny nz; colours,
    /// radius and confidence used when present).
    map: PathBuf,
    /// Output mesh (.glb, .ply or .obj).
    #[arg(long, short, value_parser = crate::mesh_path)]
    output: PathBuf,
    /// Voxel edge, metres (0.001 to 1).
    #[arg(long, default_value_t = MeshConfig::default().voxel_size_m, allow_negative_numbers = true, value_parser = crate::voxel_size)]
    voxel_size: f32,
    /// Use only surfels at least this confident (default: fusion's stable confidence).
    #[arg(long, default_value_t = MeshConfig::default().min_confidence, allow_negative_numbers = true, value_parser = crate::finite)]
    min_confidence: f32,
}

/// The mesh format `path`'s extension names, or an error naming the path.
pub(crate) fn mesh_format(path: &Path) -> Result<MeshFormat> {
    MeshFormat::from_path(path).with_context(|| {
        format!(
            "{}: unknown mesh format; use a .glb, .ply or .obj file name",
            path.display()
        )
    })
}

/// Meshes `map` and writes the mesh to `path` (format from the extension);
/// prints one line with the counts and the time.
pub(crate) fn write_mesh_file(
    map: &SurfelMap,
    config: &MeshConfig,
    path: &Path,
    quiet: bool,
) -> Result<()> {
    let format = mesh_format(path)?;
    let t0 = std::time::Instant::now();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(100)
    };
    let mut mesh = TriangleMesh::default();
    let stats = Mesher::new().mesh_into(map, config, &mut mesh, &mut |f| {
        bar.set_position((f * 100.0) as u64);
    })?;
    bar.finish_and_clear();
    let ms = t0.elapsed().as_secs_f64() * 1000.0;
    std::fs::write(path, write_mesh(&mesh, format))
        .with_context(|| format!("writing {}", path.display()))?;
    println!(
        "{}: {} vertices, {} triangles from {} surfels ({} voxel blocks of {} m voxels), meshed in {ms:.0} ms",
        path.display(),
        stats.vertices,
        stats.triangles,
        stats.surfels_used,
        stats.blocks,
        config.voxel_size_m
    );
    Ok(())
}

/// Runs `surfel-slam mesh`: meshes a saved surfel map into a mesh file.
pub fn mesh_file(args: &MeshArgs) -> Result<()> {
    mesh_format(&args.output)?;
    let config = MeshConfig {
        voxel_size_m: args.voxel_size,
        min_confidence: args.min_confidence,
        ..MeshConfig::default()
    };
    config.validate()?;
    let bytes =
        std::fs::read(&args.map).with_context(|| format!("reading {}", args.map.display()))?;
    let map = read_surfel_ply(&bytes).with_context(|| args.map.display().to_string())?;
    write_mesh_file(&map, &config, &args.output, false)
}
