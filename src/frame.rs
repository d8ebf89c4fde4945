//! One RGB-D frame: PNG decoding from bytes, depth in metres, validation.
//!
//! Depth images are 16-bit integers with `depth_scale` units per metre
//! (5000 for TUM and ICL-NUIM, 1000 for 7-Scenes); 0 (and 65535 for 7-Scenes)
//! means "no measurement". After decoding, depth is in metres with 0 = invalid;
//! values outside the configured range become 0. Never NaN.

use image::{ColorType, ImageDecoder, ImageFormat};
use thiserror::Error;

/// Which image of a frame an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// The colour image.
    Colour,
    /// The depth image.
    Depth,
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Channel::Colour => "colour",
            Channel::Depth => "depth",
        })
    }
}

/// Why a frame could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FrameError {
    /// The bytes are not a decodable image.
    #[error("{channel} image could not be decoded: {message}")]
    Decode {
        /// Colour or depth.
        channel: Channel,
        /// The decoder's message.
        message: String,
    },
    /// The depth image is not single-channel 16-bit.
    #[error("depth image must be a 16-bit single-channel PNG, found {found} (an 8-bit preview or colour image cannot hold depth)")]
    DepthNot16Bit {
        /// Description of the pixel format found.
        found: String,
    },
    /// Colour and depth sizes differ.
    #[error("colour is {colour_width}x{colour_height} but depth is {depth_width}x{depth_height}")]
    SizeMismatch {
        /// Colour width, pixels.
        colour_width: usize,
        /// Colour height, pixels.
        colour_height: usize,
        /// Depth width, pixels.
        depth_width: usize,
        /// Depth height, pixels.
        depth_height: usize,
    },
    /// The frame size differs from the expected (sequence or intrinsics) size.
    #[error("frame is {width}x{height} but the sequence is {expected_width}x{expected_height}")]
    UnexpectedSize {
        /// Frame width, pixels.
        width: usize,
        /// Frame height, pixels.
        height: usize,
        /// Expected width, pixels.
        expected_width: usize,
        /// Expected height, pixels.
        expected_height: usize,
    },
    /// A raw buffer's length does not match width x height x channels.
    #[error("{channel} buffer has {found} values, expected {expected} for the given size")]
    BufferLength {
        /// Colour or depth.
        channel: Channel,
        /// Values found.
        found: usize,
        /// Values expected.
        expected: usize,
    },
    /// The image is empty or implausibly large.
    #[error("image size {width}x{height} is not supported (1..=16384 per side, at most 16.7 million pixels)")]
    BadDimensions {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A decoded depth value is NaN, infinite or negative (only possible in a
    /// frame built by hand: decoding never produces one).
    #[error("depth must be a finite number of metres >= 0 (0 = no measurement); pixel {pixel} holds {value}")]
    InvalidDepth {
        /// Row-major pixel index.
        pixel: usize,
        /// The offending value, metres.
        value: f32,
    },
    /// The depth conversion settings are unusable.
    #[error("invalid depth settings: {0}")]
    DepthSettings(String),
}

/// How raw 16-bit depth values become metres.
#[derive(Debug, Clone, Copy, PartialEq)]
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
}

/// Largest side accepted, pixels.
pub const MAX_SIDE: usize = 16384;
/// Largest image accepted, pixels (4096 x 4096): far above any RGB-D sensor,
/// and low enough that a forged header cannot make the decoder allocate
/// gigabytes (a wasm module has 4 GiB at most).
pub const MAX_PIXELS: usize = 1 << 24;

fn check_dimensions(width: usize, height: usize) -> Result<(), FrameError> {
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

/// Reads an image's size from its header alone (no pixel decoding) and
/// checks it is supported; `png_only` refuses other formats. Run before
/// decoding so that a forged header is refused before any allocation.
pub fn image_dimensions(
    bytes: &[u8],
    channel: Channel,
    png_only: bool,
) -> Result<(usize, usize), FrameError> {
    let decode_error = |message: String| FrameError::Decode { channel, message };
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    let reader = if png_only {
        let mut r = reader;
        r.set_format(ImageFormat::Png);
        r
    } else {
        reader
            .with_guessed_format()
            .map_err(|e| decode_error(e.to_string()))?
    };
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| decode_error(e.to_string()))?;
    let (w, h) = (w as usize, h as usize);
    check_dimensions(w, h)?;
    Ok((w, h))
}

