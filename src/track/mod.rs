//! Camera tracking against the model prediction (frame-to-model), coarse to
//! fine over the frame pyramid, with a tracked / lost verdict.
//!
//! Three modes ([`TrackerMode`]): geometric (point-to-plane ICP, [`icp`]),
//! direct (photometric, [`rgb`]) and joint. The joint step solves one 6x6
//! system, ElasticFusion's `A = A_rgb + w^2 A_icp`, `b = b_rgb + w b_icp`
//! with `w` = [`TrackerConfig::icp_weight`] (ICP residuals in metres,
//! photometric residuals in grey levels / 255). Each level runs Gauss-Newton
//! with Levenberg-Marquardt damping: a step that raises the mean cost is
//! undone and retried with more damping.
//!
//! The estimate is `camera_from_world` during the solve (the increment is
//! applied on the left, in the camera frame); results are reported as
//! `world_from_camera`.

mod evaluate;
pub mod free_directions;
pub mod icp;
mod lost_reason;
pub mod model_points;
pub mod motion_prior;
pub mod rgb;
pub mod verify;

use crate::fusion::Prediction;
use crate::noise::SensorNoise;
use crate::preprocess::FramePyramid;
use crate::se3;
use crate::se3::RigidF32;
use evaluate::{noise_weights, Evaluation, Problem};
pub use free_directions::FreeDirections;
use free_directions::GridWorkspace;
use glam::DAffine3;
use icp::{icp_step, IcpGates};
pub use lost_reason::LostReason;
pub use motion_prior::{MotionPrior, MotionPriorConfig};
use rgb::{PhotometricConfig, RgbWorkspace};
use verify::VerifyConfig;

/// Which cost the tracker minimises.
///
/// ICP is the default by measurement on the real sequences (ATE and median
/// ms per frame, `surfel-slam bench`, 2 cores): ICL-NUIM kt0 0.012 cm /
/// 27 ms against joint's 0.016 cm / 33 ms; TUM fr3/teddy 0.75 cm / 30 ms
/// against 0.79 cm / 40 ms. Joint is far better under heavy white depth
/// noise (the synthetic room with Kinect-like noise: 0.45 mm against 13 mm),
/// so choose it for noisy sensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum TrackerMode {
    /// Projective point-to-plane ICP only (geometry).
    #[default]
    Icp,
    /// Photometric error against the model's colour only (direct method).
    Rgb,
    /// Both in one system, ICP weighted by `icp_weight`.
    Joint,
}

impl TrackerMode {
    /// Every mode, in CLI order.
    pub const ALL: [TrackerMode; 3] = [TrackerMode::Icp, TrackerMode::Rgb, TrackerMode::Joint];

