//! Moving points, normals and poses by an optimised graph: each point
//! blends the corrections of its nodes (nearest in space among those
//! nearest in time), in `f32` for the map's many surfels, in `f64` for
//! poses.

use glam::{DAffine3, DMat3, DVec3, Mat3, Vec3};
use rayon::prelude::*;

use super::{DeformError, DeformationGraph};
use crate::features::rigid::fit_rigid;

/// The `f32` form of the corrections used to move many points: `R - I`,
/// `R⁻ᵀ - I` (normals) and `t`, so the identity moves nothing exactly.
struct Applied {
    position_delta: Vec<Mat3>,
    normal_delta: Vec<Mat3>,
    translation: Vec<Vec3>,
}

impl DeformationGraph {
    fn applied(&self) -> Applied {
        let c = &self.corrections;
        let position_delta = c
            .rotation
            .iter()
            .map(|r| (*r - DMat3::IDENTITY).as_mat3())
            .collect();
        let normal_delta = c
            .rotation
            .iter()
            .map(|r| {
                // Normals move by the inverse transpose; an accepted graph's
                // matrices are near rotations, so the inverse exists.
                let inv_t = if r.determinant().abs() > 1e-9 {
                    r.inverse().transpose()
                } else {
                    *r
                };
                (inv_t - DMat3::IDENTITY).as_mat3()
            })
            .collect();
        let translation = c.translation.iter().map(|t| t.as_vec3()).collect();
        Applied {
            position_delta,
            normal_delta,
            translation,
        }
    }

    /// Moves points (world frame, metres) observed at `times` (frame
    /// indices) by the graph, in parallel: `p' = Σ wⱼ [Rⱼ (p - gⱼ) + gⱼ + tⱼ]`,
    /// `n' = normalise(Σ wⱼ Rⱼ⁻ᵀ n)`. `normals` is either empty (positions
    /// only) or as long as `positions`. Non-finite points are left alone, and
    /// an identity graph moves nothing (bit for bit). Times outside the
    /// graph use the nodes nearest in time.
    ///
    /// # Errors
    /// [`DeformError::LengthMismatch`] (nothing is moved).
    pub fn apply_to_points(
        &self,
        positions: &mut [Vec3],
        normals: &mut [Vec3],
        times: &[u32],
    ) -> Result<(), DeformError> {
        if times.len() != positions.len() {
            return Err(DeformError::LengthMismatch {
                positions: positions.len(),
                other: times.len(),
            });
        }
        if !normals.is_empty() && normals.len() != positions.len() {
            return Err(DeformError::LengthMismatch {
                positions: positions.len(),
                other: normals.len(),
            });
        }
        if self.is_identity() || self.is_empty() {
            return Ok(());
        }
        let applied = self.applied();
        const CHUNK: usize = 4096;
        if normals.is_empty() {
            positions
                .par_chunks_mut(CHUNK)
                .zip(times.par_chunks(CHUNK))
                .for_each(|(ps, ts)| {
                    for (p, &t) in ps.iter_mut().zip(ts) {
                        self.move_point(&applied, p, None, t);
                    }
                });
        } else {
            positions
                .par_chunks_mut(CHUNK)
                .zip(normals.par_chunks_mut(CHUNK))
                .zip(times.par_chunks(CHUNK))
                .for_each(|((ps, ns), ts)| {
                    for ((p, n), &t) in ps.iter_mut().zip(ns.iter_mut()).zip(ts) {
                        self.move_point(&applied, p, Some(n), t);
                    }
                });
        }
        Ok(())
    }

    fn move_point(&self, applied: &Applied, p: &mut Vec3, n: Option<&mut Vec3>, t: u32) {
        if !p.is_finite() {
            return;
        }
        let inf = self.influence(*p, t);
        let mut dp = Vec3::ZERO;
        let mut dn = Vec3::ZERO;
        let normal = n.as_deref().copied().unwrap_or(Vec3::ZERO);
        for i in 0..inf.count {
            let j = inf.nodes[i] as usize;
            let w = inf.weights[i];
            dp += w
                * (applied.position_delta[j] * (*p - self.nodes[j].position)
                    + applied.translation[j]);
            dn += w * (applied.normal_delta[j] * normal);
        }
        *p += dp;
        if let Some(n) = n {
            if dn != Vec3::ZERO && n.is_finite() {
                let moved = (*n + dn).normalize_or_zero();
                if moved != Vec3::ZERO {
                    *n = moved;
                }
            }
        }
    }

