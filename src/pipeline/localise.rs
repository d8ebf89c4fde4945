//! Localise mode: track and relocalise new frames against a saved map
//! without changing it (issue #36). Nothing is fused, no loop is closed,
//! no keyframe is added; the map, its trajectory, keyframes and counters
//! stay as loaded, bit for bit (`tests/session.rs`).
//!
//! A frame is placed in the map either by tracking from the last placed
//! frame (the same checks as mapping: [`Pipeline::track_or_recover`],
//! against the fixed map rendered at the last placed pose), or, when there
//! is no last placed frame (the first frame, or after an unplaced one) or
//! tracking fails, by relocalisation against the saved keyframes
//! ([`Relocaliser::place`](crate::loop_closure::relocalise::Relocaliser::place)):
//! never assumed at the origin nor at the saved last pose. A frame neither
//! places is [`Verdict::Unplaced`] and gets no pose; the next frame tries
//! relocalisation again.
//!
//! Poses are `world_from_camera` in the saved map's world frame, metres.

use super::recovery::Tracked;
use super::{FrameReport, Pipeline, StageTimings, Verdict, VerdictCounts};
use crate::clock::now_ms;
use crate::frame::RgbdFrame;
use crate::fusion::{DepthTiles, FusionStats, Measured};
use crate::loop_closure::LoopOutcome;
use crate::track::verify::TrackingChecks;
use glam::DAffine3;

/// What localising keeps from frame to frame, apart from the map (which
/// it only reads).
#[derive(Debug, Default)]
pub struct Localisation {
    /// `world_from_camera` of the last frame placed, `None` before the
    /// first and after an unplaced frame (the next one is relocalised).
    last_placed: Option<DAffine3>,
    /// `previous_from_current` of the last two frames placed in a row.
    velocity: Option<DAffine3>,
    /// `(timestamp, world_from_camera)` of every placed frame, in order.
    trajectory: Vec<(f64, DAffine3)>,
    /// Frames pushed since localising began.
    frames: u32,
    /// Verdicts of those frames: tracked or held (placed by tracking),
    /// recovered (placed by relocalisation), lost (unplaced).
    counts: VerdictCounts,
    /// The placed frame's depth tiles (the prediction's culling).
    tiles: DepthTiles,
}

impl Localisation {
    /// `(timestamp, world_from_camera)` of every frame placed in the map,
    /// in order; unplaced frames are absent.
    #[must_use]
    pub fn trajectory(&self) -> &[(f64, DAffine3)] {
        &self.trajectory
    }

    /// Frames pushed since localising began, placed or not.
    #[must_use]
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Verdict counts since localising began: `tracked` and `held`
    /// (placed by tracking), `recovered` (placed by relocalisation),
    /// `lost` (unplaced: [`Verdict::Unplaced`]).
    #[must_use]
    pub fn counts(&self) -> VerdictCounts {
        self.counts
    }

    /// Frames placed in the map.
    #[must_use]
    pub fn placed(&self) -> usize {
        self.trajectory.len()
    }
}

impl Pipeline {
    /// Switches to localise mode: from now on pushed frames are tracked
    /// and relocalised against the map as it is, which no longer changes
    /// (see the module documentation). The first frame is placed by
    /// relocalisation against the keyframes. Stays on until
    /// [`Pipeline::reset`]; a session cannot be saved while localising
    /// (the map is the one loaded).
    pub fn start_localising(&mut self) {
        self.localising = Some(Box::default());
        // Placing the camera again after a carried thing changes the map.
        self.anchored = None;
        self.first_frame = None;
    }

    /// Whether the pipeline is in localise mode ([`Self::start_localising`]).
    #[must_use]
    pub fn is_localising(&self) -> bool {
        self.localising.is_some()
    }

    /// The localised frames and their counts, in localise mode.
    #[must_use]
    pub fn localisation(&self) -> Option<&Localisation> {
        self.localising.as_deref()
    }

