#![allow(dead_code)] // each fuzz target uses one half of this file
//! Bodies of the fuzz targets, shared by cargo-fuzz (`fuzz/fuzz_targets/*.rs`)
//! and by the regression test `tests/fuzz_regressions.rs`, which replays every
//! input kept in `fuzz/regressions/<target>/` under plain `cargo test`.
//!
//! Each body panics only when the library breaks a promise: a decoded frame
//! with the wrong buffer sizes or a non-finite depth, a NaN or infinity in the
//! surfel map or a pose, a refused frame that changed the map.

use surfel_slam::frame::{image_dimensions, Channel};
use surfel_slam::{DepthSettings, Intrinsics, Pipeline, RgbdFrame, SlamConfig, Verdict};

/// Images whose header claims more pixels than this are not decoded by the
/// harness: they are valid input, only slow to fuzz (the library's own limit,
/// `frame::MAX_PIXELS`, is tested separately).
const FUZZ_MAX_PIXELS: usize = 1 << 18;

fn small_enough(bytes: &[u8], channel: Channel, png_only: bool) -> bool {
    image_dimensions(bytes, channel, png_only).map_or(true, |(w, h)| w * h <= FUZZ_MAX_PIXELS)
}

/// Arbitrary bytes as a colour image and a depth image: the first two bytes
/// say where to split the rest.
pub fn decode_frame(data: &[u8]) {
    let (head, rest) = data.split_at(data.len().min(2));
    let split = match head {
        [a, b] => usize::from(u16::from_le_bytes([*a, *b])) % (rest.len() + 1),
        _ => 0,
    };
    let (colour, depth) = rest.split_at(split);
    if !small_enough(colour, Channel::Colour, false) || !small_enough(depth, Channel::Depth, true) {
        return;
    }
    let settings = DepthSettings::default();
    if let Ok(frame) = RgbdFrame::from_png_bytes(colour, depth, &settings) {
        let n = frame.width * frame.height;
        assert!(n > 0);
        assert_eq!(frame.rgb.len(), 3 * n);
        assert_eq!(frame.depth_m.len(), n);
        assert!(
            frame
                .depth_m
                .iter()
                .all(|d| d.is_finite()
                    && (*d == 0.0 || (settings.min_m..=settings.max_m).contains(d)))
        );
    }
    // Each half on its own, and the whole input as either image.
    for bytes in [colour, depth, rest] {
        if small_enough(bytes, Channel::Colour, false) {
            if let Ok((w, h, rgb)) = surfel_slam::frame::decode_colour(bytes) {
                assert_eq!(rgb.len(), 3 * w * h);
            }
        }
        if small_enough(bytes, Channel::Depth, true) {
            if let Ok((w, h, raw)) = surfel_slam::frame::decode_depth_raw(bytes) {
                assert_eq!(raw.len(), w * h);
            }
        }
    }
}

/// Reads bytes in order, yielding zeros once exhausted.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((b, rest)) => {
                self.0 = rest;
                *b
            }
            None => 0,
        }
    }

    fn f32(&mut self) -> f32 {
        f32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
}

/// A number that is usually plausible and sometimes hostile.
fn pick(b: &mut Bytes, plausible: f32) -> f32 {
    match b.u8() % 8 {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => 0.0,
        3 => -plausible,
        4 => b.f32(),
        _ => plausible * (0.5 + f32::from(b.u8()) / 255.0),
    }
}

/// Arbitrary bytes as a camera configuration and a few raw frames of
/// arbitrary sizes pushed through one pipeline.
pub fn push_frame(data: &[u8]) {
    let mut b = Bytes(data);
    let width = 32 + usize::from(b.u8() % 48);
    let height = 32 + usize::from(b.u8() % 32);
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = Intrinsics::new(
        pick(&mut b, 0.8 * width as f32),
        pick(&mut b, 0.8 * width as f32),
        pick(&mut b, 0.5 * width as f32),
        pick(&mut b, 0.5 * height as f32),
        width,
        height,
    );
    config.depth = DepthSettings {
        scale: pick(&mut b, 5000.0),
        min_m: 0.3,
        max_m: pick(&mut b, 6.0),
        invalid_raw: None,
    };
    let Ok(mut slam) = Pipeline::new(config.clone()) else {
        return;
    };
    let k = config.intrinsics;
    for _ in 0..4 {
        let mode = b.u8();
        // Mostly the configured size; sometimes another one (must be refused).
        let (w, h) = if mode & 0x70 == 0 {
            (usize::from(b.u8()) + 1, usize::from(b.u8()) + 1)
        } else {
            (k.width, k.height)
        };
        let n = w * h;
        let base = 2000 + u16::from(b.u8()) * 20; // 0.4 .. 1.4 m at 5000 units/m
        let tile: Vec<u8> = (0..64).map(|_| b.u8()).collect();
        let depth: Vec<u16> = (0..n)
            .map(|i| {
                let r = tile[i % tile.len()];
                match mode & 3 {
                    0 => u16::from_le_bytes([r, tile[(i * 7 + 1) % tile.len()]]),
                    1 => 0,
                    // A tilted plane with byte noise: something to track.
                    _ => base
                        .saturating_add(((i % w) * 3) as u16)
                        .saturating_add(u16::from(r) / 8),
                }
            })
            .collect();
        let colour_len = if mode & 0x80 == 0 { 3 * n } else { 4 * n };
        let colour: Vec<u8> = (0..colour_len)
            .map(|i| tile[(i * 3) % tile.len()])
            .collect();
        let before = slam.map().len();
        match RgbdFrame::from_raw(w, h, &colour, &depth, &config.depth)
            .map_err(surfel_slam::PipelineError::from)
            .and_then(|frame| slam.push_frame(&frame, 0.0))
        {
            Ok(report) => {
                assert!(report.world_from_camera.is_finite(), "{report:?}");
                if matches!(report.verdict, Verdict::Lost(_)) {
                    assert!(slam.map().len() <= before, "a lost frame was fused");
                }
            }
            Err(_) => assert_eq!(slam.map().len(), before, "a refused frame changed the map"),
        }
        assert!(slam.map().all_finite(), "non-finite surfel");
        assert!(slam.trajectory().iter().all(|(_, p)| p.is_finite()));
    }
}
