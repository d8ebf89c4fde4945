//! The frame-by-frame SLAM loop: decode, preprocess, track against the model
//! prediction, fuse, predict for the next frame.
//!
//! Poses are `world_from_camera` (camera to world, metres); the world frame
//! is the first frame's camera frame.
//!
//! [`Pipeline::push_frame`] reads as the stage diagram of `ARCHITECTURE.md`:
//! `preprocess` → `track` (`recovery.rs`: checks and re-acquisition) →
//! `fuse` → `close_loops` → `predict` → `count_verdict` → `report`.
//! Each stage is a method here, or in the file named after it, that owns
//! its buffers in [`Pipeline`]'s fields.

mod carried;
mod config;
mod finish;
mod imu;
mod input;
mod localise;
mod loop_stage;
mod recovery;
mod report;
mod segments;
mod settings_check;
mod state;
mod velocity;

pub use config::{preset_tracker, PipelineError, SlamConfig, DEFAULT_RESTART_AFTER_LOST};
pub use localise::Localisation;
pub use report::{FrameReport, StageTimings, Verdict, VerdictCounts};
pub use segments::Segment;
pub use settings_check::{depth_scale_warning, layout_warnings, SettingsCheck, SettingsWarning};
pub use state::{LastFusedFrame, PipelineScalars, PipelineState, StateView};

use crate::clock::now_ms;
use crate::features::SparseEstimator;
use crate::frame::{DecodeScratch, RgbdFrame};
use crate::fusion::{
    merge_copies, remove_unstable, DepthTiles, FusionStats, Integrator, Measured, Prediction,
    SpatialOrder, SurfelMap,
};
use crate::loop_closure::relocalise::Relocaliser;
use crate::loop_closure::{LoopCloser, LoopOutcome};
use crate::noise::{depth_is_clean, SensorNoise};
use crate::preprocess::camera_fixed::CameraFixedMask;
use crate::preprocess::{half_resolution_into, FramePyramid, PreprocessConfig};
use crate::track::verify::TrackingChecks;
use crate::track::{TrackerConfig, TrackerMode, TrackerWorkspace};
use config::check_timestamp;
use glam::DAffine3;
use recovery::{recovery_tracker, Tracked};

