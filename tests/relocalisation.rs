//! Keyframe ferns and relocalisation on the synthetic room: a revisited
//! place is found and the camera placed to within 2 cm of the truth; a
//! place never mapped, or a look-alike of a mapped object, is not.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{shared_dataset, synthetic_config};
use glam::{DAffine3, DVec3};
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::loop_closure::ferns::{FernConfig, FernDatabase};
use surfel_slam::loop_closure::global::{
    constraints_into, find_global_match, GlobalConfig, GlobalMatch,
};
use surfel_slam::loop_closure::relocalise::{
    Model, Relocalisation, RelocaliseConfig, Relocaliser, Trackers,
};
use surfel_slam::preprocess::FramePyramid;
use surfel_slam::se3::{exp, motion_magnitude};
use surfel_slam::synthetic::{self, look_at, NoiseModel, Scene, SceneBox, ROOM_MAX, ROOM_MIN};
use surfel_slam::track::{TrackerConfig, TrackerWorkspace};
use surfel_slam::{Intrinsics, Pipeline, SlamConfig};

fn small() -> Intrinsics {
    synthetic::default_intrinsics().half()
}

/// Kinect-like holes, edge holes and colour noise, exact depth: the map
/// then does not drift, so the distance to the truth measures the
/// relocalisation alone.
fn noise() -> NoiseModel {
    NoiseModel {
        depth_sigma_at_1m: 0.0,
        ..NoiseModel::kinect()
    }
}

/// A 5 cm / 4 degree step off the mapped path.
fn off_path(pose: DAffine3) -> DAffine3 {
    pose * exp(&[0.04, -0.03, 0.05, 0.03, 0.02, -0.03])
}

/// The room with a row of identical boxes (one material) 1 m apart along
/// the +z wall.
fn repeated_boxes() -> Scene {
    let mut boxes = vec![SceneBox::room(ROOM_MIN, ROOM_MAX, 0)];
    for x in -2..=2 {
        let x = f64::from(x);
        boxes.push(SceneBox::solid(
            DVec3::new(x - 0.25, -0.8, 2.3),
            DVec3::new(x + 0.25, 0.0, 2.8),
            1,
        ));
    }
    Scene { boxes }
}

/// A camera at `x` along the row, looking at the boxes, with a yaw wobble of phase `t`.
fn row_pose(x: f64, t: f64) -> DAffine3 {
    let eye = DVec3::new(x, -1.4, 0.3);
    look_at(eye, DVec3::new(x + 0.3 * (0.05 * t).sin(), -0.4, 2.7))
}

/// The pipeline's re-acquisition search (wide gates, more coarse iterations).
fn wide(normal: &TrackerConfig) -> TrackerConfig {
    let mut wide = normal.clone();
    wide.gates.distance_gate_m = 0.3;
    wide.gates.normal_gate_deg = 45.0;
    wide.gates.huber_m *= 2.0;
    wide.iterations = vec![6, 12, 16];
    wide.max_translation_m = f64::INFINITY;
    wide.max_rotation_deg = f64::INFINITY;
    wide
}

/// A map built by the pipeline along a path, with the relocaliser fed the
/// same frames.
struct Mapped {
    scene: Scene,
    config: SlamConfig,
    slam: Pipeline,
    relocaliser: Relocaliser,
    pyramid: FramePyramid,
    workspace: TrackerWorkspace,
    /// world_from_scene: the pipeline's world is the first camera.
    world_from_scene: DAffine3,
}

