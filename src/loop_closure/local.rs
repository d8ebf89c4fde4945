//! Local loop closure, model to model (ElasticFusion's "local loop"): the
//! active model and the inactive model, both predicted from the current
//! pose, are registered with the tracker's point-to-plane ICP. Where the
//! camera returns to a place mapped more than an active window ago, drift
//! has laid the new (active) surfaces beside the old (inactive) ones; the
//! registration measures that offset as one rigid correction.
//!
//! The inactive prediction plays the frame: its world-frame maps are put in
//! the camera frame of the pose they were rendered from (an organised image
//! with intrinsics, what [`icp_step`] aligns against), and the active
//! prediction is the source. The estimate `T` (camera_from_world) starts at
//! the inverse of that pose, so the correction `world_from_camera * T` is
//! the identity when the two models already coincide. Both sides are fused
//! surfels, not raw depth: the residuals are not weighted by sensor noise.

use crate::fusion::Prediction;
use crate::preprocess::PyramidLevel;
use crate::se3;
use crate::se3::RigidF32;
use crate::track::icp::icp_step;
use crate::track::model_points::ModelPoints;
use crate::track::verify::{free_space_violation, VerifyConfig};
use crate::track::FreeDirections;
use glam::{DAffine3, Vec3};

use super::LoopClosureConfig;

/// Why a model-to-model registration was not accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// The two predictions share too few pixels to compare.
    TooLittleOverlap,
    /// Too few correspondences survived the gates.
    TooFewInliers,
    /// The aligned surfaces still lie apart.
    HighResidual,
    /// The overlap does not pin all six degrees of freedom.
    IllConditioned,
    /// The correction is larger than a local closure may make.
    TooLarge,
    /// Corrected, one model's points would lie in the other's free space.
    FreeSpace,
    /// The solve failed or produced a non-finite pose.
    Degenerate,
}

impl Rejection {
    /// Short kebab-case name (`too-little-overlap`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::TooLittleOverlap => "too-little-overlap",
            Self::TooFewInliers => "too-few-inliers",
            Self::HighResidual => "high-residual",
            Self::IllConditioned => "ill-conditioned",
            Self::TooLarge => "too-large",
            Self::FreeSpace => "free-space",
            Self::Degenerate => "degenerate",
        }
    }
}

/// Outcome of registering the active model onto the inactive one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// The rigid motion (world frame to world frame, metres) that moves the
    /// active model onto the inactive one; identity when rejected early.
    pub correction: DAffine3,
    /// Pixels where both predictions show a surfel.
    pub overlap: usize,
    /// Inlier correspondences of the final dense evaluation.
    pub inliers: usize,
    /// Inliers over `overlap` (at most 1).
    pub inlier_ratio: f64,
    /// RMS point-to-plane residual of the inliers, metres.
    pub residual_rms_m: f64,
    /// The same residual before the registration (the models as they lie),
    /// metres: a correction that barely lowers it is not measured by the
    /// overlap (it slides along a weakly constrained direction).
    pub start_residual_rms_m: f64,
    /// Directions of motion the inactive model's geometry leaves free
    /// (information per point below `hold_below_eigenvalue` above its
    /// normals' noise floor): the correction has no component along them.
    pub held: usize,
    /// Eigenvalue ratio of the scaled 6x6 system, the held directions
    /// counted as ordinary ones (0 = singular).
    pub conditioning: f64,
    /// Free-space violation fraction, the larger of the two directions
    /// (active points against the inactive model and the reverse).
    pub free_space: f64,
    /// The same of the models as they lie (no correction): what sensor
    /// noise and fusion leave in front of a surface on this view.
    pub start_free_space: f64,
    /// `None` when accepted, otherwise why not.
    pub rejected: Option<Rejection>,
}

impl Registration {
    fn rejected(reason: Rejection, overlap: usize) -> Self {
        Self {
            correction: DAffine3::IDENTITY,
            overlap,
            inliers: 0,
            inlier_ratio: 0.0,
            residual_rms_m: 0.0,
            start_residual_rms_m: 0.0,
            held: 0,
            conditioning: 0.0,
            free_space: 0.0,
            start_free_space: 0.0,
            rejected: Some(reason),
        }
    }

    /// True when the registration passed every check.
    #[must_use]
    pub fn accepted(&self) -> bool {
        self.rejected.is_none()
    }

    /// True when the correction is worth bending the map for: above the
    /// smallest correction `config` bends for, and lowering the residual
    /// by at least `config.min_residual_gain`. Otherwise the two models
    /// already coincide as far as the overlap can tell.
    #[must_use]
    pub fn moves_map(&self, config: &LoopClosureConfig) -> bool {
        let (dt, dr) = self.magnitude();
        let large = dt >= config.min_correction_m || dr >= config.min_correction_deg;
        large && self.start_residual_rms_m >= self.residual_rms_m * config.min_residual_gain
    }

