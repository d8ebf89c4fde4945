//! The frame-by-frame SLAM loop: decode, preprocess, track against the model
//! prediction, fuse, predict for the next frame.
//!
//! Poses are `world_from_camera` (camera to world, metres); the world frame
//! is the first frame's camera frame.

use crate::camera::{CameraPreset, Intrinsics};
use crate::clock::now_ms;
use crate::features::SparseEstimator;
use crate::frame::{DecodeScratch, DepthSettings, FrameError, RgbdFrame};
use crate::fusion::{
    remove_unstable, FusionConfig, FusionStats, Integrator, Measured, Prediction, SpatialOrder,
    SurfelMap,
};
use crate::noise::SensorNoise;
use crate::preprocess::{half_resolution_into, FramePyramid, PreprocessConfig};
use crate::se3;
use crate::track::verify::{free_space_violation, TrackingChecks};
use crate::track::{track, LostReason, TrackerConfig, TrackerMode, TrackerWorkspace};
use glam::DAffine3;
use thiserror::Error;

/// Everything the pipeline needs to know.
#[derive(Debug, Clone, PartialEq)]
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
                noise: preset.sensor_noise(),
                ..TrackerConfig::default()
            },
            fusion: FusionConfig {
                noise: preset.sensor_noise(),
                ..FusionConfig::default()
            },
        }
    }

    /// Sets the sensor's depth noise model, which weights both tracking and
    /// fusion ([`SensorNoise::uniform`] turns the weighting off).
    pub fn set_noise(&mut self, noise: SensorNoise) {
        self.tracker.noise = noise;
        self.fusion.noise = noise;
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
        for noise in [&self.tracker.noise, &self.fusion.noise] {
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
}

/// Refuses a NaN or infinite timestamp: it would end up in the trajectory
/// file and break every evaluation against ground truth.
fn check_timestamp(timestamp: f64) -> Result<(), PipelineError> {
    if timestamp.is_finite() {
        Ok(())
    } else {
        Err(PipelineError::InvalidTimestamp(timestamp))
    }
}

/// Tracking outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// First frame of the map: pose set to identity.
    Initialised,
    /// Tracked against the model and fused.
    Tracked,
    /// Re-acquired against the model and fused: the frame before was lost,
    /// or the normal tracker failed on this frame and the wider
    /// re-acquisition search (see [`Pipeline::push_frame`]) succeeded.
    Recovered,
    /// Not tracked; not fused; the pose is held at the last good one.
    Lost(LostReason),
}

impl Verdict {
    /// Short name: `initialised`, `tracked`, `recovered`, `lost`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Verdict::Initialised => "initialised",
            Verdict::Tracked => "tracked",
            Verdict::Recovered => "recovered",
            Verdict::Lost(_) => "lost",
        }
    }

    /// True when the frame was fused (initialised, tracked or recovered).
    #[must_use]
    pub fn is_fused(&self) -> bool {
        !matches!(self, Verdict::Lost(_))
    }
}

/// How many frames got each verdict since creation or the last reset.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VerdictCounts {
    /// Frames tracked normally (the first frame included).
    pub tracked: u32,
    /// Frames lost (not fused).
    pub lost: u32,
    /// Frames re-acquired after a loss.
    pub recovered: u32,
    /// Frames lost in a row up to the last one (0 when tracking).
    pub lost_streak: u32,
}

/// Re-acquisition accepts a pose only from a view that pins all six degrees
/// of freedom well: without the previous frame's pose as a prior, ICP on a
/// view dominated by one or two planes slides along them to a wrong pose with
/// a tiny residual. Measured (conditioning of the final 6x6 system): every
/// tracked frame of TUM fr3/teddy >= 0.0079; a synthetic view of a wall and
/// the floor that slid 22 cm on re-acquisition: 0.0005.
const RECOVERY_MIN_CONDITIONING: f64 = 2e-3;

