//! The pipeline's configuration and its errors.

use crate::camera::{CameraPreset, Intrinsics};
use crate::frame::{DepthSettings, FrameError};
use crate::fusion::FusionConfig;
use crate::loop_closure::relocalise::RelocaliseConfig;
use crate::loop_closure::LoopClosureConfig;
use crate::noise::SensorNoise;
use crate::preprocess::PreprocessConfig;
use crate::simulated_noise::NoiseSimulation;
use crate::track::{TrackerConfig, TrackerMode};
use thiserror::Error;

/// Everything the pipeline needs to know.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SlamConfig {
    /// Camera intrinsics at the input resolution.
    pub intrinsics: Intrinsics,
    /// Track and fuse at half the input resolution (2x2 averaged depth and
    /// colour): about 3x faster for a small accuracy cost (see README).
    pub half_resolution: bool,
    /// Raw depth to metres.
    pub depth: DepthSettings,
    /// Filtering and pyramid.
    pub preprocess: PreprocessConfig,
    /// Tracking.
    pub tracker: TrackerConfig,
    /// Fusion and prediction.
    pub fusion: FusionConfig,
    /// Keyframe database and relocalisation of a lost camera.
    pub relocalise: RelocaliseConfig,
    /// Loop closure (the active model registered against the inactive one).
    pub loop_closure: LoopClosureConfig,
    /// When set, the first frame's depth is measured
    /// ([`crate::noise::depth_is_clean`]) and, if it is clean (rendered),
    /// tracking and fusion use this noise model instead of theirs. The
    /// ICL-NUIM preset sets it: the dataset ships clean and Kinect-noised
    /// renderings in one format, and the structured-light weighting that
    /// the noisy ones need slid clean views along a wall's join with the
    /// ceiling (1508 frames: 0.57 cm ATE against 0.03 cm unweighted).
    /// [`Self::set_noise`] clears it.
    pub clean_depth_noise: Option<SensorNoise>,
    /// Noise simulated on every pushed frame's depth before anything else
    /// reads it (a clean sequence run as a real sensor would see it;
    /// [`crate::simulated_noise`]); `None`: the depth as given.
    #[serde(default)]
    pub simulate_noise: Option<NoiseSimulation>,
    /// Frames lost in a row after which the next lost one restarts mapping
    /// ([`super::Verdict::Restarted`]): fused at the last placed pose as
    /// the first frame of a new segment, the map so far kept but inactive.
    /// 0: never; a lost camera then stays lost until it is re-acquired.
    #[serde(default = "default_restart_after_lost")]
    pub restart_after_lost: u32,
    /// Once the IMU is calibrated ([`crate::Pipeline::push_imu`]), the
    /// constant-velocity guess a frame is tracked from turns by the gyro's
    /// rotation since the last placed frame instead of the last step's
    /// (its translation stays the last step's). On by default: on the
    /// synthetic swings (`examples/imu_guess.rs`, 250 frames, calibrated
    /// at frame 89) depth only went from 10 lost frames and a restart,
    /// ATE 33.3 cm, to none lost, 10.2 cm; with colour from 4.86 to 3.34
    /// cm; the swaying phone walk (`tests/hand_held_phone.rs`) from 15.96
    /// to 13.86 cm. A recording without an IMU is not affected. The gyro
    /// is a guess, not a tight prior: a prior as narrow as the gyro's own
    /// noise (5e-5 rad a frame) would also hold on to the last pose's
    /// error against the map (the swings: 7.99 / 65.9 cm).
    #[serde(default)]
    pub imu_rotation_guess: bool,
}

/// [`SlamConfig::restart_after_lost`]'s default, in frames: see `docs/design.md`.
pub const DEFAULT_RESTART_AFTER_LOST: u32 = 10;

fn default_restart_after_lost() -> u32 {
    DEFAULT_RESTART_AFTER_LOST
}

impl SlamConfig {
    /// The published defaults for a camera preset.
    #[must_use]
    pub fn from_preset(preset: CameraPreset) -> Self {
        Self {
            intrinsics: preset.intrinsics(),
            half_resolution: false,
            depth: preset.depth_settings(),
            preprocess: PreprocessConfig::default(),
            tracker: TrackerConfig {
                mode: preset_tracker(preset),
                noise: preset.sensor_noise(),
                ..TrackerConfig::default()
            },
            fusion: FusionConfig {
                noise: preset.sensor_noise(),
                ..FusionConfig::default()
            },
            relocalise: RelocaliseConfig::default(),
            loop_closure: LoopClosureConfig::default(),
            clean_depth_noise: preset.clean_depth_noise(),
            simulate_noise: None,
            restart_after_lost: DEFAULT_RESTART_AFTER_LOST,
            imu_rotation_guess: true,
        }
    }

    /// Sets the sensor's depth noise model, which weights both tracking and
    /// fusion ([`SensorNoise::uniform`] turns the weighting off).
    pub fn set_noise(&mut self, noise: SensorNoise) {
        self.tracker.noise = noise;
        self.fusion.noise = noise;
        self.clean_depth_noise = None;
    }

