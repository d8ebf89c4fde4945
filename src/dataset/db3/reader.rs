//! [`RealSenseDb3`]: a ROS2 bag opened from any `Read + Seek` (a file),
//! scanned once, then read frame by frame: each frame's depth and colour
//! messages are looked up by row id, their PNGs decoded by the project's
//! decoder and the colour registered to the depth by the ROS1 reader's
//! [`crate::dataset::rosbag::Registration`].

use std::io::{Read, Seek};

use super::cdr::compressed_head;
use super::scan::{png_encoding, png_offset, scan, Db3Recording};
use super::sqlite::{record, Sqlite, Value};
use super::Db3Error;
use crate::dataset::rosbag::RawFrame;
use crate::frame::{decode_colour_into, decode_depth_raw};

/// A RealSense `.db3` opened for reading; see the module documentation.
pub struct RealSenseDb3<R> {
    db: Sqlite<R>,
    messages_root: u32,
    recording: Db3Recording,
    colour: Vec<u8>,
    scratch: Vec<u8>,
}

impl<R: Read + Seek> RealSenseDb3<R> {
    /// Reads the file's header and scans its `topics` and `messages`
    /// tables (each message's first bytes only).
    pub fn open(reader: R) -> Result<Self, Db3Error> {
        let mut db = Sqlite::open(reader)?;
        let scanned = scan(&mut db)?;
        Ok(Self {
            db,
            messages_root: scanned.messages_root,
            recording: scanned.recording,
            colour: Vec::new(),
            scratch: Vec::new(),
        })
    }

    /// What the recording holds.
    #[must_use]
    pub fn recording(&self) -> &Db3Recording {
        &self.recording
    }

    /// The PNG of the CompressedImage in row `rowid` of `messages`.
    fn png(&mut self, rowid: i64, topic: &str) -> Result<Vec<u8>, Db3Error> {
        let bad = |reason: String| Db3Error::Message {
            topic: topic.to_owned(),
            reason,
        };
        let payload = self
            .db
            .row(self.messages_root, rowid)?
            .ok_or_else(|| bad(format!("no message row {rowid}")))?;
        let values = record(&payload).map_err(bad)?;
        let Some(Value::Blob { bytes, full_len }) = values.get(3) else {
            return Err(bad(format!("message row {rowid} holds no data")));
        };
        if bytes.len() as u64 != *full_len {
            return Err(bad(format!("message row {rowid} is cut short")));
        }
        let head = compressed_head(bytes, topic)?;
        png_encoding(&head.format, topic)?;
        let start = head.data_offset + png_offset(&head.format);
        let end = head.data_offset.checked_add(head.data_len);
        end.and_then(|end| bytes.get(start..end))
            .map(<[u8]>::to_vec)
            .ok_or_else(|| bad("its image data run past the message".to_owned()))
    }

    /// Frame `index` ([`Db3Recording::frames`]): its depth, and with
    /// `with_colour` its colour registered to the depth (when one is paired).
    pub fn read_frame(&mut self, index: usize, with_colour: bool) -> Result<RawFrame, Db3Error> {
        let frames = self.recording.frames.len();
        let frame = *self.recording.frames.get(index).ok_or(Db3Error::Recording(
            crate::dataset::rosbag::RosbagError::NoSuchFrame { index, frames },
        ))?;
        let depth_topic = self.recording.depth_topic.clone();
        let camera = self.recording.depth;
        let png = self.png(frame.depth, &depth_topic)?;
        let decode = |topic: &str, e: crate::frame::FrameError| Db3Error::Message {
            topic: topic.to_owned(),
            reason: e.to_string(),
        };
        let (w, h, depth) = decode_depth_raw(&png).map_err(|e| decode(&depth_topic, e))?;
        same_size((w, h), (camera.width, camera.height), &depth_topic)?;
        let mut out = RawFrame {
            width: w,
            height: h,
            depth,
            rgb: Vec::new(),
        };
        let colour = self.recording.colour.clone();
        if let (true, Some((_, rowid)), Some((topic, registration))) =
            (with_colour, frame.colour, colour)
        {
            let png = self.png(rowid, &topic)?;
            let size = decode_colour_into(&png, &mut self.colour, &mut self.scratch)
                .map_err(|e| decode(&topic, e))?;
            let c = &registration.colour;
            same_size(size, (c.width, c.height), &topic)?;
            registration.register(
                &out.depth,
                self.recording.depth_units_m,
                &self.colour,
                &mut out.rgb,
            );
        }
        Ok(out)
    }
}

/// Refuses an image whose size is not its stream's.
fn same_size(found: (usize, usize), stream: (usize, usize), topic: &str) -> Result<(), Db3Error> {
    if found == stream {
        return Ok(());
    }
    Err(Db3Error::Message {
        topic: topic.to_owned(),
        reason: format!(
            "an image of {}x{} in a stream of {}x{}",
            found.0, found.1, stream.0, stream.1
        ),
    })
}