impl Mapped {
    fn along(scene: Scene, path: &[DAffine3]) -> Self {
        let config = synthetic_config(small());
        let mut mapped = Self {
            scene,
            slam: Pipeline::new(config.clone()).expect("config"),
            relocaliser: Relocaliser::new(RelocaliseConfig::default()).expect("config"),
            pyramid: FramePyramid::new(&config.intrinsics, &config.preprocess),
            workspace: TrackerWorkspace::default(),
            world_from_scene: path[0].inverse(),
            config,
        };
        for (i, pose) in path.iter().enumerate() {
            mapped.show(pose, i as u64);
            let report = mapped
                .slam
                .push_frame(&mapped.frame(pose, i as u64), i as f64)
                .expect("push");
            if report.verdict.is_fused() {
                mapped
                    .relocaliser
                    .remember(&report.world_from_camera, i as u32);
            }
        }
        let lost = mapped.slam.counts().lost;
        assert!(lost <= 2, "{lost} frames lost while mapping");
        mapped
    }

    fn frame(&self, pose: &DAffine3, seed: u64) -> surfel_slam::RgbdFrame {
        synthetic::render(&self.scene, &small(), pose, &noise(), seed)
            .to_frame(&self.config.depth)
            .expect("frame")
    }

    /// Builds the pyramid of the view from `pose` and encodes it.
    fn show(&mut self, pose: &DAffine3, seed: u64) {
        let frame = self.frame(pose, seed);
        self.pyramid
            .build(&frame, &self.config.preprocess, &self.config.tracker.noise);
        self.relocaliser.encode(&self.pyramid).expect("encode");
    }

    /// Relocalises the view from `pose` (scene frame); with the error of
    /// the result against the truth (metres, degrees).
    fn relocalise(&mut self, pose: &DAffine3, seed: u64) -> Option<(Relocalisation, f64, f64)> {
        self.show(pose, seed);
        let map = self.slam.map();
        let stable = self.config.fusion.stable_confidence;
        let found = self.relocaliser.relocalise(
            &self.pyramid,
            Model {
                map,
                seen: 0..u32::MAX,
                include: |i: usize| map.confidences()[i] >= stable,
                far_m: self.config.depth.max_m,
            },
            Trackers {
                normal: &self.config.tracker,
                wide: &wide(&self.config.tracker),
                min_conditioning: 2e-3,
            },
            &mut self.workspace,
        )?;
        let truth = self.world_from_scene * *pose;
        let (dt, dr) = motion_magnitude(&(truth.inverse() * found.world_from_camera));
        Some((found, dt, dr.to_degrees()))
    }
}

#[test]
fn ferns_find_the_keyframe_of_a_revisited_place() {
    let k = small();
    let scene = Scene::room();
    let mut db = FernDatabase::new(FernConfig::default()).expect("config");
    let encode = |db: &mut FernDatabase, pose: &DAffine3, seed: u64| {
        let f = synthetic::render(&scene, &k, pose, &NoiseModel::kinect(), seed);
        let depth: Vec<f32> = f
            .depth_raw
            .iter()
            .map(|&r| f32::from(r) / synthetic::DEPTH_UNITS_PER_METRE)
            .collect();
        db.encode(&f.rgb, &depth, k.width, k.height)
            .expect("encode");
    };
    for i in 0..300 {
        let pose = synthetic::trajectory_pose(i);
        encode(&mut db, &pose, i as u64);
        db.add_if_novel(&pose, i as u32);
    }
    let keyframes = db.keyframes().len();
    // Novel views only: a keyframe every 3-8 frames of the path.
    assert!((30..=120).contains(&keyframes), "{keyframes} keyframes");
    for i in [20, 45, 77, 130, 201, 260] {
        let pose = off_path(synthetic::trajectory_pose(i));
        encode(&mut db, &pose, 1000 + i as u64);
        let best = db.best().expect("a keyframe");
        let keyframe = &db.keyframes()[best.keyframe];
        let (dt, dr) = motion_magnitude(&(keyframe.world_from_camera.inverse() * pose));
        assert!(
            dt < 0.15 && dr.to_degrees() < 10.0 && best.dissimilarity < 0.4,
            "revisit of {i}: keyframe {} at {dt:.3} m {:.1} deg, dissimilarity {}",
            keyframe.frame_index,
            dr.to_degrees(),
            best.dissimilarity
        );
    }
}

