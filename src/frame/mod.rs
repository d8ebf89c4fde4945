//! One RGB-D frame: PNG decoding from bytes, depth in metres, validation.
//!
//! Depth images are 16-bit integers with `depth_scale` units per metre
//! (5000 for TUM and ICL-NUIM, 1000 for 7-Scenes); 0 (and 65535 for 7-Scenes)
//! means "no measurement". After decoding, depth is in metres with 0 = invalid;
//! values outside the configured range become 0. Never NaN.

mod decode;
mod error;

pub use decode::{
    decode_colour, decode_colour_into, decode_depth_into, decode_depth_raw, image_dimensions,
    DecodeScratch,
};
pub use error::{Channel, FrameError};

/// How raw 16-bit depth values become metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DepthSettings {
    /// Raw units per metre (5000 TUM/ICL-NUIM, 1000 7-Scenes).
    pub scale: f32,
    /// Nearest valid depth, metres.
    pub min_m: f32,
    /// Farthest valid depth, metres.
    pub max_m: f32,
    /// A raw value meaning "invalid" besides 0 (7-Scenes: 65535).
    pub invalid_raw: Option<u16>,
}

impl Default for DepthSettings {
    fn default() -> Self {
        Self {
            scale: 5000.0,
            min_m: 0.3,
            max_m: 4.0,
            invalid_raw: None,
        }
    }
}

impl DepthSettings {
    /// Checks scale > 0 and 0 <= min < max, all finite.
    pub fn validate(&self) -> Result<(), FrameError> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(FrameError::DepthSettings(format!(
                "depth scale must be a positive number of units per metre, got {}",
                self.scale
            )));
        }
        if !(self.min_m.is_finite() && self.max_m.is_finite() && self.min_m >= 0.0)
            || self.min_m >= self.max_m
        {
            return Err(FrameError::DepthSettings(format!(
                "depth range must satisfy 0 <= min < max, got {} .. {} m",
                self.min_m, self.max_m
            )));
        }
        Ok(())
    }

    /// Converts one raw value to metres, 0 when invalid or out of range.
    #[inline]
    #[must_use]
    pub fn to_metres(&self, raw: u16) -> f32 {
        if raw == 0 || Some(raw) == self.invalid_raw {
            return 0.0;
        }
        let d = f32::from(raw) / self.scale;
        if d >= self.min_m && d <= self.max_m {
            d
        } else {
            0.0
        }
    }
}

/// A decoded RGB-D frame at full resolution.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RgbdFrame {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Colour, RGB8 interleaved, row-major (`3 * width * height` bytes).
    pub rgb: Vec<u8>,
    /// Depth along +z in metres, 0 = no measurement, row-major.
    pub depth_m: Vec<f32>,
    /// Per-pixel multiplier (>= 1) of the sensor noise model's depth
    /// deviation, row-major; empty = 1 at every pixel. A sensor's own
    /// confidence map lands here (Stray Scanner: ARKit's medium confidence
    /// is [`MEDIUM_CONFIDENCE_DEVIATION`]), so tracking and fusion weigh
    /// the pixel by `1 / factor^2` (under a noise model that weighs at
    /// all: `SensorNoise::uniform` ignores it).
    pub depth_deviation: Vec<f32>,
}

/// Depth deviation of a pixel of medium confidence (ARKit's 1) over one of
/// high confidence (2): the same factor as a depth edge's in the noise
/// models (`SensorNoise::edge_factor`), so such a pixel counts a quarter.
/// ARKit states no accuracy per level; see `docs/design.md`, "Confidence
/// of iPhone depth".
pub const MEDIUM_CONFIDENCE_DEVIATION: f32 = 2.0;

/// Largest side accepted, pixels.
pub const MAX_SIDE: usize = 16384;
/// Largest image accepted, pixels (4096 x 4096): far above any RGB-D sensor,
/// and low enough that a forged header cannot make the decoder allocate
/// gigabytes (a wasm module has 4 GiB at most).
pub const MAX_PIXELS: usize = 1 << 24;

