//! The property test's inputs: pools of valid frames in the three forms
//! the pipeline takes (synthetic, or a real sequence read on demand), and
//! the garbage it must refuse.

use super::common::{shared_dataset, synthetic_config};
use std::io::Cursor;
use std::path::PathBuf;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{Intrinsics, RgbdFrame, SlamConfig};

/// One valid frame in the three forms the pipeline takes.
#[derive(Clone)]
pub struct Encoded {
    pub colour_png: Vec<u8>,
    pub depth_png: Vec<u8>,
    /// The colour decoded (RGB8), for `push_rgba_depth_png` and `push_raw`.
    pub rgb: Vec<u8>,
    /// The raw depth decoded, for `push_raw`.
    pub depth_raw: Vec<u16>,
    pub width: usize,
    pub height: usize,
    /// The frame decoded, for `push_frame`.
    pub frame: RgbdFrame,
}

/// Where a case's valid frames come from: a synthetic room rendered ahead,
/// or a real sequence read on demand.
pub enum Frames {
    Synthetic(Vec<Encoded>),
    Real { dir: PathBuf, sequence: Sequence },
}

pub struct Pool {
    pub name: &'static str,
    pub base: SlamConfig,
    pub frames: Frames,
    /// A small budget that the pool's frames reach within a few dozen frames.
    pub small_budget: (usize, usize),
}

impl Pool {
    pub fn len(&self) -> usize {
        match &self.frames {
            Frames::Synthetic(f) => f.len(),
            Frames::Real { sequence, .. } => sequence.frames.len(),
        }
    }

    pub fn frame(&self, i: usize) -> Encoded {
        match &self.frames {
            Frames::Synthetic(f) => f[i].clone(),
            Frames::Real { dir, sequence } => {
                let entry = &sequence.frames[i];
                let colour_png = std::fs::read(dir.join(entry.colour.as_deref().expect("colour")))
                    .expect("colour file");
                let depth_png = std::fs::read(dir.join(&entry.depth)).expect("depth file");
                let rgb = image::load_from_memory(&colour_png)
                    .expect("colour decodes")
                    .to_rgb8();
                let (width, height) = (rgb.width() as usize, rgb.height() as usize);
                let frame = read_frame(dir, entry, &self.base.depth).expect("frame decodes");
                let depth_raw = image::load_from_memory(&depth_png)
                    .expect("depth decodes")
                    .to_luma16()
                    .into_raw();
                Encoded {
                    colour_png,
                    depth_png,
                    rgb: rgb.into_raw(),
                    depth_raw,
                    width,
                    height,
                    frame,
                }
            }
        }
    }
}

pub fn encode_synthetic(
    k: &Intrinsics,
    config: &SlamConfig,
    pose: usize,
    noise: &NoiseModel,
) -> Encoded {
    let r = synthetic::render(
        &Scene::room(),
        k,
        &synthetic::trajectory_pose(pose),
        noise,
        pose as u64,
    );
    let (colour_png, depth_png) = r.to_png_bytes().expect("encode");
    Encoded {
        frame: r.to_frame(&config.depth).expect("frame"),
        colour_png,
        depth_png,
        width: r.width,
        height: r.height,
        rgb: r.rgb,
        depth_raw: r.depth_raw,
    }
}

/// The synthetic room at 160x120 (fast): every third pose of its path for
/// `n` frames (3-4 cm a frame), so that the map grows past what one frame
/// adds as new parts of the room come into view; Kinect-like noise.
pub fn synthetic_pool(n: usize) -> Pool {
    let k = synthetic::default_intrinsics().half().half();
    let base = synthetic_config(k);
    let noise = NoiseModel::kinect();
    let frames = (0..n)
        .map(|i| encode_synthetic(&k, &base, 3 * i, &noise))
        .collect();
    Pool {
        name: "synthetic 160x120",
        base,
        frames: Frames::Synthetic(frames),
        small_budget: (4_000, 20_000),
    }
}

pub fn real_pool(name: &'static str, folder: &str) -> Option<Pool> {
    let dir = shared_dataset(folder)?;
    let sequence = Sequence::open(&dir).expect("sequence opens");
    Some(Pool {
        name,
        base: SlamConfig::from_preset(sequence.preset),
        frames: Frames::Real { dir, sequence },
        small_budget: (60_000, 150_000),
    })
}

/// A frame no pool uses (96x72) and an 8-bit depth PNG of a pool's size.
pub struct Garbage {
    pub odd: Encoded,
}

pub fn png_8bit(width: usize, height: usize) -> Vec<u8> {
    let grey = image::GrayImage::from_pixel(width as u32, height as u32, image::Luma([100]));
    let mut out = Cursor::new(Vec::new());
    grey.write_to(&mut out, image::ImageFormat::Png)
        .expect("encode");
    out.into_inner()
}

/// A frame of a size no pool uses (96x72).
pub fn odd_frame() -> Garbage {
    let k = Intrinsics::new(78.75, 78.75, 47.5, 35.5, 96, 72);
    let config = synthetic_config(k);
    Garbage {
        odd: encode_synthetic(&k, &config, 0, &NoiseModel::none()),
    }
}