    /// One frame in localise mode (after the checks of `push_frame`).
    pub(super) fn localise_frame(
        &mut self,
        frame: &RgbdFrame,
        timestamp: f64,
        mut loc: Box<Localisation>,
    ) -> (FrameReport, Box<Localisation>) {
        let t0 = now_ms();
        self.preprocess(frame);
        let t1 = now_ms();
        self.keep_for_sparse_and_ferns();
        let tracked = match loc.last_placed {
            Some(previous) => {
                let tracked = self.track_or_recover(&previous, (loc.velocity, f64::NAN), 0);
                match tracked.verdict {
                    Verdict::Lost(_) => self.place_in_map(),
                    _ => tracked,
                }
            }
            None => self.place_in_map(),
        };
        let t2 = now_ms();
        let placed = tracked.verdict != Verdict::Unplaced;
        match tracked.verdict {
            Verdict::Unplaced => loc.counts.lost += 1,
            Verdict::Recovered => loc.counts.recovered += 1,
            Verdict::Held => loc.counts.held += 1,
            _ => loc.counts.tracked += 1,
        }
        if placed {
            self.predict_in_map(&tracked.pose, &mut loc);
            loc.trajectory.push((timestamp, tracked.pose));
        } else {
            loc.last_placed = None;
            loc.velocity = None;
        }
        loc.counts.lost_streak = if placed {
            0
        } else {
            loc.counts.lost_streak + 1
        };
        let t3 = now_ms();
        let index = self.frame_index + loc.frames;
        loc.frames += 1;
        let mut report = self.report(
            index,
            timestamp,
            &tracked,
            (FusionStats::default(), LoopOutcome::default()),
            StageTimings {
                decode_ms: 0.0,
                preprocess_ms: t1 - t0,
                track_ms: t2 - t1,
                fuse_ms: 0.0,
                loop_ms: 0.0,
                predict_ms: t3 - t2,
                total_ms: t3 - t0,
            },
        );
        report.counts = loc.counts;
        (report, loc)
    }

    /// The frame placed by relocalisation against every keyframe and the
    /// whole map (whether or not relocalisation is on for mapping), or
    /// [`Verdict::Unplaced`] with no pose (the identity stands in).
    fn place_in_map(&mut self) -> Tracked {
        let found = self.place_in_whole_map();
        let Some(found) = found else {
            return Tracked {
                verdict: Verdict::Unplaced,
                pose: DAffine3::IDENTITY,
                result: None,
                checks: TrackingChecks::default(),
            };
        };
        let checks = TrackingChecks {
            free_space_final: found.free_space,
            relocalised_from: Some(found.keyframe_frame),
            ..TrackingChecks::default()
        };
        Tracked {
            verdict: Verdict::Recovered,
            pose: found.world_from_camera,
            result: Some(found.result),
            checks,
        }
    }

    /// After a frame was placed at `pose`: what the next frame is tracked
    /// against, as mapping's `predict` stage but from the fixed map (every
    /// stable surfel, whenever last seen) and without keyframes.
    fn predict_in_map(&mut self, pose: &DAffine3, loc: &mut Localisation) {
        let k = self.config.working_intrinsics();
        let fusion = self.config.fusion;
        let map = &self.map;
        let fused = self.counts.fused();
        let vertices = self.pyramid.levels.first().map_or(&[][..], |l| &l.vertices);
        loc.tiles.build(vertices, k.width);
        self.prediction.render(
            map,
            pose,
            &k,
            (fusion.depth_gate_m, self.config.depth.max_m),
            Measured {
                vertices,
                tiles: &loc.tiles,
            },
            0..u32::MAX,
            |i| fusion.predicts(map, i, fused),
        );
        self.tracker
            .remember_frame(&self.pyramid, pose, &self.config.tracker);
        loc.velocity = loc.last_placed.map(|before| before.inverse() * *pose);
        self.sparse.current_becomes_reference();
        loc.last_placed = Some(*pose);
    }
}
