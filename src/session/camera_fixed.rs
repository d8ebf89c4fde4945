//! `camera_fixed.bin`: what the mask of things that move with the camera
//! remembers ([`CameraFixedMask`]). Little-endian: `u64` grid step
//! (pixels), cells across and down, then per cell `f32` depth (metres,
//! 0 = none), `u8` grey and `u8` count of moving frames it stayed through.
//! Sessions saved before it existed have no such entry: the mask starts
//! afresh.

use super::binary::{put_f32, put_u64, LeReader};
use super::SessionError;
use crate::preprocess::camera_fixed::CameraFixedMask;
use std::io::{Read, Write};

const NAME: &str = "camera_fixed.bin";

/// Writes `mask`'s memory.
pub(super) fn write_camera_fixed(
    out: &mut dyn Write,
    mask: &CameraFixedMask,
) -> std::io::Result<()> {
    let (step, cols, rows, depth_m, grey, still) = mask.parts();
    put_u64(out, step as u64)?;
    put_u64(out, cols as u64)?;
    put_u64(out, rows as u64)?;
    for &z in depth_m {
        put_f32(out, z)?;
    }
    out.write_all(grey)?;
    out.write_all(still)
}

/// Reads what [`write_camera_fixed`] wrote, for a working image of at
/// most `max_pixels`.
pub(super) fn read_camera_fixed(
    input: impl Read,
    max_pixels: usize,
) -> Result<CameraFixedMask, SessionError> {
    let mut r = LeReader::new(input, NAME);
    let step = r.count(max_pixels, "pixels a cell")?;
    let cols = r.count(max_pixels, "cells across")?;
    let rows = r.count(max_pixels, "cells down")?;
    let cells = cols
        .checked_mul(rows)
        .filter(|&n| n <= max_pixels)
        .ok_or_else(|| {
            SessionError::Corrupt(format!(
                "{NAME}: {cols}x{rows} cells for {max_pixels} pixels"
            ))
        })?;
    let mut depth_m = Vec::with_capacity(cells);
    for _ in 0..cells {
        depth_m.push(r.f32()?);
    }
    let grey = r.u8s(cells)?;
    let still = r.u8s(cells)?;
    r.finish()?;
    CameraFixedMask::from_parts(step, cols, rows, depth_m, grey, still)
        .ok_or_else(|| SessionError::Corrupt(format!("{NAME}: a depth is not finite")))
}
