//! Decoding one frame's files into an [`RgbdFrame`], whatever the layout:
//! colour and depth (every layout), a missing colour image (a depth-only
//! sequence: constant grey), colour of another size than the depth
//! (scaled to it, for the layouts with a calibration file), the depth's
//! size against that file, and a confidence image (Stray Scanner: depth
//! of confidence 0 dropped, of confidence 1 weighted as
//! [`MEDIUM_CONFIDENCE_DEVIATION`] times as uncertain). Errors name the file.

use image::{imageops, DynamicImage, ImageFormat, RgbImage};

use super::{DatasetError, FrameEntry};
use crate::frame::{
    decode_colour, decode_depth_into, image_dimensions, Channel, DepthSettings, FrameError,
    RgbdFrame, MEDIUM_CONFIDENCE_DEVIATION,
};

/// The grey of a depth-only frame's colour image (RGB8, every channel).
pub const DEPTH_ONLY_GREY: u8 = 128;

/// The bytes of one frame's files (read by any means: natively, in the
/// browser), as its [`FrameEntry`] names them.
#[derive(Debug, Clone, Copy)]
pub struct FrameBytes<'a> {
    /// The colour image (PNG or JPEG); `None` for a depth-only frame.
    pub colour: Option<&'a [u8]>,
    /// The 16-bit depth PNG.
    pub depth: &'a [u8],
    /// The 8-bit confidence PNG, when the entry names one.
    pub confidence: Option<&'a [u8]>,
}

/// Decodes a frame's colour and depth bytes (read by any means, e.g. in the
/// browser), naming the offending file in the error. Depth in metres per
/// `settings`. The layouts with a colour image and no confidence image;
/// [`decode_frame_bytes`] takes every layout.
pub fn decode_frame(
    entry: &FrameEntry,
    colour: &[u8],
    depth: &[u8],
    settings: &DepthSettings,
) -> Result<RgbdFrame, DatasetError> {
    let bytes = FrameBytes {
        colour: Some(colour),
        depth,
        confidence: None,
    };
    decode_frame_bytes(entry, &bytes, settings)
}

/// Decodes a frame's files (depth in metres per `settings`): without
/// colour, a constant grey ([`DEPTH_ONLY_GREY`]) image of the depth's size;
/// for an entry with a calibrated size, the depth image must be that size
/// ([`DatasetError::ImageSize`]) and colour of another size is scaled to
/// it; with a confidence image, depth whose confidence is 0 becomes 0 and
/// that of confidence 1 is marked less certain ([`RgbdFrame::depth_deviation`]).
pub fn decode_frame_bytes(
    entry: &FrameEntry,
    bytes: &FrameBytes<'_>,
    settings: &DepthSettings,
) -> Result<RgbdFrame, DatasetError> {
    let depth_error = |source| DatasetError::Frame {
        path: entry.depth.clone(),
        source,
    };
    let colour_path = || entry.colour.clone().unwrap_or_default();
    let (dw, dh) = image_dimensions(bytes.depth, Channel::Depth, true).map_err(depth_error)?;
    if let Some(size) = &entry.calibrated_size {
        if (dw, dh) != (size.width, size.height) {
            return Err(DatasetError::ImageSize {
                path: entry.depth.clone(),
                width: dw,
                height: dh,
                expected_width: size.width,
                expected_height: size.height,
                calibration: size.file.clone(),
            });
        }
    }
    let same_size = match bytes.colour {
        Some(colour) if entry.calibrated_size.is_some() => {
            image_dimensions(colour, Channel::Colour, false).map_err(|source| {
                DatasetError::Frame {
                    path: colour_path(),
                    source,
                }
            })? == (dw, dh)
        }
        Some(_) => true,
        None => false,
    };
    let mut frame = match bytes.colour {
        Some(colour) if same_size => RgbdFrame::from_png_bytes(colour, bytes.depth, settings)
            .map_err(|source| frame_error(entry, source))?,
        colour => {
            settings.validate().map_err(depth_error)?;
            let mut frame = RgbdFrame::default();
            let (w, h) =
                decode_depth_into(bytes.depth, settings, &mut frame.depth_m, &mut Vec::new())
                    .map_err(depth_error)?;
            frame.width = w;
            frame.height = h;
            frame.rgb = match colour {
                Some(colour) => {
                    scaled_colour(colour, w, h).map_err(|source| DatasetError::Frame {
                        path: colour_path(),
                        source,
                    })?
                }
                None => vec![DEPTH_ONLY_GREY; 3 * w * h],
            };
            frame
        }
    };
    if let (Some(path), Some(confidence)) = (&entry.confidence, bytes.confidence) {
        apply_confidence(path, &entry.depth, confidence, &mut frame)?;
    }
    Ok(frame)
}