#[test]
fn revisited_places_are_relocalised_and_places_never_seen_are_not() {
    // 125 frames: from about frame 129 on, the view at this resolution is
    // mostly a wall and the floor, and the pipeline loses the camera.
    let path: Vec<DAffine3> = (0..125).map(synthetic::trajectory_pose).collect();
    let mut mapped = Mapped::along(Scene::room(), &path);
    for i in [5, 20, 45, 80, 110] {
        let (found, dt, dr) = mapped
            .relocalise(&off_path(path[i]), 9000 + i as u64)
            .unwrap_or_else(|| panic!("revisit of frame {i} not relocalised"));
        assert!(
            dt < 0.02 && dr < 1.0,
            "revisit of frame {i}: {dt:.4} m {dr:.2} deg off (keyframe {})",
            found.keyframe_frame
        );
    }
    // From the room's middle, looking all around at the walls: mostly
    // places the path never faced from here. A pose found must be right.
    for a in 0..12u32 {
        let angle = f64::from(a) * 30f64.to_radians();
        let eye = DVec3::new(0.3, -1.5, -0.2);
        let pose = look_at(eye, eye + DVec3::new(angle.cos(), 0.5, angle.sin()));
        if let Some((found, dt, dr)) = mapped.relocalise(&pose, 5000 + u64::from(a)) {
            assert!(
                dt < 0.05 && dr < 2.0,
                "view {a} placed {dt:.3} m {dr:.1} deg off by keyframe {}",
                found.keyframe_frame
            );
        }
    }
}

#[test]
fn a_repeated_object_is_not_mistaken_for_the_one_mapped() {
    // Mapped: x = -2.2 .. -0.27, the boxes at -2 and -1 (and 0 at the edge
    // of the view). Every box and the wall behind look alike in geometry;
    // only their texture differs.
    let path: Vec<DAffine3> = (0..130)
        .map(|i| row_pose(-2.2 + 0.015 * f64::from(i), f64::from(i)))
        .collect();
    let mut mapped = Mapped::along(repeated_boxes(), &path);
    let (_, dt, dr) = mapped
        .relocalise(&row_pose(-1.5, 17.0), 9000)
        .expect("a mapped view is relocalised");
    assert!(dt < 0.02 && dr < 1.0, "{dt:.4} m {dr:.2} deg off");
    for (n, x) in [-1.0, -0.6, 0.0, 0.5, 0.8, 1.0, 1.5, 2.0]
        .into_iter()
        .enumerate()
    {
        if let Some((found, dt, dr)) = mapped.relocalise(&row_pose(x, 17.0), 9100 + n as u64) {
            assert!(
                dt < 0.05 && dr < 2.0,
                "view at x = {x} placed {dt:.3} m {dr:.1} deg off by keyframe {} (photometric {:.1})",
                found.keyframe_frame,
                found.photometric_error
            );
        }
    }
}

/// A frame of noise: random colour and random depth in 0.5..4.5 m.
fn garbage(k: &Intrinsics, seed: u64) -> surfel_slam::RgbdFrame {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let n = k.pixel_count();
    surfel_slam::RgbdFrame {
        width: k.width,
        height: k.height,
        rgb: (0..3 * n).map(|_| (next() >> 56) as u8).collect(),
        depth_deviation: Vec::new(),
        depth_m: (0..n)
            .map(|_| 0.5 + 4.0 * (next() >> 40) as f32 / (1u64 << 24) as f32)
            .collect(),
    }
}

#[test]
fn a_lost_camera_that_jumps_to_a_mapped_place_is_relocalised() {
    lost_camera_jumps_to_a_mapped_place(false, 110, 20);
}

/// The same on depth alone (a Stray Scanner scan without `rgb/`): grey
/// colour, ICP.
#[test]
fn a_lost_camera_without_colour_that_jumps_to_a_mapped_place_is_relocalised() {
    lost_camera_jumps_to_a_mapped_place(true, 110, 20);
}

