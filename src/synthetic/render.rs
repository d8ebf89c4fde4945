//! Rendering a [`Scene`] into an RGB-D frame (exact depth, noise, holes,
//! 16-bit quantisation) and encoding it as PNG.

use std::io::Cursor;

use glam::{DAffine3, Vec3};
use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, Rgb};
use rayon::prelude::*;
use thiserror::Error;

use super::noise::{is_depth_edge, row_seed, sanitise, NoiseModel, NoiseStream};
use super::raycast::Prepared;
use super::scene::Scene;
use crate::camera::Intrinsics;
use crate::frame::{Channel, DepthSettings, FrameError, RgbdFrame};

/// Raw depth units per metre of [`RenderedFrame::depth_raw`] (TUM / ICL-NUIM convention).
pub const DEPTH_UNITS_PER_METRE: f32 = 5000.0;

/// How rendered raw depth reads back: [`DEPTH_UNITS_PER_METRE`], valid
/// from 0.3 to 8 m (the room's far corners lie within 8 m of any pose).
#[must_use]
pub const fn depth_settings() -> DepthSettings {
    DepthSettings {
        scale: DEPTH_UNITS_PER_METRE,
        min_m: 0.3,
        max_m: 8.0,
        invalid_raw: None,
    }
}

/// Why a rendered frame could not be encoded.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SyntheticError {
    /// PNG encoding failed (or the buffers do not match the size).
    #[error("{channel} PNG could not be encoded: {message}")]
    Encode {
        /// Colour or depth.
        channel: Channel,
        /// What went wrong.
        message: String,
    },
}

/// One rendered RGB-D frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderedFrame {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Colour, RGB8 interleaved, row-major (`3 * width * height`), noise included.
    pub rgb: Vec<u8>,
    /// Raw depth, [`DEPTH_UNITS_PER_METRE`] units per metre, 0 = hole; noise and holes included.
    pub depth_raw: Vec<u16>,
    /// Exact ray-cast z-depth in metres before noise and holes, 0 where no surface was hit.
    pub depth_m: Vec<f32>,
}

impl RenderedFrame {
    /// Converts to an [`RgbdFrame`] through [`RgbdFrame::from_raw`] (raw depth, so noise and holes included).
    pub fn to_frame(&self, settings: &DepthSettings) -> Result<RgbdFrame, FrameError> {
        RgbdFrame::from_raw(
            self.width,
            self.height,
            &self.rgb,
            &self.depth_raw,
            settings,
        )
    }

    /// Encodes as (colour RGB8 PNG, depth 16-bit grey PNG), as a dataset would store them.
    pub fn to_png_bytes(&self) -> Result<(Vec<u8>, Vec<u8>), SyntheticError> {
        let size = |channel| {
            let w = u32::try_from(self.width);
            let h = u32::try_from(self.height);
            match (w, h) {
                (Ok(w), Ok(h)) => Ok((w, h)),
                _ => Err(SyntheticError::Encode {
                    channel,
                    message: format!("size {}x{} too large", self.width, self.height),
                }),
            }
        };
        let (w, h) = size(Channel::Colour)?;
        let mismatch = |channel| SyntheticError::Encode {
            channel,
            message: format!("buffer length does not match {w}x{h}"),
        };
        let colour = ImageBuffer::<Rgb<u8>, Vec<u8>>::from_raw(w, h, self.rgb.clone())
            .ok_or_else(|| mismatch(Channel::Colour))?;
        let depth = ImageBuffer::<Luma<u16>, Vec<u16>>::from_raw(w, h, self.depth_raw.clone())
            .ok_or_else(|| mismatch(Channel::Depth))?;
        let encode = |img: DynamicImage, channel| {
            let mut out = Cursor::new(Vec::new());
            img.write_to(&mut out, ImageFormat::Png)
                .map_err(|e| SyntheticError::Encode {
                    channel,
                    message: e.to_string(),
                })?;
            Ok(out.into_inner())
        };
        Ok((
            encode(DynamicImage::ImageRgb8(colour), Channel::Colour)?,
            encode(DynamicImage::ImageLuma16(depth), Channel::Depth)?,
        ))
    }

    /// Number of pixels with a raw depth measurement.
    #[must_use]
    pub fn valid_depth_count(&self) -> usize {
        self.depth_raw.iter().filter(|&&r| r > 0).count()
    }
}

/// Renders `scene` from `world_from_camera` with `intrinsics` and `noise`.
/// Deterministic: the same arguments give the same frame on every platform and
/// thread count. Intrinsics with an empty size or a side above 16384 pixels
/// give an empty 0x0 frame.
#[must_use]
pub fn render(
    scene: &Scene,
    intrinsics: &Intrinsics,
    world_from_camera: &DAffine3,
    noise: &NoiseModel,
    seed: u64,
) -> RenderedFrame {
    let mut frame = RenderedFrame::default();
    render_into(
        &mut frame,
        scene,
        intrinsics,
        world_from_camera,
        noise,
        seed,
    );
    frame
}

