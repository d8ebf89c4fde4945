//! One evaluation of the tracking cost: the mode's normal equations
//! (ICP, photometric or both, scaled) at one pyramid level for one
//! `camera_from_world` estimate, and what every evaluation of one
//! [`track`](super::track) call reads ([`Problem`]).

use super::icp::{self, icp_step, NoiseWeights};
use super::{TrackerConfig, TrackerMode, TrackerWorkspace};
use crate::fusion::Prediction;
use crate::preprocess::FramePyramid;
use crate::se3;
use crate::se3::RigidF32;
use glam::DAffine3;

/// The noise model with the finest level's focal length, for ICP.
pub(super) fn noise_weights<'a>(
    pyramid: &FramePyramid,
    config: &'a TrackerConfig,
) -> Option<NoiseWeights<'a>> {
    let focal_px = pyramid.levels.first()?.intrinsics?.focal_abs();
    Some(NoiseWeights {
        noise: &config.noise,
        focal_px,
    })
}

/// The combined system of one evaluation and its mean cost.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Evaluation {
    /// The system solved for the step (both terms scaled in joint mode).
    pub(super) system: se3::NormalEquations,
    /// The ICP term of a finest-level evaluation over every model pixel
    /// (its statistics judge the frame), when there was one.
    pub(super) dense_icp: Option<icp::IcpStep>,
    /// Weighted cost per residual of each term, for the damping decision.
    pub(super) mean_cost: f64,
    /// The photometric term alone, unscaled (empty in ICP mode).
    pub(super) photometric: se3::NormalEquations,
}

/// Builds the mode's normal equations at `level` for the estimate
/// `camera_from_world`, with ICP sources every `stride` model pixels.
fn evaluate(
    pyramid: &FramePyramid,
    workspace: &TrackerWorkspace,
    (level, stride): (usize, usize),
    camera_from_world: &DAffine3,
    config: &TrackerConfig,
    scales: &mut Option<(f64, f64)>,
) -> Evaluation {
    let t = RigidF32::from_affine(camera_from_world);
    let target = &pyramid.levels[level];
    let mean = |s: &se3::NormalEquations| s.cost / s.count.max(1) as f64;
    let weights = noise_weights(pyramid, config);
    let icp_full = || icp_step(&workspace.model, stride, target, &t, &config.gates, weights);
    let dense = |step: &icp::IcpStep| (level == 0 && stride == 1).then_some(*step);
    let rgb = || {
        workspace
            .rgb
            .step(level, target, &t, &config.photometric)
            .system
    };
    match config.mode {
        TrackerMode::Icp => {
            let step = icp_full();
            Evaluation {
                mean_cost: mean(&step.system),
                system: step.system,
                dense_icp: dense(&step),
                photometric: se3::NormalEquations::default(),
            }
        }
        TrackerMode::Rgb => {
            let system = rgb();
            Evaluation {
                mean_cost: mean(&system),
                system,
                dense_icp: None,
                photometric: system,
            }
        }
        TrackerMode::Joint => {
            let (step, photometric) = rayon::join(icp_full, rgb);
            let geometric = step.system;
            // Each term divided by its own mean squared residual (its
            // variance estimate, this iteration), so that w is a relative
            // weight of two unit-variance terms: the noisier term (real
            // depth noise, inconsistent fused colour) gives way by itself.
            // The scales are fixed at a level's first evaluation so that
            // the level minimises one cost (and LM can compare costs).
            let (rgb_scale, icp_scale) = *scales.get_or_insert_with(|| {
                (
                    1.0 / mean(&photometric).max(1e-12),
                    config.icp_weight.powi(2) / mean(&geometric).max(1e-12),
                )
            });
            let mut system = se3::NormalEquations::default();
            system.add_scaled(&photometric, rgb_scale, rgb_scale);
            system.add_scaled(&geometric, icp_scale, icp_scale);
            Evaluation {
                mean_cost: mean(&photometric) * rgb_scale + mean(&geometric) * icp_scale,
                system,
                dense_icp: dense(&step),
                photometric,
            }
        }
    }
}

/// What every evaluation of one [`track`](super::track) call reads.
#[derive(Clone, Copy)]
pub(super) struct Problem<'a> {
    pub(super) pyramid: &'a FramePyramid,
    pub(super) prediction: &'a Prediction,
    /// Directions the step must not move along.
    pub(super) free: super::FreeDirections,
    /// The hand's motion prior, added to each step's system.
    pub(super) prior: Option<&'a super::MotionPrior>,
    pub(super) workspace: &'a TrackerWorkspace,
    pub(super) config: &'a TrackerConfig,
    /// Levenberg-Marquardt on (rgb and joint modes with `lm_damping`).
    pub(super) damped: bool,
}

impl Problem<'_> {
    /// [`evaluate`] for this problem.
    pub(super) fn evaluate(
        &self,
        level_stride: (usize, usize),
        camera_from_world: &DAffine3,
        scales: &mut Option<(f64, f64)>,
    ) -> Evaluation {
        evaluate(
            self.pyramid,
            self.workspace,
            level_stride,
            camera_from_world,
            self.config,
            scales,
        )
    }
}
