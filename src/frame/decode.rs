//! PNG (and JPEG colour) decoding into reused buffers.

use image::{ColorType, ImageDecoder, ImageFormat};

use super::{check_dimensions, Channel, DepthSettings, FrameError, RgbdFrame};

/// Reads an image's size from its header alone (no pixel decoding) and
/// checks it is supported; `png_only` refuses other formats. Run before
/// decoding so that a forged header is refused before any allocation.
pub fn image_dimensions(
    bytes: &[u8],
    channel: Channel,
    png_only: bool,
) -> Result<(usize, usize), FrameError> {
    let decoder = open_decoder(bytes, channel, png_only)?;
    checked_dimensions(&decoder)
}

/// Opens a decoder on `bytes`, which parses the image header and nothing more.
fn open_decoder(
    bytes: &[u8],
    channel: Channel,
    png_only: bool,
) -> Result<impl ImageDecoder + '_, FrameError> {
    let decode_error = |message: String| FrameError::Decode { channel, message };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    if png_only {
        reader.set_format(ImageFormat::Png);
    } else {
        reader = reader
            .with_guessed_format()
            .map_err(|e| decode_error(e.to_string()))?;
    }
    reader
        .into_decoder()
        .map_err(|e| decode_error(e.to_string()))
}

/// The size the header of an opened decoder declares, if supported.
fn checked_dimensions(decoder: &impl ImageDecoder) -> Result<(usize, usize), FrameError> {
    let (w, h) = decoder.dimensions();
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
/// The header is parsed once; its size is checked before `out` grows.
fn decode_pixels(
    bytes: &[u8],
    channel: Channel,
    png_only: bool,
    out: &mut Vec<u8>,
) -> Result<(usize, usize, ColorType), FrameError> {
    let decode_error = |message: String| FrameError::Decode { channel, message };
    let decoder = open_decoder(bytes, channel, png_only)?;
    let (w, h) = checked_dimensions(&decoder)?;
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
        // A reused frame keeps no earlier frame's confidence.
        self.depth_deviation.clear();
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
            depth_deviation: Vec::new(),
            depth_m: depth_raw.iter().map(|&r| settings.to_metres(r)).collect(),
        })
    }

    /// Builds a frame from colour pixels decoded elsewhere (RGBA8 or RGB8 by
    /// length, `width` x `height`; a browser's `getImageData`, say) and a
    /// 16-bit single-channel depth PNG, decoded here. The "RGBA + depth PNG"
    /// path, as `Pipeline::push_rgba_depth_png` and JS `pushRgbaDepthPng`.
    pub fn from_rgba_depth_png(
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u8],
        settings: &DepthSettings,
    ) -> Result<Self, FrameError> {
        let mut frame = Self::default();
        frame.decode_rgba_depth_png_into(
            width,
            height,
            colour,
            depth,
            settings,
            &mut DecodeScratch::default(),
        )?;
        Ok(frame)
    }

    /// As [`RgbdFrame::from_rgba_depth_png`], into this frame, reusing
    /// its buffers and `scratch`'s. The checks and messages are those of
    /// [`RgbdFrame::decode_into`] (colour/depth size mismatch, depth not
    /// 16-bit, ...) plus a colour buffer whose length does not match the size.
    /// On error the frame's contents are unspecified.
    pub fn decode_rgba_depth_png_into(
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
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, Rgb};

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
            let f = RgbdFrame::from_rgba_depth_png(w, h, pixels, &depth, &settings)
                .expect("pixels + depth PNG");
            assert_eq!(f, both);
        }
    }

    #[test]
    fn colour_pixels_with_depth_png_reject_bad_input() {
        let settings = DepthSettings::default();
        let rgba = vec![0_u8; 4 * 4 * 3];
        let err = RgbdFrame::from_rgba_depth_png(4, 3, &rgba[..10], &depth16(4, 3, 1), &settings);
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
        let err = RgbdFrame::from_rgba_depth_png(4, 3, &rgba, &depth16(5, 3, 1), &settings);
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
        let err = RgbdFrame::from_rgba_depth_png(4, 3, &rgba, &d8, &settings);
        assert!(
            matches!(err, Err(FrameError::DepthNot16Bit { .. })),
            "{err:?}"
        );
        let err = RgbdFrame::from_rgba_depth_png(4, 3, &rgba, b"not a png", &settings);
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
        let err = RgbdFrame::from_rgba_depth_png(0, 3, &[], &depth16(4, 3, 1), &settings);
        assert!(
            matches!(err, Err(FrameError::BadDimensions { .. })),
            "{err:?}"
        );
        let huge =
            RgbdFrame::from_rgba_depth_png(usize::MAX, 2, &rgba, &depth16(4, 3, 1), &settings);
        assert!(
            matches!(huge, Err(FrameError::BadDimensions { .. })),
            "{huge:?}"
        );
    }
}