/// Reusable decoder output buffers, so that decoding a stream of frames does
/// not allocate image-sized buffers per frame.
#[derive(Debug, Default)]
pub struct DecodeScratch {
    colour: Vec<u8>,
    depth: Vec<u8>,
}

/// Decodes an image's pixels as stored (its own colour type) into `out`.
fn decode_pixels(
    bytes: &[u8],
    channel: Channel,
    png_only: bool,
    out: &mut Vec<u8>,
) -> Result<(usize, usize, ColorType), FrameError> {
    let decode_error = |message: String| FrameError::Decode { channel, message };
    let (w, h) = image_dimensions(bytes, channel, png_only)?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    if png_only {
        reader.set_format(ImageFormat::Png);
    } else {
        reader = reader
            .with_guessed_format()
            .map_err(|e| decode_error(e.to_string()))?;
    }
    let decoder = reader
        .into_decoder()
        .map_err(|e| decode_error(e.to_string()))?;
    let colour_type = decoder.color_type();
    let n = usize::try_from(decoder.total_bytes()).map_err(|e| decode_error(e.to_string()))?;
    out.resize(n, 0);
    decoder
        .read_image(out)
        .map_err(|e| decode_error(e.to_string()))?;
    Ok((w, h, colour_type))
}

/// Decodes a colour image (PNG or JPEG bytes) into `rgb` as RGB8, reusing
/// both buffers; returns (width, height).
pub fn decode_colour_into(
    bytes: &[u8],
    rgb: &mut Vec<u8>,
    scratch: &mut Vec<u8>,
) -> Result<(usize, usize), FrameError> {
    let (w, h, colour_type) = decode_pixels(bytes, Channel::Colour, false, scratch)?;
    let n = w * h;
    match colour_type {
        // The decoded buffer is the answer: trade buffers instead of copying.
        ColorType::Rgb8 => std::mem::swap(rgb, scratch),
        ColorType::Rgba8 => {
            rgb.clear();
            rgb.extend(scratch.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]));
        }
        ColorType::L8 => {
            rgb.clear();
            rgb.extend(scratch.iter().flat_map(|&g| [g, g, g]));
        }
        // Rare formats (16-bit, float, grey with alpha): convert through `image`.
        _ => {
            let img = image::load_from_memory(bytes).map_err(|e| FrameError::Decode {
                channel: Channel::Colour,
                message: e.to_string(),
            })?;
            *rgb = img.to_rgb8().into_raw();
        }
    }
    if rgb.len() != 3 * n {
        return Err(FrameError::BufferLength {
            channel: Channel::Colour,
            found: rgb.len(),
            expected: 3 * n,
        });
    }
    Ok((w, h))
}

/// Decodes a 16-bit single-channel depth PNG into `depth_m` (metres per
/// `settings`, 0 = invalid), reusing both buffers; returns (width, height).
pub fn decode_depth_into(
    bytes: &[u8],
    settings: &DepthSettings,
    depth_m: &mut Vec<f32>,
    scratch: &mut Vec<u8>,
) -> Result<(usize, usize), FrameError> {
    let (w, h, colour_type) = decode_pixels(bytes, Channel::Depth, true, scratch)?;
    if colour_type != ColorType::L16 {
        return Err(FrameError::DepthNot16Bit {
            found: format!("{colour_type:?}"),
        });
    }
    depth_m.clear();
    // The decoder writes 16-bit samples in native byte order.
    depth_m.extend(
        scratch
            .chunks_exact(2)
            .map(|b| settings.to_metres(u16::from_ne_bytes([b[0], b[1]]))),
    );
    Ok((w, h))
}

