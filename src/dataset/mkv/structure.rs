//! A Matroska file's structure, in one pass of element headers (block
//! data is not read): the tracks (number, name, codec, the FOURCC of a
//! `V_MS/VFW/FOURCC` video track, size), the attached files (Azure
//! Kinect's `calibration.json`), and every block's track, time and place.
//! A file cut short keeps the blocks of the clusters before the cut, with
//! one warning.

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom};

use super::ebml::{data, element, header as element_header, uint, vint_in, Element};
use super::MkvError;

/// Element IDs read here.
mod id {
    pub const EBML: u32 = 0x1A45_DFA3;
    pub const DOC_TYPE: u32 = 0x4282;
    pub const SEGMENT: u32 = 0x1853_8067;
    pub const INFO: u32 = 0x1549_A966;
    pub const TIMECODE_SCALE: u32 = 0x2A_D7B1;
    pub const TRACKS: u32 = 0x1654_AE6B;
    pub const TRACK_ENTRY: u32 = 0xAE;
    pub const TRACK_NUMBER: u32 = 0xD7;
    pub const NAME: u32 = 0x536E;
    pub const CODEC_ID: u32 = 0x86;
    pub const CODEC_PRIVATE: u32 = 0x63A2;
    pub const VIDEO: u32 = 0xE0;
    pub const PIXEL_WIDTH: u32 = 0xB0;
    pub const PIXEL_HEIGHT: u32 = 0xBA;
    pub const ATTACHMENTS: u32 = 0x1941_A469;
    pub const ATTACHED_FILE: u32 = 0x61A7;
    pub const FILE_NAME: u32 = 0x466E;
    pub const FILE_DATA: u32 = 0x465C;
    pub const CLUSTER: u32 = 0x1F43_B675;
    pub const TIMECODE: u32 = 0xE7;
    pub const SIMPLE_BLOCK: u32 = 0xA3;
    pub const BLOCK_GROUP: u32 = 0xA0;
    pub const BLOCK: u32 = 0xA1;
}

/// Largest attached file or codec private data kept, bytes.
const MAX_ATTACHMENT_BYTES: u64 = 16 << 20;
/// Largest small element (numbers, names) read, bytes.
const MAX_SMALL_BYTES: u64 = 4096;

/// A track of the file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Track {
    /// Its number, as blocks name it.
    pub number: u64,
    /// Its name (Azure Kinect: `COLOR`, `DEPTH`, `IR`, `IMU`).
    pub name: String,
    /// Its codec (`V_MS/VFW/FOURCC`, `S_K4A/IMU`).
    pub codec: String,
    /// A `V_MS/VFW/FOURCC` track's FOURCC (`MJPG`, `b16g`, `NV12`, `YUY2`,
    /// `BGRA`), from its BITMAPINFOHEADER.
    pub fourcc: Option<String>,
    /// A video track's size, pixels.
    pub size: Option<(u64, u64)>,
}

/// A block: one frame (or sample) of a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Block {
    /// Its time, nanoseconds (cluster time plus the block's, scaled).
    pub time_ns: i64,
    /// Where its payload starts, bytes from the file's start.
    pub pos: u64,
    /// Its payload's length, bytes.
    pub len: u64,
}

/// What a Matroska file holds; see the module documentation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MkvFile {
    /// Nanoseconds per timecode unit (1 000 000 by default).
    pub timecode_scale_ns: u64,
    /// The tracks.
    pub tracks: Vec<Track>,
    /// The attached files: name and bytes.
    pub attachments: Vec<(String, Vec<u8>)>,
    /// Each track's blocks in file order, by track number.
    pub blocks: BTreeMap<u64, Vec<Block>>,
    /// Why the file's end was not read (cut short), one warning.
    pub cut_off: Option<String>,
}