pub(crate) fn check_dimensions(width: usize, height: usize) -> Result<(), FrameError> {
    if width == 0
        || height == 0
        || width > MAX_SIDE
        || height > MAX_SIDE
        || width * height > MAX_PIXELS
    {
        return Err(FrameError::BadDimensions { width, height });
    }
    Ok(())
}

impl RgbdFrame {
    /// Checks what a frame built by hand (its fields are public) could get
    /// wrong: a supported size, buffer lengths matching it, every depth
    /// finite and >= 0. Decoded frames always pass.
    pub fn validate(&self) -> Result<(), FrameError> {
        check_dimensions(self.width, self.height)?;
        let n = self.width * self.height;
        if self.depth_m.len() != n {
            return Err(FrameError::BufferLength {
                channel: Channel::Depth,
                found: self.depth_m.len(),
                expected: n,
            });
        }
        if self.rgb.len() != 3 * n {
            return Err(FrameError::BufferLength {
                channel: Channel::Colour,
                found: self.rgb.len(),
                expected: 3 * n,
            });
        }
        if !self.depth_deviation.is_empty() && self.depth_deviation.len() != n {
            return Err(FrameError::BufferLength {
                channel: Channel::DepthDeviation,
                found: self.depth_deviation.len(),
                expected: n,
            });
        }
        if let Some(pixel) = self
            .depth_deviation
            .iter()
            .position(|f| !(f.is_finite() && *f >= 1.0))
        {
            return Err(FrameError::InvalidDepthDeviation {
                pixel,
                value: self.depth_deviation[pixel],
            });
        }
        let invalid = |d: &f32| !(d.is_finite() && *d >= 0.0);
        // Whole pieces tested without an early exit, so the test vectorises
        // (a per-pixel search took 0.5 ms a frame); the pixel is then found
        // in the first bad piece.
        const PIECE: usize = 64;
        let bad_piece = self
            .depth_m
            .chunks(PIECE)
            .position(|piece| piece.iter().fold(false, |bad, d| bad | invalid(d)));
        let pixel = bad_piece.and_then(|p| {
            let first = p * PIECE;
            self.depth_m[first..]
                .iter()
                .position(invalid)
                .map(|i| first + i)
        });
        match pixel {
            Some(pixel) => Err(FrameError::InvalidDepth {
                pixel,
                value: self.depth_m[pixel],
            }),
            None => Ok(()),
        }
    }

    /// Errors unless the frame is `width` x `height`.
    pub fn expect_size(&self, width: usize, height: usize) -> Result<(), FrameError> {
        if (self.width, self.height) != (width, height) {
            return Err(FrameError::UnexpectedSize {
                width: self.width,
                height: self.height,
                expected_width: width,
                expected_height: height,
            });
        }
        Ok(())
    }

    /// Multiplier of the depth deviation at pixel `i` (row-major): 1 where
    /// the frame carries none.
    #[inline]
    #[must_use]
    pub fn depth_deviation_at(&self, i: usize) -> f32 {
        self.depth_deviation.get(i).copied().unwrap_or(1.0)
    }

    /// Number of pixels with a depth measurement.
    #[must_use]
    pub fn valid_depth_count(&self) -> usize {
        self.depth_m.iter().filter(|&&d| d > 0.0).count()
    }