/// Depth alone makes keyframes too: TUM fr3/teddy with its colour and,
/// beside it, with a grey image (as a depth-only sequence runs). With one
/// depth test a fern (the colour tests see one grey), frame 0 stayed the
/// only keyframe, and a lost camera could be placed only where it started.
#[test]
fn frames_without_colour_make_keyframes_too() {
    let Some(dir) = shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence opens");
    let config = SlamConfig::from_preset(sequence.preset);
    let mut with_colour = Pipeline::new(config.clone()).expect("config");
    let mut without = Pipeline::new(config.clone()).expect("config");
    for entry in &sequence.frames {
        let mut frame = read_frame(&dir, entry, &config.depth).expect("frame decodes");
        with_colour
            .push_frame(&frame, entry.timestamp)
            .expect("push");
        frame.rgb.fill(surfel_slam::dataset::DEPTH_ONLY_GREY);
        without.push_frame(&frame, entry.timestamp).expect("push");
    }
    let (with_colour, without) = (
        with_colour.state().keyframes.len(),
        without.state().keyframes.len(),
    );
    assert!(
        without >= 4 && 3 * without >= with_colour,
        "{without} keyframes without colour, {with_colour} with"
    );
}

/// Maps frames `0..mapped` of the path, then five frames of noise, then
/// moves on beside the path from frame `back_to`.
fn lost_camera_jumps_to_a_mapped_place(depth_only: bool, mapped: usize, back_to: usize) {
    let k = small();
    let mut config = synthetic_config(k);
    if depth_only {
        config.tracker.mode = surfel_slam::track::TrackerMode::Icp;
    }
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let world_from_scene = synthetic::trajectory_pose(0).inverse();
    // Mapping along the path, five frames of noise (the camera covered or
    // shaken), then the camera is far away (from frame 110 to 20: 1.1 m and
    // 57 degrees), back where it was, and moves on 5 cm / 4 degrees beside
    // its old path.
    let mut views: Vec<Option<DAffine3>> = (0..mapped)
        .map(|i| Some(synthetic::trajectory_pose(i)))
        .collect();
    views.extend([None; 5]);
    let jump = views.len();
    views.extend((back_to..back_to + 30).map(|i| Some(off_path(synthetic::trajectory_pose(i)))));
    let mut relocalised = None;
    for (i, view) in views.iter().enumerate() {
        let mut frame = match view {
            Some(pose) => synthetic::render(&scene, &k, pose, &noise(), i as u64)
                .to_frame(&config.depth)
                .expect("frame"),
            None => garbage(&k, i as u64),
        };
        if depth_only {
            frame.rgb.fill(surfel_slam::dataset::DEPTH_ONLY_GREY);
        }
        let report = slam.push_frame(&frame, i as f64).expect("push");
        if !report.verdict.is_fused() {
            continue;
        }
        let Some(pose) = view else {
            panic!("frame {i} of noise fused ({})", report.verdict.name());
        };
        let truth = world_from_scene * *pose;
        let (dt, dr) = motion_magnitude(&(truth.inverse() * report.world_from_camera));
        // Never a wrong pose reported as tracked.
        assert!(
            dt < 0.05 && dr.to_degrees() < 3.0,
            "frame {i} {}: {dt:.3} m {:.2} deg from the truth",
            report.verdict.name(),
            dr.to_degrees()
        );
        if i >= jump && relocalised.is_none() {
            relocalised = Some((i, dt, dr.to_degrees(), report.checks.relocalised_from));
        }
    }
    let (i, dt, dr, keyframe) = relocalised.expect("relocalised after the jump");
    assert!(
        dt < 0.02 && dr < 1.0,
        "frame {i} relocalised {dt:.4} m {dr:.2} deg from the truth"
    );
    assert!(keyframe.is_some(), "frame {i} placed without a keyframe");
    assert!(i <= jump + 2, "relocalised only at frame {i}");
    let counts = slam.counts();
    assert!(counts.lost <= 8, "{} frames lost", counts.lost);
}

