//! The `LoopCloser` pipeline stage: after fusion, predict the inactive model
//! from the current pose; where it overlaps the active model, register the
//! two (`local`); on an accepted correction bend the map, the trajectory
//! and the current pose with an embedded deformation graph, and reactivate
//! the inactive surfels that were matched so that fusion merges the two
//! copies of the revisited surfaces.
//!
//! When the local check did not accept a correction (none ran, or the drift
//! is too large for it), every `GlobalConfig::every_frames` frames the
//! frame is looked up among the keyframes older than the active window
//! (`global`): a verified match gives constraints (the frame's points, from
//! where the tracked pose put them to where the registered pose puts them)
//! and pins (the inactive surfels the keyframe's view shows stay), bent
//! with the same graph: the old map stays, the drifted recent part moves.
//! A match that only undoes the last frames' slide moves the pose alone;
//! either way the old surfels the frame sees become active again, so that
//! the next frames are tracked against them.

use crate::camera::Intrinsics;
use crate::fusion::{FusionConfig, Measured, Prediction, SurfelMap};
use crate::preprocess::FramePyramid;
use crate::track::verify::{against_surface, Side, VerifyConfig};
use crate::track::{TrackerConfig, TrackerWorkspace};
use glam::{DAffine3, Vec3};

use super::deformation::{Constraint, DeformError, DeformReport, DeformationGraph};
use super::global::{constraints_into, find_global_match, GlobalClosure, GlobalMatch, GlobalMiss};
use super::local::{ModelRegistration, Registration};
use super::relocalise::{Model, PlaceAttempt, Relocaliser, Trackers};
use super::slide::slide_undone;
use super::LoopClosureConfig;

/// What the stage did on one frame: every check it ran, what each found
/// and which refused (the per-frame loop record the CLI's `--loop-log`
/// writes and the page shows).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoopOutcome {
    /// The pose the stage started from (`world_from_camera`, metres: the
    /// tracked pose, before any bend of this frame).
    pub tracked: DAffine3,
    /// A registration ran (the inactive model overlapped the view).
    pub registration: Option<Registration>,
    /// The map, trajectory and pose were bent.
    pub closed: bool,
    /// The accepted registration's correction was below the bending
    /// threshold: the matched inactive surfels were only reactivated.
    pub aligned: bool,
    /// The deformation graph's report, when it was optimised and accepted.
    pub deform: Option<DeformReport>,
    /// Why the graph refused the constraints of an accepted registration.
    pub deform_error: Option<DeformError>,
    /// Inactive surfels made active again.
    pub reactivated: usize,
    /// The global check looked the frame up among the old keyframes.
    pub global_looked: bool,
    /// Keyframes the global look registered the frame against.
    pub global_candidates: usize,
    /// Of those, the one whose registration got furthest through the
    /// checks (the match itself when there was one).
    pub global_attempt: Option<PlaceAttempt>,
    /// Why the global look closed nothing (`None` when it did not look or
    /// found a match).
    pub global_miss: Option<GlobalMiss>,
    /// A verified match with a place seen long ago; `closed` (here and in
    /// the summary) when the map was bent by it.
    pub global: Option<GlobalClosure>,
    /// The map's segment since a restart after a long loss was moved, as
    /// a whole, onto the map before it (`closed` is then set too).
    pub joined: Option<SegmentJoin>,
}

/// A segment of the map, begun by a restart after a long loss
/// (`Verdict::Restarted`), moved rigidly onto the map before it when a
/// frame of the segment was relocalised against that map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentJoin {
    /// The segment's first frame.
    pub segment_start: u32,
    /// Frame index of the keyframe the frame was placed from; `None`
    /// when placed from where the camera was lost (the segment's first
    /// frame's pose, before the loss).
    pub keyframe_frame: Option<u32>,
    /// How far the frame moved: translation, metres, and rotation, degrees.
    pub correction: (f64, f64),
}

/// Everything the stage needs from the pipeline for one frame.
#[derive(Debug)]
pub struct LoopFrame<'a> {
    /// Index of the frame just fused (the map's time stamps are frame indices).
    pub now: u32,
    /// Working intrinsics.
    pub intrinsics: &'a Intrinsics,
    /// What the camera measured from the pose (see [`Measured`]).
    pub measured: Measured<'a>,
    /// Fusion settings (which surfels are predicted, the depth band).
    pub fusion: &'a FusionConfig,
    /// Surfels last seen before this frame are inactive: `fusion`'s
    /// [`FusionConfig::active_at`] start, or where the map last restarted
    /// when that is later.
    pub active_from: u32,
    /// Farthest depth predicted, metres.
    pub far_m: f32,
    /// Fused frames so far (the prediction's warm-up counts them).
    pub fused: u32,
    /// Free-space margins.
    pub verify: &'a VerifyConfig,
}