    /// Depth resampled to `width` x `height` (each output pixel takes the
    /// input pixel under its centre), metres, 0 = no measurement, row-major
    /// into `out`, which is cleared first; a thumbnail for previews. Empty
    /// when either size is zero.
    pub fn depth_thumbnail_into(&self, width: usize, height: usize, out: &mut Vec<f32>) {
        out.clear();
        if self.width == 0 || self.height == 0 || width == 0 || height == 0 {
            return;
        }
        out.reserve(width * height);
        for y in 0..height {
            let sy = ((2 * y + 1) * self.height / (2 * height)).min(self.height - 1);
            for x in 0..width {
                let sx = ((2 * x + 1) * self.width / (2 * width)).min(self.width - 1);
                out.push(
                    self.depth_m
                        .get(sy * self.width + sx)
                        .copied()
                        .unwrap_or(0.0),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_the_first_invalid_depth_wherever_it_lies() {
        let (width, height) = (50, 7);
        let n = width * height;
        let clean = RgbdFrame {
            width,
            height,
            rgb: vec![0; 3 * n],
            depth_m: vec![1.5; n],
            depth_deviation: Vec::new(),
        };
        assert!(clean.validate().is_ok());
        // Around the boundaries of the pieces the scan tests whole, and the ends.
        for first in [0, 1, 63, 64, 65, 127, 128, n - 2, n - 1] {
            for bad in [f32::NAN, f32::INFINITY, -0.5] {
                let mut frame = clean.clone();
                frame.depth_m[first] = bad;
                // A second bad pixel later must not be the one named.
                frame.depth_m[n - 1] = f32::NEG_INFINITY;
                match frame.validate() {
                    Err(FrameError::InvalidDepth { pixel, .. }) => {
                        assert_eq!(pixel, first, "value {bad}");
                    }
                    other => panic!("pixel {first}, value {bad}: {other:?}"),
                }
            }
        }
    }

    #[test]
    fn a_depth_deviation_map_must_fit_the_frame_and_hold_multipliers_of_at_least_one() {
        let (width, height) = (5, 4);
        let n = width * height;
        let mut frame = RgbdFrame {
            width,
            height,
            rgb: vec![0; 3 * n],
            depth_m: vec![1.5; n],
            depth_deviation: vec![1.0; n],
        };
        frame.depth_deviation[7] = MEDIUM_CONFIDENCE_DEVIATION;
        assert!(frame.validate().is_ok());
        assert_eq!(frame.depth_deviation_at(7), MEDIUM_CONFIDENCE_DEVIATION);
        assert_eq!(frame.depth_deviation_at(n), 1.0);
        for bad in [0.5, 0.0, -1.0, f32::NAN, f32::INFINITY] {
            let mut f = frame.clone();
            f.depth_deviation[11] = bad;
            assert!(
                matches!(
                    f.validate(),
                    Err(FrameError::InvalidDepthDeviation { pixel: 11, .. })
                ),
                "{bad}"
            );
        }
        let mut short = frame.clone();
        short.depth_deviation.pop();
        assert!(matches!(
            short.validate(),
            Err(FrameError::BufferLength {
                channel: Channel::DepthDeviation,
                found,
                expected,
            }) if found == n - 1 && expected == n
        ));
        // None at all: 1 everywhere.
        frame.depth_deviation.clear();
        assert!(frame.validate().is_ok());
        assert_eq!(frame.depth_deviation_at(7), 1.0);
    }

    #[test]
    fn depth_thumbnail_takes_the_pixel_under_each_centre() {
        let frame = RgbdFrame {
            width: 4,
            height: 2,
            rgb: vec![0; 24],
            depth_m: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.0, 8.0],
            depth_deviation: Vec::new(),
        };
        let mut out = vec![9.0];
        frame.depth_thumbnail_into(2, 1, &mut out);
        assert_eq!(out, [6.0, 8.0]);
        frame.depth_thumbnail_into(4, 2, &mut out);
        assert_eq!(out, frame.depth_m);
        frame.depth_thumbnail_into(8, 4, &mut out);
        assert_eq!(out.len(), 32);
        assert_eq!((out[0], out[7], out[24], out[29]), (1.0, 4.0, 5.0, 0.0));
        frame.depth_thumbnail_into(0, 3, &mut out);
        assert!(out.is_empty());
        RgbdFrame::default().depth_thumbnail_into(2, 2, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn out_of_range_and_invalid_raw_become_zero() {
        let s = DepthSettings {
            scale: 1000.0,
            min_m: 0.3,
            max_m: 4.0,
            invalid_raw: Some(65535),
        };
        assert_eq!(s.to_metres(65535), 0.0);
        assert_eq!(s.to_metres(100), 0.0);
        assert_eq!(s.to_metres(5000), 0.0);
        assert!((s.to_metres(1500) - 1.5).abs() < 1e-6);
        let bad = DepthSettings { scale: 0.0, ..s };
        assert!(bad.validate().is_err());
    }
}
