//! Camera tracking against the model prediction (frame-to-model), coarse to
//! fine over the frame pyramid, with a tracked / lost verdict.
//!
//! The estimate is `camera_from_world` during the solve (the increment is
//! applied on the left, in the camera frame); results are reported as
//! `world_from_camera`.

pub mod icp;

use crate::fusion::index_map::RigidF32;
use crate::fusion::Prediction;
use crate::preprocess::FramePyramid;
use crate::se3;
use glam::DAffine3;
use icp::{icp_step, IcpGates};

/// Settings of the tracker.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Gauss-Newton iterations per level, finest first (solved coarsest first).
    pub iterations: Vec<usize>,
    /// At the finest level only the last this many iterations use every
    /// model pixel; the earlier ones use every second pixel in each
    /// direction, a quarter of the cost. Measured with 2 (against all 10
    /// dense): TUM fr3/teddy ATE 0.75 vs 0.73-0.77 cm, ICL-NUIM kt0 0.012 cm
    /// both, and the tracking stage about 2x faster; with 0: teddy 0.83 cm.
    pub dense_final_iterations: usize,
    /// Correspondence gates and robust weight.
    pub gates: IcpGates,
    /// Stop iterating a level when the step is below this (rad or m).
    pub convergence: f64,
    /// Lost when fewer inliers than this fraction of the source points that projected.
    pub min_inlier_ratio: f64,
    /// Lost when fewer inlier correspondences than this at the finest level.
    pub min_inliers: usize,
    /// Lost when the RMS point-to-plane residual exceeds this, metres.
    pub max_residual_m: f64,
    /// Lost when the scaled 6x6 system's eigenvalue ratio is below this.
    pub min_conditioning: f64,
    /// Lost when the frame-to-frame motion exceeds this translation, metres.
    pub max_translation_m: f64,
    /// Lost when the frame-to-frame motion exceeds this rotation, degrees.
    pub max_rotation_deg: f64,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            iterations: vec![10, 5, 4],
            dense_final_iterations: 2,
            gates: IcpGates {
                distance_gate_m: 0.10,
                normal_gate_deg: 20.0,
                huber_m: 0.02,
            },
            convergence: 1e-6,
            min_inlier_ratio: 0.25,
            min_inliers: 1000,
            max_residual_m: 0.03,
            min_conditioning: 1e-5,
            max_translation_m: 0.30,
            max_rotation_deg: 30.0,
        }
    }
}

/// Why a frame was judged lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LostReason {
    /// Too few correspondences with the model.
    TooFewInliers,
    /// The alignment residual stayed high.
    HighResidual,
    /// The geometry does not constrain all six degrees of freedom.
    IllConditioned,
    /// The estimated motion since the last frame is implausibly large.
    ImplausibleMotion,
}

impl LostReason {
    /// Short kebab-case name (`too-few-inliers`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::TooFewInliers => "too-few-inliers",
            Self::HighResidual => "high-residual",
            Self::IllConditioned => "ill-conditioned",
            Self::ImplausibleMotion => "implausible-motion",
        }
    }
}

/// Outcome of tracking one frame.
#[derive(Debug, Clone, Copy)]
pub struct TrackResult {
    /// Estimated pose, camera to world.
    pub world_from_camera: DAffine3,
    /// Inlier correspondences at the finest level.
    pub inliers: usize,
    /// Inliers over the source points that projected into the frame.
    pub inlier_ratio: f64,
    /// RMS of the weighted point-to-plane residuals, metres.
    pub residual_rms_m: f64,
    /// Eigenvalue ratio of the scaled 6x6 system (0 = singular).
    pub conditioning: f64,
    /// `None` when tracked, otherwise why it was lost.
    pub lost: Option<LostReason>,
}

/// Step between the model pixels used as ICP sources at `level` in iteration
/// `iteration` of `iterations` (matching the level's downsampling, and
/// sparser for the finest level's early iterations).
fn source_stride(
    level: usize,
    iteration: usize,
    iterations: usize,
    config: &TrackerConfig,
) -> usize {
    if level == 0 && iteration + config.dense_final_iterations < iterations {
        2
    } else {
        1 << level
    }
}

/// Aligns the frame in `pyramid` with the model `prediction`, starting from `initial`.
#[must_use]
pub fn track(
    pyramid: &FramePyramid,
    prediction: &Prediction,
    initial_world_from_camera: &DAffine3,
    config: &TrackerConfig,
) -> TrackResult {
    let mut camera_from_world = initial_world_from_camera.inverse();
    let mut last = icp::IcpStep::default();
    let levels = pyramid.levels.len().min(config.iterations.len());
    for level in (0..levels).rev() {
        let iterations = config.iterations[level];
        for iteration in 0..iterations {
            let stride = source_stride(level, iteration, iterations, config);
            let t = RigidF32::from_affine(&camera_from_world);
            last = icp_step(
                prediction,
                stride,
                &pyramid.levels[level],
                &t,
                &config.gates,
            );
            if last.system.count < 6 {
                break;
            }
            let Some(xi) = last.system.solve(0.0) else {
                break;
            };
            camera_from_world = se3::exp(&xi) * camera_from_world;
            if xi.iter().all(|v| v.abs() < config.convergence) {
                break;
            }
        }
    }
    // Statistics of the final estimate at the finest level.
    if let Some(finest) = pyramid.levels.first() {
        let t = RigidF32::from_affine(&camera_from_world);
        last = icp_step(prediction, 1, finest, &t, &config.gates);
    }
    let world_from_camera = camera_from_world.inverse();
    let sys = &last.system;
    let inliers = sys.count;
    let inlier_ratio = inliers as f64 / last.candidates.max(1) as f64;
    let residual_rms_m = (sys.cost / inliers.max(1) as f64).sqrt();
    let conditioning = if inliers >= 6 {
        sys.conditioning()
    } else {
        0.0
    };
    let (dt, dr) =
        se3::motion_magnitude(&(initial_world_from_camera.inverse() * world_from_camera));
    let lost = if inliers < config.min_inliers || inlier_ratio < config.min_inlier_ratio {
        Some(LostReason::TooFewInliers)
    } else if conditioning < config.min_conditioning {
        Some(LostReason::IllConditioned)
    } else if residual_rms_m > config.max_residual_m {
        Some(LostReason::HighResidual)
    } else if dt > config.max_translation_m || dr.to_degrees() > config.max_rotation_deg {
        Some(LostReason::ImplausibleMotion)
    } else {
        None
    };
    TrackResult {
        world_from_camera,
        inliers,
        inlier_ratio,
        residual_rms_m,
        conditioning,
        lost,
    }
}
