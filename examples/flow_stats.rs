//! Lucas-Kanade between consecutive frames of a sequence: tracks kept by the
//! forward-backward check, median flow, and time per frame pair.
//!
//! `cargo run --release --example flow_stats -- ../shared/data/tum_fr3_teddy [frames]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::time::Instant;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::flow::{FlowConfig, OpticalFlow};
use surfel_slam::SlamConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(args.next().ok_or("usage: flow_stats <dataset> [frames]")?);
    let frames: usize = args.next().map_or(Ok(usize::MAX), |s| s.parse())?;
    let sequence = Sequence::open(&dir)?;
    let config = SlamConfig::from_preset(sequence.preset);
    let mut flow = OpticalFlow::new(FlowConfig::default())?;
    let mut previous: Option<Vec<f32>> = None;
    let (mut kept, mut ms, mut medians, mut pairs) = (0usize, 0.0, Vec::new(), 0usize);
    let mut fewest = usize::MAX;
    for entry in sequence.frames.iter().take(frames) {
        let frame = read_frame(&dir, entry, &config.depth)?;
        let grey: Vec<f32> = frame
            .rgb
            .chunks_exact(3)
            .map(|c| 0.299 * f32::from(c[0]) + 0.587 * f32::from(c[1]) + 0.114 * f32::from(c[2]))
            .collect();
        if let Some(prev) = &previous {
            let t0 = Instant::now();
            let tracks = flow.track(prev, &grey, frame.width, frame.height)?;
            ms += t0.elapsed().as_secs_f64() * 1e3;
            let mut lengths: Vec<f32> = tracks.iter().map(|t| t.to.distance(t.from)).collect();
            lengths.sort_by(f32::total_cmp);
            medians.push(lengths.get(lengths.len() / 2).copied().unwrap_or(0.0));
            kept += tracks.len();
            fewest = fewest.min(tracks.len());
            pairs += 1;
        }
        previous = Some(grey);
    }
    medians.sort_by(f32::total_cmp);
    let n = pairs.max(1);
    println!(
        "{pairs} pairs: {:.0} tracks per pair (fewest {fewest}), median flow {:.2} px (max over pairs {:.2}), {:.1} ms per pair",
        kept as f64 / n as f64,
        medians.get(medians.len() / 2).copied().unwrap_or(0.0),
        medians.last().copied().unwrap_or(0.0),
        ms / n as f64
    );
    Ok(())
}