impl MkvFile {
    /// Reads the structure of a Matroska file (`Read + Seek`); errors name
    /// what is wrong, a file cut in its clusters keeps what came before.
    pub fn read<R: Read + Seek>(mut r: R) -> Result<Self, MkvError> {
        let file_len = r
            .seek(SeekFrom::End(0))
            .map_err(|e| MkvError::Io(e.to_string()))?;
        let header = element(&mut r, 0, file_len).map_err(|_| MkvError::NotMatroska)?;
        if header.id != id::EBML {
            return Err(MkvError::NotMatroska);
        }
        let end = header.end(file_len);
        let doc_type = children(&mut r, &header, end, file_len)?
            .into_iter()
            .find(|e| e.id == id::DOC_TYPE)
            .map(|e| data(&mut r, &e, MAX_SMALL_BYTES))
            .transpose()?;
        if !matches!(doc_type.as_deref(), Some(b"matroska" | b"webm")) {
            return Err(MkvError::NotMatroska);
        }
        let mut out = Self {
            timecode_scale_ns: 1_000_000,
            ..Self::default()
        };
        let segment = element_header(&mut r, end, file_len)?;
        if segment.id != id::SEGMENT {
            return Err(MkvError::Corrupt {
                offset: end,
                reason: "no Segment after the EBML header".to_owned(),
            });
        }
        let segment_end = segment.end(file_len).min(file_len);
        let mut pos = segment.data_pos;
        while pos < segment_end {
            let e = match element(&mut r, pos, file_len) {
                Ok(e) => e,
                Err(err) => {
                    out.cut_off = Some(format!(
                        "the file is cut short at byte {pos} of {file_len} ({err}): \
                         the blocks before are read"
                    ));
                    break;
                }
            };
            let Some(size) = e.size else {
                return Err(MkvError::Corrupt {
                    offset: pos,
                    reason: format!("element {:#x} of unknown size in the segment", e.id),
                });
            };
            let read = match e.id {
                id::INFO => out.info(&mut r, &e, file_len),
                id::TRACKS => out.tracks(&mut r, &e, file_len),
                id::ATTACHMENTS => out.attachments(&mut r, &e, file_len),
                id::CLUSTER => out.cluster(&mut r, &e, file_len),
                _ => Ok(()),
            };
            if let Err(err) = read {
                if e.id != id::CLUSTER {
                    return Err(err);
                }
                out.cut_off = Some(format!(
                    "the cluster at byte {pos} of {file_len} is cut short or damaged ({err}): \
                     the blocks before it are read"
                ));
                break;
            }
            pos = e.data_pos + size;
        }
        if out.cut_off.is_none()
            && segment
                .size
                .is_some_and(|s| s > file_len - segment.data_pos)
        {
            out.cut_off = Some(format!(
                "the file is cut short: its segment ends past its {file_len} bytes"
            ));
        }
        Ok(out)
    }

    fn info<R: Read + Seek>(
        &mut self,
        r: &mut R,
        e: &Element,
        file_len: u64,
    ) -> Result<(), MkvError> {
        for c in children(r, e, e.end(file_len), file_len)? {
            if c.id == id::TIMECODE_SCALE {
                let scale = uint(&data(r, &c, MAX_SMALL_BYTES)?);
                if scale == 0 {
                    return Err(MkvError::Corrupt {
                        offset: c.data_pos,
                        reason: "a timecode scale of 0".to_owned(),
                    });
                }
                self.timecode_scale_ns = scale;
            }
        }
        Ok(())
    }

    fn tracks<R: Read + Seek>(
        &mut self,
        r: &mut R,
        e: &Element,
        file_len: u64,
    ) -> Result<(), MkvError> {
        for entry in children(r, e, e.end(file_len), file_len)? {
            if entry.id != id::TRACK_ENTRY {
                continue;
            }
            let mut track = Track::default();
            for c in children(r, &entry, entry.end(file_len), file_len)? {
                let text = |r: &mut R| -> Result<String, MkvError> {
                    Ok(String::from_utf8_lossy(&data(r, &c, MAX_SMALL_BYTES)?).into_owned())
                };
                match c.id {
                    id::TRACK_NUMBER => track.number = uint(&data(r, &c, MAX_SMALL_BYTES)?),
                    id::NAME => track.name = text(r)?,
                    id::CODEC_ID => track.codec = text(r)?,
                    id::CODEC_PRIVATE => {
                        // A BITMAPINFOHEADER: biCompression (the FOURCC) at byte 16.
                        let private = data(r, &c, MAX_ATTACHMENT_BYTES)?;
                        track.fourcc = private
                            .get(16..20)
                            .map(|f| String::from_utf8_lossy(f).into_owned());
                    }
                    id::VIDEO => {
                        let (mut w, mut h) = (0, 0);
                        for v in children(r, &c, c.end(file_len), file_len)? {
                            match v.id {
                                id::PIXEL_WIDTH => w = uint(&data(r, &v, MAX_SMALL_BYTES)?),
                                id::PIXEL_HEIGHT => h = uint(&data(r, &v, MAX_SMALL_BYTES)?),
                                _ => {}
                            }
                        }
                        track.size = Some((w, h));
                    }
                    _ => {}
                }
            }
            self.tracks.push(track);
        }
        Ok(())
    }

