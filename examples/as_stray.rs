//! Writes a sequence with ground truth (TUM, ICL-NUIM, 7-Scenes) as a Stray
//! Scanner export, the nearest thing here to an iPhone LiDAR scan with
//! exact truth (issue #52): depth sampled down to 256x192 (nearest pixel)
//! in millimetres, a confidence image (0 where there is no depth, with
//! `--edges` at depth edges and with `--far M` beyond M metres, as ARKit
//! marks them; 2 elsewhere), the
//! intrinsics at the colour camera's 1920x1440 in `camera_matrix.csv`, and
//! the ground truth as `odometry.csv` (15 columns, the last two empty). No
//! `rgb/`: the scan is depth only, as a Stray scan runs natively.
//! `surfel-slam run OUT` then reads it with no option and reports its
//! difference from the "device's odometry", which here is the truth.
//!
//! ICL-NUIM's upward image y axis (fy < 0) is turned into the usual one by
//! flipping the rows: the camera frame, so the poses, stay as they are.
//!
//! `cargo run --release --example as_stray -- IN OUT [--noisy] [--edges] [--far M] [--interpolate] [--medium M [--medium-error E]] [--imu]`
//! (`--medium M`: depth beyond M metres at confidence 1, and off by a
//! smooth error field of amplitude E (default 0.015) times its depth, a
//! new field each frame, as a time-of-flight sensor's less certain depth;
//! `--medium-error 0` keeps it exact)
//! (`--interpolate`: each depth at its pixel's exact source position, inverse
//! depth interpolated bilinearly (exact on planes) instead of the nearest
//! source pixel's, up to a quarter pixel off)
//! (`--noisy`: Kinect-v1 structured-light noise on the full-size depth
//! before sampling, frame i drawn from seed i; harsher than ARKit's
//! smoothed depth).
//! (`--imu`: an `imu.csv` simulated from the ground truth, a phone's IMU at
//! 100 Hz as `synthetic::ImuSimulation::phone` makes it (mounted as an
//! iPhone's, its clock 10 ms ahead); the truth between its poses:
//! positions on a Catmull-Rom spline, rotations slerped. Timestamps must
//! be seconds (TUM), and gravity is taken along world -z (TUM's motion
//! capture frame): the gyro is what the pipeline's calibration reads.)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::fmt::Write as _;
use std::path::Path;

use glam::{DAffine3, DMat3, DQuat, DVec3};
use image::{ImageBuffer, Luma};
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::synthetic::{ImuSimulation, StructuredLight, STANDARD_GRAVITY_MPS2};
use surfel_slam::SlamConfig;

const W: usize = 256;
const H: usize = 192;
/// Colour width over depth width in a Stray export (1920 / 256).
const COLOUR_SCALE: f64 = 7.5;
/// A depth step to a 4-neighbour beyond this share of the depth marks an
/// edge pixel low-confidence.
const EDGE_STEP: f32 = 0.05;