    /// Translation (metres) and rotation (degrees) of the correction.
    #[must_use]
    pub fn magnitude(&self) -> (f64, f64) {
        let (dt, dr) = se3::motion_magnitude(&self.correction);
        (dt, dr.to_degrees())
    }
}

/// Buffers of the registration, kept between calls so that a check every
/// frame does not allocate.
#[derive(Debug, Default)]
pub struct ModelRegistration {
    /// The inactive prediction in its camera's frame: the ICP target.
    target: PyramidLevel,
    /// Active prediction's points in the same camera frame (free-space check).
    active_points: Vec<Vec3>,
    /// The active prediction's pixels holding a surfel: the ICP sources.
    sources: ModelPoints,
    /// Squared normal differences the free directions' noise floor is the
    /// median of.
    differences: Vec<f64>,
}

/// Brings a prediction's world-frame maps into the camera frame of the pose
/// it was rendered from, as a pyramid level (`ZERO` where no surfel).
fn to_camera_frame_into(prediction: &Prediction, out: &mut PyramidLevel) {
    to_frame_of_into(prediction, &prediction.world_from_camera, out);
}

/// Brings a prediction's world-frame maps into the camera frame of
/// `world_from_camera` (metres), keeping its pixel grid, as a pyramid level
/// (`ZERO` where no surfel).
pub fn to_frame_of_into(
    prediction: &Prediction,
    world_from_camera: &DAffine3,
    out: &mut PyramidLevel,
) {
    let camera_from_world = RigidF32::from_affine(&world_from_camera.inverse());
    let n = prediction.vertices.len();
    out.intrinsics = prediction.intrinsics;
    out.vertices.resize(n, Vec3::ZERO);
    out.normals.resize(n, Vec3::ZERO);
    out.depth.resize(n, 0.0);
    for (i, (&p, &normal)) in prediction
        .vertices
        .iter()
        .zip(&prediction.normals)
        .enumerate()
    {
        let (v, nrm) = if normal == Vec3::ZERO {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (camera_from_world.point(p), camera_from_world.vector(normal))
        };
        out.vertices[i] = v;
        out.normals[i] = nrm;
        out.depth[i] = v.z.max(0.0);
    }
}

impl ModelRegistration {
    /// Registers `active` onto `inactive`, two predictions rendered from the
    /// same pose with the same intrinsics, and judges the result by
    /// `config`'s acceptance thresholds. `verify` gives the free-space margins.
    pub fn register(
        &mut self,
        active: &Prediction,
        inactive: &Prediction,
        config: &LoopClosureConfig,
        verify: &VerifyConfig,
    ) -> Registration {
        let Some(n) = comparable_pixels(active, inactive) else {
            return Registration::rejected(Rejection::TooLittleOverlap, 0);
        };
        let overlap = overlap_of(active, inactive);
        if overlap < of_image(config.min_overlap_fraction, n) {
            return Registration::rejected(Rejection::TooLittleOverlap, overlap);
        }
        let view = inactive.world_from_camera;
        to_camera_frame_into(inactive, &mut self.target);
        self.sources.gather_from(active);
        let free = FreeDirections::of_model(
            &self.target,
            |i| active.normals.get(i).is_some_and(|n| *n != Vec3::ZERO),
            config.hold_below_eigenvalue,
            &mut self.differences,
        );
        let (camera_from_world, start_residual_rms_m) = self.align(view.inverse(), &free, config);
        if !(view * camera_from_world).is_finite() {
            return Registration::rejected(Rejection::Degenerate, overlap);
        }
        let mut result = self.evaluate((view, &camera_from_world), &free, config, overlap);
        result.start_residual_rms_m = start_residual_rms_m;
        result.rejected = judge(&result, config, n);
        if result.rejected.is_none() {
            result.free_space =
                self.free_space(active, inactive, &result.correction, config, verify);
            result.start_free_space =
                self.free_space(active, inactive, &DAffine3::IDENTITY, config, verify);
            if result.free_space - result.start_free_space > config.max_free_space_fraction {
                result.rejected = Some(Rejection::FreeSpace);
            }
        }
        result
    }