    /// A camera pose (`world_from_camera`, metres) of frame `time`, moved
    /// as the surfaces it saw: the nodes of its time (the candidates of
    /// `time`) that lie in its view are moved as the surfels they were
    /// sampled from, and the pose takes the rigid motion that fits theirs
    /// best. The camera centre lies metres from those surfaces; moved as a
    /// point by the nodes nearest to it, a node's small rotation about its
    /// own surface would swing the centre by the lever arm. With fewer than
    /// three nodes in view, or all on a line, the centre is moved as a point
    /// and the orientation by the blended node rotations. Non-finite poses
    /// and identity graphs return `world_from_camera`.
    #[must_use]
    pub fn apply_to_pose(&self, world_from_camera: &DAffine3, time: u32) -> DAffine3 {
        if self.is_empty() || self.is_identity() || !world_from_camera.is_finite() {
            return *world_from_camera;
        }
        let moved = match self.seen_motion(world_from_camera, time) {
            Some(motion) => motion * *world_from_camera,
            None => self.centre_motion(world_from_camera, time),
        };
        if moved.is_finite() {
            moved
        } else {
            *world_from_camera
        }
    }

    /// The rigid motion of the nodes of `time` in the view of
    /// `world_from_camera`, when at least three not on a line are.
    fn seen_motion(&self, world_from_camera: &DAffine3, time: u32) -> Option<DAffine3> {
        let camera_from_world = world_from_camera.inverse();
        let (lo, hi) = self.candidates(time);
        let mut before = Vec::with_capacity(hi - lo);
        let mut after = Vec::with_capacity(hi - lo);
        for node in &self.nodes[lo..hi] {
            let g = node.position.as_dvec3();
            let c = camera_from_world.transform_point3(g);
            let in_view = c.z > MIN_VIEW_DEPTH_M
                && c.x.abs() <= VIEW_HALF_WIDTH * c.z
                && c.y.abs() <= VIEW_HALF_WIDTH * c.z;
            if in_view {
                before.push(g);
                after.push(g + self.displacement(g, node.time));
            }
        }
        if before.len() < 3 || !spread_in_a_plane(&before) {
            return None;
        }
        // `after ~ motion * before`.
        fit_rigid(after.iter().copied().zip(before.iter().copied()))
    }

    /// The pose moved as ElasticFusion moves it: its centre as a point,
    /// its orientation by the weighted node rotations (projected to the
    /// nearest rotation).
    fn centre_motion(&self, world_from_camera: &DAffine3, time: u32) -> DAffine3 {
        let centre = world_from_camera.translation;
        let inf = self.influence(centre.as_vec3(), time);
        let mut blend = DMat3::ZERO;
        for i in 0..inf.count {
            let j = inf.nodes[i] as usize;
            blend += self.corrections.rotation[j] * f64::from(inf.weights[i]);
        }
        let rotation = nearest_rotation(&blend);
        DAffine3::from_mat3_translation(
            rotation * world_from_camera.matrix3,
            centre + self.displacement(centre, time),
        )
    }

    /// How far the graph moves point `p` (world frame, metres) observed at
    /// frame `time`, in `f64`.
    fn displacement(&self, p: DVec3, time: u32) -> DVec3 {
        let inf = self.influence(p.as_vec3(), time);
        let mut dp = DVec3::ZERO;
        for i in 0..inf.count {
            let j = inf.nodes[i] as usize;
            let w = f64::from(inf.weights[i]);
            let g = self.nodes[j].position.as_dvec3();
            let r = self.corrections.rotation[j];
            dp += w * ((r - DMat3::IDENTITY) * (p - g) + self.corrections.translation[j]);
        }
        dp
    }
}

/// Nearest a node in view may be, metres.
const MIN_VIEW_DEPTH_M: f64 = 0.1;

/// `|x| / z` and `|y| / z` at most of a node in view: a little wider than a
/// Kinect's field of view (0.55 and 0.41), since the pose is not exact.
const VIEW_HALF_WIDTH: f64 = 0.7;

/// Whether `points` span two dimensions (not all near one line): the second
/// largest spread is at least a tenth of the largest.
fn spread_in_a_plane(points: &[DVec3]) -> bool {
    let n = points.len().max(1) as f64;
    let mean = points.iter().copied().sum::<DVec3>() / n;
    let mut cov = DMat3::ZERO;
    for p in points {
        let d = *p - mean;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let a = nalgebra::Matrix3::from_fn(|r, c| cov.col(c)[r]);
    let mut values: Vec<f64> = a.symmetric_eigenvalues().iter().copied().collect();
    values.sort_by(|x, y| y.total_cmp(x));
    values[0] > 0.0 && values[1] >= 0.01 * values[0]
}

/// The rotation nearest to `m` (polar decomposition by SVD, reflections
/// flipped); the identity when `m` is degenerate.
fn nearest_rotation(m: &DMat3) -> DMat3 {
    let a = nalgebra::Matrix3::from_fn(|r, c| m.col(c)[r]);
    let svd = a.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return DMat3::IDENTITY;
    };
    let mut u = u;
    if (u * v_t).determinant() < 0.0 {
        u.column_mut(2).neg_mut();
    }
    let r = u * v_t;
    let out = crate::se3::dmat3_from_nalgebra(&r);
    if out.is_finite() {
        out
    } else {
        DMat3::IDENTITY
    }
}