/// Re-acquisition search: gates wide enough to pull in a pose several
/// frames' motion away (dropped frames, a fast turn), more iterations at the
/// coarse levels where the wide gate is cheap. Its result is then checked by
/// the normal tracker, so the wide gates never decide alone.
fn recovery_tracker(normal: &TrackerConfig) -> TrackerConfig {
    let mut wide = normal.clone();
    wide.gates.distance_gate_m = (normal.gates.distance_gate_m * 3.0).max(0.3);
    wide.gates.normal_gate_deg = normal.gates.normal_gate_deg.max(45.0);
    wide.gates.huber_m = normal.gates.huber_m * 2.0;
    let last = wide.iterations.len().saturating_sub(1);
    for (level, n) in wide.iterations.iter_mut().enumerate() {
        // Finest level unchanged; coarser levels get 3x, the coarsest 4x.
        *n = match level {
            0 => *n,
            l if l == last => *n * 4,
            _ => *n * 3,
        };
    }
    // Motion plausibility is judged against the last good pose by the caller.
    wide.max_translation_m = f64::INFINITY;
    wide.max_rotation_deg = f64::INFINITY;
    wide
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
    /// Surfels the map holds after this frame ([`SurfelMap::live_len`]: the
    /// PLY export's vertex count).
    pub surfels: usize,
    /// Slots in the map's arrays after this frame ([`SurfelMap::len`]): the
    /// surfels plus those absorbed into others and not yet compacted away.
    pub surfel_slots: usize,
    /// Fusion counts.
    pub fusion: FusionStats,
    /// Verdict counts of the run so far, this frame included.
    pub counts: VerdictCounts,
    /// What the independent checks of the tracking result said.
    pub checks: TrackingChecks,
    /// Stage timings.
    pub timings: StageTimings,
}

/// Dense RGB-D SLAM state: the map, the trajectory and reusable buffers.
#[derive(Debug)]
pub struct Pipeline {
    config: SlamConfig,
    pyramid: FramePyramid,
    /// The input at half resolution, when `half_resolution` is set.
    half_frame: RgbdFrame,
    /// The last frame decoded by `push_png`, and the decoder's buffers.
    decoded: RgbdFrame,
    /// `decoded` is the frame of the last push, and that push succeeded.
    decoded_was_pushed: bool,
    scratch: DecodeScratch,
    map: SurfelMap,
    prediction: Prediction,
    integrator: Integrator,
    /// Buffer for sorting settled surfels in space at cleanups.
    order: SpatialOrder,
    tracker: TrackerWorkspace,
    trajectory: Vec<(f64, DAffine3)>,
    last_good: Option<DAffine3>,
    frame_index: u32,
    counts: VerdictCounts,
    recovery: TrackerConfig,
    /// Features of the last fused frame and of the current one.
    sparse: SparseEstimator,
    /// `previous_from_current` of the last two fused frames in a row.
    velocity: Option<DAffine3>,
}

