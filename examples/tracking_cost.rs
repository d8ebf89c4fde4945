//! Per-iteration cost of the photometric and ICP steps at each pyramid level,
//! on a real frame against the model fused from the frames before it.
//!
//! `cargo run --release --example tracking_cost -- ../shared/data/tum_fr3_teddy [frames]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::time::Instant;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::fusion::{DepthTiles, Measured, Prediction};
use surfel_slam::preprocess::FramePyramid;
use surfel_slam::se3::RigidF32;
use surfel_slam::track::icp::icp_step;
use surfel_slam::track::model_points::ModelPoints;
use surfel_slam::track::rgb::RgbWorkspace;
use surfel_slam::{Pipeline, SlamConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(
        args.next()
            .ok_or("usage: tracking_cost <dataset> [frames]")?,
    );
    let frames: usize = args.next().map_or(Ok(30), |s| s.parse())?;
    let sequence = Sequence::open(&dir)?;
    let config = SlamConfig::from_preset(sequence.preset);
    let mut slam = Pipeline::new(config.clone())?;
    let entries: Vec<_> = sequence.frames.iter().take(frames + 1).collect();
    let (last, fused) = entries.split_last().ok_or("empty sequence")?;
    for e in fused {
        slam.push_frame(&read_frame(&dir, e, &config.depth)?, e.timestamp)?;
    }
    let pose = slam.trajectory().last().ok_or("no pose")?.1;
    let k = config.intrinsics;
    let mut prediction = Prediction::default();
    let map = slam.map();
    let band = (config.fusion.depth_gate_m, config.depth.max_m);
    // The prediction shows what the last fused frame measured from `pose`.
    let mut pyramid = FramePyramid::new(&k, &config.preprocess);
    let newest = fused.last().ok_or("nothing fused")?;
    pyramid.build(
        &read_frame(&dir, newest, &config.depth)?,
        &config.preprocess,
        &config.tracker.noise,
    );
    let mut tiles = DepthTiles::default();
    tiles.build(&pyramid.levels[0].vertices, k.width);
    let measured = Measured {
        vertices: &pyramid.levels[0].vertices,
        tiles: &tiles,
    };
    prediction.render(map, &pose, &k, band, measured, 0..u32::MAX, |i| {
        config.fusion.predicts(map, i, frames as u32)
    });
    pyramid.build(
        &read_frame(&dir, last, &config.depth)?,
        &config.preprocess,
        &config.tracker.noise,
    );
    let t = RigidF32::from_affine(&pose.inverse());
    let mut rgb = RgbWorkspace::default();
    let photometric = &config.tracker.photometric;
    let mut sources = ModelPoints::default();
    sources.gather_from(&prediction);
    let reps = 50;
    let t0 = Instant::now();
    for _ in 0..reps {
        rgb.prepare(&pyramid, &prediction, photometric);
    }
    println!(
        "prepare (gradients + reference selection, all levels): {:.2} ms",
        t0.elapsed().as_secs_f64() * 1e3 / f64::from(reps)
    );
    for level in 0..pyramid.levels.len() {
        let target = &pyramid.levels[level];
        let t0 = Instant::now();
        let mut n = 0;
        for _ in 0..reps {
            n = rgb.step(level, target, &t, photometric).system.count;
        }
        let rgb_ms = t0.elapsed().as_secs_f64() * 1e3 / f64::from(reps);
        let t0 = Instant::now();
        let mut m = 0;
        let mut candidates = 0;
        for _ in 0..reps {
            let step = icp_step(
                &sources,
                1 << level,
                target,
                &t,
                &config.tracker.gates,
                None,
            );
            m = step.system.count;
            candidates = step.candidates;
        }
        let icp_ms = t0.elapsed().as_secs_f64() * 1e3 / f64::from(reps);
        println!(
            "level {level}: photometric {rgb_ms:.2} ms/iteration ({} selected, {n} used), ICP {icp_ms:.2} ms/iteration ({m} inliers of {candidates} candidates, {} model points)",
            rgb.reference_count(level),
            sources.len()
        );
    }
    println!("threads: {}", rayon::current_num_threads());
    Ok(())
}
