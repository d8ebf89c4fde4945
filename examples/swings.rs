//! A hand-held scan with fast swings and motion blur (issue #52): the
//! synthetic room along its known path, the camera turned 60 degrees aside
//! and back every 70 frames (`SwingPath::default`), each frame's colour
//! averaged over half a frame interval of motion, rendered at 320x240
//! (`--noisy`: at 640x480, made noisy with the Kinect-v1 recipe, seed 1,
//! and tracked at 320x240).
//! Prints frames lost, the longest lost stretch, held and recovered
//! frames, tracked frames off the truth's motion by more than 1 cm / 1
//! degree, ATE, and how far the last frame's pose relative to the first is
//! from the truth's (what a scan that ends where it began is judged by).
//!
//! `cargo run --release --example swings [-- --frames N] [--amplitude DEG]
//! [--swing-frames N] [--loop N] [--no-local-closure] [--noisy] [--lidar] [--depth-only] [--hand SHARE [--hand-from FRAME]] [--no-hand-mask] [--no-dead-reckoning] [--no-finish]
//! [--dead-reckoning-min N] [--exposure F] [--preset NAME] [--tracker icp|joint|rgb] [--smooth-blur] [--verbose
//! [--from FRAME] [--shown N]]` (`--verbose`: one line per frame for
//! `--shown` frames, default 50, from `--from`, default 30: verdict, the true turn, the pose's error, and the
//! local loop closure's registration where one ran, and a global match). `--loop N` swings
//! about the closed loop of `synthetic::loop_pose` (N frames a turn): with
//! `--frames N+1` the scan ends where it began (`--no-local-closure`: no
//! model-to-model closure; the global one still runs). The map's surfels are
//! measured against the true surfaces at the end.
//! `--depth-only` pushes a constant grey colour image and tracks with ICP,
//! as a Stray Scanner scan without `rgb/` runs natively: no photometric
//! term, no feature estimate, so no dead reckoning. `--hand 0.3` holds a
//! hand in view, 0.35 m away over the image's lower-right 30 % of each
//! side (`synthetic::hold_hand_in_view`), from frame `--hand-from` on. `--lidar` renders at
//! an iPhone's LiDAR depth size instead, 256x192 with Stray Scanner's
//! intrinsics scaled to it (fx = fy = 193 px), clean.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::eval::ate;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::synthetic::{self, render_blurred, NoiseModel, Scene, SwingPath};
use surfel_slam::{CameraPreset, Intrinsics, Pipeline, SlamConfig, Verdict};

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames: usize = arg(&args, "--frames", 320);
    let path = SwingPath {
        amplitude_deg: arg(&args, "--amplitude", 60.0),
        swing_frames: arg(&args, "--swing-frames", 10.0),
        loop_frames: args
            .iter()
            .position(|a| a == "--loop")
            .and_then(|i| args.get(i + 1))
            .and_then(|s| s.parse().ok()),
        ..SwingPath::default()
    };
    let exposure: f64 = arg(&args, "--exposure", 0.5);
    let preset_name: String = arg(&args, "--preset", "tum-fr3".to_string());
    let preset = CameraPreset::from_name(&preset_name).expect("known preset");
    let noisy = args.iter().any(|a| a == "--noisy");
    // Noisy frames are rendered at 640x480 (the recipe's disparity steps
    // are a Kinect's at that size) and tracked at 320x240, as
    // `examples/ten_circles.rs` does: the recipe applied at 320x240
    // doubles the steps and every frame is lost.
    let k = if noisy {
        synthetic::default_intrinsics()
    } else if args.iter().any(|a| a == "--lidar") {
        Intrinsics::new(193.0, 193.0, 127.5, 95.5, 256, 192)
    } else {
        Intrinsics::new(262.5, 262.5, 159.5, 119.5, 320, 240)
    };
    let mut config = SlamConfig::from_preset(preset);
    config.intrinsics = k;
    config.half_resolution = noisy;
    config.depth = synthetic::depth_settings();
    if noisy {
        config.simulate_noise = Some(NoiseSimulation {
            sensor: SimulatedSensor::KinectV1,
            seed: 1,
        });
    }
    config.tracker.verify.dead_reckoning_min_inliers = arg(
        &args,
        "--dead-reckoning-min",
        config.tracker.verify.dead_reckoning_min_inliers,
    );
    config.tracker.verify.dead_reckoning = !args.iter().any(|a| a == "--no-dead-reckoning");
    if args.iter().any(|a| a == "--no-local-closure") {
        config.loop_closure.every_frames = u32::MAX;
    }
    if args.iter().any(|a| a == "--no-hand-mask") {
        config.preprocess.camera_fixed_frames = 0;
    }
    let tracker: String = arg(&args, "--tracker", String::new());
    if let Some(mode) = surfel_slam::track::TrackerMode::from_name(&tracker) {
        config.tracker.mode = mode;
    }
    let depth_only = args.iter().any(|a| a == "--depth-only");
    if depth_only {
        config.tracker.mode = surfel_slam::track::TrackerMode::Icp;
    }
    let scene = Scene::room();
    let mut slam = Pipeline::new(config.clone())?;
    let origin = path.pose(0.0).inverse();
    let mut truth = Vec::new();
    let mut verdicts = Vec::new();
    let mut off = 0;
    // Fused frames more than 10 degrees from the true orientation.
    let mut fused_far = 0;
    let mut last_fused: Option<(usize, glam::DAffine3)> = None;
    let hand: f64 = arg(&args, "--hand", 0.0);
    let hand_from: usize = arg(&args, "--hand-from", 0);
    // `--smooth-blur`: one sample per pixel the view turns during the
    // exposure (at least 5), so that a fast turn smears instead of
    // leaving 5 sharp ghosts.
    let smooth_blur = args.iter().any(|a| a == "--smooth-blur");
    let samples = |t: f64| {
        if !smooth_blur {
            return 5;
        }
        let turn = synthetic::turn_between_deg(
            &path.pose(t - exposure / 2.0),
            &path.pose(t + exposure / 2.0),
        );
        ((turn.to_radians() * k.fx as f64).ceil() as usize + 1).max(5)
    };
    for i in 0..frames {
        let t = i as f64;
        let rendered = render_blurred(
            &scene,
            &k,
            &path.exposure(t, exposure, samples(t)),
            &NoiseModel::none(),
            i as u64,
        );
        let mut frame = rendered.to_frame(&config.depth)?;
        if depth_only {
            frame.rgb.fill(surfel_slam::dataset::DEPTH_ONLY_GREY);
        }
        if hand > 0.0 && i >= hand_from {
            synthetic::hold_hand_in_view(&mut frame, hand, 0.35, i);
        }
        let report = slam.push_frame(&frame, t)?;
        let true_pose = origin * path.pose(t);
        truth.push((t, true_pose));
        let placed = matches!(
            report.verdict,
            Verdict::Tracked | Verdict::Recovered | Verdict::Initialised | Verdict::Held
        );
        if let (true, Some((j, pose))) = (matches!(report.verdict, Verdict::Tracked), last_fused) {
            let estimated = pose.inverse() * report.world_from_camera;
            let actual = truth[j].1.inverse() * true_pose;
            let (dt, dr) = motion_magnitude(&(actual.inverse() * estimated));
            if dt > 0.01 || dr.to_degrees() > 1.0 {
                off += 1;
            }
        }
        if placed
            && motion_magnitude(&(true_pose.inverse() * report.world_from_camera))
                .1
                .to_degrees()
                > 10.0
        {
            fused_far += 1;
        }
        if placed {
            last_fused = Some((i, report.world_from_camera));
        }
        if args.iter().any(|a| a == "--verbose")
            && (arg(&args, "--from", 30)..arg(&args, "--from", 30) + arg(&args, "--shown", 50))
                .contains(&i)
        {
            let step = synthetic::turn_between_deg(&path.pose(t - 1.0), &path.pose(t));
            let (et, er) = motion_magnitude(&(true_pose.inverse() * report.world_from_camera));
            println!(
                "{i}: {:?} true turn {step:.1} deg, pose error {:.1} cm {:.1} deg, inliers {}, conditioning {:.1e}, sparse {:?}, masked {:.1} %, closures {} / {} global",
                report.verdict,
                100.0 * et,
                er.to_degrees(),
                report.inliers,
                report.conditioning,
                report.checks.sparse.map(|s| s.1),
                100.0 * report.camera_fixed_share,
                report.loop_closures,
                report.global_loop_closures,
            );
            let off = |pose: &glam::DAffine3| {
                let (dt, dr) = motion_magnitude(&(true_pose.inverse() * *pose));
                let v = (true_pose.inverse() * *pose).translation * 100.0;
                format!(
                    "{:.1} cm {:.1} deg ({:.1} {:.1} {:.1})",
                    100.0 * dt,
                    dr.to_degrees(),
                    v.x,
                    v.y,
                    v.z
                )
            };
            let c = &report.checks;
            if report.verdict != Verdict::Tracked || c.sparse_ran {
                println!(
                    "    checks: first dense {} off, sparse {} off (rms {:.1} mm), from sparse {}, sparse only {}, relocalised from {:?}, dead reckoned {}, free space {:.3} / {:.3}",
                    c.first_dense.as_ref().map_or("-".into(), off),
                    c.sparse.as_ref().map_or("-".into(), |s| off(&s.0)),
                    1000.0 * c.sparse_rms_m,
                    c.from_sparse,
                    c.sparse_only,
                    c.relocalised_from,
                    c.dead_reckoned,
                    c.free_space_first,
                    c.free_space_final,
                );
            }
            if let Some(r) = &report.loop_outcome.registration {
                let (dt, dr) = motion_magnitude(&r.correction);
                println!(
                    "    local registration: {:.2} cm {:.2} deg, overlap {}, inliers {}, residual {:.2} -> {:.2} mm, held {}, conditioning {:.1e}, free space {:.3}, refused {:?}, bent {}",
                    100.0 * dt,
                    dr.to_degrees(),
                    r.overlap,
                    r.inliers,
                    1000.0 * r.start_residual_rms_m,
                    1000.0 * r.residual_rms_m,
                    r.held,
                    r.conditioning,
                    r.free_space,
                    r.rejected,
                    report.loop_outcome.closed,
                );
            }
            if report.loop_outcome.global_looked && report.loop_outcome.global.is_none() {
                println!(
                    "    global look: {} candidates, found nothing ({:?})",
                    report.loop_outcome.global_candidates, report.loop_outcome.global_miss
                );
            }
            if let Some(g) = &report.loop_outcome.global {
                println!(
                    "    global match on keyframe {}: {:.2} cm {:.2} deg, tracked {} off, registered {} off, closed {}, pose only {}",
                    g.keyframe_frame,
                    100.0 * g.correction_m,
                    g.correction_deg,
                    off(&g.tracked),
                    off(&g.registered),
                    g.closed,
                    g.pose_only,
                );
            }
        }
        verdicts.push(report.verdict);
    }
    // The recording ended: the last frame looked up as the CLI does.
    if !args.iter().any(|a| a == "--no-finish") {
        let before = slam.trajectory().last().map(|p| p.1);
        let outcome = slam.finish();
        let after = slam.trajectory().last().map(|p| p.1);
        if let (true, Some(before), Some(after), Some(truth)) =
            (outcome.global_looked, before, after, truth.last())
        {
            // The estimate's world is the first frame's camera, as the truth's.
            let off = |pose: glam::DAffine3| {
                let (dt, dr) = motion_magnitude(&(truth.1.inverse() * pose));
                format!("{:.2} cm {:.2} deg", 100.0 * dt, dr.to_degrees())
            };
            println!(
                "finish: looked the last frame up, {} candidates, closed {}, {:?}, last frame {} -> {} off",
                outcome.global_candidates,
                outcome.closed,
                outcome.global_miss,
                off(before),
                off(after)
            );
        }
    }
    let lost: Vec<bool> = verdicts
        .iter()
        .map(|v| matches!(v, Verdict::Lost(_)))
        .collect();
    let longest = lost.split(|l| !l).map(<[bool]>::len).max().unwrap_or(0);
    let count = |f: fn(&Verdict) -> bool| verdicts.iter().filter(|v| f(v)).count();
    let estimate = slam.trajectory();
    let result = ate(estimate, &truth, 0.01)?;
    println!(
        "{frames} frames, swings {:.0} deg in {:.0} frames: lost {} (longest {longest}), held {}, recovered {}, restarted {}, tracked-but-off {off}, fused >10 deg off {fused_far}, ATE {:.3} cm ({} poses)",
        path.amplitude_deg,
        path.swing_frames,
        count(|v| matches!(v, Verdict::Lost(_))),
        count(|v| matches!(v, Verdict::Held)),
        count(|v| matches!(v, Verdict::Recovered)),
        count(|v| matches!(v, Verdict::Restarted)),
        100.0 * result.rmse_m,
        result.pairs,
    );
    // The judge of a scan that ends where it began: the last frame's pose
    // relative to the first, against the truth's.
    if let (Some(first), Some(last)) = (estimate.first(), estimate.last()) {
        let true_first = truth.iter().find(|(t, _)| *t == first.0).map(|p| p.1);
        let true_last = truth.iter().find(|(t, _)| *t == last.0).map(|p| p.1);
        if let (Some(tf), Some(tl)) = (true_first, true_last) {
            let estimated = first.1.inverse() * last.1;
            let actual = tf.inverse() * tl;
            let (dt, dr) = motion_magnitude(&(actual.inverse() * estimated));
            let (span, _) = motion_magnitude(&actual);
            println!(
                "last frame relative to the first: {:.2} cm, {:.2} deg off the truth's (which spans {:.1} cm)",
                100.0 * dt,
                dr.to_degrees(),
                100.0 * span
            );
        }
    }
    // Surfels off every true surface: what the hand or a wrong placement
    // left in the map (the map's world is the first frame's camera).
    let positions = slam.map().positions();
    let scene_from_map = path.pose(0.0);
    let beyond_5cm = positions
        .iter()
        .filter(|p| {
            p.is_finite()
                && scene.distance_to_surface(scene_from_map.transform_point3(p.as_dvec3())) > 0.05
        })
        .count();
    let error = synthetic::map_error(&scene, positions, &scene_from_map);
    println!(
        "map: {} surfels, {:.1} % within 1 cm of the true surface, {beyond_5cm} beyond 5 cm",
        error.surfels,
        100.0 * error.within_1cm,
    );
    let line: String = verdicts
        .iter()
        .map(|v| match v {
            Verdict::Lost(_) => 'L',
            Verdict::Held => 'h',
            Verdict::Recovered => 'R',
            Verdict::Restarted => 'S',
            _ => '.',
        })
        .collect();
    for (i, chunk) in line.as_bytes().chunks(70).enumerate() {
        println!("{:4} {}", i * 70, String::from_utf8_lossy(chunk));
    }
    Ok(())
}