impl Pipeline {
    /// Creates an empty pipeline after validating `config`.
    pub fn new(config: SlamConfig) -> Result<Self, PipelineError> {
        config.validate()?;
        // Grey levels are read only by the photometric term.
        let photometric = config.tracker.mode != TrackerMode::Icp;
        let mut pyramid = FramePyramid::new(&config.working_intrinsics(), &config.preprocess);
        pyramid.with_intensity = photometric;
        Ok(Self {
            pyramid,
            half_frame: RgbdFrame::default(),
            decoded: RgbdFrame::default(),
            decoded_was_pushed: false,
            scratch: DecodeScratch::default(),
            recovery: recovery_tracker(&config.tracker),
            sparse: SparseEstimator::new(config.tracker.verify.features)
                .map_err(|e| PipelineError::InvalidConfig(e.to_string()))?,
            velocity: None,
            config,
            map: SurfelMap::default(),
            prediction: Prediction::new(photometric),
            integrator: Integrator::default(),
            order: SpatialOrder::default(),
            tracker: TrackerWorkspace::default(),
            trajectory: Vec::new(),
            last_good: None,
            frame_index: 0,
            counts: VerdictCounts::default(),
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

    /// Surfel slots filled by new surfels or by surfels moved by a cleanup
    /// or a spatial sort since the last call (for incremental GPU uploads),
    /// within `0..map().len()`. Merges are not included: see
    /// [`SurfelMap::take_changed_range`].
    pub fn take_changed_range(&mut self) -> std::ops::Range<usize> {
        self.map.take_changed_range()
    }

    /// The frame of the last push when it was decoded here (`push_png`,
    /// `push_pixels_and_depth_png`) and accepted; `None` after a failed push,
    /// a push of an already decoded frame, or a reset. Input resolution.
    #[must_use]
    pub fn last_decoded_frame(&self) -> Option<&RgbdFrame> {
        self.decoded_was_pushed.then_some(&self.decoded)
    }

    /// Number of frames accepted so far.
    #[must_use]
    pub fn frames(&self) -> u32 {
        self.frame_index
    }

    /// Verdict counts since creation or the last reset.
    #[must_use]
    pub fn counts(&self) -> VerdictCounts {
        self.counts
    }

    /// Forgets the map and trajectory, keeping configuration and buffers.
    /// Everything that indexes the map or remembers a frame is forgotten or
    /// rebuilt before it is read, so the pipeline then behaves as a new one:
    /// the same frames give the same trajectory (to the rounding of parallel
    /// sums; `tests/reset_replay.rs`, `tests/pipeline_properties.rs`).
    pub fn reset(&mut self) {
        self.map.clear();
        // The sorted runs index the old map: kept, the next cleanup would
        // read past the new one's end.
        self.order.clear();
        self.trajectory.clear();
        self.last_good = None;
        self.sparse.clear();
        self.velocity = None;
        self.frame_index = 0;
        self.counts = VerdictCounts::default();
        self.prediction.clear();
        self.decoded_was_pushed = false;
    }

    /// Decodes colour and depth image bytes and processes the frame.
    pub fn push_png(
        &mut self,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decode_and_push(timestamp, |frame, settings, scratch| {
            frame.decode_into(colour, depth, settings, scratch)
        })
    }

    /// Processes a frame whose colour was decoded by the caller (RGBA8 or
    /// RGB8 pixels, `width` x `height`: a browser decodes colour PNGs and
    /// JPEGs faster than wasm) with a 16-bit depth PNG decoded here (a
    /// browser would reduce it to 8 bits). `decode_ms` counts the depth.
    pub fn push_pixels_and_depth_png(
        &mut self,
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decode_and_push(timestamp, |frame, settings, scratch| {
            frame.decode_depth_with_pixels_into(width, height, colour, depth, settings, scratch)
        })
    }

    /// Processes a frame given as buffers: `colour` RGBA8 or RGB8 and
    /// `depth` in raw units (`config.depth.scale` per metre, 0 = none), both
    /// row-major `width` x `height` (see [`RgbdFrame::from_raw`]).
    pub fn push_raw(
        &mut self,
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u16],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        let frame = RgbdFrame::from_raw(width, height, colour, depth, &self.config.depth)?;
        self.push_frame(&frame, timestamp)
    }

    /// Runs `decode` into the reused frame buffers, then [`Pipeline::push_frame`];
    /// the report's `decode_ms` is `decode`'s time.
    fn decode_and_push(
        &mut self,
        timestamp: f64,
        decode: impl FnOnce(
            &mut RgbdFrame,
            &DepthSettings,
            &mut DecodeScratch,
        ) -> Result<(), FrameError>,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        check_timestamp(timestamp)?;
        let t0 = now_ms();
        // Decoded into buffers kept from frame to frame; taken out of `self`
        // for the call below and put back whatever its outcome.
        let mut frame = std::mem::take(&mut self.decoded);
        let decoded = decode(&mut frame, &self.config.depth, &mut self.scratch);
        let decode_ms = now_ms() - t0;
        let pushed = decoded
            .map_err(PipelineError::from)
            .and_then(|()| self.push_frame(&frame, timestamp));
        self.decoded = frame;
        self.decoded_was_pushed = pushed.is_ok();
        let mut report = pushed?;
        report.timings.decode_ms = decode_ms;
        report.timings.total_ms += decode_ms;
        Ok(report)
    }

    /// Tracks the pyramid's frame from `previous` (the last good pose), or
    /// from `previous` moved on by the last frame-to-frame motion when the
    /// constant-velocity prior is on.
    ///
    /// A dense result is accepted as it stands only when it passed the
    /// tracker's own tests, its points do not land in the model's free
    /// space, and it moved the camera little (where dense tracking is
    /// reliable). Otherwise the sparse feature estimate (this frame against
    /// the last fused one) is asked: the dense result stands if the two
    /// agree; if not, the dense tracker is started again at the sparse
    /// estimate and its result counts only if it passes the same tests and
    /// agrees with the sparse estimate. Without a sparse estimate, the
    /// wider re-acquisition search runs from `previous` against the model
    /// prediction (still the one rendered at `previous`: lost frames do not
    /// touch it); its result counts only if the normal tracker, started
    /// there, accepts it, it does not violate free space, and the motion
    /// since `previous` is plausible for the number of frames lost.
    fn track_or_recover(
        &mut self,
        previous: &DAffine3,
    ) -> (
        Verdict,
        DAffine3,
        Option<crate::track::TrackResult>,
        TrackingChecks,
    ) {
        let normal = &self.config.tracker;
        let verify = normal.verify;
        let workspace = &mut self.tracker;
        let was_lost = self.counts.lost_streak > 0;
        let guess = match self.velocity {
            Some(velocity) if verify.constant_velocity && !was_lost => *previous * velocity,
            _ => *previous,
        };
        let mut checks = TrackingChecks::default();
        let first = track(&self.pyramid, &self.prediction, &guess, normal, workspace);
        checks.first_dense = Some(first.world_from_camera);
        // The coarsest level's points (160x120 from 640x480) tell a right
        // pose (violations <= 1 %) from a wrong one (>= 19 %) at a
        // sixteenth of the full resolution's cost.
        let free_space_vertices = self.pyramid.levels.last().map_or(&[][..], |l| &l.vertices);
        let free_space = |pose: &DAffine3| {
            free_space_violation(&self.prediction, free_space_vertices, 1, pose, &verify).0
        };
        let pinned = |r: &crate::track::TrackResult| {
            !was_lost || r.conditioning >= RECOVERY_MIN_CONDITIONING
        };
        let passes = |r: &crate::track::TrackResult| {
            r.lost.is_none() && r.world_from_camera.is_finite() && pinned(r)
        };
        let accepted = if was_lost {
            Verdict::Recovered
        } else {
            Verdict::Tracked
        };
        let first_ok = passes(&first);
        checks.free_space_first = if first_ok {
            free_space(&first.world_from_camera)
        } else {
            0.0
        };
        let free_ok = |fraction: f64| fraction <= verify.max_free_space_fraction;
        let moved = |pose: &DAffine3| {
            [previous, &guess].iter().any(|from| {
                let (dt, dr) = se3::motion_magnitude(&(from.inverse() * *pose));
                dt > verify.sparse_above_m || dr.to_degrees() > verify.sparse_above_deg
            })
        };
        let first_clean = first_ok && free_ok(checks.free_space_first);
        if first_clean && !moved(&first.world_from_camera) && !verify.sparse_always {
            checks.free_space_final = checks.free_space_first;
            return (accepted, first.world_from_camera, Some(first), checks);
        }
        // The sparse estimate: this frame against the last fused one, whose
        // pose is `previous`.
        let sparse = if self.sparse.has_reference() {
            checks.sparse_ran = true;
            self.sparse.estimate()
        } else {
            None
        };
        let lost = |result: crate::track::TrackResult, checks: TrackingChecks| {
            let reason = result.lost.unwrap_or(LostReason::IllConditioned);
            (Verdict::Lost(reason), *previous, Some(result), checks)
        };
        if let Some(estimate) = sparse {
            let sparse_pose = *previous * estimate.reference_from_current;
            checks.sparse = Some((sparse_pose, estimate.inliers));
            checks.sparse_rms_m = estimate.rms_m;
            if first_clean && verify.agree(&first.world_from_camera, &sparse_pose) {
                checks.free_space_final = checks.free_space_first;
                return (accepted, first.world_from_camera, Some(first), checks);
            }
            let second = track(
                &self.pyramid,
                &self.prediction,
                &sparse_pose,
                normal,
                workspace,
            );
            // Started at the sparse estimate, the dense tracker must land
            // near it, or back on its first result (the sparse estimate is
            // the less accurate of the two: on TUM fr3/teddy at strides 3-8
            // it is up to 4.6 cm / 2.9 degrees from a dense result 1.6 cm
            // from the truth). Not on a view that pins the pose poorly:
            // there both dense runs slide to the same wrong place (the
            // synthetic room's wall-and-floor views, 14 cm).
            let landed = |pose: &DAffine3| {
                verify.landed_near(pose, &sparse_pose)
                    || (first_clean
                        && first.conditioning >= RECOVERY_MIN_CONDITIONING
                        && verify.same_basin(pose, &first.world_from_camera))
            };
            if passes(&second) && landed(&second.world_from_camera) {
                let fraction = free_space(&second.world_from_camera);
                if free_ok(fraction) {
                    checks.free_space_final = fraction;
                    checks.from_sparse = true;
                    return (accepted, second.world_from_camera, Some(second), checks);
                }
            }
            // The dense tracker cannot hold a view that pins the pose poorly
            // (from a start 0.5 cm off it slides 30 cm along the synthetic
            // room's wall and floor); a strong, tight feature estimate that
            // keeps free space clear is then the better answer, unrefined.
            let strong = estimate.inliers >= verify.sparse_only_min_inliers
                && estimate.rms_m <= verify.sparse_only_max_rms_m;
            if strong && second.conditioning < RECOVERY_MIN_CONDITIONING {
                let fraction = free_space(&sparse_pose);
                if free_ok(fraction) {
                    checks.free_space_final = fraction;
                    checks.from_sparse = true;
                    checks.sparse_only = true;
                    return (accepted, sparse_pose, Some(second), checks);
                }
            }
            let mut result = if first_ok { second } else { first };
            if result.lost.is_none() {
                result.lost = Some(LostReason::Inconsistent);
            }
            return lost(result, checks);
        }
        if first_clean {
            // Moved far, and no feature estimate to confirm or refute it:
            // the dense result and free space are all there is.
            checks.free_space_final = checks.free_space_first;
            return (accepted, first.world_from_camera, Some(first), checks);
        }
        let mut first = first;
        if first_ok {
            first.lost = Some(LostReason::Inconsistent);
        }
        // Nothing to search with: skip the (costlier) wide attempt.
        if first.lost == Some(LostReason::TooFewInliers) && first.inliers < normal.min_inliers / 4 {
            return lost(first, checks);
        }
        let wide = track(
            &self.pyramid,
            &self.prediction,
            previous,
            &self.recovery,
            workspace,
        );
        if !wide.world_from_camera.is_finite() {
            return lost(first, checks);
        }
        let check = track(
            &self.pyramid,
            &self.prediction,
            &wide.world_from_camera,
            normal,
            workspace,
        );
        // The camera may have moved for every frame lost since `previous`.
        let frames = f64::from(self.counts.lost_streak.min(10) + 1);
        let (dt, dr) = se3::motion_magnitude(&(previous.inverse() * check.world_from_camera));
        let plausible = dt <= normal.max_translation_m * frames
            && dr.to_degrees() <= (normal.max_rotation_deg * frames).min(90.0);
        if check.lost.is_none()
            && plausible
            && check.conditioning >= RECOVERY_MIN_CONDITIONING
            && check.world_from_camera.is_finite()
        {
            let fraction = free_space(&check.world_from_camera);
            if free_ok(fraction) {
                checks.free_space_final = fraction;
                return (
                    Verdict::Recovered,
                    check.world_from_camera,
                    Some(check),
                    checks,
                );
            }
        }
        lost(first, checks)
    }

    /// Processes one decoded frame stamped `timestamp` (seconds or frame
    /// number; must be finite). On error nothing changes.
    ///
    /// A frame judged lost is not fused and its pose is held at the last good
    /// one. While lost (and whenever the normal tracker fails) a wider
    /// re-acquisition search runs from the last good pose against the model
    /// seen from there; a re-acquired frame is reported as
    /// [`Verdict::Recovered`] and fused. When the map is at
    /// `FusionConfig::max_surfels`, stale unstable surfels are evicted first,
    /// then new surfels are skipped (`FusionStats::skipped`).
    pub fn push_frame(
        &mut self,
        frame: &RgbdFrame,
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        check_timestamp(timestamp)?;
        let input = self.config.intrinsics;
        frame.expect_size(input.width, input.height)?;
        frame.validate()?;
        let k = self.config.working_intrinsics();
        let t0 = now_ms();
        let frame = if self.config.half_resolution {
            let gate = 3.0 * self.config.preprocess.sigma_depth_m;
            half_resolution_into(frame, gate, &mut self.half_frame);
            &self.half_frame
        } else {
            frame
        };
        self.pyramid.build(frame, &self.config.preprocess);
        let t1 = now_ms();

        let index = self.frame_index;
        // Kept for the sparse estimate (this frame against the last fused
        // one); corners are found only when an estimate is asked for. A
        // frame it cannot use leaves the estimator without a current frame.
        let level0 = self.pyramid.levels.first().map_or(&[][..], |l| &l.vertices);
        let _ = self
            .sparse
            .prepare(&self.pyramid.rgb, level0, k.width, k.height);
        let (verdict, pose, stats, checks) = match self.last_good {
            None => (
                Verdict::Initialised,
                DAffine3::IDENTITY,
                None,
                TrackingChecks::default(),
            ),
            Some(previous) => self.track_or_recover(&previous),
        };
        let t2 = now_ms();

        let mut fusion = FusionStats::default();
        let mut t3 = t2;
        if verdict.is_fused() {
            let budget = self.config.fusion.max_surfels;
            if self.map.len() >= budget {
                // Full: evict stale unstable surfels now rather than at the
                // next scheduled cleanup; adds beyond the budget are skipped
                // (counted in `FusionStats::skipped`).
                fusion.removed =
                    remove_unstable(&mut self.map, &self.config.fusion, index, &mut self.order);
            }
            let removed_early = fusion.removed;
            fusion = self.integrator.integrate(
                &mut self.map,
                &self.pyramid,
                &k,
                &pose,
                index,
                &self.config.fusion,
                self.config.depth.max_m,
            );
            fusion.removed = removed_early;
            self.order.reserve_for(&self.map);
            if index % self.config.fusion.cleanup_interval_frames.max(1) == 0 {
                fusion.removed +=
                    remove_unstable(&mut self.map, &self.config.fusion, index, &mut self.order);
            }
            t3 = now_ms();
            let fusion_cfg = self.config.fusion;
            let map = &self.map;
            // The warm-up counts fused frames: frames lost early must not end
            // it before the map had the frames to become stable.
            let fused = self.counts.tracked + self.counts.recovered;
            let far_m = self.config.depth.max_m;
            // The frame just fused was taken from `pose`: what it measured
            // hides what lies behind.
            self.prediction.render(
                map,
                &pose,
                &k,
                (fusion_cfg.depth_gate_m, far_m),
                Measured {
                    vertices: self.pyramid.levels.first().map_or(&[], |l| &l.vertices),
                    tiles: self.integrator.depth_tiles(),
                },
                |i| fusion_cfg.predicts(map, i, fused),
            );
            self.tracker
                .remember_frame(&self.pyramid, &pose, &self.config.tracker);
            // The motion of two fused frames in a row: the next frame's
            // constant-velocity start.
            self.velocity = match (self.last_good, self.counts.lost_streak) {
                (Some(before), 0) => Some(before.inverse() * pose),
                _ => None,
            };
            self.sparse.current_becomes_reference();
            self.last_good = Some(pose);
        }
        let t4 = now_ms();

        match verdict {
            Verdict::Lost(_) => {
                self.counts.lost += 1;
                self.counts.lost_streak += 1;
            }
            Verdict::Recovered => {
                self.counts.recovered += 1;
                self.counts.lost_streak = 0;
            }
            Verdict::Initialised | Verdict::Tracked => {
                self.counts.tracked += 1;
                self.counts.lost_streak = 0;
            }
        }
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
            surfels: self.map.live_len(),
            surfel_slots: self.map.len(),
            fusion,
            counts: self.counts,
            checks,
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