/// A `Mapped` place looked up as a global loop closure from `tracked`.
fn global_match(
    mapped: &mut Mapped,
    view: &DAffine3,
    tracked: &DAffine3,
    seed: u64,
) -> Option<GlobalMatch> {
    mapped.show(view, seed);
    let map = mapped.slam.map();
    let stable = mapped.config.fusion.stable_confidence;
    let config = GlobalConfig {
        min_age_frames: 50,
        every_frames: 1,
        ..GlobalConfig::default()
    };
    find_global_match(
        &mut mapped.relocaliser,
        &mapped.pyramid,
        Model {
            map,
            seen: 0..u32::MAX,
            include: |i: usize| map.confidences()[i] >= stable,
            far_m: mapped.config.depth.max_m,
        },
        Trackers {
            normal: &mapped.config.tracker,
            wide: &wide(&mapped.config.tracker),
            min_conditioning: 2e-3,
        },
        &mut mapped.workspace,
        (tracked, 125),
        &config,
    )
    .ok()
}

#[test]
fn a_drifted_return_to_an_old_place_gives_the_correction_and_a_foreign_one_none() {
    let path: Vec<DAffine3> = (0..125).map(synthetic::trajectory_pose).collect();
    let mut mapped = Mapped::along(Scene::room(), &path);
    // Back at frame 20's place, with 8 cm and 1 degree of drift in the
    // tracked pose.
    let view = off_path(path[20]);
    let truth = mapped.world_from_scene * view;
    let drift = exp(&[0.0, 0.02, 0.0, 0.06, -0.03, 0.04]);
    let tracked = truth * drift;
    let found = global_match(&mut mapped, &view, &tracked, 7000).expect("a closure");
    let registered = found.registration.world_from_camera;
    let (dt, dr) = motion_magnitude(&(truth.inverse() * registered));
    assert!(
        dt < 0.02 && dr.to_degrees() < 1.0,
        "{dt:.4} m {:.2} deg",
        dr.to_degrees()
    );
    assert!(found.registration.keyframe_frame < 75);
    let mut constraints = Vec::new();
    let level = mapped.pyramid.levels.last().expect("levels");
    let width = level.intrinsics.expect("intrinsics").width;
    constraints_into(&found, &level.vertices, width, 4, &mut constraints);
    assert!(constraints.len() > 100, "{} constraints", constraints.len());
    for (source, target) in &constraints {
        // The source is where the drifted pose put the point, the target
        // where the truth is: the target lies on the true surface.
        let world = mapped.world_from_scene.inverse();
        let on_surface = mapped
            .scene
            .distance_to_surface(world.transform_point3(target.as_dvec3()));
        assert!(
            on_surface < 0.03,
            "target {on_surface:.3} m off the surface"
        );
        assert!((*target - *source).length() < 0.2);
    }
    // The same drift at a frame of noise spliced in: nothing.
    let noise_frame = garbage(&small(), 3);
    mapped.pyramid.build(
        &noise_frame,
        &mapped.config.preprocess,
        &mapped.config.tracker.noise,
    );
    let _ = mapped.relocaliser.encode(&mapped.pyramid);
    let map = mapped.slam.map();
    let stable = mapped.config.fusion.stable_confidence;
    let spliced = find_global_match(
        &mut mapped.relocaliser,
        &mapped.pyramid,
        Model {
            map,
            seen: 0..u32::MAX,
            include: |i: usize| map.confidences()[i] >= stable,
            far_m: mapped.config.depth.max_m,
        },
        Trackers {
            normal: &mapped.config.tracker,
            wide: &wide(&mapped.config.tracker),
            min_conditioning: 2e-3,
        },
        &mut mapped.workspace,
        (&tracked, 125),
        &GlobalConfig {
            min_age_frames: 50,
            every_frames: 1,
            ..GlobalConfig::default()
        },
    );
    assert!(spliced.is_err(), "a frame of noise closed a loop");
}