    /// Lower-case name: `icp`, `rgb`, `joint`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Icp => "icp",
            Self::Rgb => "rgb",
            Self::Joint => "joint",
        }
    }

    /// The mode called `name` (as printed by [`Self::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// Settings of the tracker.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackerConfig {
    /// Which cost to minimise.
    pub mode: TrackerMode,
    /// Joint weight `w` of the ICP term (`A = A_rgb + w^2 A_icp`,
    /// `b = b_rgb + w^2 b_icp`), applied after each term is divided by its
    /// own mean squared residual at the level's first step: `w = 1` weighs
    /// the two equally per unit of their own noise.
    ///
    /// 3 by measurement (ATE; synthetic = 60 frames of the test room at 320x240):
    ///
    /// | w | ICL kt0 | TUM teddy | synthetic, no noise | synthetic, Kinect noise |
    /// | --- | --- | --- | --- | --- |
    /// | ICP alone | 0.012 cm | 0.749 cm | 0.044 mm | 13.3 mm |
    /// | 1 | 0.024 cm | 0.912 cm | 0.034 mm | 0.37 mm |
    /// | 3 | 0.014 cm | 0.799 cm | 0.042 mm | 0.45 mm |
    /// | photometric alone | 0.49 cm | 2.74 cm | 0.44 mm | 1.10 mm |
    ///
    /// (Without the normalisation, in metres against grey/255, ElasticFusion's
    /// w = 10 gave 0.14 cm / 0.93 cm and w = 100 0.014 cm / 0.77 cm on the real
    /// pair but 10.4 mm with Kinect noise: a fixed w cannot follow the depth noise.)
    pub icp_weight: f64,
    /// Photometric term settings.
    pub photometric: PhotometricConfig,
    /// Levenberg-Marquardt in the rgb and joint modes: undo a step that
    /// raises the mean cost and retry with more damping. Off by default:
    /// the inlier sets change between steps, so the mean cost is a noisy
    /// test on real data (measured on TUM fr3/teddy, joint w = 100: 1.13 cm
    /// ATE with it, 0.77 cm without; rgb alone 2.74 vs 2.74 cm).
    pub lm_damping: bool,
    /// Gauss-Newton iterations per level, finest first (solved coarsest first).
    /// Frame-to-frame motion on the real sequences is at most 2.3 cm / 2.1
    /// degrees, and [6, 4, 3] with one dense final iteration tracks them as
    /// well as [10, 5, 4] with two (TUM fr3/teddy 0.747 vs 0.749 cm, ICL-NUIM
    /// kt0 0.012-0.013 cm) at about half the tracking cost; [4, 4, 3] does
    /// not (teddy 0.96-0.98 cm).
    pub iterations: Vec<usize>,
    /// At the finest level only the last this many iterations use every
    /// model pixel; the earlier ones use every second pixel in each
    /// direction (or coarser, see `sparse_sources`), a quarter of the cost. The frame is judged (inliers,
    /// residual, conditioning) on the last dense evaluation. With 0, teddy
    /// tracked to 0.83 cm against 0.75 cm.
    pub dense_final_iterations: usize,
    /// Most model pixels used as ICP sources by an iteration that is not a
    /// dense final one: the source grid is made coarser until the model's
    /// valid pixels on it are at most this many. Without a cap the
    /// tracking cost follows how complete the model is (on TUM fr3/teddy,
    /// 68 k model pixels on the first pass, 105-132 k once mapped; tracking
    /// went from 4.3 to 6.9 ms between frames 100-200 and 1400-1500 of a
    /// 1500-frame run, and is 4.1-4.4 vs 4.3-4.5 ms with the cap). Same ATE
    /// on ICL-NUIM kt0 (0.012 cm) with its tracking 6.0 -> 3.9 ms; teddy
    /// 0.685 vs 0.697 cm, within the spread that reordering sums gives.
    pub sparse_sources: usize,
    /// Correspondence gates and robust weight.
    pub gates: IcpGates,
    /// Depth noise of the sensor: ICP residuals are divided by their
    /// predicted deviation (see [`icp`]); uniform = no weighting. Set with
    /// the fusion's by `SlamConfig::set_noise`.
    pub noise: SensorNoise,
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
    /// ICP mode: motions along which the frame's coarse geometry has less
    /// information per point than this (see [`free_directions`]) are held
    /// at the start instead of solved; 0 = never. The pipeline starts the
    /// frame at the constant-velocity prior, and a frame that held a
    /// direction is tracked again from the sparse feature estimate when
    /// there is one, with the same directions held: the colour image then
    /// decides what the geometry cannot (a velocity kept along a free
    /// direction for 40 frames integrates one bad step into 75 cm).
    ///
    /// The information is taken above the noise floor the frame's normals
    /// show, and a direction the coarse grid proposes is held only when
    /// the full resolution confirms it (see [`free_directions`]). 1e-3
    /// holds the synthetic loop's degenerate views (frames 62-68) and no
    /// other, under i.i.d. noise (0.21 cm ATE, 12.4 cm without holding)
    /// and under structured-light noise (1.74 cm, 12.8 cm without;
    /// `examples/holding_check.rs`), and no frame of TUM fr3/teddy,
    /// ICL-NUIM kt0, kt0 with Kinect noise or the 7-Scenes kitchen.
    pub hold_below_eigenvalue: f64,
    /// ICP mode: a direction the geometry leaves free (see
    /// `hold_below_eigenvalue`) is solved with the photometric term
    /// instead of held when colour pins it to this standard deviation or
    /// better (metres, rotations in radians at 1 m; at the finest level,
    /// doubled per coarser level), from the photometric information along
    /// it and its residuals (gain and bias fitted,
    /// [`rgb::PhotometricConfig::affine_brightness`]). Colour informs only
    /// those directions: the geometry's are solved as before. 0 = always
    /// hold.
    #[serde(default = "colour_pins_below_m_default")]
    pub colour_pins_below_m: f64,
    /// Lost when the frame-to-frame motion exceeds this translation, metres.
    pub max_translation_m: f64,
    /// Lost when the frame-to-frame motion exceeds this rotation, degrees.
    pub max_rotation_deg: f64,
    /// Independent checks of the result and the sparse start (used by the pipeline).
    pub verify: VerifyConfig,
    /// The motion a hand can make between frames, as a prior in the solve
    /// (see [`motion_prior`]; used by the pipeline between consecutive frames).
    #[serde(default)]
    pub motion_prior: MotionPriorConfig,
}

