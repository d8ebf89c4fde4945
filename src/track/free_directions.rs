//! Directions of camera motion that the frame's geometry leaves free.
//!
//! Point-to-plane ICP constrains a motion only through the surface normals:
//! a flat wall leaves the motions within it free, a wall meeting a floor the
//! slide along their join. The information `sum J^T J` with rows
//! `J = [q x n, n]` (measured point `q` and normal `n`, camera frame, metres)
//! shows such directions as near-zero eigenvalues, but only with honest
//! normals. With Kinect-class depth noise the full-resolution normals scatter
//! by several degrees and fill a free direction with information the data do
//! not hold: the synthetic room's wall-and-floor view (`examples/noisy_loop.rs`,
//! frame 62) reads 0.008 per point with noise, as well-constrained views do,
//! against 0.00004 without. On a coarse grid (at most [`GRID_COLUMNS`]
//! columns, vertices block-averaged, so normals span a wide baseline of
//! averaged depth) the same view reads 0.0004-0.0007 with noise.
//!
//! Only geometry ICP can use counts: each grid cell is weighted by the
//! correspondences it gets at the start pose (the box that pins the slide
//! is in the frame but not yet stable in the model; right after the
//! warm-up a noisy model is sparse, and a cell half covered still
//! constrains as much as its correspondences).
//!
//! Eigenvalues are per correspondence, with rotations expressed as the
//! displacement they cause [`ROTATION_ARM_M`] from the camera (twist
//! coordinates `[w, t]` with `w` in metres at 1 m): an eigenvalue is the
//! mean squared component of the normals along that motion. A direction
//! below the threshold is *held*: the tracker's steps get no component
//! along it, so the estimate keeps its start there instead of sliding on
//! noise. The pipeline starts at the motion prior and, for a frame that
//! held a direction, again at the sparse feature estimate with the same
//! directions held ([`super::track_holding`]).

use super::icp::IcpGates;
use crate::camera::Intrinsics;
use crate::fusion::Prediction;
use crate::preprocess::{normals_into, PyramidLevel};
use crate::se3::NormalEquations;
use crate::se3::RigidF32;
use glam::Vec3;

/// Columns of the grid the geometry is measured on.
pub const GRID_COLUMNS: usize = 80;

/// Lever arm that puts rotations in metres: a rotation of `w` radians
/// counts as a displacement of `w * ROTATION_ARM_M`. With 2 m, the roll
/// about the optical axis of TUM fr3/teddy's first views (a rounded
/// object in the middle of the image) read 0.0008-0.001 and was held; with
/// 1 m its smallest is 0.0028 and ICL-NUIM kt0's 0.0083, while the noisy
/// synthetic loop's slide (a translation) reads the same.
pub const ROTATION_ARM_M: f64 = 1.0;

/// How much stiffer than the system's mean diagonal a held direction is made.
const HOLD_STIFFNESS: f64 = 1e6;

/// The directions held for one frame (as the covectors `u` that a step
/// `x = [w, t]`, camera-frame twist, must satisfy `u . x = 0` for), and the
/// geometry's smallest eigenvalue per point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FreeDirections {
    directions: [[f64; 6]; 6],
    count: usize,
    /// Smallest eigenvalue of the coarse geometry's information per point
    /// (see the module doc); 0 when the frame has too few points.
    pub smallest_eigenvalue: f64,
}

/// Reusable buffers of the coarse grid.
#[derive(Debug, Clone, Default)]
pub struct GridWorkspace {
    vertices: Vec<Vec3>,
    normals: Vec<Vec3>,
    /// Correspondences per grid cell.
    counts: Vec<u32>,
    /// Grid columns and block size (coarsest-level pixels) of `counts`.
    shape: (usize, usize),
}

/// Full-resolution pixels sampled by the confirmation, every this many
/// each way.
const CONFIRM_STEP: usize = 2;

