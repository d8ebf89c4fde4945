//! Loop closure end to end on the synthetic loop (known truth) and the real sequences.

mod common;

use common::synthetic_config;
use glam::DAffine3;
use surfel_slam::eval::ate;
use surfel_slam::fusion::{DepthTiles, Measured, Prediction, SurfelMap};
use surfel_slam::loop_closure::local::{ModelRegistration, Rejection};
use surfel_slam::loop_closure::LoopClosureConfig;
use surfel_slam::preprocess::FramePyramid;
use surfel_slam::se3::exp;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::synthetic::{self, loop_pose, NoiseModel, Scene};
use surfel_slam::track::verify::VerifyConfig;
use surfel_slam::{FrameReport, Intrinsics, Pipeline, SlamConfig};

struct LoopRun {
    slam: Pipeline,
    reports: Vec<FrameReport>,
    truth: Vec<(f64, DAffine3)>,
}

/// Runs `frames` frames of the loop (`per_loop` frames a turn), rendered
/// with `render_k` and `noise`, through a pipeline configured with `config`.
fn run_loop(
    config: &SlamConfig,
    render_k: surfel_slam::Intrinsics,
    per_loop: usize,
    frames: usize,
    noise: NoiseModel,
) -> LoopRun {
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let origin_inv = loop_pose(0, per_loop).inverse();
    let mut reports = Vec::new();
    let mut truth = Vec::new();
    for i in 0..frames {
        let pose = loop_pose(i, per_loop);
        let frame = synthetic::render(&scene, &render_k, &pose, &noise, i as u64)
            .to_frame(&config.depth)
            .expect("frame");
        reports.push(slam.push_frame(&frame, i as f64).expect("push"));
        truth.push((i as f64, origin_inv * pose));
    }
    LoopRun {
        slam,
        reports,
        truth,
    }
}

#[test]
#[ignore]
fn drift_explore() {
    let k = synthetic::default_intrinsics().half();
    for (name, fx_scale, noise) in [
        ("clean", 1.0, NoiseModel::none()),
        ("kinect", 1.0, NoiseModel::kinect()),
        ("fx+1%", 1.01, NoiseModel::none()),
        ("fx+2%", 1.02, NoiseModel::none()),
        ("fx+1% kinect", 1.01, NoiseModel::kinect()),
    ] {
        let mut config = synthetic_config(k);
        config.intrinsics.fx *= fx_scale;
        config.intrinsics.fy *= fx_scale;
        let run = run_loop(&config, k, 240, 270, noise);
        let lost = run.reports.iter().filter(|r| !r.verdict.is_fused()).count();
        let a = ate(run.slam.trajectory(), &run.truth, 0.01).expect("ate");
        let end = run.slam.trajectory()[240].1;
        let (dt, dr) = motion_magnitude(&(run.slam.trajectory()[0].1.inverse() * end));
        println!(
            "{name}: lost {lost}, ATE {:.2} cm, pose 240 vs 0: {:.2} cm {:.2} deg, surfels {}",
            a.rmse_m * 100.0,
            dt * 100.0,
            dr.to_degrees(),
            run.slam.map().live_len()
        );
    }
}

/// One synthetic view's points and normals at `k`, camera frame.
fn view_points(k: &Intrinsics, pose: &DAffine3) -> (Vec<glam::Vec3>, Vec<glam::Vec3>) {
    let config = synthetic_config(*k);
    let frame = synthetic::render(&Scene::room(), k, pose, &NoiseModel::none(), 0)
        .to_frame(&config.depth)
        .expect("frame");
    let mut pyramid = FramePyramid::new(k, &config.preprocess);
    pyramid.build(&frame, &config.preprocess);
    let level = &pyramid.levels[0];
    (level.vertices.clone(), level.normals.clone())
}

/// Adds the surfels of the view `(points, normals)` placed by `world_from_camera`.
fn add_view(
    map: &mut SurfelMap,
    view: &(Vec<glam::Vec3>, Vec<glam::Vec3>),
    world_from_camera: &DAffine3,
    frame: u32,
) {
    let t = world_from_camera.as_affine3a();
    for (p, n) in view.0.iter().zip(&view.1) {
        if p.z > 0.0 && *n != glam::Vec3::ZERO {
            let n = t.transform_vector3(*n);
            map.push(
                t.transform_point3(*p),
                n,
                [128, 128, 128, 255],
                0.004,
                10.0,
                frame,
            );
        }
    }
}

