//! `first_frame.bin`: the map's first frame as pushed, kept while a thing
//! carried with the camera may still turn out to have been in it (only
//! then). Little-endian: `u64` width and height (the camera's input
//! size), RGB8 per pixel, `f32` depth per pixel (metres, 0 = none), `u64`
//! count of depth deviation factors (0 or one per pixel), then each as
//! `f32`.

use super::binary::{alloc, put_f32, put_u64, LeReader};
use super::SessionError;
use crate::RgbdFrame;
use std::io::{Read, Write};

/// The entry's name.
pub(super) const FIRST_FRAME: &str = "first_frame.bin";

/// Writes `frame`.
pub(super) fn write_first_frame(out: &mut dyn Write, frame: &RgbdFrame) -> std::io::Result<()> {
    put_u64(out, frame.width as u64)?;
    put_u64(out, frame.height as u64)?;
    out.write_all(&frame.rgb)?;
    for &z in &frame.depth_m {
        put_f32(out, z)?;
    }
    put_u64(out, frame.depth_deviation.len() as u64)?;
    for &f in &frame.depth_deviation {
        put_f32(out, f)?;
    }
    Ok(())
}

/// Reads what [`write_first_frame`] wrote, for a camera of `width x
/// height` pixels; a frame of another size or with invalid values is
/// corrupt.
pub(super) fn read_first_frame(
    input: impl Read,
    (width, height): (usize, usize),
) -> Result<RgbdFrame, SessionError> {
    let mut r = LeReader::new(input, FIRST_FRAME);
    let pixels = width * height;
    let w = r.count(pixels, "pixels wide")?;
    let h = r.count(pixels, "pixels high")?;
    if (w, h) != (width, height) {
        return Err(SessionError::Corrupt(format!(
            "{FIRST_FRAME}: a {w}x{h} frame for a {width}x{height} camera"
        )));
    }
    let rgb = r.u8s(3 * pixels)?;
    let mut depth_m = alloc(pixels, FIRST_FRAME)?;
    for _ in 0..pixels {
        depth_m.push(r.f32()?);
    }
    let deviations = r.count(pixels, "depth deviation factors")?;
    let mut depth_deviation = alloc(deviations, FIRST_FRAME)?;
    for _ in 0..deviations {
        depth_deviation.push(r.f32()?);
    }
    r.finish()?;
    let frame = RgbdFrame {
        width,
        height,
        rgb,
        depth_m,
        depth_deviation,
    };
    frame
        .validate()
        .map_err(|e| SessionError::Corrupt(format!("{FIRST_FRAME}: {e}")))?;
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> RgbdFrame {
        RgbdFrame {
            width: 4,
            height: 3,
            rgb: (0..36).collect(),
            depth_m: (0..12).map(|i| 0.5 + i as f32 * 0.25).collect(),
            depth_deviation: Vec::new(),
        }
    }

    #[test]
    fn a_first_frame_comes_back_and_a_damaged_one_is_refused() {
        let mut bytes = Vec::new();
        write_first_frame(&mut bytes, &frame()).unwrap();
        assert_eq!(read_first_frame(&bytes[..], (4, 3)).unwrap(), frame());
        // Another camera's size.
        assert!(read_first_frame(&bytes[..], (3, 4)).is_err());
        // Cut short.
        assert!(read_first_frame(&bytes[..bytes.len() - 1], (4, 3)).is_err());
        // A depth that is not a number.
        let mut nan = frame();
        nan.depth_m[5] = f32::NAN;
        let mut bad = Vec::new();
        write_first_frame(&mut bad, &nan).unwrap();
        assert!(read_first_frame(&bad[..], (4, 3)).is_err());
        // Deviation factors for some pixels only.
        let mut some = frame();
        some.depth_deviation = vec![1.0; 5];
        let mut short = Vec::new();
        write_first_frame(&mut short, &some).unwrap();
        assert!(read_first_frame(&short[..], (4, 3)).is_err());
    }
}