impl FreeDirections {
    /// The directions whose eigenvalue per point is below `threshold`, for
    /// the geometry of `level` (the frame's coarsest pyramid level) where
    /// ICP can find correspondences: each grid cell counts as many times as
    /// model pixels (every second one each way) land in it at the start
    /// pose `camera_from_world` within `gates`' distance and normal gates
    /// of its averaged point and normal. A box just entering the view is
    /// not yet in the model and counts nothing; a sparsely modelled wall
    /// counts as much as its correspondences. None when `threshold` is 0
    /// or fewer than 6 correspondences count.
    #[must_use]
    pub fn of_frame(
        level: &PyramidLevel,
        model: &Prediction,
        (camera_from_world, gates): (&RigidF32, &IcpGates),
        threshold: f64,
        grid: &mut GridWorkspace,
    ) -> Self {
        let (Some(k), Some(mk)) = (level.intrinsics, model.intrinsics) else {
            return Self::default();
        };
        if threshold <= 0.0 || k.width == 0 {
            return Self::default();
        }
        let (width, factor) = block_average(&level.vertices, k.width, grid);
        grid.shape = (width, factor);
        grid.normals.resize(grid.vertices.len(), Vec3::ZERO);
        normals_into(&grid.vertices, width, &mut grid.normals);
        count_correspondences(
            model,
            &mk,
            (&k, width, factor),
            camera_from_world,
            gates,
            grid,
        );
        let mut info = nalgebra::Matrix6::<f64>::zeros();
        let mut points = 0.0f64;
        for ((q, n), &count) in grid.vertices.iter().zip(&grid.normals).zip(&grid.counts) {
            if *n == Vec3::ZERO || count == 0 {
                continue;
            }
            let c = q.as_dvec3().cross(n.as_dvec3()) * ROTATION_ARM_M.recip();
            let n = n.as_dvec3();
            let row = nalgebra::Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
            info += row * row.transpose() * f64::from(count);
            points += f64::from(count);
        }
        // A non-finite sum would keep the eigen solver iterating forever.
        if points < 6.0 || !info.iter().all(|v| v.is_finite()) {
            return Self::default();
        }
        let eigen = nalgebra::SymmetricEigen::new(info / points);
        let mut free = Self {
            smallest_eigenvalue: eigen.eigenvalues.min().max(0.0),
            ..Self::default()
        };
        for (i, value) in eigen.eigenvalues.iter().enumerate() {
            if *value < threshold {
                let v = eigen.eigenvectors.column(i);
                // The step `x = [w, t]` is held by `u . x = 0` with
                // `u = [ARM v_w, v_t]`: no component along `v` in `[ARM w, t]`.
                let s = ROTATION_ARM_M;
                free.directions[free.count] = [v[0] * s, v[1] * s, v[2] * s, v[3], v[4], v[5]];
                free.count += 1;
            }
        }
        free
    }

    /// Keeps only the held directions that the full-resolution geometry
    /// leaves free too; for clean (rendered) depth only, whose
    /// full-resolution normals are honest.
    ///
    /// The coarse grid averages small structure away: on ICL-NUIM's clean
    /// renderings it read 3e-4..1e-3 per point on views whose full
    /// resolution reads 4e-3 or more, and holding them cost 2 mm a frame.
    /// On noisy depth the full-resolution normals scatter and pose as
    /// information (the synthetic room with Kinect noise: 0.048 per point
    /// along a true slide); the scatter could not be told apart from small
    /// structure there (taking off the mean squared difference from the
    /// grid's normals takes off the structure too; its median, 0.042,
    /// misses the heavy tail), so noisy depth keeps the grid's answer.
    /// Only pixels in grid cells the model covers count, as in
    /// [`Self::of_frame`], whose grid (in `grid`) this reads. `fine` is the
    /// finest pyramid level, `coarsest` the level `of_frame` measured.
    #[must_use]
    pub fn confirmed(
        mut self,
        (fine, coarsest): (&PyramidLevel, &PyramidLevel),
        threshold: f64,
        grid: &GridWorkspace,
    ) -> Self {
        let (Some(k), Some(kg)) = (fine.intrinsics, coarsest.intrinsics) else {
            return self;
        };
        let (grid_width, factor) = grid.shape;
        if self.count == 0
            || fine.normals.len() != k.pixel_count()
            || kg.width == 0
            || grid_width == 0
        {
            return self;
        }
        let block = (k.width / kg.width).max(1) * factor.max(1);
        let mut kept = 0;
        for d in 0..self.count {
            let u = self.directions[d];
            let arm = ROTATION_ARM_M;
            let v = [u[0] / arm, u[1] / arm, u[2] / arm, u[3], u[4], u[5]];
            let (mut information, mut samples) = (0.0f64, 0usize);
            for row in (0..k.height).step_by(CONFIRM_STEP) {
                for col in (0..k.width).step_by(CONFIRM_STEP) {
                    let cell = (row / block) * grid_width + col / block;
                    if grid.counts.get(cell).is_none_or(|&c| c == 0) {
                        continue;
                    }
                    let i = row * k.width + col;
                    let (q, n) = (fine.vertices[i], fine.normals[i]);
                    if q.z <= 0.0 || n == Vec3::ZERO {
                        continue;
                    }
                    let c = q.as_dvec3().cross(n.as_dvec3());
                    let n = n.as_dvec3();
                    let j_v =
                        c.x * v[0] + c.y * v[1] + c.z * v[2] + n.x * v[3] + n.y * v[4] + n.z * v[5];
                    information += j_v * j_v;
                    samples += 1;
                }
            }
            if samples < 6 || information / (samples as f64) < threshold {
                self.directions[kept] = u;
                kept += 1;
            }
        }
        self.count = kept;
        self
    }

