//! `keyframes.bin`: the fern keyframes that relocalisation and the global
//! loop check look frames up in, oldest first. Little-endian: `u64` count,
//! `u64` small-image width, height and fern count; then per keyframe
//! `u32` frame index, 12 `f64` (`world_from_camera`, row-major 3x4,
//! metres), `u64` block width and height (input pixels per small pixel),
//! then per small pixel `u8` red, green, blue, then `f32` mean depth per
//! small pixel, `f32` farthest depth per small pixel (metres, 0 = none),
//! then one `u8` code per fern (255 = no depth). The fern index is rebuilt
//! from the codes on loading.

use super::binary::{alloc, put_f32, put_f64, put_u32, put_u64, LeReader};
use super::poses::{pose_from_rows, pose_to_rows};
use super::SessionError;
use crate::loop_closure::ferns::{FernConfig, FernFrame, Keyframe, BAD_CODE};
use std::io::{Read, Write};

const NAME: &str = "keyframes.bin";

/// Writes `keyframes` (all of one small-image size, as a database holds them).
pub(super) fn write_keyframes(
    out: &mut dyn Write,
    keyframes: &[Keyframe],
    ferns: &FernConfig,
) -> std::io::Result<()> {
    put_u64(out, keyframes.len() as u64)?;
    for v in [ferns.width, ferns.height, ferns.ferns] {
        put_u64(out, v as u64)?;
    }
    for k in keyframes {
        let f = &k.frame;
        put_u32(out, k.frame_index)?;
        for v in pose_to_rows(&k.world_from_camera) {
            put_f64(out, v)?;
        }
        put_u64(out, f.block.0 as u64)?;
        put_u64(out, f.block.1 as u64)?;
        for c in &f.rgb {
            out.write_all(c)?;
        }
        for &d in f.depth_m.iter().chain(&f.far_m) {
            put_f32(out, d)?;
        }
        out.write_all(&f.codes)?;
    }
    Ok(())
}

/// Reads the `expected` keyframes of a database configured as `ferns`.
pub(super) fn read_keyframes(
    input: impl Read,
    expected: usize,
    ferns: &FernConfig,
) -> Result<Vec<Keyframe>, SessionError> {
    let mut r = LeReader::new(input, NAME);
    let count = r.count(ferns.max_keyframes, "keyframes")?;
    let size = (r.u64()?, r.u64()?, r.u64()?);
    if count != expected || size != (ferns.width as u64, ferns.height as u64, ferns.ferns as u64) {
        return Err(SessionError::Corrupt(format!(
            "{NAME}: {count} keyframes of {size:?} (width, height, ferns) where the manifest says {expected} of {:?}",
            (ferns.width, ferns.height, ferns.ferns)
        )));
    }
    let pixels = ferns.width * ferns.height;
    let mut keyframes = alloc(count, NAME)?;
    for _ in 0..count {
        let frame_index = r.u32()?;
        let mut rows = [0.0; 12];
        for v in &mut rows {
            *v = r.f64()?;
        }
        let block = (
            r.count(1 << 16, "pixels per block")?,
            r.count(1 << 16, "pixels per block")?,
        );
        let rgb = r.u8s(3 * pixels)?;
        let mut depths = alloc(2 * pixels, NAME)?;
        for _ in 0..2 * pixels {
            depths.push(r.f32()?);
        }
        let far_m = depths.split_off(pixels);
        let codes = r.u8s(ferns.ferns)?;
        let good = codes.iter().filter(|&&c| c != BAD_CODE).count();
        keyframes.push(Keyframe {
            frame_index,
            world_from_camera: pose_from_rows(&rows),
            frame: FernFrame {
                width: ferns.width,
                height: ferns.height,
                block,
                rgb: rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                depth_m: depths,
                far_m,
                codes,
                good,
            },
        });
    }
    r.finish()?;
    Ok(keyframes)
}
