//! The `LoopCloser` pipeline stage: after fusion, predict the inactive model
//! from the current pose; where it overlaps the active model, register the
//! two (`local`); on an accepted correction bend the map, the trajectory
//! and the current pose with an embedded deformation graph, and reactivate
//! the inactive surfels that were matched so that fusion merges the two
//! copies of the revisited surfaces.

use crate::camera::Intrinsics;
use crate::fusion::{FusionConfig, Measured, Prediction, SurfelMap};
use crate::track::verify::VerifyConfig;
use glam::{DAffine3, Vec3};

use super::deformation::{Constraint, DeformError, DeformReport, DeformationGraph};
use super::local::{ModelRegistration, Registration};
use super::LoopClosureConfig;

/// What the stage did on one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoopOutcome {
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
    /// Farthest depth predicted, metres.
    pub far_m: f32,
    /// Fused frames so far (the prediction's warm-up counts them).
    pub fused: u32,
    /// Free-space margins.
    pub verify: &'a VerifyConfig,
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
    /// Inactive surfels matched by the last accepted registration.
    matched: Vec<usize>,
    graph: Option<DeformationGraph>,
    closures: u32,
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
            matched: Vec::new(),
            graph: None,
            closures: 0,
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

    /// Forgets the map-dependent state (the map was cleared).
    pub fn reset(&mut self) {
        self.active.clear();
        self.inactive.clear();
        self.constraints.clear();
        self.matched.clear();
        self.graph = None;
        self.closures = 0;
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
    /// `i`, `world_from_camera`) and `pose`.
    pub fn run(
        &mut self,
        map: &mut SurfelMap,
        trajectory: &mut [(f64, DAffine3)],
        pose: &mut DAffine3,
        frame: &LoopFrame<'_>,
    ) -> LoopOutcome {
        let mut outcome = LoopOutcome::default();
        let every = self.config.every_frames.max(1);
        if !self.config.enabled || frame.now % every != 0 || map.is_empty() {
            return outcome;
        }
        let k = frame.intrinsics;
        let now = frame.now;
        let band = (frame.fusion.depth_gate_m, frame.far_m);
        let map_ref = &*map;
        let (fusion, fused) = (frame.fusion, frame.fused);
        let predicts = |i| fusion.predicts(map_ref, i, fused);
        // The inactive model first: most frames see none, and then the
        // active one is not rendered at all.
        let inactive = fusion.inactive_at(now);
        if inactive.is_empty() {
            return outcome;
        }
        self.inactive
            .render(map_ref, pose, k, band, frame.measured, inactive, predicts);
        let min_overlap = (self.config.min_overlap_fraction * k.pixel_count() as f64) as usize;
        if self.inactive.valid < min_overlap.max(1) {
            return outcome;
        }
        self.active.render(
            map_ref,
            pose,
            k,
            band,
            frame.measured,
            fusion.active_at(now),
            predicts,
        );
        let registration =
            self.registration
                .register(&self.active, &self.inactive, &self.config, frame.verify);
        outcome.registration = Some(registration);
        if !registration.accepted() {
            return outcome;
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
                    return outcome;
                }
            }
        } else {
            outcome.aligned = true;
        }
        for &i in &self.matched {
            map.touch(i, now);
        }
        outcome.reactivated = self.matched.len();
        outcome
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
            &map.positions,
            &map.last_seen,
            self.config.deform.clone(),
        )?;
        let report = graph.optimise(&self.constraints)?;
        graph.apply_to_points(&mut map.positions, &mut map.normals, &map.last_seen)?;
        // Every surfel may have moved: the renderer re-uploads the whole
        // map, and the blocks' boxes are recomputed.
        if let Some(last) = map.len().checked_sub(1) {
            map.mark_changed(0);
            map.mark_changed(last);
        }
        map.rebuild_bounds_from(0);
        for (i, (_, p)) in trajectory.iter_mut().enumerate() {
            *p = graph.apply_to_pose(p, u32::try_from(i).unwrap_or(u32::MAX));
        }
        *pose = graph.apply_to_pose(pose, now);
        self.graph = Some(graph);
        Ok(report)
    }
}