    /// Number of held directions (0..=6).
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// `system` made stiff along every held direction, so that its step
    /// has no component there.
    #[must_use]
    pub fn held(&self, system: &NormalEquations) -> NormalEquations {
        self.pinned(system, HOLD_STIFFNESS)
    }

    /// `system` with every held direction given `stiffness` times its mean
    /// diagonal: with 1, a held direction counts as an ordinary one, so the
    /// conditioning judges only the directions that were solved.
    #[must_use]
    pub fn pinned(&self, system: &NormalEquations, stiffness: f64) -> NormalEquations {
        let mut held = *system;
        if self.count == 0 {
            return held;
        }
        let mean_diagonal = (0..6).map(|i| system.a[i][i]).sum::<f64>() / 6.0;
        let stiffness = stiffness * mean_diagonal.max(f64::MIN_POSITIVE);
        for u in &self.directions[..self.count] {
            for r in 0..6 {
                for c in r..6 {
                    held.a[r][c] += stiffness * u[r] * u[c];
                }
            }
        }
        held
    }
}

/// Counts into `grid.counts`, per grid cell (`width` columns, `factor`
/// pixels of level `k` square), the model pixels (every second one each
/// way) that `camera_from_world` puts in it within `gates` of the cell's
/// averaged point and normal.
fn count_correspondences(
    model: &Prediction,
    mk: &Intrinsics,
    (k, width, factor): (&Intrinsics, usize, usize),
    camera_from_world: &RigidF32,
    gates: &IcpGates,
    grid: &mut GridWorkspace,
) {
    grid.counts.clear();
    grid.counts.resize(grid.vertices.len(), 0);
    let height = grid.vertices.len() / width.max(1);
    let cos_gate = libm::cosf(gates.normal_gate_deg.to_radians());
    for v in (0..mk.height).step_by(2) {
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
            let (q, n) = (grid.vertices[g], grid.normals[g]);
            if n != Vec3::ZERO
                && (p - q).length() <= gates.distance_gate_m
                && camera_from_world.vector(normal).dot(n) >= cos_gate
            {
                grid.counts[g] += 1;
            }
        }
    }
}