/// Copies `pixels` RGB8 (`3 * count` bytes) or RGBA8 (`4 * count`, alpha
/// dropped) into `rgb` as RGB8, reusing its allocation.
fn rgb_from_pixels(pixels: &[u8], count: usize, rgb: &mut Vec<u8>) -> Result<(), FrameError> {
    if pixels.len() == 4 * count {
        rgb.resize(3 * count, 0);
        for (out, p) in rgb.chunks_exact_mut(3).zip(pixels.chunks_exact(4)) {
            out.copy_from_slice(&p[..3]);
        }
    } else if pixels.len() == 3 * count {
        rgb.clear();
        rgb.extend_from_slice(pixels);
    } else {
        return Err(FrameError::BufferLength {
            channel: Channel::Colour,
            found: pixels.len(),
            expected: 4 * count,
        });
    }
    Ok(())
}

/// Decodes a colour image (PNG or JPEG bytes) to RGB8; returns (width, height, rgb).
pub fn decode_colour(bytes: &[u8]) -> Result<(usize, usize, Vec<u8>), FrameError> {
    let mut rgb = Vec::new();
    let (w, h) = decode_colour_into(bytes, &mut rgb, &mut Vec::new())?;
    Ok((w, h, rgb))
}

/// Decodes a 16-bit single-channel depth PNG; returns (width, height, raw values).
pub fn decode_depth_raw(bytes: &[u8]) -> Result<(usize, usize, Vec<u16>), FrameError> {
    let mut scratch = Vec::new();
    let (w, h, colour_type) = decode_pixels(bytes, Channel::Depth, true, &mut scratch)?;
    if colour_type != ColorType::L16 {
        return Err(FrameError::DepthNot16Bit {
            found: format!("{colour_type:?}"),
        });
    }
    let raw = scratch
        .chunks_exact(2)
        .map(|b| u16::from_ne_bytes([b[0], b[1]]))
        .collect();
    Ok((w, h, raw))
}

impl RgbdFrame {
    /// Decodes colour and depth image bytes into a frame.
    pub fn from_png_bytes(
        colour: &[u8],
        depth: &[u8],
        settings: &DepthSettings,
    ) -> Result<Self, FrameError> {
        let mut frame = Self::default();
        frame.decode_into(colour, depth, settings, &mut DecodeScratch::default())?;
        Ok(frame)
    }

    /// Decodes colour and depth image bytes into this frame, reusing its
    /// buffers and `scratch`'s. On error the frame's contents are unspecified.
    pub fn decode_into(
        &mut self,
        colour: &[u8],
        depth: &[u8],
        settings: &DepthSettings,
        scratch: &mut DecodeScratch,
    ) -> Result<(), FrameError> {
        settings.validate()?;
        let DecodeScratch {
            colour: colour_scratch,
            depth: depth_scratch,
        } = scratch;
        let (rgb, depth_m) = (&mut self.rgb, &mut self.depth_m);
        // The two images are independent: decode them on two threads.
        let (depth_size, colour_size) = rayon::join(
            || decode_depth_into(depth, settings, depth_m, depth_scratch),
            || decode_colour_into(colour, rgb, colour_scratch),
        );
        let depth_size = depth_size?;
        self.set_size(colour_size?, depth_size)
    }

    /// Records the frame's size once the colour and depth images agree on it.
    fn set_size(
        &mut self,
        (cw, ch): (usize, usize),
        (dw, dh): (usize, usize),
    ) -> Result<(), FrameError> {
        if (cw, ch) != (dw, dh) {
            return Err(FrameError::SizeMismatch {
                colour_width: cw,
                colour_height: ch,
                depth_width: dw,
                depth_height: dh,
            });
        }
        self.width = dw;
        self.height = dh;
        Ok(())
    }