/// Off: with 1 mm, `tests/hand_held_swings.rs` regressed (the real 7-Scenes
/// kitchen at every 8th frame 3.09 cm ATE over its bound, the synthetic
/// swings lost longer); on in `tests/textured_ceiling.rs` only.
fn colour_pins_below_m_default() -> f64 {
    0.0
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            mode: TrackerMode::default(),
            icp_weight: 3.0,
            photometric: PhotometricConfig::default(),
            lm_damping: false,
            iterations: vec![6, 4, 3],
            dense_final_iterations: 1,
            sparse_sources: 20_000,
            gates: IcpGates {
                distance_gate_m: 0.10,
                normal_gate_deg: 20.0,
                huber_m: 0.02,
            },
            noise: SensorNoise::default(),
            convergence: 1e-6,
            min_inlier_ratio: 0.25,
            min_inliers: 1000,
            max_residual_m: 0.03,
            min_conditioning: 1e-5,
            hold_below_eigenvalue: 1e-3,
            colour_pins_below_m: colour_pins_below_m_default(),
            max_translation_m: 0.30,
            max_rotation_deg: 30.0,
            verify: VerifyConfig::default(),
            motion_prior: MotionPriorConfig::default(),
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
    /// RMS of the weighted photometric residuals at the finest level, grey
    /// levels (0..255); 0 in ICP mode.
    pub photometric_rms: f64,
    /// Photometric residuals used at the finest level (0 in ICP mode).
    pub photometric_residuals: usize,
    /// Eigenvalue ratio of the scaled 6x6 system (0 = singular), with the
    /// held directions made stiff.
    pub conditioning: f64,
    /// Directions of motion the geometry left free and the tracker held
    /// at its start (see [`free_directions`]); 0 when all six were solved.
    pub held_directions: usize,
    /// The directions held (camera-frame twist covectors), for another
    /// attempt on the same frame ([`track_holding`]).
    pub free: FreeDirections,
    /// Directions the final system pins poorly (below
    /// [`WEAK_CONDITIONING`] of its strongest, held ones excluded): where a
    /// result slid if it moved, with nothing else to check it.
    pub weak: FreeDirections,
    /// `None` when tracked, otherwise why it was lost.
    pub lost: Option<LostReason>,
}

/// Eigenvalue ratio of the scaled final system below which a direction
/// counts as pinned poorly ([`TrackResult::weak`]). Every tracked frame of
/// TUM fr3/teddy reads >= 0.0079; a synthetic view of a wall and the floor
/// that slid 22 cm on re-acquisition, 0.0005.
pub const WEAK_CONDITIONING: f64 = 2e-3;

/// Step between the model pixels used as ICP sources at `level` in iteration
/// `iteration` of `iterations`, for a model with `valid` pixels: 1 for the
/// finest level's dense final iterations; otherwise the level's
/// downsampling (2 at the finest level), made coarser until at most
/// `sparse_sources` model pixels lie on the grid.
fn source_stride(
    (level, iteration, iterations): (usize, usize, usize),
    valid: usize,
    config: &TrackerConfig,
) -> usize {
    if level == 0 && iteration + config.dense_final_iterations >= iterations {
        return 1;
    }
    let mut stride = (1usize << level).max(2);
    while valid / (stride * stride) > config.sparse_sources.max(1) {
        stride += 1;
    }
    stride
}

