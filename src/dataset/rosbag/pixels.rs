//! A `sensor_msgs/Image`'s pixels as the pipeline takes them: 16-bit depth
//! (`mono16`, `16UC1`) as raw units, colour (`rgb8`, `bgr8`, `rgba8`,
//! `bgra8`) as RGB8. Other encodings are refused by name.

use super::message::ImageHead;
use super::RosbagError;
use crate::frame::{MAX_PIXELS, MAX_SIDE};

/// Whether an encoding is 16-bit depth.
pub(crate) fn is_depth_encoding(encoding: &str) -> bool {
    matches!(encoding, "mono16" | "16UC1")
}

/// Bytes per pixel of a colour encoding read here.
pub(crate) fn colour_bytes_per_pixel(encoding: &str) -> Option<usize> {
    match encoding {
        "rgb8" | "bgr8" => Some(3),
        "rgba8" | "bgra8" => Some(4),
        _ => None,
    }
}

/// The rows of an image, `bpp` bytes a pixel: checks the size, the step
/// and that the pixels hold every row. `data` is the message's bytes.
fn rows<'a>(
    head: &ImageHead,
    data: &'a [u8],
    bpp: usize,
    topic: &str,
) -> Result<impl Iterator<Item = &'a [u8]>, RosbagError> {
    let (w, h) = (head.width as usize, head.height as usize);
    let bad = |reason: String| RosbagError::Message {
        topic: topic.to_owned(),
        reason,
    };
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS {
        return Err(bad(format!("an image of {w}x{h} pixels")));
    }
    let step = head.step as usize;
    if step < w * bpp {
        return Err(bad(format!(
            "a row step of {step} bytes for {w} pixels of {bpp} bytes"
        )));
    }
    let pixels = head
        .data_offset
        .checked_add(head.data_len)
        .and_then(|end| data.get(head.data_offset..end))
        .ok_or_else(|| bad("the pixels lie past the message".to_owned()))?;
    // In u64: a forged step must not wrap a 32-bit usize (wasm).
    let needed = head.step as u64 * (h as u64 - 1) + (w * bpp) as u64;
    if (pixels.len() as u64) < needed {
        return Err(bad(format!(
            "{} bytes of pixels for {h} rows of {step} bytes",
            pixels.len()
        )));
    }
    Ok(pixels
        .chunks(step)
        .take(h)
        .map(move |row| row.get(..w * bpp).unwrap_or_default()))
}

/// The depth image of a message (its `head` and bytes `data`), raw units,
/// row-major, into `out`.
pub(crate) fn depth_pixels(
    head: &ImageHead,
    data: &[u8],
    topic: &str,
    out: &mut Vec<u16>,
) -> Result<(), RosbagError> {
    if !is_depth_encoding(&head.encoding) {
        return Err(RosbagError::UnsupportedEncoding {
            topic: topic.to_owned(),
            encoding: head.encoding.clone(),
            expected: "mono16 or 16UC1 depth",
        });
    }
    out.clear();
    for row in rows(head, data, 2, topic)? {
        out.extend(row.chunks_exact(2).map(|p| {
            let b = [p[0], p[1]];
            if head.big_endian {
                u16::from_be_bytes(b)
            } else {
                u16::from_le_bytes(b)
            }
        }));
    }
    Ok(())
}

/// The colour image of a message as RGB8, row-major, into `out`.
pub(crate) fn colour_pixels(
    head: &ImageHead,
    data: &[u8],
    topic: &str,
    out: &mut Vec<u8>,
) -> Result<(), RosbagError> {
    let bpp =
        colour_bytes_per_pixel(&head.encoding).ok_or_else(|| RosbagError::UnsupportedEncoding {
            topic: topic.to_owned(),
            encoding: head.encoding.clone(),
            expected: "rgb8, bgr8, rgba8 or bgra8 colour",
        })?;
    let bgr = head.encoding.starts_with("bgr");
    out.clear();
    for row in rows(head, data, bpp, topic)? {
        for p in row.chunks_exact(bpp) {
            let (r, g, b) = (p[0], p[1], p[2]);
            if bgr {
                out.extend([b, g, r]);
            } else {
                out.extend([r, g, b]);
            }
        }
    }
    Ok(())
}
