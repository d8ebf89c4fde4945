//! Shared by `tests/wasm_parity_native.rs` (native) and `tests/wasm_node.rs`
//! (wasm32 under Node): the deterministic computations both run, and the
//! reference files through which they are compared.
//!
//! How native and wasm results are compared (no hard-coded numbers):
//! 1. the native test `wasm_parity_native` runs a computation and writes
//!    the poses' bits (hexadecimal, [`format_bits`]) to
//!    `target/wasm-parity/<name>.bits`, with a fingerprint of the sources
//!    (`src/**`, `tests/wasm_common/**`, `Cargo.toml`, `Cargo.lock`) in its
//!    first line;
//! 2. the wasm test `wasm_node` runs the same computation through the
//!    bindings and requires the same bits — only when the fingerprint
//!    equals the current sources' (a stale file is never used). The result
//!    depends neither on the thread count nor on the target: reductions
//!    are summed in fixed blocks (`ordered_sum`) and transcendental
//!    functions come from the `libm` crate (`portable_math`), so native,
//!    the single-threaded module and the threaded page give the same bits
//!    (`docs/performance.md#determinism`). The browser test
//!    `tests/browser/threaded-parity.test.mjs` compares the threaded
//!    module with the same files.
//!
//! `scripts/test-wasm.sh` runs step 1 then step 2 and sets
//! `SURFEL_SLAM_REQUIRE_PARITY=1`, which turns a missing or stale reference
//! into a failure. A plain `cargo test --target wasm32-unknown-unknown`
//! without a fresh reference still checks everything else and says that the
//! comparison was skipped.

#![allow(dead_code)]

use glam::{DAffine3, DQuat};
use surfel_slam::synthetic;
use surfel_slam::{DepthSettings, Intrinsics, RgbdFrame, SlamConfig};

/// The revisit sequence of `tests/determinism.rs` (shared with the
/// native/wasm parity check: see [`revisit_sequence`]).
#[path = "../common/revisit.rs"]
pub mod revisit;

/// Frames of the synthetic sequence.
pub const SYNTHETIC_FRAMES: usize = 20;
/// Frames of the real sequence (ICL-NUIM office kt0) compared.
pub const REAL_FRAMES: usize = 10;
/// Real sequence used, under `../shared/data/`.
pub const REAL_SEQUENCE: &str = "icl_office_kt0";

/// ATE bound of the synthetic sequence (noise-free: tracking should be
/// near-exact), metres.
pub const SYNTHETIC_ATE_BOUND_M: f64 = 0.005;
/// ATE bound of the first ICL-NUIM frames (noise-free renderings), metres.
pub const REAL_ATE_BOUND_M: f64 = 0.005;