/// Reusable buffers of the tracker (image gradients, selected reference
/// pixels), kept across frames so that steady-state tracking does not allocate.
#[derive(Debug, Default, Clone)]
pub struct TrackerWorkspace {
    rgb: RgbWorkspace,
    grid: GridWorkspace,
    /// The prediction's pixels holding a surfel: ICP's sources.
    model: model_points::ModelPoints,
}

impl TrackerWorkspace {
    /// Call after a frame is accepted at `world_from_camera`: keeps what the
    /// next frame's photometric term needs from it (see [`rgb::PhotometricReference`]).
    pub fn remember_frame(
        &mut self,
        pyramid: &FramePyramid,
        world_from_camera: &DAffine3,
        config: &TrackerConfig,
    ) {
        if config.mode != TrackerMode::Icp {
            self.rgb
                .remember_frame(pyramid, world_from_camera, &config.photometric);
        }
    }

    /// The photometric term's reference pixels per pyramid level (world
    /// frame): what [`Self::remember_frame`] kept, for saving a session.
    pub fn photometric_memory(&self) -> impl Iterator<Item = &[rgb::ReferencePoint]> {
        self.rgb.references()
    }

    /// Restores [`Self::photometric_memory`] (loading a session).
    pub fn restore_photometric_memory(&mut self, levels: Vec<Vec<rgb::ReferencePoint>>) {
        self.rgb.restore_references(levels);
    }
}

/// Aligns the frame in `pyramid` with the model `prediction`, starting from `initial`.
#[must_use]
pub fn track(
    pyramid: &FramePyramid,
    prediction: &Prediction,
    initial_world_from_camera: &DAffine3,
    config: &TrackerConfig,
    workspace: &mut TrackerWorkspace,
) -> TrackResult {
    track_holding(
        pyramid,
        prediction,
        (initial_world_from_camera, None),
        config,
        workspace,
    )
}

/// [`track`], holding `held` (the directions an earlier attempt on the same
/// frame found free, [`TrackResult::free`]) instead of measuring them again
/// at this start: a start a little elsewhere can read a free direction just
/// above the threshold and slide along it.
#[must_use]
pub fn track_holding(
    pyramid: &FramePyramid,
    prediction: &Prediction,
    start: (&DAffine3, Option<&FreeDirections>),
    config: &TrackerConfig,
    workspace: &mut TrackerWorkspace,
) -> TrackResult {
    track_with_prior(pyramid, prediction, start, None, config, workspace)
}

/// [`track_holding`] with the hand's motion `prior` (see [`motion_prior`])
/// added to every step's system: the estimate leaves the prior's guess only
/// as far as the data pins it.
#[must_use]
pub fn track_with_prior(
    pyramid: &FramePyramid,
    prediction: &Prediction,
    (initial_world_from_camera, held): (&DAffine3, Option<&FreeDirections>),
    prior: Option<&MotionPrior>,
    config: &TrackerConfig,
    workspace: &mut TrackerWorkspace,
) -> TrackResult {
    if config.mode != TrackerMode::Icp {
        workspace
            .rgb
            .prepare(pyramid, prediction, &config.photometric);
    }
    // Every mode: the frame is judged on ICP's statistics (`track_result`).
    workspace.model.gather_from(prediction);
    let free = match (config.mode, pyramid.levels.last(), held) {
        (TrackerMode::Icp, _, Some(held)) => *held,
        (TrackerMode::Icp, Some(coarsest), None) => {
            let coarse = FreeDirections::of_frame(
                coarsest,
                prediction,
                (
                    &RigidF32::from_affine(&initial_world_from_camera.inverse()),
                    &config.gates,
                ),
                config.hold_below_eigenvalue,
                &mut workspace.grid,
            );
            match pyramid.levels.first() {
                Some(fine) => coarse.confirmed(
                    (fine, coarsest),
                    config.hold_below_eigenvalue,
                    &mut workspace.grid,
                ),
                None => coarse,
            }
        }
        _ => FreeDirections::default(),
    };
    let colour =
        config.mode == TrackerMode::Icp && free.count() > 0 && config.colour_pins_below_m > 0.0;
    if colour {
        workspace
            .rgb
            .prepare(pyramid, prediction, &config.photometric);
    }
    let problem = Problem {
        pyramid,
        prediction,
        free,
        colour,
        prior,
        workspace: &*workspace,
        config,
        // Plain ICP keeps undamped Gauss-Newton (its behaviour before the other modes existed).
        damped: config.mode != TrackerMode::Icp && config.lm_damping,
    };
    let mut camera_from_world = initial_world_from_camera.inverse();
    let levels = pyramid.levels.len().min(config.iterations.len());
    let mut finest = Evaluation::default();
    for level in (0..levels).rev() {
        if let Some(eval) = track_level(&problem, level, &mut camera_from_world) {
            finest = eval;
        }
    }
    track_result(
        &problem,
        initial_world_from_camera,
        &camera_from_world,
        &finest,
    )
}

