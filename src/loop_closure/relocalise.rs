//! Relocalisation of a lost camera from the keyframe database.
//!
//! The frame is looked up among the keyframes ([`FernDatabase`]); for each
//! similar keyframe, most similar first, the model is rendered as that
//! keyframe saw it (from its pose, down to the depth it measured), the
//! re-acquisition tracker (wide gates) is started at the keyframe's pose,
//! the normal tracker is started at its result, and the pose counts only if
//! the normal tracker accepts it, the view pins all six degrees of freedom,
//! the frame's points keep out of the model's free space and the model's
//! surfaces out of the space the frame sees through, the pose lies near the
//! keyframe whose look-alike it is, and the frame's colours agree with the
//! keyframe's where the pose puts them. A place that only looks alike
//! (another wall of the same colour) fails on the geometry around it; a
//! repeated object whose surroundings repeat too fails on the colours; a
//! view too plain to pin the pose fails on the conditioning.
//!
//! Poses are `world_from_camera` (metres); times are frame indices.

use super::ferns::{FernConfig, FernDatabase, FernError, FernFrame, FernMatch, Keyframe};
use crate::camera::Intrinsics;
use crate::fusion::{DepthTiles, Measured, Prediction, SurfelMap};
use crate::preprocess::FramePyramid;
use crate::preprocess::PyramidLevel;
use crate::se3;
use crate::track::verify::{against_surface, free_space_violation, Side, VerifyConfig};
use crate::track::{track, TrackResult, TrackerConfig, TrackerMode, TrackerWorkspace};
use glam::{DAffine3, Vec3};

/// Settings of relocalisation.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RelocaliseConfig {
    /// Relocalise lost frames (keyframes are kept either way, for global
    /// loop closure).
    pub enabled: bool,
    /// The keyframe database.
    pub ferns: FernConfig,
    /// Keyframes more dissimilar than this (0..1) are not tried. Measured
    /// on the synthetic room (500 ferns, 80x60): a revisit 5 cm and 3
    /// degrees off the path matches its keyframe at 0.27-0.34; views from
    /// places the path never went match at best 0.37-0.45.
    pub max_dissimilarity: f32,
    /// Most keyframes tried per lost frame (each costs a model render and
    /// two tracker runs).
    pub candidates: usize,
    /// The model is rendered down to this far behind the depth the keyframe
    /// measured, metres (its map may have been refined since).
    pub render_band_m: f32,
    /// The relocalised pose may lie at most this far from the keyframe it
    /// was started at, metres: a look-alike keyframe is near the camera.
    pub max_from_keyframe_m: f64,
    /// ... and this rotation, degrees.
    pub max_from_keyframe_deg: f64,
    /// Mean absolute grey-level difference (0..255, less the mean
    /// difference: exposure) between the frame's small image and the
    /// keyframe's, each block compared with the block it lands on at the
    /// relocalised pose (where the two depths agree).
    /// Geometry cannot tell a repeated object from the one mapped; its
    /// texture around it usually can. Measured, poses that passed every
    /// geometric check: on the synthetic room with a row of identical boxes
    /// 1 m apart, right 5.3, shifted by one to three boxes 15.3-21.3; on
    /// TUM fr3/teddy (keyframes of frames 0-119, every 6th frame looked
    /// up), within 1.4 cm of the tracked pose 2.2-12.2, and 16 cm / 9
    /// degrees and 35 cm / 20 degrees off 16.5 and 19.9.
    pub max_photometric_error: f32,
    /// Fewer blocks than this fraction of the small image compared: the
    /// frame hardly overlaps the keyframe it was placed by; refused.
    pub min_photometric_overlap: f32,
}

impl Default for RelocaliseConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            ferns: FernConfig::default(),
            max_dissimilarity: 0.45,
            candidates: 3,
            render_band_m: 0.1,
            max_from_keyframe_m: 0.5,
            max_from_keyframe_deg: 45.0,
            max_photometric_error: 14.0,
            min_photometric_overlap: 0.2,
        }
    }
}