    /// Intrinsics of the images tracked and fused (halved with `half_resolution`).
    #[must_use]
    pub fn working_intrinsics(&self) -> Intrinsics {
        if self.half_resolution {
            self.intrinsics.half()
        } else {
            self.intrinsics
        }
    }

    /// Pyramid levels of the images tracked: with `half_resolution`, one
    /// fewer than `preprocess.levels` (at least one), so that halving a
    /// frame drops its finest level and keeps its coarsest. A 640x480
    /// sequence at half resolution is tracked from 160x120, as at full
    /// size: from 80x60 the coarse-to-fine start slid 3.6-5 cm into a
    /// wrong basin for single frames where each circle of the noisy
    /// synthetic room starts (`examples/ten_circles.rs`: ATE 0.34 cm
    /// after ten circles, 0.076 cm from 160x120), and the noisy long
    /// ICL-NUIM office slid along its ceiling-wall join (seeds 2 / 3:
    /// 3.9 / 3.5 cm, 0.65 / 0.64 cm from 160x120).
    #[must_use]
    pub fn working_levels(&self) -> usize {
        if self.half_resolution {
            self.preprocess.levels.saturating_sub(1).max(1)
        } else {
            self.preprocess.levels
        }
    }

    /// Checks intrinsics, depth settings and pyramid against each other.
    pub fn validate(&self) -> Result<(), PipelineError> {
        let k = &self.intrinsics;
        let intrinsics_error =
            |problem: String| PipelineError::InvalidConfig(format!("camera intrinsics: {problem}"));
        let problem = k.problem();
        let size_ok = (1..=16384).contains(&k.width) && (1..=16384).contains(&k.height);
        if !size_ok {
            if let Some(problem) = problem {
                return Err(intrinsics_error(problem));
            }
        }
        // An image too small for the pyramid is the more basic problem:
        // reported before the focal length and principal point.
        let levels = self.preprocess.levels;
        let working = self.working_intrinsics();
        let min_side = working.width.min(working.height);
        if levels == 0 || levels > 5 || (min_side >> (levels - 1)) < 8 {
            return Err(PipelineError::InvalidConfig(format!(
                "{levels} pyramid levels do not fit a {}x{} image",
                working.width, working.height
            )));
        }
        if let Some(problem) = problem {
            return Err(intrinsics_error(problem));
        }
        self.depth.validate()?;
        for noise in [&self.tracker.noise, &self.fusion.noise]
            .into_iter()
            .chain(self.clean_depth_noise.as_ref())
        {
            if let Some(problem) = noise.problem() {
                return Err(PipelineError::InvalidConfig(problem));
            }
        }
        if self.tracker.iterations.len() < levels {
            return Err(PipelineError::InvalidConfig(format!(
                "tracker needs iterations for {levels} levels, got {:?}",
                self.tracker.iterations
            )));
        }
        Ok(())
    }
}

/// The tracker a preset's sequences are tracked with by default.
///
/// - ICL-NUIM: joint (ICP + photometric). Its office looks up at a ceiling
///   meeting a wall (two planes: the slide along their join is free in
///   geometry, pinned by the tiles and lights in colour). The long office
///   (`icl_office_kt0_long`, 503 frames at 10 Hz): clean 1.102 cm with ICP,
///   0.029 cm joint; kt0 (150 frames) 0.0122 cm either way (docs/design.md,
///   "Defaults per preset").
/// - TUM, 7-Scenes: ICP. Joint cost TUM fr3/teddy 0.75 -> 0.79 cm, and the
///   7-Scenes colour camera is not registered to its depth camera.
/// - RealSense, Stray Scanner: ICP, until recordings decide (a Stray scan
///   read natively has no colour at all).
#[must_use]
pub fn preset_tracker(preset: CameraPreset) -> TrackerMode {
    match preset {
        CameraPreset::IclNuim => TrackerMode::Joint,
        CameraPreset::TumFr1
        | CameraPreset::TumFr2
        | CameraPreset::TumFr3
        | CameraPreset::SevenScenes
        | CameraPreset::RealSenseD400
        | CameraPreset::StrayLidar => TrackerMode::Icp,
    }
}

/// Why the pipeline refused a frame or a configuration; the map is untouched.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PipelineError {
    /// The frame could not be decoded or does not fit the sequence.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The configuration is unusable.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// The frame's timestamp is NaN or infinite (seconds or frame number).
    #[error("timestamp must be a finite number, got {0}")]
    InvalidTimestamp(f64),
    /// IMU samples were refused ([`crate::Pipeline::push_imu`]).
    #[error(transparent)]
    Imu(#[from] crate::imu::ImuError),
}

/// Refuses a NaN or infinite timestamp: it would end up in the trajectory
/// file and break every evaluation against ground truth.
pub(super) fn check_timestamp(timestamp: f64) -> Result<(), PipelineError> {
    if timestamp.is_finite() {
        Ok(())
    } else {
        Err(PipelineError::InvalidTimestamp(timestamp))
    }
}