#[test]
fn a_look_alike_object_closes_no_loop() {
    let path: Vec<DAffine3> = (0..125)
        .map(|i| row_pose(-2.2 + 0.015 * f64::from(i), f64::from(i)))
        .collect();
    let mut mapped = Mapped::along(repeated_boxes(), &path);
    for (n, x) in [0.0, 0.8, 1.0, 1.5, 2.0].into_iter().enumerate() {
        let view = row_pose(x, 17.0);
        let truth = mapped.world_from_scene * view;
        let tracked = truth * exp(&[0.0, 0.01, 0.0, 0.05, 0.0, 0.03]);
        if let Some(found) = global_match(&mut mapped, &view, &tracked, 7100 + n as u64) {
            let (dt, dr) =
                motion_magnitude(&(truth.inverse() * found.registration.world_from_camera));
            assert!(
                dt < 0.05 && dr.to_degrees() < 2.0,
                "a view at x = {x} closed a loop {dt:.3} m off"
            );
        }
    }
}

#[test]
fn teddy_frames_are_relocalised_near_the_truth_or_not_at_all() {
    let Some(dir) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence");
    let config = SlamConfig::from_preset(sequence.preset);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut relocaliser = Relocaliser::new(RelocaliseConfig::default()).expect("config");
    let mut pyramid = FramePyramid::new(&config.intrinsics, &config.preprocess);
    let frames: Vec<_> = sequence
        .frames
        .iter()
        .map(|e| read_frame(&dir, e, &config.depth).expect("frame"))
        .collect();
    // Keyframes from the first 120 frames; the map from all of them.
    for (i, (entry, frame)) in sequence.frames.iter().zip(&frames).enumerate() {
        let report = slam.push_frame(frame, entry.timestamp).expect("push");
        pyramid.build(frame, &config.preprocess, &config.tracker.noise);
        relocaliser.encode(&pyramid).expect("encode");
        if report.verdict.is_fused() && i < 120 {
            relocaliser.remember(&report.world_from_camera, i as u32);
        }
    }
    let align = ate(slam.trajectory(), &sequence.ground_truth, 0.02)
        .expect("ate")
        .ground_truth_from_estimate;
    let mut workspace = TrackerWorkspace::default();
    let (mut placed, mut mapped_places) = (0, 0);
    for (i, (entry, frame)) in sequence.frames.iter().zip(&frames).enumerate().step_by(6) {
        pyramid.build(frame, &config.preprocess, &config.tracker.noise);
        relocaliser.encode(&pyramid).expect("encode");
        let map = slam.map();
        let stable = config.fusion.stable_confidence;
        let found = relocaliser.relocalise(
            &pyramid,
            Model {
                map,
                seen: 0..u32::MAX,
                include: |j: usize| map.confidences()[j] >= stable,
                far_m: config.depth.max_m,
            },
            Trackers {
                normal: &config.tracker,
                wide: &wide(&config.tracker),
                min_conditioning: 2e-3,
            },
            &mut workspace,
        );
        mapped_places += usize::from(i < 120);
        let Some(found) = found else {
            continue;
        };
        placed += usize::from(i < 120);
        let Some(truth) = sequence.ground_truth_for(entry.timestamp, 0.02) else {
            continue;
        };
        let error = (align.transform_point3(found.world_from_camera.translation)
            - truth.translation)
            .length();
        // The tracked poses themselves are within about 1.5 cm.
        assert!(
            error < 0.03,
            "frame {i} relocalised {error:.3} m from the truth by keyframe {} (photometric {:.1})",
            found.keyframe_frame,
            found.photometric_error
        );
    }
    assert!(
        2 * placed >= mapped_places,
        "only {placed} of {mapped_places} frames of mapped places relocalised"
    );
}