/// Dense RGB-D SLAM state: the map, the trajectory and reusable buffers.
#[derive(Debug)]
pub struct Pipeline {
    config: SlamConfig,
    pyramid: FramePyramid,
    /// The input at half resolution, when `half_resolution` is set.
    half_frame: RgbdFrame,
    /// The last frame decoded by `push_png`, and the decoder's buffers.
    decoded: RgbdFrame,
    /// The pushed frame with `SlamConfig::simulate_noise` applied.
    noisy_frame: RgbdFrame,
    /// What stays in view as the camera moves (a hand holding it).
    camera_fixed: CameraFixedMask,
    /// The pushed frame without depth where `camera_fixed` masks it.
    masked_frame: RgbdFrame,
    /// Set by [`Self::forget_what_the_camera_carried`] when it emptied the
    /// map: this push's frame starts a new one at that pose (`world_from_camera`).
    reseed_at: Option<DAffine3>,
    /// Set by [`Self::forget_what_the_camera_carried`] when it left a map:
    /// the frames the carried thing anchored, until the camera is placed
    /// again by the map from before them.
    anchored: Option<carried::Anchored>,
    /// The map's first frame as pushed (simulated noise applied), while a
    /// thing carried with the camera may still turn out to have been in
    /// it: until the mask first masks something, for at most
    /// [`carried::FIRST_FRAME_KEPT_FRAMES`] frames.
    first_frame: Option<Box<RgbdFrame>>,
    /// Set when the map was begun again from `first_frame` on this push:
    /// the last pose the carried thing anchored, whose frames take a share
    /// of the correction once this frame is tracked.
    anchored_last: Option<DAffine3>,
    /// `decoded` is the frame of the last push, and that push succeeded.
    decoded_was_pushed: bool,
    scratch: DecodeScratch,
    /// Camera settings that look wrong for the data (warnings, kept for the run).
    settings_check: SettingsCheck,
    map: SurfelMap,
    prediction: Prediction,
    integrator: Integrator,
    /// Buffer for sorting settled surfels in space at cleanups.
    order: SpatialOrder,
    tracker: TrackerWorkspace,
    trajectory: Vec<(f64, DAffine3)>,
    /// Each frame's pose as tracked, before any loop closure moved it.
    online_trajectory: Vec<(f64, DAffine3)>,
    /// Pose of the last placed frame (`world_from_camera`): the last fused
    /// one or, while lost, the last one dead-reckoned
    /// ([`crate::track::verify::VerifyConfig::dead_reckoning`]). The
    /// prediction and the sparse reference are that frame's.
    last_good: Option<DAffine3>,
    /// Index of that frame.
    placed_frame: u32,
    /// Index of the last fused frame whose pose was measured in every
    /// direction (not `Held` at the constant-velocity guess): the start
    /// of the velocity that follows a held run.
    measured_frame: Option<u32>,
    /// Depth tiles of a dead-reckoned frame, which hide what lies behind
    /// it in its prediction (a fused frame's are the integrator's).
    lost_tiles: DepthTiles,
    frame_index: u32,
    counts: VerdictCounts,
    recovery: TrackerConfig,
    /// Features of the last fused frame and of the current one.
    sparse: SparseEstimator,
    /// `previous_from_current` of the last two fused frames in a row.
    velocity: Option<DAffine3>,
    /// Keyframes of the fused frames, to place a lost camera.
    relocaliser: Relocaliser,
    /// The loop-closure stage.
    loop_closer: LoopCloser,
    /// The tracker's and fusion's noise models as configured, before the
    /// first frame's clean-depth check (`SlamConfig::clean_depth_noise`).
    configured_noise: (SensorNoise, SensorNoise),
    /// Localise mode ([`Pipeline::start_localising`]): what it keeps; `None`
    /// while mapping.
    localising: Option<Box<Localisation>>,
    /// Where the map's current segment began ([`Verdict::Restarted`]).
    segment: Segment,
    /// While a restarted segment is not joined: the last frame placed
    /// before the loss (working colour and camera-frame points), whose
    /// view of the map the segment is looked for in first.
    lost_frame: Option<Box<LastFusedFrame<Vec<u8>, Vec<glam::Vec3>>>>,
    /// IMU samples, the frames' rotations and the calibration (`imu.rs`).
    imu: imu::ImuState,
}