/// As [`render`], reusing `frame`'s buffers (no allocation once sized).
pub fn render_into(
    frame: &mut RenderedFrame,
    scene: &Scene,
    intrinsics: &Intrinsics,
    world_from_camera: &DAffine3,
    noise: &NoiseModel,
    seed: u64,
) {
    let (w, h) = (intrinsics.width, intrinsics.height);
    let size_ok = (1..=16384).contains(&w) && (1..=16384).contains(&h);
    let (w, h) = if size_ok { (w, h) } else { (0, 0) };
    let n = w * h;
    frame.width = w;
    frame.height = h;
    frame.rgb.resize(3 * n, 0);
    frame.depth_raw.resize(n, 0);
    frame.depth_m.resize(n, 0.0);
    if n == 0 {
        return;
    }

    let prepared = Prepared::new(scene, world_from_camera.translation);
    let rot = world_from_camera.matrix3.as_mat3();
    let k = *intrinsics;
    let colour_sigma = sanitise(noise.colour_sigma);

    // Pass 1: ray-cast exact depth and colour.
    frame
        .depth_m
        .par_chunks_mut(w)
        .zip(frame.rgb.par_chunks_mut(3 * w))
        .enumerate()
        .for_each(|(v, (depth_row, rgb_row))| {
            let mut rng = NoiseStream::new(row_seed(seed, v, 0x00C0_10E5));
            let y = (v as f32 - k.cy) / k.fy;
            let row_dir = rot * Vec3::new(0.0, y, 1.0);
            for (u, (depth, rgb)) in depth_row
                .iter_mut()
                .zip(rgb_row.chunks_exact_mut(3))
                .enumerate()
            {
                let dir = row_dir + rot.x_axis * ((u as f32 - k.cx) / k.fx);
                let (z, colour) = match prepared.cast(dir) {
                    Some(hit) => (hit.t, prepared.shade(&hit)),
                    None => (0.0, [0.0; 3]),
                };
                *depth = if z.is_finite() { z } else { 0.0 };
                for (out, c) in rgb.iter_mut().zip(colour) {
                    let c = if colour_sigma > 0.0 {
                        c + colour_sigma * rng.gaussian()
                    } else {
                        c
                    };
                    *out = (c.clamp(0.0, 255.0) + 0.5) as u8;
                }
            }
        });

    // Pass 2: depth noise, holes and quantisation.
    let depth_m = &frame.depth_m;
    let sigma1 = sanitise(noise.depth_sigma_at_1m);
    let holes = sanitise(noise.hole_fraction);
    let edge_holes = noise.edge_holes;
    frame
        .depth_raw
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(v, raw_row)| {
            // One stream per noise source, one draw per pixel: turning one
            // source on or off does not reshuffle the others.
            let mut hole_rng = NoiseStream::new(row_seed(seed, v, 0x0401_E500));
            let mut depth_rng = NoiseStream::new(row_seed(seed, v, 0xDE97_4000));
            let row = &depth_m[v * w..(v + 1) * w];
            for (u, raw) in raw_row.iter_mut().enumerate() {
                let z = row[u];
                let dropout = holes > 0.0 && hole_rng.next_f32() < holes;
                let gauss = if sigma1 > 0.0 {
                    depth_rng.gaussian()
                } else {
                    0.0
                };
                if z <= 0.0 || dropout || (edge_holes && is_depth_edge(depth_m, w, h, u, v)) {
                    *raw = 0;
                    continue;
                }
                let noisy = z + sigma1 * z * z * gauss;
                let units = (noisy * DEPTH_UNITS_PER_METRE).round();
                *raw = if units >= 1.0 {
                    units.min(f32::from(u16::MAX)) as u16
                } else {
                    0
                };
            }
        });
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::synthetic::test_support::{settings, small};
    use crate::synthetic::trajectory_pose;

    #[test]
    fn png_round_trip_keeps_depth() {
        let scene = Scene::room();
        let k = small();
        let f = render(&scene, &k, &trajectory_pose(5), &NoiseModel::kinect(), 11);
        let (colour, depth) = f.to_png_bytes().expect("encodes");
        let decoded = RgbdFrame::from_png_bytes(&colour, &depth, &settings()).expect("decodes");
        let direct = f.to_frame(&settings()).expect("valid");
        assert_eq!(decoded, direct);
        assert_eq!(decoded.rgb, f.rgb);
        for (&d, &raw) in decoded.depth_m.iter().zip(&f.depth_raw) {
            assert_eq!(d, settings().to_metres(raw));
        }
        for (&d, &exact) in direct.depth_m.iter().zip(&f.depth_m) {
            assert!(d == 0.0 || (d - exact).abs() < 6e-3 * exact * exact + 2e-4);
        }
    }

    #[test]
    fn odd_arguments_do_not_panic() {
        let scene = Scene::room();
        let pose = trajectory_pose(0);
        let empty = render(
            &scene,
            &Intrinsics::new(1.0, 1.0, 0.0, 0.0, 0, 10),
            &pose,
            &NoiseModel::kinect(),
            0,
        );
        assert_eq!((empty.width, empty.height, empty.rgb.len()), (0, 0, 0));
        assert!(empty.to_frame(&settings()).is_err());
        let nan = Intrinsics::new(f32::NAN, 0.0, f32::INFINITY, 1.0, 8, 4);
        let f = render(&scene, &nan, &pose, &NoiseModel::kinect(), 0);
        assert_eq!(f.depth_m.len(), 32);
        let noise = NoiseModel {
            depth_sigma_at_1m: f32::NAN,
            hole_fraction: -1.0,
            edge_holes: true,
            colour_sigma: f32::INFINITY,
        };
        let f = render(
            &scene,
            &small(),
            &DAffine3::from_translation(DVec3::splat(100.0)),
            &noise,
            0,
        );
        assert_eq!(
            f.valid_depth_count(),
            0,
            "outside the room nothing faces the camera"
        );
        let empty_scene = Scene { boxes: Vec::new() };
        let f = render(&empty_scene, &small(), &pose, &NoiseModel::none(), 0);
        assert!(f.depth_m.iter().all(|&z| z == 0.0));
        let bad = RenderedFrame {
            width: 4,
            height: 4,
            ..RenderedFrame::default()
        };
        assert!(bad.to_png_bytes().is_err());
    }
}