    fn attachments<R: Read + Seek>(
        &mut self,
        r: &mut R,
        e: &Element,
        file_len: u64,
    ) -> Result<(), MkvError> {
        for file in children(r, e, e.end(file_len), file_len)? {
            if file.id != id::ATTACHED_FILE {
                continue;
            }
            let (mut name, mut bytes) = (String::new(), Vec::new());
            for c in children(r, &file, file.end(file_len), file_len)? {
                match c.id {
                    id::FILE_NAME => {
                        name = String::from_utf8_lossy(&data(r, &c, MAX_SMALL_BYTES)?).into_owned();
                    }
                    id::FILE_DATA => bytes = data(r, &c, MAX_ATTACHMENT_BYTES)?,
                    _ => {}
                }
            }
            self.attachments.push((name, bytes));
        }
        Ok(())
    }

    fn cluster<R: Read + Seek>(
        &mut self,
        r: &mut R,
        e: &Element,
        file_len: u64,
    ) -> Result<(), MkvError> {
        let mut time = 0i64;
        for c in children(r, e, e.end(file_len), file_len)? {
            match c.id {
                id::TIMECODE => {
                    time = i64::try_from(uint(&data(r, &c, MAX_SMALL_BYTES)?)).unwrap_or(i64::MAX);
                }
                id::SIMPLE_BLOCK => self.block(r, &c, time)?,
                id::BLOCK_GROUP => {
                    for b in children(r, &c, c.end(file_len), file_len)? {
                        if b.id == id::BLOCK {
                            self.block(r, &b, time)?;
                        }
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// A (simple) block's track, time and payload: its head is the track
    /// number (a variable-length integer), a signed 16-bit time relative
    /// to the cluster's, and a flags byte. Laced blocks are refused.
    fn block<R: Read + Seek>(
        &mut self,
        r: &mut R,
        e: &Element,
        cluster_time: i64,
    ) -> Result<(), MkvError> {
        let size = e.size.unwrap_or(0);
        r.seek(SeekFrom::Start(e.data_pos))
            .map_err(|err| MkvError::Io(err.to_string()))?;
        let mut head = Vec::with_capacity(12);
        r.by_ref()
            .take(size.min(12))
            .read_to_end(&mut head)
            .map_err(|err| MkvError::Io(err.to_string()))?;
        let bad = |reason: &str| MkvError::Corrupt {
            offset: e.data_pos,
            reason: reason.to_owned(),
        };
        let (track, n) = vint_in(&head).ok_or_else(|| bad("a block's track number is cut off"))?;
        let rest = head
            .get(n..n + 3)
            .ok_or_else(|| bad("a block's head is cut off"))?;
        if rest[2] & 0x06 != 0 {
            return Err(bad("laced blocks are not read"));
        }
        let relative = i64::from(i16::from_be_bytes([rest[0], rest[1]]));
        let ticks = cluster_time.saturating_add(relative);
        let scale = i64::try_from(self.timecode_scale_ns).unwrap_or(i64::MAX);
        let skip = n as u64 + 3;
        self.blocks.entry(track).or_default().push(Block {
            time_ns: ticks.saturating_mul(scale),
            pos: e.data_pos + skip,
            len: size - skip,
        });
        Ok(())
    }
}

/// The child elements of master element `e` (ending at `end`): their
/// headers, each checked to end within the file.
fn children<R: Read + Seek>(
    r: &mut R,
    e: &Element,
    end: u64,
    file_len: u64,
) -> Result<Vec<Element>, MkvError> {
    let mut out = Vec::new();
    let mut pos = e.data_pos;
    while pos < end {
        let c = element(r, pos, file_len)?;
        let Some(size) = c.size else {
            return Err(MkvError::Corrupt {
                offset: pos,
                reason: format!("element {:#x} of unknown size", c.id),
            });
        };
        pos = c.data_pos + size;
        if pos > end {
            return Err(MkvError::Corrupt {
                offset: c.data_pos,
                reason: format!("element {:#x} runs past its parent", c.id),
            });
        }
        out.push(c);
    }
    Ok(out)
}