impl Pipeline {
    /// Creates an empty pipeline after validating `config`.
    pub fn new(config: SlamConfig) -> Result<Self, PipelineError> {
        config.validate()?;
        // Grey levels are read only by the photometric term (in ICP mode,
        // where the geometry leaves directions free).
        let photometric =
            config.tracker.mode != TrackerMode::Icp || config.tracker.colour_pins_below_m > 0.0;
        let levels = PreprocessConfig {
            levels: config.working_levels(),
            ..config.preprocess
        };
        let mut pyramid = FramePyramid::new(&config.working_intrinsics(), &levels);
        pyramid.with_intensity = photometric;
        Ok(Self {
            pyramid,
            half_frame: RgbdFrame::default(),
            decoded: RgbdFrame::default(),
            noisy_frame: RgbdFrame::default(),
            camera_fixed: CameraFixedMask::default(),
            reseed_at: None,
            masked_frame: RgbdFrame::default(),
            anchored: None,
            first_frame: None,
            anchored_last: None,
            decoded_was_pushed: false,
            scratch: DecodeScratch::default(),
            settings_check: SettingsCheck::default(),
            recovery: recovery_tracker(&config.tracker),
            sparse: SparseEstimator::new(config.tracker.verify.features)
                .map_err(|e| PipelineError::InvalidConfig(e.to_string()))?,
            velocity: None,
            relocaliser: Relocaliser::new(config.relocalise)
                .map_err(|e| PipelineError::InvalidConfig(e.to_string()))?,
            loop_closer: LoopCloser::new(config.loop_closure.clone()),
            configured_noise: (config.tracker.noise, config.fusion.noise),
            config,
            map: SurfelMap::default(),
            prediction: Prediction::new(photometric),
            integrator: Integrator::default(),
            order: SpatialOrder::default(),
            tracker: TrackerWorkspace::default(),
            trajectory: Vec::new(),
            online_trajectory: Vec::new(),
            last_good: None,
            placed_frame: 0,
            measured_frame: None,
            lost_tiles: DepthTiles::default(),
            frame_index: 0,
            counts: VerdictCounts::default(),
            localising: None,
            segment: Segment::default(),
            lost_frame: None,
            imu: imu::ImuState::default(),
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

    /// `(timestamp, world_from_camera)` of every frame pushed so far as it
    /// was tracked (online): loop closures bend [`Self::trajectory`], not
    /// this one. The two are equal until the first closure.
    #[must_use]
    pub fn online_trajectory(&self) -> &[(f64, DAffine3)] {
        &self.online_trajectory
    }

    /// Surfel slots filled by new surfels or by surfels moved by a cleanup
    /// or a spatial sort since the last call (for incremental GPU uploads),
    /// within `0..map().len()`. Merges are not included: see
    /// [`SurfelMap::take_changed_range`].
    pub fn take_changed_range(&mut self) -> std::ops::Range<usize> {
        self.map.take_changed_range()
    }

    /// The frame of the last push when it was decoded here (`push_png`,
    /// `push_rgba_depth_png`) and accepted; `None` after a failed push,
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

    /// Loop closures (map and trajectory bent) since creation or the last reset.
    #[must_use]
    pub fn loop_closures(&self) -> u32 {
        self.loop_closer.closures()
    }

    /// Of [`Self::loop_closures`], those the global check made (a place
    /// seen long ago, found among the keyframes).
    #[must_use]
    pub fn global_loop_closures(&self) -> u32 {
        self.loop_closer.global_closures()
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
    /// Leaves localise mode.
    pub fn reset(&mut self) {
        self.map.clear();
        // The sorted runs index the old map: kept, the next cleanup would
        // read past the new one's end.
        self.order.clear();
        self.trajectory.clear();
        self.online_trajectory.clear();
        self.last_good = None;
        self.placed_frame = 0;
        self.measured_frame = None;
        self.anchored = None;
        self.first_frame = None;
        self.anchored_last = None;
        self.sparse.clear();
        self.relocaliser.clear();
        self.velocity = None;
        self.frame_index = 0;
        self.counts = VerdictCounts::default();
        self.prediction.clear();
        self.loop_closer.reset();
        self.decoded_was_pushed = false;
        self.localising = None;
        self.camera_fixed = CameraFixedMask::default();
        self.segment = Segment::default();
        self.lost_frame = None;
        self.reset_imu();
    }

    /// Processes one decoded frame stamped `timestamp` (seconds or frame
    /// number; must be finite). On error nothing changes.
    ///
    /// A frame judged lost is not fused; its pose is carried on from the
    /// last placed frame by the sparse feature estimate when one is tight
    /// enough (dead reckoning, `VerifyConfig::dead_reckoning`), else held
    /// at the last placed one. While lost (and whenever the normal tracker
    /// fails) a wider re-acquisition search runs from the last placed pose
    /// against the model seen from there, and if that fails, relocalisation
    /// from the keyframes that look like the frame
    /// (`loop_closure::relocalise`); a re-acquired frame is reported as
    /// [`Verdict::Recovered`] and fused. When the map is at
    /// `FusionConfig::max_surfels`, stale unstable surfels are evicted first,
    /// then new surfels are skipped (`FusionStats::skipped`).
    ///
    /// In localise mode ([`Pipeline::start_localising`]) the frame is only
    /// placed in the map, which does not change (`localise.rs`).
    pub fn push_frame(
        &mut self,
        frame: &RgbdFrame,
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        crate::pool::on_pool(|| self.push_frame_here(frame, timestamp))
    }

    fn push_frame_here(
        &mut self,
        frame: &RgbdFrame,
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        check_timestamp(timestamp)?;
        let input = self.config.intrinsics;
        frame.expect_size(input.width, input.height)?;
        frame.validate()?;
        // Taken out and put back: the stages borrow the pipeline mutably.
        let mut noisy = std::mem::take(&mut self.noisy_frame);
        let mut masked = std::mem::take(&mut self.masked_frame);
        let mut frame = frame;
        if let Some(simulation) = self.config.simulate_noise {
            noisy.width = frame.width;
            noisy.height = frame.height;
            noisy.rgb.clone_from(&frame.rgb);
            simulation.apply_into(
                &frame.depth_m,
                frame.width,
                input.fx,
                u64::from(self.frame_index),
                &mut noisy.depth_m,
            );
            frame = &noisy;
        }
        let min_frames = self.config.preprocess.camera_fixed_frames;
        self.keep_first_frame(frame, min_frames);
        let mut masked_share = 0.0;
        let masked_before = self.camera_fixed.masked_count();
        if min_frames > 0 && self.camera_fixed.observe(frame, min_frames) > 0 {
            // Localising leaves the map as mapping built it.
            if masked_before == 0 && self.localising.is_none() {
                self.forget_what_the_camera_carried();
            }
            masked_share = self.camera_fixed.apply_into(frame, &mut masked);
            frame = &masked;
        }
        let mut report = self.push_valid(frame, timestamp);
        self.reseed_at = None;
        report.camera_fixed_share = masked_share;
        self.noisy_frame = noisy;
        self.masked_frame = masked;
        Ok(report)
    }

    /// [`Self::push_frame`] for a frame of the right size that passed
    /// validation (with the simulated noise, when configured).
    fn push_valid(&mut self, frame: &RgbdFrame, timestamp: f64) -> FrameReport {
        if let Some(localisation) = self.localising.take() {
            let (report, localisation) = self.localise_frame(frame, timestamp, localisation);
            self.localising = Some(localisation);
            return report;
        }
        let index = self.frame_index;
        if index == 0 {
            self.choose_noise(frame);
        }
        let t0 = now_ms();
        self.preprocess(frame);
        let t1 = now_ms();
        let mut tracked = self.track(timestamp);
        self.dead_reckon(&mut tracked);
        self.restart_if_lost_long(&mut tracked);
        let as_tracked = tracked.pose;
        let t2 = now_ms();
        let mut fusion = FusionStats::default();
        let mut closure = LoopOutcome::default();
        let (mut t3, mut t3b) = (t2, t2);
        if tracked.verdict.is_fused() {
            fusion = self.fuse(&tracked.pose, index);
            t3 = now_ms();
            // After fusion (the map holds what this frame saw), before the
            // prediction (so that it shows the map as corrected).
            closure = self.close_loops(&mut tracked.pose, index);
            if let Some(joined) = self.join_segment(&mut tracked.pose, index) {
                closure.closed = true;
                closure.joined = Some(joined);
            }
            t3b = now_ms();
            // A held frame placed by the sparse estimate measured its held
            // directions by features; only one held at the guess did not.
            let at_guess = tracked.verdict == Verdict::Held && !tracked.checks.from_sparse;
            let interval_s = self
                .trajectory
                .last()
                .map_or(f64::NAN, |&(before, _)| timestamp - before);
            self.predict(&tracked.pose, (at_guess, interval_s));
        }
        let t4 = now_ms();
        self.count_verdict(tracked.verdict);
        self.observe_imu(timestamp, &as_tracked, tracked.verdict);
        self.trajectory.push((timestamp, tracked.pose));
        self.online_trajectory.push((timestamp, as_tracked));
        self.frame_index += 1;
        let timings = StageTimings {
            decode_ms: 0.0,
            preprocess_ms: t1 - t0,
            track_ms: t2 - t1,
            fuse_ms: t3 - t2,
            loop_ms: t3b - t3,
            predict_ms: t4 - t3b,
            total_ms: t4 - t0,
        };
        let mut report = self.report(index, timestamp, &tracked, (fusion, closure), timings);
        report.settings_warning = self.settings_check.take_unreported();
        report
    }

    /// On the first frame: the configured noise models, or the clean-depth
    /// one when the configuration has one and the depth is clean.
    fn choose_noise(&mut self, frame: &RgbdFrame) {
        let (mut tracker, mut fusion) = self.configured_noise;
        let clean = depth_is_clean(&frame.depth_m, frame.width) == Some(true);
        if let (true, Some(model)) = (clean, self.config.clean_depth_noise) {
            (tracker, fusion) = (model, model);
        }
        self.config.tracker.noise = tracker;
        self.config.fusion.noise = fusion;
        self.recovery = recovery_tracker(&self.config.tracker);
    }

    /// Stage `preprocess`: halves the frame when asked, then builds the
    /// pyramid (filtered depth, vertices, normals, grey levels).
    fn preprocess(&mut self, frame: &RgbdFrame) {
        let frame = if self.config.half_resolution {
            let gate = 3.0 * self.config.preprocess.sigma_depth_m;
            half_resolution_into(frame, gate, &mut self.half_frame);
            &self.half_frame
        } else {
            frame
        };
        self.pyramid
            .build(frame, &self.config.preprocess, &self.config.tracker.noise);
    }

    /// Stage `track`: the pose of the pyramid's frame against the model
    /// prediction, with its verdict ([`Pipeline::track_or_recover`]); the
    /// first frame of a map is the world frame.
    fn track(&mut self, timestamp: f64) -> Tracked {
        self.keep_for_sparse_and_ferns();
        if let Some(pose) = self.reseed_at.take() {
            return Tracked {
                verdict: Verdict::Restarted,
                pose,
                result: None,
                checks: TrackingChecks::default(),
            };
        }
        let tracked = match self.last_good {
            None => Tracked {
                verdict: Verdict::Initialised,
                pose: DAffine3::IDENTITY,
                result: None,
                checks: TrackingChecks::default(),
            },
            Some(previous) => {
                let velocity = self.velocity_with_imu(timestamp);
                let interval_s = self
                    .trajectory
                    .last()
                    .map_or(f64::NAN, |&(before, _)| timestamp - before);
                self.track_or_recover(&previous, (velocity, interval_s), self.counts.lost_streak)
            }
        };
        let tracked = self.relocalise_if_lost(tracked);
        let tracked = self.place_as_before_carried(tracked);
        self.spread_over_anchored(&tracked);
        tracked
    }

    /// Keeps the pyramid's frame for the sparse estimate (this frame
    /// against the last fused one: a copy, reduced and searched for corners
    /// only when an estimate is asked for) and encodes it for the keyframe
    /// ferns. A frame the estimator cannot use leaves it without a current
    /// frame; one the fern code cannot use is neither looked up nor kept.
    fn keep_for_sparse_and_ferns(&mut self) {
        let k = self.config.working_intrinsics();
        let level0 = self.pyramid.levels.first().map_or(&[][..], |l| &l.vertices);
        let _ = self
            .sparse
            .keep_frame(&self.pyramid.rgb, level0, k.width, k.height);
        let _ = self.relocaliser.encode(&self.pyramid);
    }

    /// Stage `fuse`: integrates the frame at `pose` into the map, with the
    /// two cleanups: early eviction when the map is at its budget, and the
    /// scheduled one every `cleanup_interval_frames`.
    fn fuse(&mut self, pose: &DAffine3, index: u32) -> FusionStats {
        let mut removed = 0;
        if self.map.len() >= self.config.fusion.max_surfels {
            // Full: evict stale unstable surfels now rather than at the
            // next scheduled cleanup; adds beyond the budget are skipped
            // (counted in `FusionStats::skipped`).
            removed = remove_unstable(&mut self.map, &self.config.fusion, index, &mut self.order);
        }
        let active = self.active_at(index);
        let mut fusion = self.integrator.integrate(
            &mut self.map,
            &self.pyramid,
            &self.config.working_intrinsics(),
            pose,
            (index, active.clone()),
            &self.config.fusion,
            self.config.depth.max_m,
        );
        fusion.removed = removed;
        self.order.reserve_for(&self.map);
        if index % self.config.fusion.cleanup_interval_frames.max(1) == 0 {
            fusion.absorbed +=
                merge_copies(&mut self.map, &self.config.fusion, (index, active.start));
            fusion.removed +=
                remove_unstable(&mut self.map, &self.config.fusion, index, &mut self.order);
        }
        fusion
    }

    /// Stage `predict`: what the next frame is tracked against, all from the
    /// frame just fused at `pose`: the model prediction, the photometric
    /// memory of this frame, the constant-velocity motion and the sparse
    /// estimator's reference.
    fn predict(&mut self, pose: &DAffine3, (held_at_guess, interval_s): (bool, f64)) {
        self.render_prediction(pose, false);
        self.velocity = match (self.last_good, self.counts.lost_streak) {
            (Some(before), 0) => {
                Some(self.motion_since_measured(before, pose, (held_at_guess, interval_s)))
            }
            _ => None,
        };
        if !held_at_guess {
            self.measured_frame = Some(self.frame_index);
        }
        self.place_current(pose);
        self.relocaliser.remember(pose, self.frame_index);
    }

    /// The current frame becomes the placed one, at `pose`: the
    /// photometric memory, the sparse estimator's reference and the last
    /// good pose are its.
    fn place_current(&mut self, pose: &DAffine3) {
        self.tracker
            .remember_frame(&self.pyramid, pose, &self.config.tracker);
        self.sparse.current_becomes_reference();
        self.last_good = Some(*pose);
        self.placed_frame = self.frame_index;
    }

    /// Renders the model prediction from `pose`, the current frame's: its
    /// measured points hide what lies behind them (with the integrator's
    /// depth tiles for a fused frame, `lost_tiles` for a dead-reckoned
    /// one). The segment's active surfels; the warm-up counts the
    /// segment's fused frames, so that frames lost early do not end it
    /// before the map had the frames to become stable.
    fn render_prediction(&mut self, pose: &DAffine3, lost: bool) {
        let k = self.config.working_intrinsics();
        let fusion_cfg = self.config.fusion;
        let fused = self.fused_in_segment();
        // The frame being processed: `frame_index` moves on after `predict`.
        let active = self.active_at(self.frame_index);
        let map = &self.map;
        let far_m = self.config.depth.max_m;
        let tiles = if lost {
            &self.lost_tiles
        } else {
            self.integrator.depth_tiles()
        };
        self.prediction.render(
            map,
            pose,
            &k,
            (fusion_cfg.depth_gate_m, far_m),
            Measured {
                vertices: self.pyramid.levels.first().map_or(&[], |l| &l.vertices),
                tiles,
            },
            active,
            |i| fusion_cfg.predicts(map, i, fused),
        );
    }

    /// Stage `count_verdict`: the run's verdict counts and lost streak.
    fn count_verdict(&mut self, verdict: Verdict) {
        match verdict {
            // Unplaced only while localising, which counts apart.
            Verdict::Lost(_) | Verdict::Unplaced => {
                self.counts.lost += 1;
                self.counts.lost_streak += 1;
            }
            Verdict::Recovered => {
                self.counts.recovered += 1;
                self.counts.lost_streak = 0;
            }
            Verdict::Held => {
                self.counts.held += 1;
                self.counts.lost_streak = 0;
            }
            Verdict::Restarted => {
                self.counts.restarted += 1;
                self.counts.lost_streak = 0;
            }
            Verdict::Initialised | Verdict::Tracked => {
                self.counts.tracked += 1;
                self.counts.lost_streak = 0;
            }
        }
    }

    /// The report of frame `index`, after every stage ran.
    fn report(
        &self,
        index: u32,
        timestamp: f64,
        tracked: &Tracked,
        (fusion, loop_outcome): (FusionStats, LoopOutcome),
        timings: StageTimings,
    ) -> FrameReport {
        let stats = tracked.result;
        FrameReport {
            index,
            timestamp,
            world_from_camera: tracked.pose,
            verdict: tracked.verdict,
            inliers: stats.map_or(0, |s| s.inliers),
            inlier_ratio: stats.map_or(1.0, |s| s.inlier_ratio),
            residual_rms_m: stats.map_or(0.0, |s| s.residual_rms_m),
            conditioning: stats.map_or(1.0, |s| s.conditioning),
            surfels: self.map.live_len(),
            surfel_slots: self.map.len(),
            fusion,
            counts: self.counts,
            checks: tracked.checks,
            loop_closures: self.loop_closer.closures(),
            global_loop_closures: self.loop_closer.global_closures(),
            loop_outcome,
            settings_warning: None,
            camera_fixed_share: 0.0,
            timings,
        }
    }
}
