//! `camera_fixed.bin`: what the mask of things that move with the camera
//! remembers ([`CameraFixedMask`]). Little-endian: `u64` grid step
//! (pixels), cells across and down, then per cell `f32` depth (metres,
//! 0 = none), `u8` grey and `u8` count of moving frames it stayed through,
//! then per cell `u8` 1 where the last frame was masked, else 0 (sessions
//! saved before that field decide it again from the counts). Sessions
//! saved before the entry existed have none: the mask starts afresh.

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
    out.write_all(still)?;
    let masked: Vec<u8> = mask.masked_cells().iter().map(|&m| u8::from(m)).collect();
    out.write_all(&masked)
}

/// Reads what [`write_camera_fixed`] wrote, for a working image of at
/// most `max_pixels`, with the mask deciding after `min_frames` moving
/// frames (`PreprocessConfig::camera_fixed_frames`).
pub(super) fn read_camera_fixed(
    input: impl Read,
    max_pixels: usize,
    min_frames: u8,
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
    let masked = r.rest()?;
    let mut mask = CameraFixedMask::from_parts(step, cols, rows, depth_m, grey, still)
        .ok_or_else(|| SessionError::Corrupt(format!("{NAME}: a depth is not finite")))?;
    if masked.is_empty() {
        mask.decide_mask_again(min_frames);
    } else if masked.len() != cells || masked.iter().any(|&m| m > 1) {
        return Err(SessionError::Corrupt(format!(
            "{NAME}: {} bytes of masked cells for {cells} cells, or one not 0 or 1",
            masked.len()
        )));
    } else {
        mask.set_masked(masked.iter().map(|&m| m == 1).collect());
    }
    Ok(mask)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20x15 grid 3 m away with a 6x6 part 0.4 m away that stayed
    /// through 10 moving frames, masked as `observe` would mask it.
    fn mask_with_a_part() -> CameraFixedMask {
        let (cols, rows) = (20, 15);
        let part =
            |c: usize| (c % cols) >= 12 && (c % cols) < 18 && (c / cols) >= 7 && (c / cols) < 13;
        let depth = (0..cols * rows)
            .map(|c| if part(c) { 0.4 } else { 3.0 })
            .collect();
        let still = (0..cols * rows)
            .map(|c| if part(c) { 10 } else { 0 })
            .collect();
        let mut mask =
            CameraFixedMask::from_parts(4, cols, rows, depth, vec![100; cols * rows], still)
                .expect("finite depths");
        mask.decide_mask_again(6);
        mask
    }

    fn written(mask: &CameraFixedMask) -> Vec<u8> {
        let mut bytes = Vec::new();
        write_camera_fixed(&mut bytes, mask).expect("written");
        bytes
    }

    #[test]
    fn which_cells_were_masked_comes_back_and_older_entries_decide_it_again() {
        let mask = mask_with_a_part();
        assert_eq!(mask.masked_count(), 36, "the part (its ring is far)");
        let bytes = written(&mask);
        let read = read_camera_fixed(&bytes[..], 10_000, 6).expect("read");
        assert_eq!(read.masked_cells(), mask.masked_cells());
        assert_eq!(read.masked_count(), mask.masked_count());
        // Without the last field (an older session): decided from the counts.
        let older = &bytes[..bytes.len() - 20 * 15];
        let read = read_camera_fixed(older, 10_000, 6).expect("read");
        assert_eq!(read.masked_cells(), mask.masked_cells());
        // A field of another length, or a value not 0 or 1, is corrupt.
        assert!(read_camera_fixed(&bytes[..bytes.len() - 1], 10_000, 6).is_err());
        let mut two = bytes.clone();
        if let Some(last) = two.last_mut() {
            *last = 2;
        }
        assert!(read_camera_fixed(&two[..], 10_000, 6).is_err());
    }
}