/// The Gauss-Newton (or Levenberg-Marquardt) iterations of one pyramid
/// level, moving `camera_from_world`; returns the evaluation of the estimate
/// kept, or `None` when the level ran no iteration.
fn track_level(
    problem: &Problem,
    level: usize,
    camera_from_world: &mut DAffine3,
) -> Option<Evaluation> {
    let config = problem.config;
    // Levenberg-Marquardt: `best` is the last accepted estimate and its
    // system; a step that raises the mean cost is undone and re-solved
    // from `best` with ten times the damping.
    let mut best: Option<(DAffine3, Evaluation)> = None;
    let mut kept = None;
    let mut damping = 0.0;
    let mut scales = None;
    let iterations = config.iterations[level];
    let mut iteration = 0;
    while iteration < iterations {
        let stride = source_stride(
            (level, iteration, iterations),
            problem.prediction.valid,
            config,
        );
        iteration += 1;
        let current = problem.evaluate((level, stride), camera_from_world, &mut scales);
        let (pose, eval) = match best {
            Some((pose, eval)) if problem.damped && current.mean_cost > eval.mean_cost => {
                damping = if damping == 0.0 { 1e-4 } else { damping * 10.0 };
                (pose, eval)
            }
            _ => {
                damping *= 0.1;
                if damping < 1e-6 {
                    damping = 0.0;
                }
                best = Some((*camera_from_world, current));
                kept = Some(current);
                (*camera_from_world, current)
            }
        };
        let held = eval.held.held(&eval.solved());
        let system = match problem.prior {
            Some(prior) => {
                let pixels = (stride << level) as f64;
                prior.added_to(held, &eval.system, &pose, pixels * pixels)
            }
            None => held,
        };
        let Some(xi) = solve_step(&system, damping) else {
            break;
        };
        *camera_from_world = se3::exp(&xi) * pose;
        if xi.iter().all(|v| v.abs() < config.convergence) {
            if level > 0 || stride == 1 {
                break;
            }
            // Converged on sparse sources: finish with the dense iterations.
            iteration = iteration.max(iterations.saturating_sub(config.dense_final_iterations));
        }
    }
    if problem.damped {
        if let Some(best) = best {
            kept = Some(check_last_step(
                problem,
                level,
                best,
                camera_from_world,
                &mut scales,
            ));
        }
    }
    kept
}

/// The step (a camera-frame twist) that `system` asks for with
/// `damping`, or `None` when the level should stop: too few residuals,
/// damping run away, or a singular system.
fn solve_step(system: &se3::NormalEquations, damping: f64) -> Option<se3::Twist> {
    if system.count < 6 || damping > 1e6 {
        return None;
    }
    system.solve(damping)
}

/// The last step of a damped level was never evaluated: evaluates it and
/// goes back to `best` if it raised the cost (plain ICP keeps the last step
/// unchecked: it had no cost check before and converges monotonically on
/// its own). Returns the evaluation of the estimate kept.
fn check_last_step(
    problem: &Problem,
    level: usize,
    (best_pose, best_eval): (DAffine3, Evaluation),
    camera_from_world: &mut DAffine3,
    scales: &mut Option<(f64, f64)>,
) -> Evaluation {
    let last = problem.evaluate((level, 1 << level), camera_from_world, scales);
    if last.mean_cost > best_eval.mean_cost {
        *camera_from_world = best_pose;
        best_eval
    } else {
        last
    }
}

