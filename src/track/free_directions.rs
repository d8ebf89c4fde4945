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
//! Noise still poses as information, on the grid too: under i.i.d. depth
//! noise the synthetic loop's wall-and-floor views read 4.4-7.8e-4 per
//! point where clean depth reads 0.9-4e-4, and under structured-light noise
//! (disparity quantised to 1/8 px, as a Kinect v1 measures; its depth comes
//! in terraces) they read 2.1-2.5e-3, as much as views that are not
//! degenerate read under the same noise with the old absolute rule. So the
//! information a direction gets is taken *above the noise floor*: the
//! normals' own scatter, estimated from the frame, is what noise alone
//! would give along any direction (`noise_floor_of_grid`,
//! [`FreeDirections::confirmed`]'s full-resolution one).
//! The grid proposes (its floor counts curvature as noise too, so it holds
//! generously: on TUM fr3/teddy's rounded bear it proposed 37 of 193
//! frames), and the full resolution confirms, with a floor from second
//! differences of the normals, which smooth curvature does not reach
//! (teddy then holds none).
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
use crate::fusion::Prediction;
use crate::preprocess::{normals_into, PyramidLevel};
use crate::se3::NormalEquations;
use crate::se3::RigidF32;
use glam::Vec3;

mod colour;
mod grid;
use grid::{block_average, count_correspondences};
mod noise_floor;
use noise_floor::{noise_floor_at_full_resolution, noise_floor_of_grid};

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
    /// Smallest eigenvalue of the coarse geometry's information per point,
    /// above the grid's noise floor (see the module doc); 0 when the frame
    /// has too few points.
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
    /// Squared normal differences the noise floors are the median of.
    differences: Vec<f64>,
    /// Per sampled model row: the grid cells its correspondences fall in.
    hits: Vec<Vec<u32>>,
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
        let floor = noise_floor_of_grid(grid, width);
        Self::below(&(info / points), floor, threshold)
    }

    /// The eigenvectors of `information` (per point) whose eigenvalue above
    /// `floor` is below `threshold`, as held covectors.
    fn below(information: &nalgebra::Matrix6<f64>, floor: f64, threshold: f64) -> Self {
        let eigen = nalgebra::SymmetricEigen::new(*information);
        let mut free = Self {
            smallest_eigenvalue: (eigen.eigenvalues.min() - floor).max(0.0),
            ..Self::default()
        };
        for (i, value) in eigen.eigenvalues.iter().enumerate() {
            if *value - floor < threshold {
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
    /// leaves free too: whose information per point, above the noise
    /// floor of the full-resolution normals, is below `threshold`.
    ///
    /// The coarse grid averages small structure away: on ICL-NUIM's clean
    /// renderings it read 3e-4..1e-3 per point on views whose full
    /// resolution reads 4e-3 or more, and holding them cost 2 mm a frame;
    /// on TUM fr3/teddy (stride 5) it proposed 11-37 frames whose full
    /// resolution holds 1.2-7.8e-3 above a floor of 1.5e-4. On noisy depth
    /// the full-resolution normals scatter and pose as information (the
    /// synthetic room with i.i.d. Kinect-like noise: 0.048 per point along
    /// a true slide, its floor 0.050; with structured-light noise 0.13,
    /// floor 0.20). The floor is taken from second differences of the
    /// normals (`noise_floor::SECOND_DIFFERENCE_TO_VARIANCE`), which smooth surfaces
    /// do not reach (a mean or median squared difference from the grid's
    /// normals took the structure off too).
    /// Only pixels in grid cells the model covers count, as in
    /// [`Self::of_frame`], whose grid (in `grid`) this reads. `fine` is the
    /// finest pyramid level, `coarsest` the level `of_frame` measured.
    #[must_use]
    pub fn confirmed(
        mut self,
        (fine, coarsest): (&PyramidLevel, &PyramidLevel),
        threshold: f64,
        grid: &mut GridWorkspace,
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
        let covered = |row: usize, col: usize| {
            let cell = (row / block) * grid_width + col / block;
            grid.counts.get(cell).is_some_and(|&c| c > 0)
        };
        let floor = noise_floor_at_full_resolution(fine, &k, covered, &mut grid.differences);
        let mut kept = 0;
        for d in 0..self.count {
            let u = self.directions[d];
            let arm = ROTATION_ARM_M;
            let v = [u[0] / arm, u[1] / arm, u[2] / arm, u[3], u[4], u[5]];
            let (mut information, mut samples) = (0.0f64, 0usize);
            for row in (0..k.height).step_by(CONFIRM_STEP) {
                for col in (0..k.width).step_by(CONFIRM_STEP) {
                    if !covered(row, col) {
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
            if samples < 6 || information / (samples as f64) - floor < threshold {
                self.directions[kept] = u;
                kept += 1;
            }
        }
        self.count = kept;
        self
    }

    /// The directions whose information per point, above the noise floor
    /// of its normals, is below `threshold`, for the organised points of
    /// `level` (camera frame, metres) at the pixels where `counted`: the
    /// geometry of a model prediction as the model-to-model registration
    /// sees it, every `CONFIRM_STEP`-th pixel each way. Fused normals
    /// scatter less than a frame's but still pose as information; the
    /// floor is the full-resolution one of [`Self::confirmed`]. None when
    /// `threshold` is 0 or fewer than 6 points count.
    #[must_use]
    pub fn of_model(
        level: &PyramidLevel,
        counted: impl Fn(usize) -> bool,
        threshold: f64,
        differences: &mut Vec<f64>,
    ) -> Self {
        let Some(k) = level.intrinsics else {
            return Self::default();
        };
        let n = k.pixel_count();
        if threshold <= 0.0 || level.vertices.len() != n || level.normals.len() != n {
            return Self::default();
        }
        let mut info = nalgebra::Matrix6::<f64>::zeros();
        let mut points = 0.0f64;
        for row in (0..k.height).step_by(CONFIRM_STEP) {
            for col in (0..k.width).step_by(CONFIRM_STEP) {
                let i = row * k.width + col;
                let (q, n) = (level.vertices[i], level.normals[i]);
                if q.z <= 0.0 || n == Vec3::ZERO || !counted(i) {
                    continue;
                }
                let c = q.as_dvec3().cross(n.as_dvec3()) * ROTATION_ARM_M.recip();
                let n = n.as_dvec3();
                let row = nalgebra::Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
                info += row * row.transpose();
                points += 1.0;
            }
        }
        if points < 6.0 || !info.iter().all(|v| v.is_finite()) {
            return Self::default();
        }
        let floor = noise_floor_at_full_resolution(
            level,
            &k,
            |row, col| counted(row * k.width + col),
            differences,
        );
        let mut free = Self::below(&(info / points), floor, threshold);
        free.orthonormalise();
        free
    }

    /// The motions `system` pins poorly: the eigenvectors `v` of its
    /// unit-diagonal scaling (as [`NormalEquations::conditioning`] takes
    /// it) whose eigenvalue is below `ratio` times the largest, as the
    /// covectors `D v` (`D` the scaling) that hold exactly that motion.
    /// A diagonal below a millionth of the largest is scaled as that, so a
    /// motion with no information at all is not scaled up into one.
    /// Used where the frame's own measure of free directions missed a
    /// slide the final system shows.
    #[must_use]
    pub fn weak_in(system: &NormalEquations, ratio: f64) -> Self {
        let m = system.full_matrix();
        if !m.iter().flatten().all(|v| v.is_finite()) {
            return Self::default();
        }
        let largest_diagonal = (0..6).map(|i| m[i][i]).fold(0.0, f64::max);
        let floor = (1e-6 * largest_diagonal).max(1e-300);
        let d: [f64; 6] = std::array::from_fn(|i| m[i][i].max(floor).sqrt());
        let scaled = nalgebra::Matrix6::from_fn(|r, c| m[r][c] / (d[r] * d[c]));
        let eigen = nalgebra::SymmetricEigen::new(scaled);
        let largest = eigen.eigenvalues.max();
        let mut weak = Self::default();
        if !(largest > 0.0 && largest.is_finite()) {
            return weak;
        }
        for (i, &value) in eigen.eigenvalues.iter().enumerate() {
            if value < ratio * largest {
                let v = eigen.eigenvectors.column(i);
                weak.directions[weak.count] = std::array::from_fn(|r| d[r] * v[r]);
                weak.count += 1;
            }
        }
        weak.orthonormalise();
        weak
    }

    /// These directions and `other`'s, at most six.
    #[must_use]
    pub fn with(&self, other: &Self) -> Self {
        let mut all = *self;
        for u in &other.directions[..other.count] {
            if all.count < 6 {
                all.directions[all.count] = *u;
                all.count += 1;
            }
        }
        all.orthonormalise();
        all
    }

    /// Length of `twist`'s part along the held directions (metres, with
    /// rotations in radians at 1 m, as the directions are measured).
    #[must_use]
    pub fn length_along(&self, twist: &[f64; 6]) -> f64 {
        self.directions[..self.count]
            .iter()
            .map(|u| {
                let along: f64 = u.iter().zip(twist).map(|(a, b)| a * b).sum();
                along * along
            })
            .sum::<f64>()
            .sqrt()
    }

    /// `twist` without its part along the held directions (metres, with
    /// rotations in radians at 1 m, as [`Self::length_along`] measures it).
    #[must_use]
    pub fn removed_from(&self, twist: &[f64; 6]) -> [f64; 6] {
        let mut kept = *twist;
        for u in &self.directions[..self.count] {
            let along: f64 = u.iter().zip(&kept).map(|(a, b)| a * b).sum();
            for (x, y) in kept.iter_mut().zip(u) {
                *x -= along * y;
            }
        }
        kept
    }

    /// Gram-Schmidt over the held covectors; a dependent one is dropped.
    fn orthonormalise(&mut self) {
        let mut kept = 0;
        for i in 0..self.count {
            let mut u = self.directions[i];
            for k in 0..kept {
                let b: [f64; 6] = self.directions[k];
                let along: f64 = u.iter().zip(&b).map(|(x, y)| x * y).sum();
                for (x, y) in u.iter_mut().zip(&b) {
                    *x -= along * y;
                }
            }
            let norm = u.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 1e-9 {
                self.directions[kept] = u.map(|x| x / norm);
                kept += 1;
            }
        }
        self.count = kept;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
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

    /// The point-to-plane system, rows `[q x n, n]`, of every pixel of a
    /// view of `planes`.
    fn system(planes: &[(Vec3, f32)]) -> NormalEquations {
        let (level, model) = view(planes, |_, _| true);
        let mut system = NormalEquations::default();
        for (q, n) in level.vertices.iter().zip(&model.normals) {
            if q.z > 0.0 && q.is_finite() && *n != Vec3::ZERO {
                let c = q.cross(*n);
                system.add(&[c.x, c.y, c.z, n.x, n.y, n.z], 0.0, 1.0);
            }
        }
        system
    }

    #[test]
    fn the_final_system_shows_the_slide_along_a_join_as_weak() {
        let weak = FreeDirections::weak_in(&system(&[WALL, FLOOR]), 2e-3);
        assert_eq!(weak.count(), 1);
        let slide = weak.length_along(&[0.0, 0.0, 0.0, 0.05, 0.0, 0.0]);
        assert!((slide - 0.05).abs() < 0.005, "{slide}");
        let into_the_wall = weak.length_along(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.05]);
        assert!(into_the_wall < 0.005, "{into_the_wall}");
        let pinned = FreeDirections::weak_in(&system(&[WALL, FLOOR, SIDE_WALL]), 2e-3);
        assert_eq!(pinned.count(), 0);
        assert_eq!(pinned.length_along(&[0.1; 6]), 0.0);
    }

    #[test]
    fn directions_combined_twice_count_once() {
        let wall = FreeDirections::weak_in(&system(&[WALL]), 2e-3);
        assert_eq!(wall.count(), 3);
        let join = FreeDirections::weak_in(&system(&[WALL, FLOOR]), 2e-3);
        // The join's slide is one of the wall's three.
        assert_eq!(wall.with(&join).count(), 3);
        assert_eq!(join.with(&FreeDirections::default()).count(), 1);
        let empty = NormalEquations::default();
        assert_eq!(FreeDirections::weak_in(&empty, 2e-3).count(), 0);
        let mut broken = system(&[WALL, FLOOR]);
        broken.a[0][3] = f64::NAN;
        assert_eq!(FreeDirections::weak_in(&broken, 2e-3).count(), 0);
    }

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

    /// `level` with every depth scaled by a factor drawn from
    /// `1 +- sigma` (uniform), as depth noise moves points along their rays.
    fn with_depth_noise(level: &PyramidLevel, sigma: f32) -> PyramidLevel {
        let mut random = crate::random::SplitMix::new(7);
        let mut noisy = level.clone();
        for p in &mut noisy.vertices {
            *p *= 1.0 + sigma * (2.0 * random.next_f32() - 1.0);
        }
        noisy
    }

    #[test]
    fn noise_lifts_the_floor_and_the_slide_stays_held() {
        let (level, model) = view(&[WALL, FLOOR], |_, _| true);
        let mut grid = GridWorkspace::default();
        let at = (&identity(), &GATES);
        let clean = FreeDirections::of_frame(&level, &model, at, 1e-3, &mut grid);
        assert!(noise_floor_of_grid(&mut grid, 80) < 1e-9);
        let noisy_level = with_depth_noise(&level, 0.004);
        let noisy = FreeDirections::of_frame(&noisy_level, &model, at, 1e-3, &mut grid);
        let floor = noise_floor_of_grid(&mut grid, 80);
        assert!(floor > 1e-4, "floor {floor:e}");
        assert_eq!(
            (clean.count(), noisy.count()),
            (1, 1),
            "{clean:?} {noisy:?}"
        );
        assert!(noisy.directions[0][3].abs() > 0.95, "{noisy:?}");
    }

    #[test]
    fn the_full_resolution_floor_is_blind_to_smooth_curvature() {
        // A cylinder's normals turn steadily: first differences see the
        // turn, second differences do not.
        let k = Intrinsics::new(150.0, 150.0, 79.5, 59.5, 160, 120);
        let (radius, axis_z) = (0.5f32, 1.5f32);
        let mut level = PyramidLevel {
            intrinsics: Some(k),
            vertices: vec![Vec3::ZERO; k.pixel_count()],
            normals: vec![Vec3::ZERO; k.pixel_count()],
            ..PyramidLevel::default()
        };
        for v in 0..k.height {
            for u in 0..k.width {
                let ray = k.back_project(u as f32, v as f32, 1.0);
                // Nearest hit of the ray with the cylinder x^2 + (z - axis_z)^2 = r^2.
                let (a, b) = (ray.x * ray.x + ray.z * ray.z, -2.0 * axis_z * ray.z);
                let c = axis_z * axis_z - radius * radius;
                let disc = b * b - 4.0 * a * c;
                if disc <= 0.0 {
                    continue;
                }
                let t = (-b - disc.sqrt()) / (2.0 * a);
                let p = ray * t;
                let i = v * k.width + u;
                level.vertices[i] = p;
                level.normals[i] = Vec3::new(p.x, 0.0, p.z - axis_z).normalize();
            }
        }
        let mut differences = Vec::new();
        let all = |_: usize, _: usize| true;
        let floor = noise_floor_at_full_resolution(&level, &k, all, &mut differences);
        assert!(floor < 1e-6, "smooth: {floor:e}");
        let noisy = with_depth_noise(&level, 0.004);
        let mut noisy_normals = vec![Vec3::ZERO; k.pixel_count()];
        normals_into(&noisy.vertices, k.width, &mut noisy_normals);
        let noisy = PyramidLevel {
            normals: noisy_normals,
            ..noisy
        };
        let floor = noise_floor_at_full_resolution(&noisy, &k, all, &mut differences);
        assert!(floor > 1e-3, "noisy: {floor:e}");
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