/// Depth at source position `(x, y)` (pixel centres at integers): inverse
/// depth interpolated bilinearly, exact on a plane, where the four pixels
/// around hold depth within [`EDGE_STEP`] of each other; else the nearest
/// pixel's (a silhouette is not bridged).
fn depth_at(depth: &[f32], (width, height): (usize, usize), x: f64, y: f64) -> f32 {
    let (x, y) = (
        x.clamp(0.0, (width - 1) as f64),
        y.clamp(0.0, (height - 1) as f64),
    );
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let z = [
        depth[y0 * width + x0],
        depth[y0 * width + x1],
        depth[y1 * width + x0],
        depth[y1 * width + x1],
    ];
    let (lo, hi) = z
        .iter()
        .fold((f32::INFINITY, 0f32), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    if lo <= 0.0 || hi - lo > EDGE_STEP * lo {
        return depth[(y.round() as usize) * width + x.round() as usize];
    }
    let w = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    let inverse: f32 = z.iter().zip(w).map(|(d, w)| w / d).sum();
    1.0 / inverse
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(input), Some(output)) = (args.get(1), args.get(2)) else {
        return Err("usage: as_stray IN OUT [--noisy] [--edges] [--far M] [--interpolate] [--medium M [--medium-error E]] [--imu]".into());
    };
    let (input, output) = (Path::new(input), Path::new(output));
    let noisy = args.iter().any(|a| a == "--noisy");
    let edges = args.iter().any(|a| a == "--edges");
    let nearest = !args.iter().any(|a| a == "--interpolate");
    let far_m: f32 = args
        .iter()
        .position(|a| a == "--far")
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(f32::INFINITY), |s| s.parse())?;
    let number_after = |flag: &str, default: f32| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map_or(Ok(default), |s| s.parse::<f32>())
    };
    let medium_m = number_after("--medium", f32::INFINITY)?;
    let medium_error = number_after("--medium-error", 0.015)?;
    let sequence = Sequence::open(input)?;
    let config = SlamConfig::from_preset(sequence.preset);
    let k = sequence.intrinsics.unwrap_or(config.intrinsics);
    let (sx, sy) = (W as f64 / k.width as f64, H as f64 / k.height as f64);
    let flip = k.fy < 0.0;
    for sub in ["depth", "confidence"] {
        std::fs::create_dir_all(output.join(sub))?;
    }
    // Pixel centres scale about the image's corner: c' = (c + 0.5) s - 0.5.
    let fx = f64::from(k.fx) * sx;
    let fy = f64::from(k.fy.abs()) * sy;
    let cx = (f64::from(k.cx) + 0.5) * sx - 0.5;
    let cy_in = if flip {
        k.height as f64 - 1.0 - f64::from(k.cy)
    } else {
        f64::from(k.cy)
    };
    let cy = (cy_in + 0.5) * sy - 0.5;
    let c = COLOUR_SCALE;
    std::fs::write(
        output.join("camera_matrix.csv"),
        format!(
            "{}, 0.0, {}\n0.0, {}, {}\n0.0, 0.0, 1.0\n",
            fx * c,
            cx * c,
            fy * c,
            cy * c
        ),
    )?;
    let mut odometry = String::from(
        "timestamp, frame, x, y, z, qx, qy, qz, qw, fx, fy, cx, cy, distortion_center_x, distortion_center_y\n",
    );
    let noise = StructuredLight::kinect();
    let mut written = 0usize;
    for entry in &sequence.frames {
        let Some(gt) = sequence.ground_truth_for(entry.timestamp, 0.02) else {
            continue;
        };
        let frame = read_frame(input, entry, &config.depth)?;
        let depth = if noisy {
            noise
                .measured(
                    &frame,
                    &frame.depth_m,
                    &k,
                    (written as u64, config.depth.max_m),
                )
                .depth_m
        } else {
            frame.depth_m
        };
        let mut sampled = vec![0f32; W * H];
        for v in 0..H {
            let y = (v as f64 + 0.5) / sy - 0.5;
            let y = if flip { (k.height - 1) as f64 - y } else { y };
            for u in 0..W {
                let x = (u as f64 + 0.5) / sx - 0.5;
                sampled[v * W + u] = if nearest {
                    depth[(y.round() as usize).min(k.height - 1) * k.width
                        + (x.round() as usize).min(k.width - 1)]
                } else {
                    depth_at(&depth, (k.width, k.height), x, y)
                };
            }
        }
        let mut confidence = vec![0u8; W * H];
        for v in 0..H {
            for u in 0..W {
                let z = sampled[v * W + u];
                if z <= 0.0 {
                    continue;
                }
                let step = [(0i64, 1i64), (0, -1), (1, 0), (-1, 0)]
                    .iter()
                    .filter_map(|&(du, dv)| {
                        let (nu, nv) = (u as i64 + du, v as i64 + dv);
                        let inside = nu >= 0 && nv >= 0 && (nu as usize) < W && (nv as usize) < H;
                        inside.then(|| sampled[nv as usize * W + nu as usize])
                    })
                    .map(|n| if n > 0.0 { (n - z).abs() } else { z })
                    .fold(0f32, f32::max);
                confidence[v * W + u] = if z > far_m || (edges && step > EDGE_STEP * z) {
                    0
                } else if z > medium_m {
                    1
                } else {
                    2
                };
            }
        }
        // Confidence 1 is found on exact depth, then that depth is put off
        // by a smooth field (phases from the frame number, deterministic).
        let phase = |salt: usize| ((written * 7919 + salt * 104_729) % 1000) as f32 / 1000.0;
        let (pu, pv) = (phase(1), phase(2));
        for v in 0..H {
            for u in 0..W {
                let i = v * W + u;
                if confidence[i] == 1 {
                    let field = (std::f32::consts::TAU * (u as f32 / 64.0 + pu)).sin()
                        * (std::f32::consts::TAU * (v as f32 / 48.0 + pv)).cos();
                    sampled[i] *= 1.0 + medium_error * field;
                }
            }
        }
        let mm: Vec<u16> = sampled
            .iter()
            .map(|&z| (f64::from(z) * 1000.0).round().clamp(0.0, 65535.0) as u16)
            .collect();
        ImageBuffer::<Luma<u16>, _>::from_raw(W as u32, H as u32, mm)
            .unwrap()
            .save(output.join(format!("depth/{written:06}.png")))?;
        ImageBuffer::<Luma<u8>, _>::from_raw(W as u32, H as u32, confidence)
            .unwrap()
            .save(output.join(format!("confidence/{written:06}.png")))?;
        let q = glam::DQuat::from_mat3(&gt.matrix3);
        let t = gt.translation;
        writeln!(
            odometry,
            "{}, {written}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}, , ",
            entry.timestamp,
            t.x,
            t.y,
            t.z,
            q.x,
            q.y,
            q.z,
            q.w,
            fx * c,
            fy * c,
            cx * c,
            cy * c
        )?;
        written += 1;
    }
    std::fs::write(output.join("odometry.csv"), odometry)?;
    println!("{written} frames written to {}", output.display());
    if args.iter().any(|a| a == "--imu") {
        write_imu(&sequence.ground_truth, output)?;
    }
    Ok(())
}