    /// Builds a frame from raw buffers: colour RGBA8 or RGB8 (by length), depth raw u16.
    pub fn from_raw(
        width: usize,
        height: usize,
        colour: &[u8],
        depth_raw: &[u16],
        settings: &DepthSettings,
    ) -> Result<Self, FrameError> {
        settings.validate()?;
        check_dimensions(width, height)?;
        let n = width * height;
        if depth_raw.len() != n {
            return Err(FrameError::BufferLength {
                channel: Channel::Depth,
                found: depth_raw.len(),
                expected: n,
            });
        }
        let mut rgb = Vec::new();
        rgb_from_pixels(colour, n, &mut rgb)?;
        Ok(Self {
            width,
            height,
            rgb,
            depth_m: depth_raw.iter().map(|&r| settings.to_metres(r)).collect(),
        })
    }

    /// Builds a frame from colour pixels decoded elsewhere (RGBA8 or RGB8 by
    /// length, `width` x `height`; a browser's `getImageData`, say) and a
    /// 16-bit single-channel depth PNG, decoded here.
    pub fn from_pixels_and_depth_png(
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u8],
        settings: &DepthSettings,
    ) -> Result<Self, FrameError> {
        let mut frame = Self::default();
        frame.decode_depth_with_pixels_into(
            width,
            height,
            colour,
            depth,
            settings,
            &mut DecodeScratch::default(),
        )?;
        Ok(frame)
    }

    /// As [`RgbdFrame::from_pixels_and_depth_png`], into this frame, reusing
    /// its buffers and `scratch`'s. The checks and messages are those of
    /// [`RgbdFrame::decode_into`] (colour/depth size mismatch, depth not
    /// 16-bit, ...) plus a colour buffer whose length does not match the size.
    /// On error the frame's contents are unspecified.
    pub fn decode_depth_with_pixels_into(
        &mut self,
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u8],
        settings: &DepthSettings,
        scratch: &mut DecodeScratch,
    ) -> Result<(), FrameError> {
        settings.validate()?;
        check_dimensions(width, height)?;
        rgb_from_pixels(colour, width * height, &mut self.rgb)?;
        let depth_size = decode_depth_into(depth, settings, &mut self.depth_m, &mut scratch.depth)?;
        self.set_size((width, height), depth_size)
    }

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
        match self
            .depth_m
            .iter()
            .position(|d| !(d.is_finite() && *d >= 0.0))
        {
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
    use image::{DynamicImage, ImageBuffer, Luma, Rgb};

    #[test]
    fn depth_thumbnail_takes_the_pixel_under_each_centre() {
        let frame = RgbdFrame {
            width: 4,
            height: 2,
            rgb: vec![0; 24],
            depth_m: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.0, 8.0],
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

    fn png(img: DynamicImage) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, ImageFormat::Png).expect("encode");
        out.into_inner()
    }

    fn depth16(w: u32, h: u32, v: u16) -> Vec<u8> {
        png(DynamicImage::ImageLuma16(ImageBuffer::from_pixel(
            w,
            h,
            Luma([v]),
        )))
    }

    fn colour8(w: u32, h: u32) -> Vec<u8> {
        png(DynamicImage::ImageRgb8(ImageBuffer::from_pixel(
            w,
            h,
            Rgb([10, 20, 30]),
        )))
    }

    #[test]
    fn decodes_depth_in_metres() {
        let f = RgbdFrame::from_png_bytes(
            &colour8(4, 3),
            &depth16(4, 3, 5000),
            &DepthSettings::default(),
        )
        .expect("valid frame");
        assert_eq!((f.width, f.height), (4, 3));
        assert!(f.depth_m.iter().all(|&d| (d - 1.0).abs() < 1e-6));
        assert_eq!(&f.rgb[..3], &[10, 20, 30]);
    }

    #[test]
    fn rejects_8bit_depth() {
        let d8 = png(DynamicImage::ImageLuma8(ImageBuffer::from_pixel(
            4,
            3,
            Luma([7]),
        )));
        let err = RgbdFrame::from_png_bytes(&colour8(4, 3), &d8, &DepthSettings::default());
        assert!(
            matches!(err, Err(FrameError::DepthNot16Bit { .. })),
            "{err:?}"
        );
    }

    #[test]
    fn rejects_size_mismatch_and_garbage() {
        let err =
            RgbdFrame::from_png_bytes(&colour8(5, 3), &depth16(4, 3, 1), &DepthSettings::default());
        assert!(matches!(err, Err(FrameError::SizeMismatch { .. })));
        let err =
            RgbdFrame::from_png_bytes(b"not a png", &depth16(4, 3, 1), &DepthSettings::default());
        assert!(matches!(
            err,
            Err(FrameError::Decode {
                channel: Channel::Colour,
                ..
            })
        ));
        let mut truncated = depth16(64, 64, 1000);
        truncated.truncate(truncated.len() / 2);
        let err =
            RgbdFrame::from_png_bytes(&colour8(64, 64), &truncated, &DepthSettings::default());
        assert!(matches!(
            err,
            Err(FrameError::Decode {
                channel: Channel::Depth,
                ..
            })
        ));
    }

    #[test]
    fn colour_pixels_with_depth_png_match_both_pngs() {
        let settings = DepthSettings::default();
        let (w, h) = (5_usize, 3_usize);
        let rgb: Vec<u8> = (0..3 * w * h).map(|i| (i * 7 % 251) as u8).collect();
        let rgba: Vec<u8> = rgb
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 200])
            .collect();
        let colour_png = png(DynamicImage::ImageRgb8(
            ImageBuffer::from_raw(w as u32, h as u32, rgb.clone()).expect("rgb"),
        ));
        let depth = depth16(w as u32, h as u32, 7500);
        let both = RgbdFrame::from_png_bytes(&colour_png, &depth, &settings).expect("pngs");
        for pixels in [&rgba, &rgb] {
            let f = RgbdFrame::from_pixels_and_depth_png(w, h, pixels, &depth, &settings)
                .expect("pixels + depth PNG");
            assert_eq!(f, both);
        }
    }

    #[test]
    fn colour_pixels_with_depth_png_reject_bad_input() {
        let settings = DepthSettings::default();
        let rgba = vec![0_u8; 4 * 4 * 3];
        let err =
            RgbdFrame::from_pixels_and_depth_png(4, 3, &rgba[..10], &depth16(4, 3, 1), &settings);
        assert!(
            matches!(
                err,
                Err(FrameError::BufferLength {
                    channel: Channel::Colour,
                    found: 10,
                    ..
                })
            ),
            "{err:?}"
        );
        let err = RgbdFrame::from_pixels_and_depth_png(4, 3, &rgba, &depth16(5, 3, 1), &settings);
        let message = err
            .as_ref()
            .map_err(ToString::to_string)
            .expect_err("mismatch");
        assert_eq!(message, "colour is 4x3 but depth is 5x3");
        let d8 = png(DynamicImage::ImageLuma8(ImageBuffer::from_pixel(
            4,
            3,
            Luma([7]),
        )));
        let err = RgbdFrame::from_pixels_and_depth_png(4, 3, &rgba, &d8, &settings);
        assert!(
            matches!(err, Err(FrameError::DepthNot16Bit { .. })),
            "{err:?}"
        );
        let err = RgbdFrame::from_pixels_and_depth_png(4, 3, &rgba, b"not a png", &settings);
        assert!(
            matches!(
                err,
                Err(FrameError::Decode {
                    channel: Channel::Depth,
                    ..
                })
            ),
            "{err:?}"
        );
        let err = RgbdFrame::from_pixels_and_depth_png(0, 3, &[], &depth16(4, 3, 1), &settings);
        assert!(
            matches!(err, Err(FrameError::BadDimensions { .. })),
            "{err:?}"
        );
        let huge = RgbdFrame::from_pixels_and_depth_png(
            usize::MAX,
            2,
            &rgba,
            &depth16(4, 3, 1),
            &settings,
        );
        assert!(
            matches!(huge, Err(FrameError::BadDimensions { .. })),
            "{huge:?}"
        );
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
