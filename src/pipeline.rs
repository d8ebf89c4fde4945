//! The frame-by-frame SLAM loop: decode, preprocess, track against the model
//! prediction, fuse, predict for the next frame.
//!
//! Poses are `world_from_camera` (camera to world, metres); the world frame
//! is the first frame's camera frame.

use crate::camera::{CameraPreset, Intrinsics};
use crate::clock::now_ms;
use crate::frame::{DepthSettings, FrameError, RgbdFrame};
use crate::fusion::{
    remove_unstable, FusionConfig, FusionStats, Integrator, Prediction, SurfelMap,
};
use crate::preprocess::{FramePyramid, PreprocessConfig};
use crate::track::{track, LostReason, TrackerConfig, TrackerWorkspace};
use glam::DAffine3;
use thiserror::Error;

/// Everything the pipeline needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct SlamConfig {
    /// Camera intrinsics at the input resolution.
    pub intrinsics: Intrinsics,
    /// Raw depth to metres.
    pub depth: DepthSettings,
    /// Filtering and pyramid.
    pub preprocess: PreprocessConfig,
    /// Tracking.
    pub tracker: TrackerConfig,
    /// Fusion and prediction.
    pub fusion: FusionConfig,
}

impl SlamConfig {
    /// The published defaults for a camera preset.
    #[must_use]
    pub fn from_preset(preset: CameraPreset) -> Self {
        Self {
            intrinsics: preset.intrinsics(),
            depth: preset.depth_settings(),
            preprocess: PreprocessConfig::default(),
            tracker: TrackerConfig::default(),
            fusion: FusionConfig::default(),
        }
    }

    /// Checks intrinsics, depth settings and pyramid against each other.
    pub fn validate(&self) -> Result<(), PipelineError> {
        if !self.intrinsics.is_valid() {
            return Err(PipelineError::InvalidConfig(format!(
                "intrinsics must be finite with |f| > 1 px and a size of 1..=16384 px: {:?}",
                self.intrinsics
            )));
        }
        self.depth.validate()?;
        let levels = self.preprocess.levels;
        let min_side = self.intrinsics.width.min(self.intrinsics.height);
        if levels == 0 || levels > 5 || (min_side >> (levels - 1)) < 8 {
            return Err(PipelineError::InvalidConfig(format!(
                "{levels} pyramid levels do not fit a {}x{} image",
                self.intrinsics.width, self.intrinsics.height
            )));
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

/// Why the pipeline refused a frame or a configuration; the map is untouched.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PipelineError {
    /// The frame could not be decoded or does not fit the sequence.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The configuration is unusable.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
}

/// Tracking outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// First frame of the map: pose set to identity.
    Initialised,
    /// Tracked against the model and fused.
    Tracked,
    /// Not tracked; not fused; the pose is held at the last good one.
    Lost(LostReason),
}

impl Verdict {
    /// Short name: `initialised`, `tracked`, `lost`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Verdict::Initialised => "initialised",
            Verdict::Tracked => "tracked",
            Verdict::Lost(_) => "lost",
        }
    }
}

/// Milliseconds spent in each stage of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// PNG decoding (0 when the caller passed decoded buffers).
    pub decode_ms: f64,
    /// Bilateral filter, pyramid, vertex and normal maps.
    pub preprocess_ms: f64,
    /// Tracking.
    pub track_ms: f64,
    /// Fusion (index map, merge, add, cleanup).
    pub fuse_ms: f64,
    /// Model prediction for the next frame.
    pub predict_ms: f64,
    /// Whole frame.
    pub total_ms: f64,
}

/// What happened to one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// Frame index within this run (0-based).
    pub index: u32,
    /// The caller's timestamp (seconds or frame number).
    pub timestamp: f64,
    /// Estimated camera pose (camera to world).
    pub world_from_camera: DAffine3,
    /// Tracked, lost or initialised.
    pub verdict: Verdict,
    /// Inlier correspondences at the finest level.
    pub inliers: usize,
    /// Inliers over projected model points.
    pub inlier_ratio: f64,
    /// RMS point-to-plane residual, metres.
    pub residual_rms_m: f64,
    /// Conditioning of the final 6x6 system.
    pub conditioning: f64,
    /// Surfels in the map after this frame.
    pub surfels: usize,
    /// Fusion counts.
    pub fusion: FusionStats,
    /// Stage timings.
    pub timings: StageTimings,
}

/// Dense RGB-D SLAM state: the map, the trajectory and reusable buffers.
#[derive(Debug)]
pub struct Pipeline {
    config: SlamConfig,
    pyramid: FramePyramid,
    map: SurfelMap,
    prediction: Prediction,
    integrator: Integrator,
    tracker: TrackerWorkspace,
    trajectory: Vec<(f64, DAffine3)>,
    last_good: Option<DAffine3>,
    frame_index: u32,
}

