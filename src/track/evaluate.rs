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
    /// The photometric term alone, unscaled (in ICP mode: only where
    /// colour was asked about the free directions).
    pub(super) photometric: se3::NormalEquations,
    /// ICP mode: the photometric term in ICP's units, where it pins free
    /// directions ([`colour_where_free`]); empty otherwise.
    pub(super) colour: se3::NormalEquations,
    /// The directions held in this evaluation's step: the frame's free
    /// ones less those colour pins.
    pub(super) held: super::FreeDirections,
}

impl Evaluation {
    /// The system the step solves before holding: the mode's, plus colour
    /// along the free directions it pins.
    pub(super) fn solved(&self) -> se3::NormalEquations {
        self.system.merged(&self.colour)
    }
}

/// On a frame with free directions, the directions whose geometric
/// information (unit-diagonal scaling) is below this fraction of the
/// strongest are colour's to pin too, or held.
const COLOUR_CANDIDATE_RATIO: f64 = 0.05;

/// Full-resolution pixels of colour that count as one independent
/// measurement: a JPEG block (8x8), over which compression, demosaicing
/// and motion blur share their errors.
const COLOUR_CORRELATED_PIXELS: f64 = 64.0;

/// Residuals colour needs before it may pin a direction.
const MIN_COLOUR_RESIDUALS: usize = 100;

/// ICP mode, a frame with free directions: which of them the photometric
/// term `photometric` pins to [`TrackerConfig::colour_pins_below_m`]
/// (scaled by the level's pixel size), and, when it pins any, that term in
/// the units of the ICP system `geometric` (each divided by its mean
/// squared residual, then multiplied by ICP's), to be added to it: the
/// joint system, on the frames whose geometry needs it. Returns (colour,
/// still held).
fn colour_where_free(
    free: &super::FreeDirections,
    photometric: &se3::NormalEquations,
    geometric: &se3::NormalEquations,
    level: usize,
    config: &TrackerConfig,
) -> (se3::NormalEquations, super::FreeDirections) {
    // One residual of `level` covers 4^level pixels; JPEG's errors are
    // shared over its 8x8 blocks, so a finer residual is not a whole
    // measurement.
    let shared = (COLOUR_CORRELATED_PIXELS / f64::from(1u32 << (2 * level.min(8)))).max(1.0);
    let max_sigma = config.colour_pins_below_m * f64::from(1u32 << level.min(16)) / shared.sqrt();
    // The frame's measure of what is free misses directions depth noise
    // poses as information for; on a view that leaves any direction free,
    // every direction the geometry pins poorly is colour's to pin, or held.
    let weak = super::FreeDirections::weak_in(&free.pinned(geometric, 1.0), COLOUR_CANDIDATE_RATIO);
    let free = &free.with(&weak);
    let (pinned, held) = free.split_by_colour(photometric, max_sigma, MIN_COLOUR_RESIDUALS);
    if pinned.count() == 0 {
        return (se3::NormalEquations::default(), held);
    }
    let mean = |s: &se3::NormalEquations| s.cost / s.count.max(1) as f64;
    let scale = mean(geometric) / mean(photometric).max(1e-12);
    let mut colour = se3::NormalEquations::default();
    colour.add_scaled(photometric, scale, scale);
    (colour, held)
}

/// Builds the mode's normal equations at `level` for the estimate
/// `camera_from_world`, with ICP sources every `stride` model pixels.
fn evaluate(
    problem: &Problem,
    (level, stride): (usize, usize),
    camera_from_world: &DAffine3,
    scales: &mut Option<(f64, f64)>,
) -> Evaluation {
    let (pyramid, workspace, config) = (problem.pyramid, problem.workspace, problem.config);
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
        TrackerMode::Icp if problem.colour => {
            let (step, photometric) = rayon::join(icp_full, rgb);
            let (colour, held) =
                colour_where_free(&problem.free, &photometric, &step.system, level, config);
            Evaluation {
                mean_cost: mean(&step.system),
                system: step.system,
                dense_icp: dense(&step),
                photometric,
                colour,
                held,
            }
        }
        TrackerMode::Icp => {
            let step = icp_full();
            Evaluation {
                mean_cost: mean(&step.system),
                system: step.system,
                dense_icp: dense(&step),
                held: problem.free,
                ..Evaluation::default()
            }
        }
        TrackerMode::Rgb => {
            let system = rgb();
            Evaluation {
                mean_cost: mean(&system),
                system,
                dense_icp: None,
                photometric: system,
                ..Evaluation::default()
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
                ..Evaluation::default()
            }
        }
    }
}

/// What every evaluation of one [`track`](super::track) call reads.
#[derive(Clone, Copy)]
pub(super) struct Problem<'a> {
    pub(super) pyramid: &'a FramePyramid,
    pub(super) prediction: &'a Prediction,
    /// Directions the frame's geometry leaves free: held unless colour
    /// pins them (`colour`).
    pub(super) free: super::FreeDirections,
    /// ICP mode: ask the photometric term about `free` (see
    /// [`TrackerConfig::colour_pins_below_m`]).
    pub(super) colour: bool,
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
        evaluate(self, level_stride, camera_from_world, scales)
    }
}