    /// Gauss-Newton point-to-plane ICP of `active` onto the target, from
    /// `camera_from_world`, coarse to fine on the source grid (the target
    /// stays full resolution), with no step along the `free` directions.
    /// Returns the estimate and the RMS residual before the first step
    /// (metres).
    fn align(
        &self,
        mut camera_from_world: DAffine3,
        free: &FreeDirections,
        config: &LoopClosureConfig,
    ) -> (DAffine3, f64) {
        let start = icp_step(
            &self.sources,
            1,
            &self.target,
            &RigidF32::from_affine(&camera_from_world),
            &config.gates,
            None,
        );
        let start_residual_rms_m = (start.system.cost / start.system.count.max(1) as f64).sqrt();
        for (level, &iterations) in config.iterations.iter().enumerate().rev() {
            let stride = 1usize << level;
            for _ in 0..iterations {
                let t = RigidF32::from_affine(&camera_from_world);
                let step = icp_step(&self.sources, stride, &self.target, &t, &config.gates, None);
                if step.system.count < 6 {
                    break;
                }
                let Some(xi) = free.held(&step.system).solve(0.0) else {
                    break;
                };
                camera_from_world = se3::exp(&xi) * camera_from_world;
                if xi.iter().all(|v| v.abs() < 1e-6) {
                    break;
                }
            }
        }
        (camera_from_world, start_residual_rms_m)
    }

    /// The statistics of a dense evaluation at the final estimate (not yet judged).
    /// `(view, camera_from_world)`: the pose the models were rendered from
    /// and the estimate.
    fn evaluate(
        &self,
        (view, camera_from_world): (DAffine3, &DAffine3),
        free: &FreeDirections,
        config: &LoopClosureConfig,
        overlap: usize,
    ) -> Registration {
        let t = RigidF32::from_affine(camera_from_world);
        let last = icp_step(&self.sources, 1, &self.target, &t, &config.gates, None);
        let system = &last.system;
        let inliers = system.count;
        Registration {
            correction: view * *camera_from_world,
            overlap,
            inliers,
            inlier_ratio: (inliers as f64 / overlap as f64).min(1.0),
            residual_rms_m: (system.cost / inliers.max(1) as f64).sqrt(),
            start_residual_rms_m: 0.0,
            held: free.count(),
            conditioning: if inliers >= 6 {
                free.pinned(system, 1.0).conditioning()
            } else {
                0.0
            },
            free_space: 0.0,
            start_free_space: 0.0,
            rejected: None,
        }
    }

    /// Free-space violation of the corrected models, the larger of the two
    /// directions: corrected active points must not lie in front of the
    /// inactive surface, nor inactive points in front of the active one.
    fn free_space(
        &mut self,
        active: &Prediction,
        inactive: &Prediction,
        correction: &DAffine3,
        config: &LoopClosureConfig,
        verify: &VerifyConfig,
    ) -> f64 {
        let view = inactive.world_from_camera;
        let correction = *correction;
        let camera_from_world = RigidF32::from_affine(&view.inverse());
        self.active_points.clear();
        self.active_points.extend(
            active
                .vertices
                .iter()
                .zip(&active.normals)
                .map(|(&p, &nrm)| {
                    if nrm == Vec3::ZERO {
                        Vec3::ZERO
                    } else {
                        camera_from_world.point(p)
                    }
                }),
        );
        let step = config.free_space_step.max(1);
        let (forward, _) = free_space_violation(
            inactive,
            &self.active_points,
            step,
            &(correction * view),
            verify,
        );
        let (backward, _) = free_space_violation(
            active,
            &self.target.vertices,
            step,
            &(correction.inverse() * view),
            verify,
        );
        forward.max(backward)
    }
}

/// The pixel count of the two predictions when they can be compared (same
/// intrinsics, full maps), else `None`.
fn comparable_pixels(active: &Prediction, inactive: &Prediction) -> Option<usize> {
    let (k, k_inactive) = (active.intrinsics?, inactive.intrinsics?);
    let n = k.pixel_count();
    let full = |p: &Prediction| p.vertices.len() == n && p.normals.len() == n;
    (k == k_inactive && full(active) && full(inactive)).then_some(n)
}

/// Pixels where both predictions show a surfel.
fn overlap_of(active: &Prediction, inactive: &Prediction) -> usize {
    active
        .normals
        .iter()
        .zip(&inactive.normals)
        .filter(|(a, b)| **a != Vec3::ZERO && **b != Vec3::ZERO)
        .count()
}

/// `fraction` of an image of `n` pixels, at least 6 (a 6-dof solve).
fn of_image(fraction: f64, n: usize) -> usize {
    ((fraction * n as f64).ceil() as usize).max(6)
}

/// Why `result` is refused by `config`'s thresholds before the free-space
/// check (`n`: pixels of the image), or `None`.
fn judge(result: &Registration, config: &LoopClosureConfig, n: usize) -> Option<Rejection> {
    let (dt, dr) = result.magnitude();
    if result.inliers < of_image(config.min_inlier_fraction, n)
        || result.inlier_ratio < config.min_inlier_ratio
    {
        Some(Rejection::TooFewInliers)
    } else if result.conditioning < config.min_conditioning {
        Some(Rejection::IllConditioned)
    } else if result.residual_rms_m > config.max_residual_m {
        Some(Rejection::HighResidual)
    } else if dt > config.max_correction_m || dr > config.max_correction_deg {
        Some(Rejection::TooLarge)
    } else {
        None
    }
}
