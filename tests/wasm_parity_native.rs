//! Native half of the native/wasm parity check (see `tests/wasm_common`):
//! runs the synthetic sequence, the window sequence, the revisit sequence
//! to just past its loop closure and the first ICL-NUIM frames on a
//! single-thread rayon pool and writes the poses' bits to
//! `target/wasm-parity/`, where `tests/wasm_node.rs` (wasm32, Node)
//! compares its own against them. For the window sequence it also writes
//! the frames, the JS config and the per-frame report poses, which
//! `tests/browser/threaded-parity.test.mjs` plays through the threaded
//! module in Chromium.

#![cfg(not(target_arch = "wasm32"))]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod wasm_common;

use std::path::Path;

use surfel_slam::dataset::Sequence;
use surfel_slam::{eval, Pipeline, RgbdFrame, SlamConfig, Verdict};
use wasm_common::*;

fn single_thread<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread rayon pool")
        .install(f)
}

fn list_recursive(root: &Path, rel: &str, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(root.join(rel)) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let child = if rel.is_empty() {
            name
        } else {
            format!("{rel}/{name}")
        };
        if entry.file_type().is_ok_and(|t| t.is_dir()) {
            if child != "target" && !child.starts_with('.') && child != "node_modules" {
                list_recursive(root, &child, out);
            }
        } else {
            out.push(child);
        }
    }
}

fn source_fingerprint() -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut names = Vec::new();
    list_recursive(root, "", &mut names);
    let files = names
        .into_iter()
        .filter(|n| is_fingerprinted(n))
        .map(|n| {
            let bytes = std::fs::read(root.join(&n)).expect("readable source file");
            (n, bytes)
        })
        .collect();
    fingerprint(files)
}

fn write_reference(name: &str, poses: &[(f64, glam::DAffine3)]) {
    let path = reference_path(name);
    let text = header(&source_fingerprint()) + &format_bits(poses);
    std::fs::create_dir_all(Path::new(&path).parent().expect("has a parent"))
        .expect("create target/wasm-parity");
    std::fs::write(&path, text).expect("write the reference");
    eprintln!("wrote {path}");
}

/// The window sequence for the browser test: `window-frames.bin` (per
/// frame the RGBA8 pixels, then the depth as little-endian u16) and
/// `window-config.json` (the JS config object `tests/wasm_node.rs` builds,
/// the timestamps, the frame size and the sources' fingerprint).
fn write_browser_input(config: &SlamConfig, frames: &[RawFrame]) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/wasm-parity");
    let mut bytes = Vec::new();
    for f in frames {
        bytes.extend_from_slice(&f.rgba);
        bytes.extend(f.depth.iter().flat_map(|d| d.to_le_bytes()));
    }
    std::fs::write(dir.join("window-frames.bin"), bytes).expect("write the frames");
    let (k, d) = (config.intrinsics, config.depth);
    let timestamps: Vec<String> = frames.iter().map(|f| format!("{}", f.timestamp)).collect();
    // Rust prints the shortest text that reads back as the same f64, as
    // JSON.parse reads it: the config's values arrive bit for bit.
    let json = format!(
        "{{\"sources\": {:?}, \"width\": {}, \"height\": {}, \"timestamps\": [{}], \"config\": {{\"preset\": \"tum-fr3\", \"fx\": {}, \"fy\": {}, \"cx\": {}, \"cy\": {}, \"width\": {}, \"height\": {}, \"depthScale\": {}, \"depthMin\": {}, \"depthMax\": {}, \"activeWindowFrames\": {}}}}}\n",
        source_fingerprint(),
        frames[0].width,
        frames[0].height,
        timestamps.join(", "),
        f64::from(k.fx),
        f64::from(k.fy),
        f64::from(k.cx),
        f64::from(k.cy),
        k.width,
        k.height,
        f64::from(d.scale),
        f64::from(d.min_m),
        f64::from(d.max_m),
        config.fusion.active_window_frames,
    );
    std::fs::write(dir.join("window-config.json"), json).expect("write the config");
}

