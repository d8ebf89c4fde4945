//! An Azure Kinect recording's frames: the `DEPTH` track (`b16g`: 16-bit
//! big-endian millimetres) undistorted to a pinhole image of the depth
//! mode's intrinsics (each pixel takes the nearest distorted pixel, as
//! tracking assumes a pinhole camera), and the `COLOR` track (`MJPG`)
//! registered to it: each depth pixel back-projected, moved into the
//! colour camera by `calibration.json`'s extrinsics, projected with its
//! distortion, sampled bilinearly. Colour pairs with the depth frame
//! nearest in time within half a frame period.

use std::io::{Read, Seek, SeekFrom};

use glam::DVec3;

use super::calibration::{camera, AzureCamera, Purpose};
use super::structure::{Block, MkvFile, Track};
use super::MkvError;
use crate::dataset::rosbag::RawFrame;
use crate::dataset::DEPTH_ONLY_GREY;

/// One frame: a depth image and, if paired, a colour image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MkvFrame {
    /// The depth block's time, seconds from the recording's start.
    pub time_s: f64,
    /// The depth block.
    pub depth: Block,
    /// The colour block nearest in time, if within half a frame period.
    pub colour: Option<Block>,
}

/// An Azure Kinect `.mkv` opened for reading frames; see the module
/// documentation.
pub struct AzureRecording<R> {
    reader: R,
    /// The depth camera in the recorded mode (its pinhole part drives tracking).
    pub depth: AzureCamera,
    /// The colour camera, when the file has a colour track.
    pub colour: Option<AzureCamera>,
    /// The frames in time order.
    pub frames: Vec<MkvFrame>,
    /// What did not stop the recording (cut short, frames without colour).
    pub warnings: Vec<MkvError>,
    /// For each pixel of the undistorted depth image, its pixel in the
    /// recorded one (`u32::MAX`: none).
    undistort: Vec<u32>,
}

fn track<'a>(file: &'a MkvFile, name: &str) -> Option<&'a Track> {
    file.tracks.iter().find(|t| t.name == name)
}

impl<R: Read + Seek> AzureRecording<R> {
    /// Reads the file's structure and calibration. Errors: no depth track,
    /// no depth frame, no calibration, a colour format not read.
    pub fn open(mut reader: R) -> Result<Self, MkvError> {
        reader
            .seek(SeekFrom::Start(0))
            .map_err(|e| MkvError::Io(e.to_string()))?;
        let file = MkvFile::read(&mut reader)?;
        let mut warnings: Vec<MkvError> = file
            .cut_off
            .clone()
            .map(MkvError::CutShort)
            .into_iter()
            .collect();
        let Some(depth_track) =
            track(&file, "DEPTH").filter(|t| t.fourcc.as_deref() == Some("b16g"))
        else {
            let found: Vec<String> = file
                .tracks
                .iter()
                .map(|t| format!("{} ({})", t.name, t.fourcc.as_deref().unwrap_or(&t.codec)))
                .collect();
            return Err(MkvError::NoDepthTrack { tracks: found });
        };
        let (w, h) = depth_track.size.unwrap_or((0, 0));
        let json = file
            .attachments
            .iter()
            .find(|(name, _)| name == "calibration.json")
            .map(|(_, bytes)| bytes.as_slice())
            .ok_or_else(|| MkvError::Calibration("no calibration.json attached".to_owned()))?;
        let depth = camera(json, Purpose::Depth, w as usize, h as usize)?;
        let colour_track = track(&file, "COLOR");
        let colour = match colour_track {
            Some(t) if t.fourcc.as_deref() == Some("MJPG") => {
                let (cw, ch) = t.size.unwrap_or((0, 0));
                Some((
                    t.number,
                    camera(json, Purpose::Colour, cw as usize, ch as usize)?,
                ))
            }
            Some(t) => {
                return Err(MkvError::UnsupportedFormat {
                    track: t.name.clone(),
                    format: t.fourcc.clone().unwrap_or_else(|| t.codec.clone()),
                })
            }
            None => None,
        };
        let no_blocks = Vec::new();
        let depth_blocks = file.blocks.get(&depth_track.number).unwrap_or(&no_blocks);
        if depth_blocks.is_empty() {
            return Err(MkvError::NoFrames);
        }
        let colour_blocks = colour
            .as_ref()
            .and_then(|(n, _)| file.blocks.get(n))
            .unwrap_or(&no_blocks);
        let frames = pair(depth_blocks, colour_blocks);
        let unpaired = frames.iter().filter(|f| f.colour.is_none()).count();
        if colour.is_some() && unpaired > 0 {
            warnings.push(MkvError::FramesWithoutColour {
                unpaired,
                frames: frames.len(),
            });
        }
        let undistort = undistortion(&depth);
        Ok(Self {
            reader,
            depth,
            colour: colour.map(|(_, c)| c),
            frames,
            warnings,
            undistort,
        })
    }

    fn payload(
        &mut self,
        block: Block,
        expected: Option<u64>,
        what: &str,
    ) -> Result<Vec<u8>, MkvError> {
        let limit = expected.unwrap_or(64 << 20);
        if block.len > limit {
            return Err(MkvError::Image {
                track: what.to_owned(),
                reason: format!("a block of {} bytes (expected {limit})", block.len),
            });
        }
        if expected.is_some_and(|e| e != block.len) {
            return Err(MkvError::Image {
                track: what.to_owned(),
                reason: format!("a block of {} bytes, not {limit}", block.len),
            });
        }
        self.reader
            .seek(SeekFrom::Start(block.pos))
            .map_err(|e| MkvError::Io(e.to_string()))?;
        let mut out = vec![0u8; block.len as usize];
        self.reader
            .read_exact(&mut out)
            .map_err(|e| MkvError::Io(e.to_string()))?;
        Ok(out)
    }