/// The pose of `truth` (sorted by time) at `t`: the position on the
/// Catmull-Rom spline through its positions, the rotation slerped between
/// its two poses around `t`.
fn pose_at(truth: &[(f64, DAffine3)], t: f64) -> DAffine3 {
    let n = truth.len();
    let i = truth.partition_point(|(s, _)| *s <= t).clamp(1, n - 1) - 1;
    let (t0, a) = truth[i];
    let (t1, b) = truth[i + 1];
    let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let p = |k: usize| truth[k.min(n - 1)].1.translation;
    let (p0, p1, p2, p3) = (p(i.saturating_sub(1)), p(i), p(i + 1), p(i + 2));
    let (f2, f3) = (f * f, f * f * f);
    let position = 0.5
        * (2.0 * p1
            + (p2 - p0) * f
            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2
            + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f3);
    let qa = DQuat::from_mat3(&a.matrix3);
    let mut qb = DQuat::from_mat3(&b.matrix3);
    if qa.dot(qb) < 0.0 {
        qb = -qb;
    }
    DAffine3::from_mat3_translation(DMat3::from_quat(qa.slerp(qb, f)), position)
}

/// `imu.csv` simulated from `truth`, as Stray Scanner writes it.
fn write_imu(truth: &[(f64, DAffine3)], output: &Path) -> Result<(), Box<dyn std::error::Error>> {
    if truth.len() < 4 {
        return Err("--imu needs the sequence's ground truth".into());
    }
    let sim = ImuSimulation {
        gravity_world_mps2: DVec3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2),
        ..ImuSimulation::phone()
    };
    let (first, last) = (truth[0].0, truth[truth.len() - 1].0);
    let samples = sim.simulate(|t| pose_at(truth, t), first + 0.05, last - 0.05);
    let mut text = String::from("timestamp, a_x, a_y, a_z, alpha_x, alpha_y, alpha_z\n");
    for s in &samples {
        let (a, g) = (s.accel_mps2, s.gyro_radps);
        writeln!(
            text,
            "{:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}",
            s.time_s, a.x, a.y, a.z, g.x, g.y, g.z
        )?;
    }
    std::fs::write(output.join("imu.csv"), text)?;
    println!("{} IMU samples written (100 Hz)", samples.len());
    Ok(())
}
