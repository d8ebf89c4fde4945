//! The coarse grid the frame's geometry is measured on: the frame's
//! vertices block-averaged to at most [`super::GRID_COLUMNS`] columns, and
//! each cell's count of ICP correspondences at the start pose.

use super::{GridWorkspace, GRID_COLUMNS};
use crate::camera::Intrinsics;
use crate::fusion::Prediction;
use crate::se3::RigidF32;
use crate::track::icp::IcpGates;
use glam::Vec3;
use rayon::prelude::*;

/// Counts into `grid.counts`, per grid cell (`width` columns, `factor`
/// pixels of level `k` square), the model pixels (every second one each
/// way) with a normal that `camera_from_world` puts in it within `gates`'
/// distance of the cell's averaged point.
///
/// Not within the normal gate of the cell's normal: under quantised depth
/// the grid's normals follow the terraces and fail a 20 degree gate on
/// oblique surfaces that ICP, on finer levels, does use (the synthetic
/// loop under structured-light noise then read 13 views that are not
/// degenerate as free, and held them).
pub(super) fn count_correspondences(
    model: &Prediction,
    mk: &Intrinsics,
    (k, width, factor): (&Intrinsics, usize, usize),
    camera_from_world: &RigidF32,
    gates: &IcpGates,
    grid: &mut GridWorkspace,
) {
    let height = grid.vertices.len() / width.max(1);
    let (vertices, normals) = (&grid.vertices, &grid.normals);
    // The sampled model rows are projected in parallel, each listing the
    // cells it counts in; the counts are then added up in row order.
    grid.hits.resize_with(mk.height.div_ceil(2), Vec::new);
    grid.hits.par_iter_mut().enumerate().for_each(|(r, hits)| {
        hits.clear();
        let v = 2 * r;
        for u in (0..mk.width).step_by(2) {
            let i = v * mk.width + u;
            let (Some(&normal), Some(&vertex)) = (model.normals.get(i), model.vertices.get(i))
            else {
                continue;
            };
            if normal == Vec3::ZERO {
                continue;
            }
            let p = camera_from_world.point(vertex);
            if p.z <= 0.0 {
                continue;
            }
            let Some(j) = k.pixel_index(k.project(p)) else {
                continue;
            };
            let (gu, gv) = (j % k.width / factor, j / k.width / factor);
            if gu >= width || gv >= height {
                continue;
            }
            let g = gv * width + gu;
            let (q, n) = (vertices[g], normals[g]);
            if n != Vec3::ZERO && (p - q).length() <= gates.distance_gate_m {
                hits.push(g as u32);
            }
        }
    });
    grid.counts.clear();
    grid.counts.resize(grid.vertices.len(), 0);
    for &g in grid.hits.iter().flatten() {
        grid.counts[g as usize] += 1;
    }
}

/// Averages `vertices` (`width` columns) over square blocks so that at most
/// [`GRID_COLUMNS`] remain, into `grid.vertices`; returns the grid's width
/// and the block size.
/// A block averages the valid vertices within 5 % of its first valid
/// one's depth (as the pyramid does), so silhouettes are not bridged.
pub(super) fn block_average(
    vertices: &[Vec3],
    width: usize,
    grid: &mut GridWorkspace,
) -> (usize, usize) {
    let factor = width.div_ceil(GRID_COLUMNS).max(1);
    let height = vertices.len() / width;
    let (gw, gh) = (width / factor, height / factor);
    grid.vertices.clear();
    grid.vertices.resize(gw * gh, Vec3::ZERO);
    for gv in 0..gh {
        for gu in 0..gw {
            let mut first = 0.0f32;
            let (mut sum, mut n) = (Vec3::ZERO, 0.0f32);
            for v in gv * factor..(gv + 1) * factor {
                for u in gu * factor..(gu + 1) * factor {
                    let p = vertices[v * width + u];
                    if p.z <= 0.0 {
                        continue;
                    }
                    if first == 0.0 {
                        first = p.z;
                    }
                    if (p.z - first).abs() <= 0.05 * first {
                        sum += p;
                        n += 1.0;
                    }
                }
            }
            if n > 0.0 {
                grid.vertices[gv * gw + gu] = sum / n;
            }
        }
    }
    (gw, factor)
}