/// What the global check needs beyond [`LoopFrame`]: the keyframe database
/// (with this frame encoded), the frame, and the trackers that register it.
#[derive(Debug)]
pub struct GlobalLook<'a> {
    /// Keyframes; this frame was encoded (`Relocaliser::encode`) and is
    /// not yet remembered.
    pub relocaliser: &'a mut Relocaliser,
    /// The frame fused at the tracked pose (camera frame, metres).
    pub pyramid: &'a FramePyramid,
    /// The pipeline's tracker, whose verdict a registration must pass.
    pub normal: &'a TrackerConfig,
    /// The re-acquisition search (wide gates) that finds the start.
    pub wide: &'a TrackerConfig,
    /// The trackers' buffers.
    pub workspace: &'a mut TrackerWorkspace,
}

/// The loop-closure stage: owns its predictions, registration buffers,
/// constraints and the last deformation graph.
#[derive(Debug)]
pub struct LoopCloser {
    config: LoopClosureConfig,
    active: Prediction,
    inactive: Prediction,
    registration: ModelRegistration,
    constraints: Vec<Constraint>,
    /// Frame points of a global match: (tracked, registered), world frame.
    pairs: Vec<(Vec3, Vec3)>,
    /// Inactive surfels matched by the last accepted registration.
    matched: Vec<usize>,
    graph: Option<DeformationGraph>,
    closures: u32,
    /// Of `closures`, those made by the global check.
    global_closures: u32,
    /// Frame of the last global closure.
    last_global: Option<u32>,
    /// The last frame the stage ran on (a fused one).
    ran_at: Option<u32>,
    /// The last frame the global check looked up.
    looked_at: Option<u32>,
}

impl LoopCloser {
    /// A stage with `config`'s thresholds and an empty state.
    #[must_use]
    pub fn new(config: LoopClosureConfig) -> Self {
        Self {
            config,
            active: Prediction::new(false),
            inactive: Prediction::new(false),
            registration: ModelRegistration::default(),
            constraints: Vec::new(),
            pairs: Vec::new(),
            matched: Vec::new(),
            graph: None,
            closures: 0,
            global_closures: 0,
            last_global: None,
            ran_at: None,
            looked_at: None,
        }
    }

    /// The settings in use.
    #[must_use]
    pub fn config(&self) -> &LoopClosureConfig {
        &self.config
    }

    /// Closures (map bent) since creation or the last reset.
    #[must_use]
    pub fn closures(&self) -> u32 {
        self.closures
    }

    /// Of [`Self::closures`], those made by the global check (a place seen
    /// long ago, found by the keyframe ferns).
    #[must_use]
    pub fn global_closures(&self) -> u32 {
        self.global_closures
    }

    /// The counters that decide later frames: closures, global closures
    /// and the frame of the last global closure (its cooldown), for saving
    /// a session.
    #[must_use]
    pub fn counters(&self) -> (u32, u32, Option<u32>) {
        (self.closures, self.global_closures, self.last_global)
    }

    /// Restores [`Self::counters`] (loading a session).
    pub fn restore_counters(&mut self, (closures, global, last_global): (u32, u32, Option<u32>)) {
        self.closures = closures;
        self.global_closures = global;
        self.last_global = last_global;
    }

    /// Forgets the map-dependent state (the map was cleared).
    pub fn reset(&mut self) {
        self.active.clear();
        self.inactive.clear();
        self.constraints.clear();
        self.matched.clear();
        self.graph = None;
        self.closures = 0;
        self.global_closures = 0;
        self.last_global = None;
        self.ran_at = None;
        self.looked_at = None;
    }

    /// The last frame the stage ran on: the last fused frame, when it is
    /// the last pushed one.
    #[must_use]
    pub fn ran_at(&self) -> Option<u32> {
        self.ran_at
    }

    /// A `world_from_camera` pose of frame `time` moved by the last closure
    /// (unchanged when there was none): for poses the pipeline keeps
    /// outside the trajectory (the last good pose).
    #[must_use]
    pub fn deform_pose(&self, world_from_camera: &DAffine3, time: u32) -> DAffine3 {
        self.graph.as_ref().map_or(*world_from_camera, |g| {
            g.apply_to_pose(world_from_camera, time)
        })
    }