/// Predictions of the surfels below `split` (inactive) and from `split` on
/// (active), rendered from `believed` with the view `measured` taken there.
fn predictions(
    map: &SurfelMap,
    split: usize,
    k: &Intrinsics,
    believed: &DAffine3,
    measured: &[glam::Vec3],
) -> (Prediction, Prediction) {
    let mut tiles = DepthTiles::default();
    tiles.build(measured, k.width);
    let render = |include: &(dyn Fn(usize) -> bool + Sync)| {
        let mut p = Prediction::new(false);
        p.render(
            map,
            believed,
            k,
            (0.05, 8.0),
            Measured {
                vertices: measured,
                tiles: &tiles,
            },
            0..u32::MAX,
            |i| include(i),
        );
        p
    };
    (render(&|i| i >= split), render(&|i| i < split))
}

#[test]
fn model_to_model_registration_measures_a_known_drift() {
    let k = synthetic::default_intrinsics().half();
    let config = LoopClosureConfig::default();
    let verify = VerifyConfig::default();
    let (old_pose, new_pose) = (loop_pose(0, 240), loop_pose(6, 240));
    let (old_view, new_view) = (view_points(&k, &old_pose), view_points(&k, &new_pose));
    let mut registration = ModelRegistration::default();
    // The new view mapped with drift: the pipeline believes the camera is
    // at `drift * new_pose`, so its surfels lie `drift` away from the old ones.
    for drift in [
        exp(&[0.01, -0.015, 0.008, 0.03, -0.01, 0.02]),
        exp(&[-0.02, 0.01, 0.0, -0.05, 0.03, 0.0]),
        DAffine3::IDENTITY,
    ] {
        let mut map = SurfelMap::default();
        add_view(&mut map, &old_view, &old_pose, 0);
        let split = map.len();
        let believed = drift * new_pose;
        add_view(&mut map, &new_view, &believed, 100);
        let (active, inactive) = predictions(&map, split, &k, &believed, &new_view.0);
        let r = registration.register(&active, &inactive, &config, &verify);
        assert!(r.accepted(), "{r:?}");
        let (dt, dr) = motion_magnitude(&(r.correction * drift));
        assert!(
            dt < 0.002 && dr.to_degrees() < 0.1,
            "{dt} m {} deg off: {r:?}",
            dr.to_degrees()
        );
        println!(
            "drift {:?}: overlap {}, inliers {}, rms {:.2} mm, conditioning {:.4}, free space {:.3}, error {:.2} mm {:.3} deg",
            motion_magnitude(&drift),
            r.overlap,
            r.inliers,
            r.residual_rms_m * 1000.0,
            r.conditioning,
            r.free_space,
            dt * 1000.0,
            dr.to_degrees()
        );
    }
}

#[test]
fn model_to_model_registration_refuses_another_place() {
    let k = synthetic::default_intrinsics().half();
    let config = LoopClosureConfig::default();
    let verify = VerifyConfig::default();
    let here = loop_pose(0, 240);
    let here_view = view_points(&k, &here);
    let mut registration = ModelRegistration::default();
    // Views of other parts of the room, spliced in as if seen from here: the
    // inactive model shows surfaces of another place where the camera looks.
    let mut checked = 0;
    for other in [60, 100, 140, 180] {
        let other_pose = loop_pose(other, 240);
        let other_view = view_points(&k, &other_pose);
        let mut map = SurfelMap::default();
        add_view(&mut map, &other_view, &here, 0);
        let split = map.len();
        add_view(&mut map, &here_view, &here, 100);
        let (active, inactive) = predictions(&map, split, &k, &here, &here_view.0);
        let r = registration.register(&active, &inactive, &config, &verify);
        println!("other place {other}: {:?} overlap {} inliers {} rms {:.2} mm free space {:.3} correction {:?}", r.rejected, r.overlap, r.inliers, r.residual_rms_m * 1000.0, r.free_space, r.magnitude());
        assert!(
            !r.accepted(),
            "closure accepted against frame {other}: {r:?}"
        );
        checked += usize::from(r.rejected != Some(Rejection::TooLittleOverlap));
    }
    assert!(
        checked > 0,
        "every other place was refused for lack of overlap alone"
    );
}
