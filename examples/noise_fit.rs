//! Measures a sensor's axial depth noise against the fused model: runs a
//! sequence, then renders the final map's stable surfels from every
//! `step`-th fused pose and compares each raw depth pixel facing its surface
//! (|cos| of ray and model normal above 0.8) with the model depth on the
//! same ray. Per 0.25 m depth bin, the robust deviation (1.4826 x median
//! absolute difference) of `z_measured - z_model`, then least-squares fits
//! of `sigma = a + b (z - 0.4)^2` (Nguyen et al.'s form) and
//! `sigma = b z^2` (Khoshelham and Elberink's), weighted by pixel counts.
//!
//! The model is an average of many frames, so the spread is mostly the
//! single measurement's noise; pose error and the model's own blur add to
//! it, so the fit is an upper bound.
//!
//! `cargo run --release --example noise_fit -- ../shared/data/tum_fr3_teddy [step]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::fusion::{DepthTiles, Measured, Prediction};
use surfel_slam::preprocess::back_project_into;
use surfel_slam::{Pipeline, SensorNoise, SlamConfig};

const BIN_M: f32 = 0.25;
const GATE_M: f32 = 0.1;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(args.next().ok_or("usage: noise_fit <dataset> [step]")?);
    let step: usize = args.next().map_or(Ok(5), |s| s.parse())?;
    let sequence = Sequence::open(&dir)?;
    let mut config = SlamConfig::from_preset(sequence.preset);
    // The model built without weighting, so the fit does not depend on the model it checks.
    config.set_noise(SensorNoise::uniform());
    let mut slam = Pipeline::new(config.clone())?;
    let (mut frames, mut fused) = (Vec::new(), 0usize);
    for entry in &sequence.frames {
        let frame = read_frame(&dir, entry, &config.depth)?;
        let report = slam.push_frame(&frame, entry.timestamp)?;
        if report.verdict.is_fused() {
            if fused % step == 0 {
                frames.push((frame, report.world_from_camera));
            }
            fused += 1;
        }
    }
    let k = config.intrinsics;
    let map = slam.map();
    let mut bins: Vec<Vec<f32>> = Vec::new();
    let (mut vertices, mut tiles, mut prediction) = (
        vec![glam::Vec3::ZERO; k.pixel_count()],
        DepthTiles::default(),
        Prediction::default(),
    );
    for (frame, pose) in &frames {
        back_project_into(&k, &frame.depth_m, &mut vertices);
        tiles.build(&vertices, k.width);
        let measured = Measured {
            vertices: &vertices,
            tiles: &tiles,
        };
        prediction.render(
            map,
            pose,
            &k,
            (GATE_M, config.depth.max_m),
            measured,
            0..u32::MAX,
            |i| map.confidences()[i] >= config.fusion.stable_confidence,
        );
        let camera_from_world = pose.inverse().as_affine3a();
        for (i, q) in vertices.iter().enumerate() {
            let (p, n) = (prediction.vertices[i], prediction.normals[i]);
            if q.z <= 0.0 || n == glam::Vec3::ZERO {
                continue;
            }
            let p = camera_from_world.transform_point3(p);
            let n = camera_from_world.transform_vector3(n);
            if n.dot(p).abs() / p.length() < 0.8 {
                continue;
            }
            let dz = q.z - p.z;
            if dz.abs() > GATE_M {
                continue;
            }
            let bin = (p.z / BIN_M) as usize;
            if bins.len() <= bin {
                bins.resize_with(bin + 1, Vec::new);
            }
            bins[bin].push(dz);
        }
    }
    // (z centre, robust sigma, count)
    let mut table = Vec::new();
    println!("depth (m) | pixels | sigma (mm) | Nguyen Kinect v1 (mm) | Khoshelham (mm)");
    for (b, values) in bins.iter_mut().enumerate() {
        if values.len() < 2000 {
            continue;
        }
        let z = (b as f32 + 0.5) * BIN_M;
        let median = median_of(values);
        let mut dev: Vec<f32> = values.iter().map(|v| (v - median).abs()).collect();
        let sigma = 1.4826 * median_of(&mut dev);
        println!(
            "{z:.3} | {} | {:.2} | {:.2} | {:.2}",
            values.len(),
            sigma * 1000.0,
            SensorNoise::kinect_v1().axial_m(z) * 1000.0,
            SensorNoise::structured_light().axial_m(z) * 1000.0
        );
        table.push((f64::from(z), f64::from(sigma), values.len() as f64));
    }
    // sigma = a + b (z - 0.4)^2: linear least squares in (a, b), weighted.
    let (mut s11, mut s12, mut s22, mut t1, mut t2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut z4, mut z2s) = (0.0, 0.0);
    for &(z, sigma, n) in &table {
        let x = (z - 0.4) * (z - 0.4);
        s11 += n;
        s12 += n * x;
        s22 += n * x * x;
        t1 += n * sigma;
        t2 += n * x * sigma;
        z4 += n * z.powi(4);
        z2s += n * z * z * sigma;
    }
    let det = s11 * s22 - s12 * s12;
    if det.abs() > 1e-12 {
        let a = (s22 * t1 - s12 * t2) / det;
        let b = (s11 * t2 - s12 * t1) / det;
        println!("fit sigma = {a:.5} + {b:.5} (z - 0.4)^2 m   (Nguyen et al.: 0.0012 + 0.0019 (z - 0.4)^2)");
    }
    if z4 > 0.0 {
        println!(
            "fit sigma = {:.3e} z^2 m   (Khoshelham and Elberink: 1.425e-3 z^2)",
            z2s / z4
        );
    }
    Ok(())
}

fn median_of(values: &mut [f32]) -> f32 {
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f32::total_cmp);
    *m
}
