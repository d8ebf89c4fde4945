//! Save and load times and file size of a session (issue #36): plays a
//! sequence, then saves its session to a file and loads it back, several
//! times in turn (the machine's speed drifts: compare within one run), and
//! prints each time, the file size and what the map holds.
//!
//! `cargo run --release --example session_io -- ../shared/data/7scenes_redkitchen_even [frames] [repeats]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::time::Instant;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::session;
use surfel_slam::{Pipeline, SlamConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: session_io <dataset> [frames] [repeats]";
    let dir = std::path::PathBuf::from(args.next().ok_or(usage)?);
    let frames: usize = args.next().map_or(Ok(usize::MAX), |s| s.parse())?;
    let repeats: usize = args.next().map_or(Ok(3), |s| s.parse())?;
    let sequence = Sequence::open(&dir)?;
    let config = SlamConfig::from_preset(sequence.preset);
    let mut slam = Pipeline::new(config.clone())?;
    for entry in sequence.frames.iter().take(frames) {
        let frame = read_frame(&dir, entry, &config.depth)?;
        slam.push_frame(&frame, entry.timestamp)?;
    }
    let path = std::env::temp_dir().join(format!("session_io-{}.slam", std::process::id()));
    let state = slam.state();
    println!(
        "{} frames, {} surfel slots, {} keyframes",
        slam.frames(),
        slam.map().len(),
        state.keyframes.len()
    );
    for _ in 0..repeats {
        let t0 = Instant::now();
        let out = session::save(&slam, BufWriter::new(File::create(&path)?))?;
        out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        let save_ms = t0.elapsed().as_secs_f64() * 1e3;
        let bytes = std::fs::metadata(&path)?.len();
        let t0 = Instant::now();
        let loaded = session::load(BufReader::new(File::open(&path)?))?;
        let load_ms = t0.elapsed().as_secs_f64() * 1e3;
        assert_eq!(loaded.map().len(), slam.map().len());
        println!(
            "save {save_ms:.0} ms, load {load_ms:.0} ms, {:.1} MB ({:.1} bytes per surfel slot)",
            bytes as f64 / 1e6,
            bytes as f64 / slam.map().len().max(1) as f64
        );
    }
    std::fs::remove_file(&path)?;
    Ok(())
}
