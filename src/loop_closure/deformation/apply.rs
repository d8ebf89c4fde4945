//! Moving points, normals and poses by an optimised graph: each point
//! blends the corrections of its nodes (nearest in space among those
//! nearest in time), in `f32` for the map's many surfels, in `f64` for
//! poses.

use glam::{DAffine3, DMat3, DVec3, Mat3, Vec3};
use rayon::prelude::*;

use super::{DeformError, DeformationGraph};

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
    /// with the surfaces seen then: its centre as a point, its orientation
    /// by the weighted node rotations (projected to the nearest rotation).
    /// Non-finite poses and identity graphs return `world_from_camera`.
    #[must_use]
    pub fn apply_to_pose(&self, world_from_camera: &DAffine3, time: u32) -> DAffine3 {
        let centre = world_from_camera.translation;
        if self.is_empty() || self.is_identity() || !centre.is_finite() {
            return *world_from_camera;
        }
        let c32 = centre.as_vec3();
        let inf = self.influence(c32, time);
        let mut dp = DVec3::ZERO;
        let mut blend = DMat3::ZERO;
        for i in 0..inf.count {
            let j = inf.nodes[i] as usize;
            let w = f64::from(inf.weights[i]);
            let g = self.nodes[j].position.as_dvec3();
            let r = self.corrections.rotation[j];
            dp += w * ((r - DMat3::IDENTITY) * (centre - g) + self.corrections.translation[j]);
            blend += r * w;
        }
        let rotation = nearest_rotation(&blend);
        let moved =
            DAffine3::from_mat3_translation(rotation * world_from_camera.matrix3, centre + dp);
        if moved.is_finite() {
            moved
        } else {
            *world_from_camera
        }
    }
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