impl Pipeline {
    /// Creates an empty pipeline after validating `config`.
    pub fn new(config: SlamConfig) -> Result<Self, PipelineError> {
        config.validate()?;
        Ok(Self {
            pyramid: FramePyramid::new(&config.intrinsics, &config.preprocess),
            config,
            map: SurfelMap::default(),
            prediction: Prediction::default(),
            integrator: Integrator::default(),
            tracker: TrackerWorkspace::default(),
            trajectory: Vec::new(),
            last_good: None,
            frame_index: 0,
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &SlamConfig {
        &self.config
    }

    /// The surfel map (world frame).
    #[must_use]
    pub fn map(&self) -> &SurfelMap {
        &self.map
    }

    /// `(timestamp, world_from_camera)` of every frame pushed so far.
    #[must_use]
    pub fn trajectory(&self) -> &[(f64, DAffine3)] {
        &self.trajectory
    }

    /// Surfel index range added, merged or moved since the last call (for
    /// incremental GPU uploads); see [`SurfelMap::take_changed_range`].
    pub fn take_changed_range(&mut self) -> std::ops::Range<usize> {
        self.map.take_changed_range()
    }

    /// Number of frames accepted so far.
    #[must_use]
    pub fn frames(&self) -> u32 {
        self.frame_index
    }

    /// Forgets the map and trajectory, keeping configuration and buffers.
    pub fn reset(&mut self) {
        self.map.clear();
        self.trajectory.clear();
        self.last_good = None;
        self.frame_index = 0;
        self.prediction.valid = 0;
    }

    /// Decodes colour and depth image bytes and processes the frame.
    pub fn push_png(
        &mut self,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        let t0 = now_ms();
        let frame = RgbdFrame::from_png_bytes(colour, depth, &self.config.depth)?;
        let decode_ms = now_ms() - t0;
        let mut report = self.push_frame(&frame, timestamp)?;
        report.timings.decode_ms = decode_ms;
        report.timings.total_ms += decode_ms;
        Ok(report)
    }

    /// Processes one decoded frame. On error nothing changes.
    pub fn push_frame(
        &mut self,
        frame: &RgbdFrame,
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        let k = self.config.intrinsics;
        frame.expect_size(k.width, k.height)?;
        let t0 = now_ms();
        self.pyramid.build(frame, &self.config.preprocess);
        let t1 = now_ms();

        let index = self.frame_index;
        let (verdict, pose, stats) = match self.last_good {
            None => (Verdict::Initialised, DAffine3::IDENTITY, None),
            Some(previous) => {
                let result = track(
                    &self.pyramid,
                    &self.prediction,
                    &previous,
                    &self.config.tracker,
                    &mut self.tracker,
                );
                match result.lost {
                    None => (Verdict::Tracked, result.world_from_camera, Some(result)),
                    Some(reason) => (Verdict::Lost(reason), previous, Some(result)),
                }
            }
        };
        let t2 = now_ms();

        let mut fusion = FusionStats::default();
        let mut t3 = t2;
        if !matches!(verdict, Verdict::Lost(_)) {
            fusion = self.integrator.integrate(
                &mut self.map,
                &self.pyramid,
                &k,
                &pose,
                index,
                &self.config.fusion,
            );
            if index % self.config.fusion.cleanup_interval_frames.max(1) == 0 {
                fusion.removed = remove_unstable(&mut self.map, &self.config.fusion, index);
            }
            t3 = now_ms();
            let fusion_cfg = self.config.fusion;
            let map = &self.map;
            self.prediction
                .render(map, &pose, &k, fusion_cfg.depth_gate_m, |i| {
                    fusion_cfg.predicts(map, i, index)
                });
            self.tracker
                .remember_frame(&self.pyramid, &pose, &self.config.tracker);
            self.last_good = Some(pose);
        }
        let t4 = now_ms();

        self.trajectory.push((timestamp, pose));
        self.frame_index += 1;
        Ok(FrameReport {
            index,
            timestamp,
            world_from_camera: pose,
            verdict,
            inliers: stats.map_or(0, |s| s.inliers),
            inlier_ratio: stats.map_or(1.0, |s| s.inlier_ratio),
            residual_rms_m: stats.map_or(0.0, |s| s.residual_rms_m),
            conditioning: stats.map_or(1.0, |s| s.conditioning),
            surfels: self.map.len(),
            fusion,
            timings: StageTimings {
                decode_ms: 0.0,
                preprocess_ms: t1 - t0,
                track_ms: t2 - t1,
                fuse_ms: t3 - t2,
                predict_ms: t4 - t3,
                total_ms: t4 - t0,
            },
        })
    }
}
