//! The information per point that normal noise alone gives along any
//! direction of motion: the floor a direction's information is measured
//! above ([`super::FreeDirections`]). On the grid from first differences of
//! neighbouring cells' normals, at full resolution from second differences,
//! which smooth curvature does not reach.

use super::{GridWorkspace, CONFIRM_STEP};
use crate::camera::Intrinsics;
use crate::preprocess::PyramidLevel;
use glam::Vec3;

/// Normal noise of variance `s^2` along each tangent axis makes two
/// neighbours' normals differ by `|a - b|^2` with mean `4 s^2`, exponentially
/// distributed (two axes), so with median `4 s^2 ln 2`; `s^2` is what noise
/// alone adds to the information along any direction.
const FIRST_DIFFERENCE_TO_VARIANCE: f64 = 1.0 / (4.0 * std::f64::consts::LN_2);

/// As [`FIRST_DIFFERENCE_TO_VARIANCE`] for second differences
/// `|a - 2 b + c|^2` of three neighbours in a line: mean `12 s^2`.
const SECOND_DIFFERENCE_TO_VARIANCE: f64 = 1.0 / (12.0 * std::f64::consts::LN_2);

/// Relative depth step between neighbours taken for a silhouette, not a
/// surface (as `block_average` and the pyramid take it).
const SAME_SURFACE: f32 = 0.05;

/// The information per point that the grid's normal noise alone gives
/// along any direction: from the median squared difference between the
/// normals of 4-neighbouring counted cells on one surface (curvature and
/// creases count as noise here, which makes the grid hold generously; the
/// full resolution confirms). Reads `grid.normals`, `vertices` and
/// `counts`; 0 without neighbours.
pub(super) fn noise_floor_of_grid(grid: &mut GridWorkspace, width: usize) -> f64 {
    let GridWorkspace {
        vertices,
        normals,
        counts,
        differences,
        ..
    } = grid;
    differences.clear();
    let height = vertices.len() / width.max(1);
    let counted = |i: usize| counts[i] > 0 && normals[i] != Vec3::ZERO;
    for v in 0..height {
        for u in 0..width {
            let i = v * width + u;
            if !counted(i) {
                continue;
            }
            let right = (u + 1 < width).then_some(i + 1);
            let below = (v + 1 < height).then_some(i + width);
            for j in [right, below].into_iter().flatten() {
                if counted(j) && on_one_surface(vertices[i].z, vertices[j].z) {
                    differences.push(f64::from((normals[i] - normals[j]).length_squared()));
                }
            }
        }
    }
    median(differences) * FIRST_DIFFERENCE_TO_VARIANCE
}

/// The information per point that the normal noise of `fine` (the finest
/// level, intrinsics `k`) alone gives along any direction: from the median
/// squared second difference of the normals of pixels [`CONFIRM_STEP`]
/// apart in rows and columns, around the sampled pixels where `covered`.
/// 0 without such triples.
pub(super) fn noise_floor_at_full_resolution(
    fine: &PyramidLevel,
    k: &Intrinsics,
    covered: impl Fn(usize, usize) -> bool,
    differences: &mut Vec<f64>,
) -> f64 {
    differences.clear();
    let s = CONFIRM_STEP;
    let (vertices, normals) = (&fine.vertices, &fine.normals);
    let measured = |i: usize| vertices[i].z > 0.0 && normals[i] != Vec3::ZERO;
    for row in (s..k.height.saturating_sub(s)).step_by(s) {
        for col in (s..k.width.saturating_sub(s)).step_by(s) {
            let i = row * k.width + col;
            if !covered(row, col) || !measured(i) {
                continue;
            }
            let z = vertices[i].z;
            for (a, b) in [(i - s, i + s), (i - s * k.width, i + s * k.width)] {
                if measured(a)
                    && measured(b)
                    && on_one_surface(z, vertices[a].z)
                    && on_one_surface(z, vertices[b].z)
                {
                    let d = normals[a] - 2.0 * normals[i] + normals[b];
                    differences.push(f64::from(d.length_squared()));
                }
            }
        }
    }
    median(differences) * SECOND_DIFFERENCE_TO_VARIANCE
}

/// Whether depths `a` and `b` (metres) are close enough to be one surface.
fn on_one_surface(a: f32, b: f32) -> bool {
    (a - b).abs() <= SAME_SURFACE * a
}

/// Median of `values` (reordered), 0 when empty.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let at = values.len() / 2;
    *values.select_nth_unstable_by(at, f64::total_cmp).1
}