/// A relocalised pose and how it was found.
#[derive(Debug, Clone, Copy)]
pub struct Relocalisation {
    /// The camera pose found (camera to world, metres).
    pub world_from_camera: DAffine3,
    /// Frame index of the keyframe the tracker was started at.
    pub keyframe_frame: u32,
    /// Fern dissimilarity of that keyframe to the frame (0..1).
    pub dissimilarity: f32,
    /// The normal tracker's result at the pose.
    pub result: TrackResult,
    /// Free-space violation fraction at the pose (see
    /// [`free_space_violation`]).
    pub free_space: f64,
    /// Mean grey-level difference to the keyframe's small image (see
    /// `RelocaliseConfig::max_photometric_error`).
    pub photometric_error: f32,
}

/// The check of [`Relocaliser::place`] that refused a keyframe's
/// registration, in the order they run (a later one got further).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum PlaceRefusal {
    /// The wide search from the keyframe's pose diverged.
    Diverged,
    /// The normal tracker lost the frame against the keyframe's view.
    Lost,
    /// The normal tracker's system was too weakly conditioned.
    IllConditioned,
    /// The pose landed too far from the keyframe it started at.
    FarFromKeyframe,
    /// The frame's points lie in front of the model, or the model shows
    /// through the frame's surfaces.
    FreeSpace,
    /// Too few of the small images' blocks could be compared.
    NoPhotometricOverlap,
    /// The grey levels disagree with the keyframe's.
    Photometric,
}

impl PlaceRefusal {
    /// Short kebab-case name (`far-from-keyframe`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Diverged => "diverged",
            Self::Lost => "lost",
            Self::IllConditioned => "ill-conditioned",
            Self::FarFromKeyframe => "far-from-keyframe",
            Self::FreeSpace => "free-space",
            Self::NoPhotometricOverlap => "no-photometric-overlap",
            Self::Photometric => "photometric",
        }
    }
}

/// One keyframe tried by [`Relocaliser::place`]: where its registration
/// put the frame and which check refused it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceAttempt {
    /// Frame index of the keyframe.
    pub keyframe_frame: u32,
    /// Fern dissimilarity of the keyframe to the frame (0..1).
    pub dissimilarity: f32,
    /// The pose registration found (`world_from_camera`, metres; the
    /// keyframe's own pose when the search diverged).
    pub world_from_camera: DAffine3,
    /// The normal tracker's eigenvalue ratio at that pose.
    pub conditioning: f64,
    /// Free-space violation fraction (0 when not reached).
    pub free_space: f64,
    /// Mean grey-level difference to the keyframe (0..255; `None` when
    /// not reached or too few blocks compared).
    pub photometric_error: Option<f32>,
    /// `None` when every check passed.
    pub refused: Option<PlaceRefusal>,
}

/// The trackers relocalisation runs: the normal one (whose verdict counts)
/// and the re-acquisition one with wide gates (which finds the start).
#[derive(Debug, Clone, Copy)]
pub struct Trackers<'a> {
    /// The pipeline's tracker settings.
    pub normal: &'a TrackerConfig,
    /// The re-acquisition search settings.
    pub wide: &'a TrackerConfig,
    /// The normal tracker's final system must be at least this well
    /// conditioned: without a prior pose, ICP on a view of one or two
    /// planes slides to a wrong pose with a tiny residual (the pipeline's
    /// re-acquisition bound).
    pub min_conditioning: f64,
}

/// The model a frame is relocalised against.
#[derive(Debug, Clone)]
pub struct Model<'a, F> {
    /// The surfel map (world frame).
    pub map: &'a SurfelMap,
    /// Surfels last seen in these frames are rendered (all of them to
    /// relocalise; the inactive ones for a global loop closure).
    pub seen: std::ops::Range<u32>,
    /// Which of those may be rendered (the pipeline's stable ones).
    pub include: F,
    /// Farthest depth rendered, metres.
    pub far_m: f32,
}

/// Keyframe database and the buffers relocalisation renders into.
#[derive(Debug)]
pub struct Relocaliser {
    config: RelocaliseConfig,
    database: FernDatabase,
    prediction: Prediction,
    measured: Vec<Vec3>,
    /// Never built: no tile culling (the keyframe's depth is coarse).
    tiles: DepthTiles,
    matches: Vec<FernMatch>,
    /// The keyframes the last [`Self::place`] tried, in order.
    attempts: Vec<PlaceAttempt>,
    /// Whether the last [`Self::encode`] succeeded.
    encoded: bool,
}

