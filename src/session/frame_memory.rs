//! `last_frame.bin`: what later frames remember of the last fused frame.
//! The sparse estimator matches the next frames against it, and the model
//! prediction the next frame is tracked against is rendered again from it
//! on loading; with the photometric term on the last frame, also that
//! term's reference pixels. `lost_frame.bin`, in the same format without
//! photometric references: while a restarted segment is not joined, the
//! last frame placed before the loss (optional). Little-endian: `u64` width and height (working
//! resolution; 0 and 0 before the first frame), RGB8 per pixel, 3 `f32`
//! per pixel (camera-frame point, metres; 0 = no depth); `u64` pyramid
//! levels, per level `u64` count and per pixel 4 `f32` (point, world frame,
//! metres; grey level 0..255).

use super::binary::{alloc, put_f32, put_u64, LeReader};
use super::SessionError;
use crate::pipeline::LastFusedFrame;
use crate::track::rgb::ReferencePoint;
use glam::Vec3;
use std::io::{Read, Write};

/// The last fused frame's entry.
pub(super) const LAST_FRAME: &str = "last_frame.bin";

/// The last frame placed before a loss that restarted the map.
pub(super) const LOST_FRAME: &str = "lost_frame.bin";

/// The last fused frame and the photometric references, owned.
pub(super) type FrameMemory = (
    Option<LastFusedFrame<Vec<u8>, Vec<Vec3>>>,
    Vec<Vec<ReferencePoint>>,
);

/// Writes the last fused frame (if any) and the photometric references.
pub(super) fn write_frame_memory(
    out: &mut dyn Write,
    last: Option<&LastFusedFrame<&[u8], &[Vec3]>>,
    photometric: &[&[ReferencePoint]],
) -> std::io::Result<()> {
    let (w, h) = last.map_or((0, 0), |l| (l.width, l.height));
    put_u64(out, w as u64)?;
    put_u64(out, h as u64)?;
    if let Some(l) = last {
        out.write_all(l.rgb)?;
        for p in l.vertices {
            for v in p.to_array() {
                put_f32(out, v)?;
            }
        }
    }
    put_u64(out, photometric.len() as u64)?;
    for level in photometric {
        put_u64(out, level.len() as u64)?;
        for r in *level {
            for v in r.point_in_world.to_array() {
                put_f32(out, v)?;
            }
            put_f32(out, r.intensity)?;
        }
    }
    Ok(())
}

/// Reads what [`write_frame_memory`] wrote to entry `name` for a working
/// image of at most `max_pixels`.
pub(super) fn read_frame_memory(
    input: impl Read,
    (name, max_pixels): (&'static str, usize),
) -> Result<FrameMemory, SessionError> {
    let mut r = LeReader::new(input, name);
    let width = r.count(max_pixels, "pixels wide")?;
    let height = r.count(max_pixels, "pixels high")?;
    let pixels = width * height;
    if pixels > max_pixels {
        return Err(SessionError::Corrupt(format!(
            "{name}: a {width}x{height} frame for a camera of {max_pixels} pixels"
        )));
    }
    let last = if pixels == 0 {
        None
    } else {
        let rgb = r.u8s(3 * pixels)?;
        let mut vertices = alloc(pixels, name)?;
        for _ in 0..pixels {
            vertices.push(Vec3::new(r.f32()?, r.f32()?, r.f32()?));
        }
        if !vertices.iter().all(|v| v.is_finite()) {
            return Err(SessionError::Corrupt(format!(
                "{name}: a point is not finite"
            )));
        }
        Some(LastFusedFrame {
            rgb,
            vertices,
            width,
            height,
        })
    };
    let levels = r.count(8, "pyramid levels")?;
    let mut photometric = Vec::with_capacity(levels);
    for _ in 0..levels {
        let n = r.count(max_pixels, "reference pixels")?;
        let mut level = alloc(n, name)?;
        for _ in 0..n {
            level.push(ReferencePoint {
                point_in_world: Vec3::new(r.f32()?, r.f32()?, r.f32()?),
                intensity: r.f32()?,
            });
        }
        photometric.push(level);
    }
    r.finish()?;
    Ok((last, photometric))
}