#[test]
fn synthetic_reference() {
    let (config, frames, ground_truth) = synthetic_sequence();
    let trajectory = single_thread(|| {
        let settings = config.depth;
        let mut pipeline = Pipeline::new(config).expect("valid config");
        for f in &frames {
            let frame = RgbdFrame::from_raw(f.width, f.height, &f.rgba, &f.depth, &settings)
                .expect("valid frame");
            pipeline
                .push_frame(&frame, f.timestamp)
                .expect("frame accepted");
        }
        pipeline.trajectory().to_vec()
    });
    // Written before the accuracy check: parity is checked even when the
    // accuracy regresses (the wasm test then fails on accuracy too).
    write_reference("synthetic", &trajectory);
    let ate = eval::ate(&trajectory, &ground_truth, 1e-3).expect("ATE");
    eprintln!("native synthetic ATE rmse {:.6} m", ate.rmse_m);
    assert!(
        ate.rmse_m < SYNTHETIC_ATE_BOUND_M,
        "synthetic ATE {} m",
        ate.rmse_m
    );
}

/// Past the active window (`wasm_common::window_sequence`): the loop
/// stage registers the inactive model on the way back; the wasm module
/// must give the same poses.
#[test]
fn window_reference() {
    let (config, frames, ground_truth) = window_sequence();
    let (trajectory, online, registrations) = single_thread(|| {
        let settings = config.depth;
        let mut pipeline = Pipeline::new(config.clone()).expect("valid config");
        let mut registrations = 0;
        let mut online = Vec::new();
        for f in &frames {
            let frame = RgbdFrame::from_raw(f.width, f.height, &f.rgba, &f.depth, &settings)
                .expect("valid frame");
            let r = pipeline
                .push_frame(&frame, f.timestamp)
                .expect("frame accepted");
            registrations += usize::from(r.loop_outcome.registration.is_some());
            online.push((r.timestamp, r.world_from_camera));
        }
        (pipeline.trajectory().to_vec(), online, registrations)
    });
    write_reference("window", &trajectory);
    // The poses as each frame's report gave them (what the page sees).
    write_reference("window-online", &online);
    write_browser_input(&config, &frames);
    let ate = eval::ate(&trajectory, &ground_truth, 1e-3).expect("ATE");
    eprintln!(
        "native window sequence: ATE rmse {:.6} m, {registrations} loop registrations",
        ate.rmse_m
    );
    assert!(
        registrations > 0,
        "the sequence never left the active window"
    );
}

/// The revisit sequence up to just past its loop closure
/// (`wasm_common::revisit_sequence`): the global check closes the loop
/// and the deformation graph bends map and trajectory; the wasm module
/// must give the same poses, before the bend (`revisit-online`, each
/// frame's report) and after it (`revisit`, the bent trajectory).
#[test]
fn revisit_reference() {
    let (config, frames) = revisit_sequence();
    let (trajectory, online, closed_at) = single_thread(|| {
        let mut pipeline = Pipeline::new(config).expect("valid config");
        let mut closed_at = Vec::new();
        let mut online = Vec::new();
        for (i, f) in frames.iter().enumerate() {
            let r = pipeline.push_frame(f, i as f64).expect("frame accepted");
            if r.loop_outcome.closed {
                closed_at.push(i);
            }
            online.push((r.timestamp, r.world_from_camera));
        }
        (pipeline.trajectory().to_vec(), online, closed_at)
    });
    write_reference("revisit", &trajectory);
    write_reference("revisit-online", &online);
    eprintln!("native revisit sequence: loop closed at frames {closed_at:?}");
    assert!(
        !closed_at.is_empty(),
        "no loop closed: the deformation's solve is not compared"
    );
}

#[test]
fn real_frames_reference() {
    let dir = data_dir(REAL_SEQUENCE);
    let dir = Path::new(&dir);
    if !dir.is_dir() {
        eprintln!("skipping: {} is absent (no ../shared/data)", dir.display());
        return;
    }
    let sequence = Sequence::open(dir).expect("ICL-NUIM sequence parses");
    let config = SlamConfig::from_preset(sequence.preset);
    let trajectory = single_thread(|| {
        let mut pipeline = Pipeline::new(config.clone()).expect("valid config");
        for entry in sequence.frames.iter().take(REAL_FRAMES) {
            let colour =
                std::fs::read(dir.join(entry.colour.as_deref().expect("colour"))).expect("colour");
            let depth = std::fs::read(dir.join(&entry.depth)).expect("depth");
            let r = pipeline
                .push_png(&colour, &depth, entry.timestamp)
                .expect("frame accepted");
            assert!(
                !matches!(r.verdict, Verdict::Lost(_)),
                "frame {} lost: {:?}",
                r.index,
                r
            );
        }
        pipeline.trajectory().to_vec()
    });
    write_reference(REAL_SEQUENCE, &trajectory);
}