    /// Runs the stage after frame `frame.now` was fused at `pose`: may move
    /// every surfel of `map`, every pose of `trajectory` (entry `i` is frame
    /// `i`, `world_from_camera`) and `pose`. The local check first; the
    /// global one (when `global` is given and enabled) on the frames it
    /// looks at unless the local check accepted a correction.
    pub fn run(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        frame: &LoopFrame<'_>,
        global: Option<GlobalLook<'_>>,
    ) -> LoopOutcome {
        let mut outcome = LoopOutcome {
            tracked: *pose,
            ..LoopOutcome::default()
        };
        self.ran_at = Some(frame.now);
        if !self.config.enabled || map.is_empty() || frame.active_from == 0 {
            return outcome;
        }
        if frame.now % self.config.every_frames.max(1) == 0 {
            self.run_local(map, trajectory, pose, frame, &mut outcome);
        }
        let local_accepted = outcome.registration.is_some_and(|r| r.accepted());
        if let (false, Some(look)) = (local_accepted, global) {
            self.run_global(map, trajectory, pose, frame, (look, false), &mut outcome);
        }
        outcome
    }

    /// The global check on frame `frame.now`, the one [`Self::run`] ran on
    /// last, whatever `GlobalConfig::every_frames` says: the recording
    /// ended there (see [`crate::Pipeline::finish`]). Nothing when the
    /// stage did not run on that frame or already looked it up. The rest
    /// after a global closure (`GlobalConfig::cooldown_frames`) does not
    /// hold: no frame follows for a second closure to undo it.
    /// `trajectory` holds the frames before it.
    pub fn look_now(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        frame: &LoopFrame<'_>,
        look: GlobalLook<'_>,
    ) -> LoopOutcome {
        let mut outcome = LoopOutcome {
            tracked: *pose,
            ..LoopOutcome::default()
        };
        let unseen = self.ran_at == Some(frame.now) && self.looked_at != Some(frame.now);
        if unseen && self.config.enabled && !map.is_empty() && frame.active_from > 0 {
            self.run_global(map, trajectory, pose, frame, (look, true), &mut outcome);
        }
        outcome
    }

    /// The local (model-to-model) check, see the module documentation.
    fn run_local(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        frame: &LoopFrame<'_>,
        outcome: &mut LoopOutcome,
    ) {
        let k = frame.intrinsics;
        let now = frame.now;
        let band = (frame.fusion.depth_gate_m, frame.far_m);
        let map_ref = &*map;
        let (fusion, fused) = (frame.fusion, frame.fused);
        let predicts = |i| fusion.predicts(map_ref, i, fused);
        // The inactive model first: most frames see none, and then the
        // active one is not rendered at all.
        let inactive = 0..frame.active_from;
        self.inactive
            .render(map_ref, pose, k, band, frame.measured, inactive, predicts);
        let min_overlap = (self.config.min_overlap_fraction * k.pixel_count() as f64) as usize;
        if self.inactive.valid < min_overlap.max(1) {
            return;
        }
        self.active.render(
            map_ref,
            pose,
            k,
            band,
            frame.measured,
            frame.active_from..u32::MAX,
            predicts,
        );
        let registration =
            self.registration
                .register(&self.active, &self.inactive, &self.config, frame.verify);
        outcome.registration = Some(registration);
        if !registration.accepted() {
            return;
        }
        self.collect_matches(map, &registration);
        if registration.moves_map(&self.config) {
            match self.bend(map, trajectory, pose, now) {
                Ok(report) => {
                    outcome.closed = true;
                    outcome.deform = Some(report);
                    self.closures += 1;
                }
                Err(e) => {
                    outcome.deform_error = Some(e);
                    return;
                }
            }
        } else {
            outcome.aligned = true;
        }
        outcome.reactivated = self.touch_matched(map, now);
    }