/// Statistics and verdict of the final estimate `camera_from_world`, from
/// `finest`, the evaluation kept at the finest level.
fn track_result(
    problem: &Problem,
    initial_world_from_camera: &DAffine3,
    camera_from_world: &DAffine3,
    finest: &Evaluation,
) -> TrackResult {
    let config = problem.config;
    // Statistics at the finest level: those of the last dense evaluation
    // (one step before the final estimate, which differs by less than the
    // gates resolve), else of a dense pass at the final estimate.
    let mut last = finest.dense_icp.unwrap_or_default();
    if let (None, Some(finest_level)) = (finest.dense_icp, problem.pyramid.levels.first()) {
        let t = RigidF32::from_affine(camera_from_world);
        let weights = noise_weights(problem.pyramid, config);
        last = icp_step(
            &problem.workspace.model,
            1,
            finest_level,
            &t,
            &config.gates,
            weights,
        );
    }
    let world_from_camera = camera_from_world.inverse();
    let sys = &last.system;
    let inliers = sys.count;
    // Held: what the geometry left free and colour did not pin.
    let held = &finest.held;
    let solved = sys.merged(&finest.colour);
    let inlier_ratio = last.inlier_ratio();
    let residual_rms_m = (sys.cost / inliers.max(1) as f64).sqrt();
    let photometric = &finest.photometric;
    let photometric_rms = 255.0 * (photometric.cost / photometric.count.max(1) as f64).sqrt();
    // The conditioning of the system actually solved: photometric rows can
    // constrain what geometry alone cannot (a textured flat wall).
    let conditioning = match config.mode {
        TrackerMode::Icp if inliers >= 6 => held.pinned(&solved, 1.0).conditioning(),
        TrackerMode::Rgb | TrackerMode::Joint if finest.system.count >= 6 => {
            finest.system.conditioning()
        }
        _ => 0.0,
    };
    let mut result = TrackResult {
        world_from_camera,
        inliers,
        inlier_ratio,
        residual_rms_m,
        photometric_rms,
        photometric_residuals: photometric.count,
        conditioning,
        held_directions: held.count(),
        free: problem.free,
        weak: match config.mode {
            TrackerMode::Icp if inliers >= 6 => {
                FreeDirections::weak_in(&held.pinned(&solved, 1.0), WEAK_CONDITIONING)
            }
            _ => FreeDirections::default(),
        },
        lost: None,
    };
    result.lost = verdict(&result, initial_world_from_camera, config);
    result
}

/// Why `result` counts as lost, or `None` when it passes the tracker's own
/// tests (inliers, conditioning, residual, motion from `initial`).
fn verdict(
    result: &TrackResult,
    initial_world_from_camera: &DAffine3,
    config: &TrackerConfig,
) -> Option<LostReason> {
    let (dt, dr) =
        se3::motion_magnitude(&(initial_world_from_camera.inverse() * result.world_from_camera));
    if result.inliers < config.min_inliers || result.inlier_ratio < config.min_inlier_ratio {
        Some(LostReason::TooFewInliers)
    } else if result.conditioning < config.min_conditioning {
        Some(LostReason::IllConditioned)
    } else if result.residual_rms_m > config.max_residual_m {
        Some(LostReason::HighResidual)
    } else if dt > config.max_translation_m || dr.to_degrees() > config.max_rotation_deg {
        Some(LostReason::ImplausibleMotion)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sparse_iterations_cap_their_sources_and_the_final_one_is_dense() {
        let config = TrackerConfig::default();
        let cap = config.sparse_sources;
        let [fine, middle, coarse] = [0, 1, 2].map(|level| (level, 0, config.iterations[level]));
        // A sparse model keeps each level's own grid.
        assert_eq!(source_stride(fine, cap, &config), 2);
        assert_eq!(source_stride(middle, cap, &config), 2);
        assert_eq!(source_stride(coarse, cap, &config), 4);
        // A complete model gets a coarser grid holding at most `cap` of its pixels.
        let complete = 640 * 480;
        for level in [fine, middle, coarse] {
            let stride = source_stride(level, complete, &config);
            assert!(complete / (stride * stride) <= cap, "stride {stride}");
            assert!(complete / ((stride - 1) * (stride - 1)) > cap || stride <= 4);
        }
        // The finest level's last iteration uses every model pixel.
        let last = (0, config.iterations[0] - 1, config.iterations[0]);
        assert_eq!(source_stride(last, complete, &config), 1);
    }
}