/// A colour image decoded and scaled (bilinear) to `width` x `height`, RGB8.
fn scaled_colour(bytes: &[u8], width: usize, height: usize) -> Result<Vec<u8>, FrameError> {
    let (w, h, rgb) = decode_colour(bytes)?;
    let size_error = || FrameError::BadDimensions {
        width: w,
        height: h,
    };
    let to_u32 = |v: usize| u32::try_from(v).map_err(|_| size_error());
    let image = RgbImage::from_raw(to_u32(w)?, to_u32(h)?, rgb).ok_or_else(size_error)?;
    let scaled = imageops::resize(
        &image,
        to_u32(width)?,
        to_u32(height)?,
        imageops::FilterType::Triangle,
    );
    Ok(scaled.into_raw())
}

/// Sets to 0 the depth of `frame` wherever the 8-bit confidence image
/// `bytes` (file `path`, beside depth image `depth_path`) is 0, and its
/// depth deviation to [`MEDIUM_CONFIDENCE_DEVIATION`] where it is 1.
fn apply_confidence(
    path: &str,
    depth_path: &str,
    bytes: &[u8],
    frame: &mut RgbdFrame,
) -> Result<(), DatasetError> {
    let bad = |reason: String| DatasetError::Confidence {
        path: path.to_owned(),
        reason,
    };
    let (w, h) = image_dimensions(bytes, Channel::Depth, true)
        .map_err(|e| bad(format!("not a readable PNG: {e}")))?;
    if (w, h) != (frame.width, frame.height) {
        return Err(DatasetError::ImageSize {
            path: path.to_owned(),
            width: w,
            height: h,
            expected_width: frame.width,
            expected_height: frame.height,
            calibration: format!("its depth image {depth_path}"),
        });
    }
    let image = image::load_from_memory_with_format(bytes, ImageFormat::Png)
        .map_err(|e| bad(format!("not a readable PNG: {e}")))?;
    let DynamicImage::ImageLuma8(levels) = image else {
        return Err(bad(format!(
            "expected an 8-bit single-channel PNG (confidence 0, 1, 2), found {:?}",
            image.color()
        )));
    };
    for (d, &c) in frame.depth_m.iter_mut().zip(levels.as_raw()) {
        if c == 0 {
            *d = 0.0;
        }
    }
    frame.depth_deviation.clear();
    frame
        .depth_deviation
        .extend(levels.as_raw().iter().map(|&c| {
            if c == 1 {
                MEDIUM_CONFIDENCE_DEVIATION
            } else {
                1.0
            }
        }));
    Ok(())
}

/// A decoder's error as a [`DatasetError`] naming the file it concerns.
fn frame_error(entry: &FrameEntry, source: FrameError) -> DatasetError {
    let colour = entry.colour.clone().unwrap_or_default();
    let path = match &source {
        FrameError::Decode {
            channel: Channel::Colour,
            ..
        }
        | FrameError::BufferLength {
            channel: Channel::Colour,
            ..
        } => colour,
        FrameError::Decode {
            channel: Channel::Depth,
            ..
        }
        | FrameError::BufferLength {
            channel: Channel::Depth,
            ..
        }
        | FrameError::DepthNot16Bit { .. }
        | FrameError::InvalidDepth { .. } => entry.depth.clone(),
        _ => format!("{colour} + {}", entry.depth),
    };
    DatasetError::Frame { path, source }
}
