//! [`RealSenseBag`]: a recording opened from any `Read + Seek` (a file),
//! scanned once, then read frame by frame: each frame's depth and colour
//! messages are read from their chunks (the last chunk read is kept, so
//! messages that share a chunk decompress it once).

use std::io::{Read, Seek, SeekFrom};

use super::message::image_head;
use super::pixels::{colour_pixels, depth_pixels};
use super::recording::{Collected, Recording};
use super::scan::{read_chunk, scan, Location};
use super::RosbagError;

/// One frame as the pipeline takes it: raw depth and colour registered to
/// it, both at the depth camera's size (`Pipeline::push_raw`,
/// `RgbdFrame::from_raw`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RawFrame {
    /// Width, pixels (the depth camera's).
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Depth in the recording's units ([`Recording::depth_units_m`]), 0 = none, row-major.
    pub depth: Vec<u16>,
    /// Colour registered to the depth, RGB8 row-major; empty when the
    /// frame has no colour (read without, or none paired).
    pub rgb: Vec<u8>,
}

/// A RealSense `.bag` opened for reading; see the module documentation.
pub struct RealSenseBag<R> {
    reader: R,
    file_len: u64,
    recording: Recording,
    /// The last chunk read: its position and decompressed bytes.
    cached: Option<(u64, Vec<u8>)>,
    colour_scratch: Vec<u8>,
}

impl<R: Read + Seek> RealSenseBag<R> {
    /// Scans the bag (every chunk once, one in memory at a time) and finds
    /// the recording in it. An unfinished bag gives its complete chunks
    /// and a warning ([`RosbagError::Unfinished`] in
    /// [`Recording::warnings`]).
    pub fn open(mut reader: R) -> Result<Self, RosbagError> {
        let file_len = reader
            .seek(SeekFrom::End(0))
            .map_err(|e| RosbagError::Io(e.to_string()))?;
        let mut collected = Collected::default();
        let scanned = scan(&mut reader, file_len, |conn, location, data| {
            collected.visit(conn, location, data)
        })?;
        let recording = Recording::from_collected(collected);
        let mut recording = match (recording, &scanned.cut_off) {
            (Ok(r), _) => r,
            (Err(e), Some(cut_off)) => {
                return Err(RosbagError::CutShort {
                    source: Box::new(e),
                    cut_off: cut_off.clone(),
                })
            }
            (Err(e), None) => return Err(e),
        };
        if let Some(why) = scanned.cut_off {
            recording.warnings.insert(0, RosbagError::Unfinished(why));
        }
        Ok(Self {
            reader,
            file_len,
            recording,
            cached: None,
            colour_scratch: Vec::new(),
        })
    }

    /// What the recording holds.
    #[must_use]
    pub fn recording(&self) -> &Recording {
        &self.recording
    }

    /// The bytes of the message at `location`.
    fn message(&mut self, location: Location) -> Result<&[u8], RosbagError> {
        if self.cached.as_ref().map(|c| c.0) != Some(location.chunk_pos) {
            self.cached = None;
            let bytes = read_chunk(&mut self.reader, location.chunk_pos, self.file_len)?;
            self.cached = Some((location.chunk_pos, bytes));
        }
        let start = location.offset as usize;
        let end = start.checked_add(location.len as usize);
        self.cached
            .as_ref()
            .zip(end)
            .and_then(|((_, bytes), end)| bytes.get(start..end))
            .ok_or(RosbagError::Corrupt {
                offset: location.chunk_pos,
                reason: "a message past its chunk".to_owned(),
            })
    }

    /// Frame `index` ([`Recording::frames`]): its depth, and with
    /// `with_colour` its colour registered to the depth (when one is paired).
    pub fn read_frame(&mut self, index: usize, with_colour: bool) -> Result<RawFrame, RosbagError> {
        let frames = self.recording.frames.len();
        let frame = *self
            .recording
            .frames
            .get(index)
            .ok_or(RosbagError::NoSuchFrame { index, frames })?;
        let depth_topic = self.recording.depth_topic.clone();
        let depth_camera = self.recording.depth;
        let mut out = RawFrame {
            width: depth_camera.width,
            height: depth_camera.height,
            ..RawFrame::default()
        };
        let data = self.message(frame.depth)?;
        let head = image_head(data, &depth_topic)?;
        same_size(&head, out.width, out.height, &depth_topic)?;
        depth_pixels(&head, data, &depth_topic, &mut out.depth)?;
        let colour = self.recording.colour.clone();
        if let (true, Some((_, location)), Some((topic, registration))) =
            (with_colour, frame.colour, colour)
        {
            let data = self.message(location)?;
            let head = image_head(data, &topic)?;
            same_size(
                &head,
                registration.colour.width,
                registration.colour.height,
                &topic,
            )?;
            let mut rgb = std::mem::take(&mut self.colour_scratch);
            let data = self.message(location)?;
            let decoded = colour_pixels(&head, data, &topic, &mut rgb);
            if decoded.is_ok() {
                registration.register(&out.depth, self.recording.depth_units_m, &rgb, &mut out.rgb);
            }
            self.colour_scratch = rgb;
            decoded?;
        }
        Ok(out)
    }
}

/// Refuses an image whose size is not its stream's.
fn same_size(
    head: &super::message::ImageHead,
    width: usize,
    height: usize,
    topic: &str,
) -> Result<(), RosbagError> {
    if (head.width as usize, head.height as usize) == (width, height) {
        return Ok(());
    }
    Err(RosbagError::Message {
        topic: topic.to_owned(),
        reason: format!(
            "an image of {}x{} in a stream of {width}x{height}",
            head.width, head.height
        ),
    })
}
