//! Replays every input kept from fuzzing (`fuzz/seeds/<target>/`, a sample of
//! the corpus the fuzzers grew, `fuzz/found/<target>/`, and the crashes found,
//! `fuzz/regressions/<target>/`) through the same harness the
//! fuzz targets run (`fuzz/harness.rs`), under plain `cargo test`: no fuzzer,
//! no nightly. See fuzz/README.md for running the fuzzers themselves.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

#[path = "../fuzz/harness.rs"]
mod harness;

use std::path::PathBuf;

use surfel_slam::frame::{decode_depth_raw, Channel, MAX_PIXELS};
use surfel_slam::{DepthSettings, FrameError, RgbdFrame};

fn inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut out = Vec::new();
    for kind in ["seeds", "found", "regressions"] {
        let Ok(dir) = std::fs::read_dir(root.join(kind).join(target)) else {
            continue;
        };
        for entry in dir.flatten() {
            let path = entry.path();
            if path.is_file() {
                let bytes = std::fs::read(&path).expect("readable");
                out.push((path, bytes));
            }
        }
    }
    out.sort();
    out
}

fn replay(target: &str, body: fn(&[u8])) {
    let cases = inputs(target);
    assert!(!cases.is_empty(), "no inputs kept for {target}");
    for (path, bytes) in cases {
        eprintln!("{target}: {}", path.display());
        body(&bytes);
    }
}

#[test]
fn decode_frame_inputs() {
    replay("decode_frame", harness::decode_frame);
}

#[test]
fn push_frame_inputs() {
    replay("push_frame", harness::push_frame);
}

/// A PNG whose header claims `width` x `height` 16-bit grey pixels, with a
/// few bytes of image data: a forged size must be refused before decoding.
fn forged_png(width: u32, height: u32) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&u32::try_from(data.len()).expect("small").to_be_bytes());
        let start = out.len();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        let crc = crc32(&out[start..]);
        out.extend_from_slice(&crc.to_be_bytes());
    }
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffff_u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(
        &mut out,
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    );
    chunk(&mut out, b"IEND", &[]);
    out
}

#[test]
fn forged_image_sizes_are_refused_before_decoding() {
    for (w, h) in [(16384, 16384), (16384, 1025), (100_000, 1)] {
        let err = decode_depth_raw(&forged_png(w, h)).expect_err("refused");
        assert!(
            matches!(err, FrameError::BadDimensions { .. }),
            "{w}x{h}: {err}"
        );
    }
    const { assert!(16384 * 1025 > MAX_PIXELS) };
    // Within the limits the same forgery is a decode error (truncated data).
    let err = RgbdFrame::from_png_bytes(
        &forged_png(64, 48),
        &forged_png(64, 48),
        &DepthSettings::default(),
    )
    .expect_err("truncated");
    assert!(
        matches!(
            err,
            FrameError::Decode {
                channel: Channel::Depth,
                ..
            }
        ),
        "{err}"
    );
}