/// Averages `vertices` (`width` columns) over square blocks so that at most
/// [`GRID_COLUMNS`] remain, into `grid.vertices`; returns the grid's width
/// and the block size.
/// A block averages the valid vertices within 5 % of its first valid
/// one's depth (as the pyramid does), so silhouettes are not bridged.
fn block_average(vertices: &[Vec3], width: usize, grid: &mut GridWorkspace) -> (usize, usize) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::back_project_into;

    /// A 160x120 view (the grid averages it 2x2 down to 80x60) of the
    /// planes `(n, d)` (points with `n . p = d`, camera frame), each ray
    /// hitting the nearest; and a model prediction holding every pixel
    /// where `modelled(u, v)`.
    fn view(
        planes: &[(Vec3, f32)],
        modelled: impl Fn(usize, usize) -> bool,
    ) -> (PyramidLevel, Prediction) {
        let k = Intrinsics::new(150.0, 150.0, 79.5, 59.5, 160, 120);
        let mut depth = vec![0.0; k.pixel_count()];
        for v in 0..k.height {
            for u in 0..k.width {
                let ray = k.back_project(u as f32, v as f32, 1.0);
                depth[v * k.width + u] = planes
                    .iter()
                    .filter_map(|(n, d)| {
                        let t = d / n.dot(ray);
                        (t > 0.0).then_some(t)
                    })
                    .fold(f32::INFINITY, f32::min);
            }
        }
        let mut vertices = vec![Vec3::ZERO; k.pixel_count()];
        back_project_into(&k, &depth, &mut vertices);
        let level = PyramidLevel {
            intrinsics: Some(k),
            vertices,
            ..PyramidLevel::default()
        };
        // The model: the same surfaces, seen from the same (identity) pose.
        let mut normals = vec![Vec3::ZERO; k.pixel_count()];
        normals_into(&level.vertices, k.width, &mut normals);
        let mut model = Prediction::new(false);
        model.intrinsics = Some(k);
        model.vertices = level.vertices.clone();
        model.normals = (0..k.pixel_count())
            .map(|i| {
                if modelled(i % k.width, i / k.width) {
                    normals[i]
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        (level, model)
    }

    fn identity() -> RigidF32 {
        RigidF32::from_affine(&glam::DAffine3::IDENTITY)
    }

    const GATES: IcpGates = IcpGates {
        distance_gate_m: 0.1,
        normal_gate_deg: 20.0,
        huber_m: 0.02,
    };

    fn free(planes: &[(Vec3, f32)], modelled: impl Fn(usize, usize) -> bool) -> FreeDirections {
        let (level, model) = view(planes, modelled);
        FreeDirections::of_frame(
            &level,
            &model,
            (&identity(), &GATES),
            1e-3,
            &mut GridWorkspace::default(),
        )
    }

    const WALL: (Vec3, f32) = (Vec3::Z, 2.0);
    const FLOOR: (Vec3, f32) = (Vec3::Y, 0.5);
    const SIDE_WALL: (Vec3, f32) = (Vec3::X, 0.6);

    #[test]
    fn a_wall_leaves_three_directions_free() {
        let f = free(&[WALL], |_, _| true);
        assert_eq!(f.count(), 3, "{f:?}");
        assert!(f.smallest_eigenvalue < 1e-9);
    }

    #[test]
    fn a_wall_and_the_floor_leave_the_slide_along_their_join() {
        let f = free(&[WALL, FLOOR], |_, _| true);
        assert_eq!(f.count(), 1, "{f:?}");
        let u = f.directions[0];
        assert!(u[3].abs() > 0.99, "held along x (the join): {u:?}");
        // Held: a step along the join costs a million times more than before.
        let mut system = NormalEquations::default();
        for j in [
            [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            [1.0; 6],
        ] {
            system.add(&j, 0.1, 1.0);
        }
        let held = f.held(&system);
        assert!(held.a[3][3] > 1e5 * system.a[3][3]);
    }

    #[test]
    fn three_walls_pin_every_direction() {
        let f = free(&[WALL, FLOOR, SIDE_WALL], |_, _| true);
        assert_eq!(f.count(), 0, "{f:?}");
        assert!(f.smallest_eigenvalue > 1e-3);
    }

    #[test]
    fn structure_the_model_does_not_hold_yet_does_not_count() {
        // The floor is in view but not yet in the model: the wall alone.
        let f = free(&[WALL, FLOOR], |_, v| v < 50);
        assert_eq!(f.count(), 3, "{f:?}");
    }

    #[test]
    fn threshold_zero_or_an_empty_view_holds_nothing() {
        let (level, model) = view(&[WALL], |_, _| true);
        let mut grid = GridWorkspace::default();
        let t = identity();
        let start = (&t, &GATES);
        assert_eq!(
            FreeDirections::of_frame(&level, &model, start, 0.0, &mut grid).count(),
            0
        );
        let empty = PyramidLevel::default();
        assert_eq!(
            FreeDirections::of_frame(&empty, &model, start, 1e-3, &mut grid).count(),
            0
        );
        let none = FreeDirections::default();
        let system = NormalEquations::default();
        assert_eq!(none.held(&system).a, system.a);
    }
}