/// Where the native reference trajectories are written.
#[must_use]
pub fn reference_path(name: &str) -> String {
    format!(
        "{}/target/wasm-parity/{name}.bits",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// Poses as text that keeps every bit: per pose one line of 13 hexadecimal
/// `f64` bit patterns, the timestamp then the affine's columns
/// (`DAffine3::to_cols_array`).
#[must_use]
pub fn format_bits(poses: &[(f64, DAffine3)]) -> String {
    let mut out = String::new();
    for (t, pose) in poses {
        let words: Vec<String> = std::iter::once(*t)
            .chain(pose.to_cols_array())
            .map(|x| format!("{:016x}", x.to_bits()))
            .collect();
        out.push_str(&words.join(" "));
        out.push('\n');
    }
    out
}

/// Reads [`format_bits`] text back.
pub fn parse_bits(text: &str) -> Result<Vec<(f64, DAffine3)>, String> {
    text.lines()
        .enumerate()
        .map(|(i, line)| {
            let values = line
                .split_whitespace()
                .map(|w| u64::from_str_radix(w, 16).map(f64::from_bits))
                .collect::<Result<Vec<f64>, _>>()
                .map_err(|e| format!("line {}: {e}", i + 1))?;
            match values.as_slice() {
                [t, cols @ ..] if cols.len() == 12 => {
                    let mut m = [0.0; 12];
                    m.copy_from_slice(cols);
                    Ok((*t, DAffine3::from_cols_array(&m)))
                }
                _ => Err(format!("line {}: {} values, not 13", i + 1, values.len())),
            }
        })
        .collect()
}

/// `../shared/data/<name>` (absolute).
#[must_use]
pub fn data_dir(name: &str) -> String {
    format!("{}/../shared/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Files whose content determines the computed poses, relative to the
/// manifest directory; filter applied to a recursive listing of the crate.
#[must_use]
pub fn is_fingerprinted(relative: &str) -> bool {
    relative == "Cargo.toml"
        || relative == "Cargo.lock"
        || (relative.starts_with("src/") && relative.ends_with(".rs"))
        || (relative.starts_with("tests/wasm_common/") && relative.ends_with(".rs"))
        || relative == "tests/common/revisit.rs"
}

/// FNV-1a over `(path, contents)` in path order: identifies the sources.
#[must_use]
pub fn fingerprint(mut files: Vec<(String, Vec<u8>)>) -> String {
    files.sort_by(|a, b| a.0.cmp(&b.0));
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for (path, contents) in &files {
        eat(path.as_bytes());
        eat(&[0]);
        eat(contents);
        eat(&[0xff]);
    }
    format!("{h:016x} ({} files)", files.len())
}

/// First line of a reference file.
#[must_use]
pub fn header(fingerprint: &str) -> String {
    format!("# surfel-slam native reference, sources {fingerprint}\n")
}

/// The reference's poses if its header matches `fingerprint`, else why not.
pub fn read_reference(
    text: Option<String>,
    fingerprint: &str,
) -> Result<Vec<(f64, DAffine3)>, String> {
    let text = text.ok_or("no native reference file")?;
    let expected = header(fingerprint);
    let body = text.strip_prefix(&expected).ok_or_else(|| {
        format!(
            "stale native reference (written for other sources: {:?}, current {fingerprint})",
            text.lines().next().unwrap_or("")
        )
    })?;
    parse_bits(body)
}

/// One synthetic frame as a caller with decoded buffers has it.
pub struct RawFrame {
    /// Seconds.
    pub timestamp: f64,
    /// Pixels.
    pub width: usize,
    /// Pixels.
    pub height: usize,
    /// RGBA8, row-major.
    pub rgba: Vec<u8>,
    /// Raw depth units (`depth_settings().scale` per metre), 0 = none.
    pub depth: Vec<u16>,
}

impl RawFrame {
    /// A rendered synthetic frame as the page hands frames to the module
    /// (RGBA, raw depth), at `timestamp` seconds.
    fn of_rendered(timestamp: f64, frame: synthetic::RenderedFrame) -> Self {
        Self {
            timestamp,
            width: frame.width,
            height: frame.height,
            rgba: frame
                .rgb
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            depth: frame.depth_raw,
        }
    }
}

/// The synthetic sequence (`surfel_slam::synthetic`: the room, its known
/// trajectory, no noise (exact depth quantised to 1/5000 m), 320x240):
/// config, frames, ground truth (`world_from_camera`).
pub fn synthetic_sequence() -> (SlamConfig, Vec<RawFrame>, Vec<(f64, DAffine3)>) {
    let intrinsics = synthetic::default_intrinsics().half();
    let depth = DepthSettings {
        scale: synthetic::DEPTH_UNITS_PER_METRE,
        min_m: 0.3,
        max_m: 5.0,
        invalid_raw: None,
    };
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = intrinsics;
    config.depth = depth;
    let scene = synthetic::Scene::room();
    let noise = synthetic::NoiseModel::none();
    let mut frames = Vec::new();
    let mut ground_truth = Vec::new();
    for (i, pose) in synthetic::trajectory(SYNTHETIC_FRAMES).iter().enumerate() {
        let timestamp = i as f64 / 30.0;
        let frame = synthetic::render(&scene, &intrinsics, pose, &noise, i as u64);
        frames.push(RawFrame::of_rendered(timestamp, frame));
        ground_truth.push((timestamp, *pose));
    }
    (config, frames, ground_truth)
}

/// Frames out along the loop path in [`window_sequence`] (then as many back).
pub const WINDOW_OUT_FRAMES: usize = 40;
/// Active window of [`window_sequence`], frames: the way back meets views
/// last seen longer ago than this (the loop stage registers the inactive
/// model against the active one).
pub const WINDOW_FRAMES: u32 = 10;

/// A sequence past the active window: the synthetic loop path
/// (`synthetic::loop_pose`, 240 frames a turn) out [`WINDOW_OUT_FRAMES`]
/// frames and back to its start, under Kinect-like noise, 320x240, with a
/// [`WINDOW_FRAMES`]-frame active window: config, frames, ground truth
/// (`world_from_camera`, in the first camera's frame).
pub fn window_sequence() -> (SlamConfig, Vec<RawFrame>, Vec<(f64, DAffine3)>) {
    let intrinsics = synthetic::default_intrinsics().half();
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = intrinsics;
    config.depth = synthetic::depth_settings();
    config.fusion.active_window_frames = WINDOW_FRAMES;
    let scene = synthetic::Scene::room();
    let noise = synthetic::NoiseModel::kinect();
    let origin = synthetic::loop_pose(0, 240).inverse();
    let path = (0..WINDOW_OUT_FRAMES).chain((0..WINDOW_OUT_FRAMES).rev());
    let mut frames = Vec::new();
    let mut ground_truth = Vec::new();
    for (i, j) in path.enumerate() {
        let timestamp = i as f64 / 30.0;
        let pose = synthetic::loop_pose(j, 240);
        let frame = synthetic::render(&scene, &intrinsics, &pose, &noise, i as u64);
        frames.push(RawFrame::of_rendered(timestamp, frame));
        ground_truth.push((timestamp, origin * pose));
    }
    (config, frames, ground_truth)
}

/// Config for synthetic frames rendered with `k` (5000 units/m, 0.3..8 m);
/// the same as `tests/common`'s, which [`revisit`] builds on.
#[must_use]
pub fn synthetic_config(k: Intrinsics) -> SlamConfig {
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = k;
    config.depth = synthetic::depth_settings();
    config
}

/// Frames of [`revisit`] compared: the way out and back, which the global
/// check closes at frame 90 (the deformation graph's sparse solve runs),
/// and five frames tracked in the bent map after it.
pub const REVISIT_FRAMES: usize = 96;

/// The first [`REVISIT_FRAMES`] frames of [`revisit`] with its config;
/// frame `i` is pushed with timestamp `i` seconds.
pub fn revisit_sequence() -> (SlamConfig, Vec<RgbdFrame>) {
    let config = revisit::config();
    let mut frames = revisit::frames(&config);
    frames.truncate(REVISIT_FRAMES);
    (config, frames)
}

/// The first pose (index) at which two trajectories' bits differ
/// (timestamps and poses), the shorter one's length if one is a prefix of
/// the other, `None` when they are the same bits.
#[must_use]
pub fn first_difference(a: &[(f64, DAffine3)], b: &[(f64, DAffine3)]) -> Option<usize> {
    let bits = |(t, p): &(f64, DAffine3)| {
        let mut v = vec![t.to_bits()];
        v.extend(p.to_cols_array().map(f64::to_bits));
        v
    };
    a.iter()
        .zip(b)
        .position(|(x, y)| bits(x) != bits(y))
        .or((a.len() != b.len()).then_some(a.len().min(b.len())))
}

/// Largest translation (m) and rotation (rad) difference between two
/// trajectories of equal length and timestamps.
pub fn max_difference(a: &[(f64, DAffine3)], b: &[(f64, DAffine3)]) -> Result<(f64, f64), String> {
    if a.len() != b.len() {
        return Err(format!("{} poses vs {} poses", a.len(), b.len()));
    }
    let mut worst = (0.0f64, 0.0f64);
    for ((ta, pa), (tb, pb)) in a.iter().zip(b) {
        if (ta - tb).abs() > 1e-6 {
            return Err(format!("timestamps differ: {ta} vs {tb}"));
        }
        let dt = (pa.translation - pb.translation).length();
        let qa = DQuat::from_mat3(&pa.matrix3).normalize();
        let qb = DQuat::from_mat3(&pb.matrix3).normalize();
        let dr = qa.angle_between(qb);
        worst = (worst.0.max(dt), worst.1.max(dr));
    }
    Ok(worst)
}