impl Relocaliser {
    /// An empty relocaliser with `config`.
    pub fn new(config: RelocaliseConfig) -> Result<Self, FernError> {
        if !(config.render_band_m >= 0.0 && config.render_band_m.is_finite()) {
            return Err(FernError::InvalidConfig("render band must be >= 0"));
        }
        Ok(Self {
            database: FernDatabase::new(config.ferns)?,
            config,
            prediction: Prediction::new(false),
            measured: Vec::new(),
            tiles: DepthTiles::default(),
            matches: Vec::new(),
            attempts: Vec::new(),
            encoded: false,
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &RelocaliseConfig {
        &self.config
    }

    /// The keyframe database.
    #[must_use]
    pub fn database(&self) -> &FernDatabase {
        &self.database
    }

    /// The keyframe database, to move keyframe poses after a loop closure.
    pub fn database_mut(&mut self) -> &mut FernDatabase {
        &mut self.database
    }

    /// The model as the keyframe of the last successful [`Self::place`] (or
    /// [`Self::relocalise`]) saw it, rendered from that keyframe's pose:
    /// which surfels a global loop closure pins. After a failed look it
    /// holds the last keyframe tried.
    #[must_use]
    pub fn keyframe_view(&self) -> &Prediction {
        &self.prediction
    }

    /// The keyframes the last [`Self::place`] (or [`Self::relocalise`])
    /// tried, most similar first; the last one is the match when it found one.
    #[must_use]
    pub fn attempts(&self) -> &[PlaceAttempt] {
        &self.attempts
    }

    /// Forgets every keyframe.
    pub fn clear(&mut self) {
        self.database.clear();
        self.prediction.clear();
        self.attempts.clear();
        self.encoded = false;
    }

    /// Encodes the frame of `pyramid` (working colour and finest depth) for
    /// [`Self::remember`] and [`Self::relocalise`]; call once per frame.
    pub fn encode(&mut self, pyramid: &FramePyramid) -> Result<(), FernError> {
        self.encoded = false;
        let (depth, width, height) = pyramid
            .levels
            .first()
            .and_then(|l| Some((&l.depth, l.intrinsics?)))
            .map_or((&[][..], 0, 0), |(d, k)| (&d[..], k.width, k.height));
        self.database.encode(&pyramid.rgb, depth, width, height)?;
        self.encoded = true;
        Ok(())
    }

    /// After the encoded frame was fused at `world_from_camera` (frame
    /// `frame_index`): keeps it as a keyframe when no keyframe looks like
    /// it. Returns the keyframe's index when added.
    pub fn remember(&mut self, world_from_camera: &DAffine3, frame_index: u32) -> Option<usize> {
        if !self.encoded {
            return None;
        }
        self.database.add_if_novel(world_from_camera, frame_index)
    }

    /// Tries to place the encoded frame (`pyramid`) in `model` from the
    /// keyframes that look like it; `None` when relocalisation is off or no
    /// keyframe's registration passes every check (see the module
    /// documentation).
    pub fn relocalise<F: Fn(usize) -> bool + Sync>(
        &mut self,
        pyramid: &FramePyramid,
        model: Model<'_, F>,
        trackers: Trackers<'_>,
        workspace: &mut TrackerWorkspace,
    ) -> Option<Relocalisation> {
        if !self.config.enabled {
            return None;
        }
        self.place(pyramid, model, trackers, workspace, 0..u32::MAX)
    }

    /// As [`Self::relocalise`] (whether or not relocalisation is on), from
    /// the keyframes of frames in `frames` only: a global loop closure
    /// looks for places seen long ago.
    pub fn place<F: Fn(usize) -> bool + Sync>(
        &mut self,
        pyramid: &FramePyramid,
        model: Model<'_, F>,
        trackers: Trackers<'_>,
        workspace: &mut TrackerWorkspace,
        frames: std::ops::Range<u32>,
    ) -> Option<Relocalisation> {
        let k = pyramid.levels.first()?.intrinsics?;
        if !self.encoded {
            return None;
        }
        let mut matches = std::mem::take(&mut self.matches);
        self.database.query_into(
            self.config.max_dissimilarity,
            frames,
            self.config.candidates,
            &mut matches,
        );
        let (normal, wide) = (icp_only(trackers.normal), icp_only(trackers.wide));
        self.attempts.clear();
        let mut found = None;
        for m in &matches {
            let Some(keyframe) = self.database.keyframes().get(m.keyframe) else {
                continue;
            };
            let start = keyframe.world_from_camera;
            let mut attempt = PlaceAttempt {
                keyframe_frame: keyframe.frame_index,
                dissimilarity: m.dissimilarity,
                world_from_camera: start,
                conditioning: 0.0,
                free_space: 0.0,
                photometric_error: None,
                refused: None,
            };
            self.render_keyframe_view(m.keyframe, &k, &model);
            let result = self.try_keyframe(
                pyramid,
                m.keyframe,
                (&normal, &wide),
                &trackers,
                workspace,
                &mut attempt,
            );
            self.attempts.push(attempt);
            if let Some(result) = result {
                found = Some(Relocalisation {
                    world_from_camera: attempt.world_from_camera,
                    keyframe_frame: attempt.keyframe_frame,
                    dissimilarity: attempt.dissimilarity,
                    result,
                    free_space: attempt.free_space,
                    photometric_error: attempt.photometric_error.unwrap_or(0.0),
                });
                break;
            }
        }
        self.matches = matches;
        found
    }

    /// Registers the frame against keyframe `id`'s view (rendered into
    /// `self.prediction`) and runs every check, filling `attempt`; the
    /// normal tracker's result when all pass.
    fn try_keyframe(
        &self,
        pyramid: &FramePyramid,
        id: usize,
        (normal, wide): (&TrackerConfig, &TrackerConfig),
        trackers: &Trackers<'_>,
        workspace: &mut TrackerWorkspace,
        attempt: &mut PlaceAttempt,
    ) -> Option<TrackResult> {
        let start = attempt.world_from_camera;
        let refuse = |attempt: &mut PlaceAttempt, why| {
            attempt.refused = Some(why);
            None
        };
        let searched = track(pyramid, &self.prediction, &start, wide, workspace);
        if !searched.world_from_camera.is_finite() {
            return refuse(attempt, PlaceRefusal::Diverged);
        }
        let result = track(
            pyramid,
            &self.prediction,
            &searched.world_from_camera,
            normal,
            workspace,
        );
        let pose = result.world_from_camera;
        if result.lost.is_some() || !pose.is_finite() {
            return refuse(attempt, PlaceRefusal::Lost);
        }
        attempt.world_from_camera = pose;
        attempt.conditioning = result.conditioning;
        if result.conditioning < trackers.min_conditioning {
            return refuse(attempt, PlaceRefusal::IllConditioned);
        }
        let (dt, dr) = se3::motion_magnitude(&(start.inverse() * pose));
        if dt > self.config.max_from_keyframe_m
            || dr.to_degrees() > self.config.max_from_keyframe_deg
        {
            return refuse(attempt, PlaceRefusal::FarFromKeyframe);
        }
        let Some(sampled) = pyramid.check_level() else {
            return refuse(attempt, PlaceRefusal::Lost);
        };
        let verify = &normal.verify;
        let (free_space, landed) =
            free_space_violation(&self.prediction, &sampled.vertices, 1, &pose, verify);
        let see_through = see_through_fraction(&self.prediction, sampled, &pose, verify);
        attempt.free_space = free_space.max(see_through);
        let limit = verify.max_free_space_fraction;
        if landed == 0 || free_space > limit || see_through > limit {
            return refuse(attempt, PlaceRefusal::FreeSpace);
        }
        let Some(keyframe) = self.database.keyframes().get(id) else {
            return refuse(attempt, PlaceRefusal::Lost);
        };
        let Some(k) = pyramid.levels.first().and_then(|l| l.intrinsics) else {
            return refuse(attempt, PlaceRefusal::Lost);
        };
        let Some(photometric) = photometric_error(
            self.database.current(),
            keyframe,
            &k,
            &pose,
            self.config.min_photometric_overlap,
        ) else {
            return refuse(attempt, PlaceRefusal::NoPhotometricOverlap);
        };
        attempt.photometric_error = Some(photometric);
        if photometric > self.config.max_photometric_error {
            return refuse(attempt, PlaceRefusal::Photometric);
        }
        Some(result)
    }

    /// The normal tracker (as [`Relocaliser::place`] runs it) from `from`
    /// against the model as the keyframe of the last [`Relocaliser::place`]
    /// saw it.
    pub fn track_in_placed_view(
        &self,
        pyramid: &FramePyramid,
        from: &DAffine3,
        normal: &TrackerConfig,
        workspace: &mut TrackerWorkspace,
    ) -> TrackResult {
        track(
            pyramid,
            &self.prediction,
            from,
            &icp_only(normal),
            workspace,
        )
    }

    /// Renders `model` from keyframe `id`'s pose, each pixel down to the
    /// farthest depth the keyframe measured in its block (plus the band):
    /// the model as the keyframe saw it.
    fn render_keyframe_view<F: Fn(usize) -> bool + Sync>(
        &mut self,
        id: usize,
        k: &Intrinsics,
        model: &Model<'_, F>,
    ) {
        let Some(keyframe) = self.database.keyframes().get(id) else {
            return;
        };
        let small = &keyframe.frame;
        let (w, h) = (small.width.max(1), small.height.max(1));
        let (width, height) = (k.width.max(1), k.height.max(1));
        self.measured.clear();
        self.measured.extend((0..k.pixel_count()).map(|i| {
            let (x, y) = (i % width, i / width);
            let cell = (y * h / height).min(h - 1) * w + (x * w / width).min(w - 1);
            Vec3::new(0.0, 0.0, small.far_m.get(cell).copied().unwrap_or(0.0))
        }));
        self.prediction.render(
            model.map,
            &keyframe.world_from_camera,
            k,
            (self.config.render_band_m, model.far_m),
            Measured {
                vertices: &self.measured,
                tiles: &self.tiles,
            },
            model.seen.clone(),
            &model.include,
        );
    }
}

/// Fraction of the model points of `prediction` (world frame, every 4th
/// pixel each way) that the frame (`level`, camera frame), placed at
/// `world_from_camera`, sees through: measured farther along the same ray
/// than the model point by more than the free-space margin. The converse of
/// [`free_space_violation`]: a look-alike place explains the frame's points
/// well (they land on or behind model surfaces) but the model then has
/// surfaces where the camera sees empty space. Among model points that land
/// on a measured pixel; 0 when none do.
pub(crate) fn see_through_fraction(
    prediction: &Prediction,
    level: &PyramidLevel,
    world_from_camera: &DAffine3,
    config: &VerifyConfig,
) -> f64 {
    let Some(k) = level.intrinsics else {
        return 0.0;
    };
    if level.vertices.len() != k.pixel_count() {
        return 0.0;
    }
    let camera_from_world = world_from_camera.inverse().as_affine3a();
    let (mut seen_through, mut landed) = (0usize, 0usize);
    let frame_z = |i: usize| Some(level.vertices[i].z).filter(|&z| z > 0.0);
    let width = prediction.intrinsics.map_or(1, |p| p.width.max(1));
    for (i, model) in prediction.vertices.iter().enumerate().step_by(4) {
        if (i / width) % 4 != 0 || *model == Vec3::ZERO {
            continue;
        }
        let Some((q_z, _, z)) = against_surface(&k, &camera_from_world, *model, frame_z) else {
            continue;
        };
        landed += 1;
        // The frame's point lies behind the model's surface: seen through it.
        if config.side(z, q_z) == Side::Behind {
            seen_through += 1;
        }
    }
    seen_through as f64 / landed.max(1) as f64
}

/// Intrinsics of the small image `frame` made from the image seen through
/// `k` (block centres at the centres of the pixels they average). Its
/// blocks split the image evenly, so a block spans `k.width / frame.width`
/// pixels, not a whole number of them at 256x192 or 848x480.
fn small_intrinsics(k: &Intrinsics, frame: &FernFrame) -> Intrinsics {
    let (bx, by) = (
        k.width as f32 / frame.width.max(1) as f32,
        k.height as f32 / frame.height.max(1) as f32,
    );
    Intrinsics::new(
        k.fx / bx,
        k.fy / by,
        (k.cx - 0.5 * (bx - 1.0)) / bx,
        (k.cy - 0.5 * (by - 1.0)) / by,
        frame.width,
        frame.height,
    )
}

fn grey(c: [u8; 3]) -> f32 {
    0.299 * f32::from(c[0]) + 0.587 * f32::from(c[1]) + 0.114 * f32::from(c[2])
}

/// Mean absolute grey difference, less its mean (exposure), between the blocks of `current` (taken at
/// `world_from_camera` through `k` at full size) and the blocks of
/// `keyframe` they land on, where the keyframe measured about the same
/// depth there (5 % + 5 cm: else one of the two sees something else).
/// `None` when fewer than `min_overlap` of the blocks were compared.
fn photometric_error(
    current: &FernFrame,
    keyframe: &Keyframe,
    k: &Intrinsics,
    world_from_camera: &DAffine3,
    min_overlap: f32,
) -> Option<f32> {
    let small = small_intrinsics(k, current);
    let theirs = &keyframe.frame;
    let their_k = small_intrinsics(k, theirs);
    let keyframe_from_current =
        (keyframe.world_from_camera.inverse() * *world_from_camera).as_affine3a();
    let mut differences = Vec::with_capacity(current.depth_m.len());
    for (i, (&z, &c)) in current.depth_m.iter().zip(&current.rgb).enumerate() {
        if z <= 0.0 {
            continue;
        }
        let (u, v) = ((i % current.width) as f32, (i / current.width) as f32);
        let q = keyframe_from_current.transform_point3(small.back_project(u, v, z));
        if q.z <= 0.0 {
            continue;
        }
        let Some(j) = their_k.pixel_index(their_k.project(q)) else {
            continue;
        };
        let their_z = theirs.depth_m.get(j).copied().unwrap_or(0.0);
        if their_z <= 0.0 || (their_z - q.z).abs() > 0.05 + 0.05 * q.z {
            continue;
        }
        let Some(&their_c) = theirs.rgb.get(j) else {
            continue;
        };
        differences.push(grey(c) - grey(their_c));
    }
    let count = differences.len();
    let needed = min_overlap * current.depth_m.len() as f32;
    if count == 0 || (count as f32) < needed {
        return None;
    }
    // A camera's exposure moves every grey level alike: that offset is not
    // a sign of another place.
    let offset = differences.iter().sum::<f32>() / count as f32;
    Some(differences.iter().map(|d| (d - offset).abs()).sum::<f32>() / count as f32)
}

/// `c` as relocalisation runs it. The photometric term compares with the
/// previous fused frame, which is not where the camera is now: geometry
/// alone. Nothing is held: the start (a keyframe's pose) is no motion
/// prior, and the conditioning and free-space checks judge the view.
fn icp_only(c: &TrackerConfig) -> TrackerConfig {
    TrackerConfig {
        mode: TrackerMode::Icp,
        hold_below_eigenvalue: 0.0,
        ..c.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each small pixel is the mean of a block that splits the image
    /// evenly (`ferns::downsample_into`): the point seen at that block's
    /// mean column and row must land on that small pixel, at 640x480 (8x8
    /// blocks) as at an iPhone's 256x192 (3.2) and an 848x480 RealSense
    /// frame (10.6 x 8).
    #[test]
    fn small_intrinsics_put_each_block_mean_on_its_small_pixel() {
        for (width, height) in [(640, 480), (256, 192), (848, 480)] {
            let k = Intrinsics::new(
                0.8 * width as f32,
                0.8 * width as f32,
                0.5 * width as f32 - 0.3,
                0.5 * height as f32 + 0.7,
                width,
                height,
            );
            let frame = FernFrame {
                width: 80,
                height: 60,
                block: (width / 80, height / 60),
                ..FernFrame::default()
            };
            let small = small_intrinsics(&k, &frame);
            let mean = |i: usize, full: usize, n: usize| {
                let (a, b) = (i * full / n, (i + 1) * full / n);
                0.5 * (a + b - 1) as f32
            };
            for (i, j) in [(0, 0), (17, 42), (79, 59), (40, 30)] {
                let p = k.back_project(mean(i, width, 80), mean(j, height, 60), 2.0);
                let uv = small.project(p);
                assert!(
                    (uv.x - i as f32).abs() < 0.3 && (uv.y - j as f32).abs() < 0.3,
                    "{width}x{height}: block ({i}, {j}) lands at {uv}"
                );
            }
        }
    }
}