    /// The global check (see the module documentation): look the frame up
    /// among the old keyframes, register it against the inactive model as
    /// the keyframe saw it, and on a verified match bend the map.
    fn run_global(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        frame: &LoopFrame<'_>,
        (look, off_schedule): (GlobalLook<'_>, bool),
        outcome: &mut LoopOutcome,
    ) {
        let config = self.config.global;
        let now = frame.now;
        let resting = !off_schedule
            && self
                .last_global
                .is_some_and(|t| now.saturating_sub(t) < config.cooldown_frames);
        let looks = if off_schedule {
            config.may_look_at(now)
        } else {
            config.looks_at(now)
        };
        if !looks || resting {
            return;
        }
        outcome.global_looked = true;
        self.looked_at = Some(now);
        let found = {
            let map_ref = &*map;
            let (fusion, fused) = (frame.fusion, frame.fused);
            // The old map: surfels created before the keyframes looked at.
            // Those created since are the drifted copy of the place; old
            // surfels seen again since (active again after a closure) are
            // kept, else the leftovers a closure did not reactivate would
            // be all the model shows there.
            let before = now.saturating_sub(config.min_age_frames);
            let first_seen = map_ref.first_seen();
            find_global_match(
                look.relocaliser,
                look.pyramid,
                Model {
                    map: map_ref,
                    seen: 0..u32::MAX,
                    include: |i| {
                        fusion.predicts(map_ref, i, fused)
                            && first_seen.get(i).is_some_and(|&t| t < before)
                    },
                    far_m: frame.far_m,
                },
                Trackers {
                    normal: look.normal,
                    wide: look.wide,
                    min_conditioning: config.min_conditioning,
                },
                look.workspace,
                (pose, now),
                &config,
            )
        };
        let attempts = look.relocaliser.attempts();
        outcome.global_candidates = attempts.len();
        outcome.global_attempt = match &found {
            Ok(_) => attempts.last().copied(),
            Err(_) => furthest(attempts),
        };
        let found = match found {
            Ok(found) => found,
            Err(miss) => {
                outcome.global_miss = Some(miss);
                return;
            }
        };
        let view = look.relocaliser.keyframe_view();
        let registered = found.registration.world_from_camera;
        let slid = slide_undone(trajectory, (&found.tracked, &registered), &config);
        if slid {
            // The map did not drift: only this frame is put back, and the
            // old surfels it sees there become active again, so that the
            // next frames are tracked against them and not against the
            // little the active model shows there (which slid).
            *pose = registered;
            self.graph = None;
            outcome.closed = true;
            outcome.global = Some(GlobalClosure::of(&found, (true, true)));
            self.closures += 1;
            self.global_closures += 1;
            self.last_global = Some(now);
            self.collect_seen(map, view, look.pyramid, pose, frame.verify);
            outcome.reactivated = self.touch_matched(map, now);
            return;
        }
        let inactive_before = frame.active_from;
        self.collect_global(map, &found, view, look.pyramid, (now, inactive_before));
        match self.bend(map, trajectory, pose, now) {
            Ok(report) => {
                outcome.closed = true;
                outcome.deform = Some(report);
                outcome.global = Some(GlobalClosure::of(&found, (true, false)));
                self.closures += 1;
                self.global_closures += 1;
                self.last_global = Some(now);
            }
            Err(e) => {
                outcome.deform_error = Some(e);
                outcome.global = Some(GlobalClosure::of(&found, (false, false)));
                return;
            }
        }
        self.collect_seen(map, view, look.pyramid, pose, frame.verify);
        outcome.reactivated = self.touch_matched(map, now);
    }

    /// Constraints of a global match: the frame's points (observed now)
    /// carried from where the tracked pose put them to where the registered
    /// pose puts them, and pins on the surfels `view` (the model as the
    /// keyframe saw it) shows that were last seen before `inactive_before`,
    /// at their own times.
    fn collect_global(
        &mut self,
        map: &SurfelMap,
        found: &GlobalMatch,
        view: &Prediction,
        pyramid: &FramePyramid,
        (now, inactive_before): (u32, u32),
    ) {
        self.constraints.clear();
        self.matched.clear();
        self.pairs.clear();
        let step = self.config.global.constraint_step.max(1);
        if let Some((level, k)) = pyramid
            .levels
            .first()
            .and_then(|l| Some((l, l.intrinsics?)))
        {
            constraints_into(found, &level.vertices, k.width, step, &mut self.pairs);
        }
        self.constraints.extend(
            self.pairs
                .iter()
                .map(|&(source, target)| Constraint::new(source, target, now)),
        );
        let Some(k) = view.intrinsics else {
            return;
        };
        let (positions, last_seen) = (map.positions(), map.last_seen());
        // Only surfels the graph moves with old nodes can be pinned: an old
        // surfel seen again lately moves with the recent part.
        let inactive = inactive_before;
        for v in (0..k.height).step_by(step) {
            for u in (0..k.width).step_by(step) {
                let pixel = v * k.width + u;
                if view.normals.get(pixel).is_none_or(|n| *n == Vec3::ZERO) {
                    continue;
                }
                let Some(b) = view.surfel_at_pixel(pixel) else {
                    continue;
                };
                if let (Some(&p), Some(&t)) = (positions.get(b), last_seen.get(b)) {
                    if t < inactive {
                        self.constraints.push(Constraint::pin(p, t));
                    }
                }
            }
        }
    }

    /// Makes the surfels collected in `self.matched` active at frame
    /// `now`; returns how many.
    fn touch_matched(&self, map: &mut SurfelMap, now: u32) -> usize {
        for &i in &self.matched {
            map.touch(i, now);
        }
        self.matched.len()
    }

    /// The inactive surfels of `view` that the frame (`pyramid`, finest
    /// level), at the corrected `pose`, measures where they lie (within the
    /// free-space margins of `verify`): the old copy of what the camera
    /// sees, to reactivate so that fusion merges the two.
    fn collect_seen(
        &mut self,
        map: &SurfelMap,
        view: &Prediction,
        pyramid: &FramePyramid,
        pose: &DAffine3,
        verify: &VerifyConfig,
    ) {
        self.matched.clear();
        let Some((level, k)) = pyramid
            .levels
            .first()
            .and_then(|l| Some((l, l.intrinsics?)))
        else {
            return;
        };
        if level.vertices.len() != k.pixel_count() {
            return;
        }
        let camera_from_world = pose.inverse().as_affine3a();
        let positions = map.positions();
        let frame_z = |i: usize| Some(level.vertices[i].z).filter(|&z| z > 0.0);
        for (pixel, normal) in view.normals.iter().enumerate() {
            if *normal == Vec3::ZERO {
                continue;
            }
            let Some(b) = view.surfel_at_pixel(pixel) else {
                continue;
            };
            let Some(&p) = positions.get(b) else {
                continue;
            };
            let Some((q_z, _, z)) = against_surface(&k, &camera_from_world, p, frame_z) else {
                continue;
            };
            // The frame measures a point on the old surfel's surface.
            if verify.side(z, q_z) == Side::OnSurface {
                self.matched.push(b);
            }
        }
    }

    /// Fills the constraints (sampled active points: where they are, where
    /// the correction puts them), the pins (inactive points stay) and the
    /// matched inactive surfels, from the pixels both predictions show.
    fn collect_matches(&mut self, map: &SurfelMap, registration: &Registration) {
        self.constraints.clear();
        self.matched.clear();
        let Some(k) = self.active.intrinsics else {
            return;
        };
        let correction = registration.correction.as_affine3a();
        let step = self.config.constraint_step.max(1);
        let last_seen = map.last_seen();
        for v in (0..k.height).step_by(step) {
            for u in (0..k.width).step_by(step) {
                let pixel = v * k.width + u;
                let (Some(a), Some(b)) = (
                    self.active.surfel_at_pixel(pixel),
                    self.inactive.surfel_at_pixel(pixel),
                ) else {
                    continue;
                };
                let (Some(&ta), Some(&tb)) = (last_seen.get(a), last_seen.get(b)) else {
                    continue;
                };
                let p = self.active.vertices[pixel];
                let q = self.inactive.vertices[pixel];
                self.constraints
                    .push(Constraint::new(p, correction.transform_point3(p), ta));
                self.constraints.push(Constraint::pin(q, tb));
            }
        }
        // Every matched inactive surfel, not only the sampled ones.
        for pixel in 0..k.pixel_count() {
            if self.active.normals[pixel] != Vec3::ZERO {
                if let Some(b) = self.inactive.surfel_at_pixel(pixel) {
                    self.matched.push(b);
                }
            }
        }
    }

    /// Builds the graph over the map, optimises it for the constraints and,
    /// when accepted, moves every surfel, every past pose and `pose`.
    fn bend(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        now: u32,
    ) -> Result<DeformReport, DeformError> {
        let mut graph = DeformationGraph::from_samples(
            map.positions(),
            map.last_seen(),
            self.config.deform.clone(),
        )?;
        let report = graph.optimise(&self.constraints)?;
        map.warp(|positions, normals, times| graph.apply_to_points(positions, normals, times))?;
        for (i, (_, p)) in trajectory.iter_mut().enumerate() {
            *p = graph.apply_to_pose(p, u32::try_from(i).unwrap_or(u32::MAX));
        }
        *pose = graph.apply_to_pose(pose, now);
        self.graph = Some(graph);
        Ok(report)
    }
}

/// The attempt that passed the most checks (a refusal later in the order,
/// or none); the most similar keyframe among equals.
fn furthest(attempts: &[PlaceAttempt]) -> Option<PlaceAttempt> {
    attempts.iter().copied().reduce(|best, a| {
        let stage = |x: &PlaceAttempt| x.refused.map_or(u8::MAX, |r| r as u8);
        if stage(&a) > stage(&best) {
            a
        } else {
            best
        }
    })
}