    /// Frame `index`: its depth undistorted (millimetres, 0 = none) and,
    /// with `with_colour`, its colour registered to it (empty without).
    pub fn read_frame(&mut self, index: usize, with_colour: bool) -> Result<RawFrame, MkvError> {
        let frames = self.frames.len();
        let frame = *self
            .frames
            .get(index)
            .ok_or(MkvError::NoSuchFrame { index, frames })?;
        let (w, h) = (self.depth.width, self.depth.height);
        let bytes = self.payload(frame.depth, Some(2 * (w * h) as u64), "DEPTH")?;
        let recorded: Vec<u16> = bytes
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect();
        let depth: Vec<u16> = self
            .undistort
            .iter()
            .map(|&i| recorded.get(i as usize).copied().unwrap_or(0))
            .collect();
        let mut out = RawFrame {
            width: w,
            height: h,
            depth,
            rgb: Vec::new(),
        };
        if let (true, Some(block), Some(colour)) = (with_colour, frame.colour, self.colour) {
            let jpeg = self.payload(block, None, "COLOR")?;
            let image = image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg)
                .map_err(|e| MkvError::Image {
                    track: "COLOR".to_owned(),
                    reason: format!("not a readable JPEG: {e}"),
                })?
                .into_rgb8();
            if (image.width() as usize, image.height() as usize) != (colour.width, colour.height) {
                return Err(MkvError::Image {
                    track: "COLOR".to_owned(),
                    reason: format!(
                        "a {}x{} image in a {}x{} track",
                        image.width(),
                        image.height(),
                        colour.width,
                        colour.height
                    ),
                });
            }
            out.rgb = register(&self.depth, &colour, &out.depth, image.as_raw());
        }
        Ok(out)
    }
}

/// Depth blocks in time order, each with the colour block nearest in time
/// within half the depth's median frame period (1/30 s with one frame).
fn pair(depth: &[Block], colour: &[Block]) -> Vec<MkvFrame> {
    let mut depth = depth.to_vec();
    depth.sort_by_key(|b| b.time_ns);
    let mut colour = colour.to_vec();
    colour.sort_by_key(|b| b.time_ns);
    // abs_diff: forged times must not overflow.
    let mut steps: Vec<u64> = depth
        .windows(2)
        .map(|w| w[1].time_ns.abs_diff(w[0].time_ns))
        .collect();
    steps.sort_unstable();
    let period = steps
        .get(steps.len() / 2)
        .copied()
        .filter(|s| *s > 0)
        .unwrap_or(33_333_333);
    depth
        .into_iter()
        .map(|d| {
            let i = colour.partition_point(|c| c.time_ns < d.time_ns);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|j| colour.get(j))
                .min_by_key(|c| c.time_ns.abs_diff(d.time_ns))
                .filter(|c| c.time_ns.abs_diff(d.time_ns) <= period / 2)
                .copied();
            MkvFrame {
                time_s: d.time_ns as f64 * 1e-9,
                depth: d,
                colour: nearest,
            }
        })
        .collect()
}

/// For each pixel of the pinhole depth image, the recorded (distorted)
/// pixel nearest where the depth camera sees its ray.
fn undistortion(depth: &AzureCamera) -> Vec<u32> {
    let (w, h) = (depth.width, depth.height);
    (0..w * h)
        .map(|i| {
            let (u, v) = ((i % w) as f64, (i / w) as f64);
            let ray = DVec3::new((u - depth.cx) / depth.fx, (v - depth.cy) / depth.fy, 1.0);
            depth
                .project(ray)
                .map(|(du, dv)| (du.round(), dv.round()))
                .filter(|&(du, dv)| du >= 0.0 && dv >= 0.0 && du < w as f64 && dv < h as f64)
                .map_or(u32::MAX, |(du, dv)| (dv as usize * w + du as usize) as u32)
        })
        .collect()
}

/// The colour (RGB8 at the depth's size) of each undistorted depth pixel
/// (`depth_mm`), sampled from `rgb` (the colour camera's image); grey where
/// the colour camera does not see it.
fn register(depth: &AzureCamera, colour: &AzureCamera, depth_mm: &[u16], rgb: &[u8]) -> Vec<u8> {
    let w = depth.width.max(1);
    let mut out = vec![DEPTH_ONLY_GREY; 3 * depth_mm.len()];
    let (sum, n) = depth_mm
        .iter()
        .filter(|&&d| d > 0)
        .fold((0.0, 0usize), |(s, n), &d| (s + f64::from(d), n + 1));
    let mean_m = if n > 0 { sum / n as f64 * 1e-3 } else { 1.0 };
    for (i, (&d, px)) in depth_mm.iter().zip(out.chunks_exact_mut(3)).enumerate() {
        let z = if d > 0 { f64::from(d) * 1e-3 } else { mean_m };
        let (u, v) = ((i % w) as f64, (i / w) as f64);
        let p = DVec3::new(
            (u - depth.cx) / depth.fx * z,
            (v - depth.cy) / depth.fy * z,
            z,
        );
        if let Some((cu, cv)) = colour.project(colour.from_depth.transform_point3(p)) {
            if let Some(c) =
                crate::dataset::rosbag::sample_bilinear(rgb, colour.width, colour.height, cu, cv)
            {
                px.copy_from_slice(&c);
            }
        }
    }
    out
}
