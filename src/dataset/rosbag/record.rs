//! ROS1 bag v2.0 records: `header_len` (u32 LE), the header (fields
//! `len` u32 + `name=value`), `data_len` (u32 LE), the data. Every length
//! read from the file is checked against the bytes that remain before
//! anything is allocated for it.

use std::io::{Read, Seek, SeekFrom};

use super::RosbagError;

/// The first bytes of a ROS1 bag of format 2.0.
pub const MAGIC: &[u8; 13] = b"#ROSBAG V2.0\n";

/// Largest record header accepted, bytes (a connection's header, with its
/// topic and type, is well under a kilobyte; its message definition is in
/// its data).
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Largest connection record's data accepted, bytes (its message
/// definition: a few kilobytes).
pub(crate) const MAX_CONNECTION_BYTES: u32 = 1 << 20;

/// The record kinds of format 2.0 (the header field `op`).
pub(crate) mod op {
    /// A message: `conn`, `time`; the data is the serialised message.
    pub const MESSAGE_DATA: u8 = 0x02;
    /// The bag header: `index_pos`, `conn_count`, `chunk_count`.
    pub const BAG_HEADER: u8 = 0x03;
    /// A chunk's index of one connection (skipped: the scan reads chunks).
    pub const INDEX_DATA: u8 = 0x04;
    /// A chunk: `compression`, `size`; the data holds connection and
    /// message records, compressed.
    pub const CHUNK: u8 = 0x05;
    /// A chunk's summary in the index at the end (skipped).
    pub const CHUNK_INFO: u8 = 0x06;
    /// A connection: `conn`, `topic`; the data is a header with `type`,
    /// `md5sum`, `message_definition`.
    pub const CONNECTION: u8 = 0x07;
}

/// A header's fields, `name=value` (values are bytes: numbers little-endian).
#[derive(Debug, Clone, Default)]
pub(crate) struct Fields(Vec<(Vec<u8>, Vec<u8>)>);

impl Fields {
    /// Parses a header; `at` (byte offset, for errors) locates it.
    pub(crate) fn parse(bytes: &[u8], at: u64) -> Result<Self, RosbagError> {
        let mut rest = bytes;
        let mut out = Vec::new();
        while !rest.is_empty() {
            let (len, tail) =
                split_u32(rest).ok_or_else(|| corrupt(at, "a header field's length is cut off"))?;
            let field = tail
                .get(..len as usize)
                .ok_or_else(|| corrupt(at, "a header field runs past its header"))?;
            let eq = field
                .iter()
                .position(|&b| b == b'=')
                .ok_or_else(|| corrupt(at, "a header field has no '='"))?;
            let (name, value) = field.split_at(eq);
            out.push((name.to_vec(), value.get(1..).unwrap_or_default().to_vec()));
            rest = tail.get(len as usize..).unwrap_or_default();
        }
        Ok(Self(out))
    }

    /// The value of field `name`, if present.
    pub(crate) fn get(&self, name: &str) -> Option<&[u8]> {
        self.0
            .iter()
            .find(|(n, _)| n.as_slice() == name.as_bytes())
            .map(|(_, v)| v.as_slice())
    }

    fn fixed<const N: usize>(&self, name: &str, at: u64) -> Result<[u8; N], RosbagError> {
        let value = self
            .get(name)
            .ok_or_else(|| corrupt(at, &format!("no `{name}` field")))?;
        value
            .try_into()
            .map_err(|_| corrupt(at, &format!("`{name}` is {} bytes, not {N}", value.len())))
    }

    /// Field `name` as one byte.
    pub(crate) fn u8(&self, name: &str, at: u64) -> Result<u8, RosbagError> {
        Ok(self.fixed::<1>(name, at)?[0])
    }

    /// Field `name` as a little-endian u32.
    pub(crate) fn u32(&self, name: &str, at: u64) -> Result<u32, RosbagError> {
        Ok(u32::from_le_bytes(self.fixed(name, at)?))
    }

    /// Field `name` as a little-endian u64.
    pub(crate) fn u64(&self, name: &str, at: u64) -> Result<u64, RosbagError> {
        Ok(u64::from_le_bytes(self.fixed(name, at)?))
    }

    /// Field `name` as text (lossy UTF-8).
    pub(crate) fn text(&self, name: &str, at: u64) -> Result<String, RosbagError> {
        self.get(name)
            .map(|v| String::from_utf8_lossy(v).into_owned())
            .ok_or_else(|| corrupt(at, &format!("no `{name}` field")))
    }
}

/// A little-endian u32 and the bytes after it.
pub(crate) fn split_u32(bytes: &[u8]) -> Option<(u32, &[u8])> {
    let (head, tail) = bytes.split_first_chunk::<4>()?;
    Some((u32::from_le_bytes(*head), tail))
}

/// [`RosbagError::Corrupt`] at byte `at`.
pub(crate) fn corrupt(at: u64, reason: &str) -> RosbagError {
    RosbagError::Corrupt {
        offset: at,
        reason: reason.to_owned(),
    }
}

/// A record's header read from the file; its data not yet read.
#[derive(Debug, Clone)]
pub(crate) struct RecordHead {
    /// Where the record starts, bytes from the file's start.
    pub pos: u64,
    /// Its `op`.
    pub op: u8,
    /// Its header fields.
    pub fields: Fields,
    /// Where its data starts.
    pub data_pos: u64,
    /// Its data's length, bytes (checked to end within the file).
    pub data_len: u32,
}

impl RecordHead {
    /// The byte after the record.
    pub(crate) fn end(&self) -> u64 {
        self.data_pos + u64::from(self.data_len)
    }
}

fn io(e: &std::io::Error) -> RosbagError {
    RosbagError::Io(e.to_string())
}

/// Reads the header of the record at `pos` in a file of `file_len` bytes:
/// [`RosbagError::Truncated`] when it (or its data) ends past the file.
pub(crate) fn read_head<R: Read + Seek>(
    r: &mut R,
    pos: u64,
    file_len: u64,
) -> Result<RecordHead, RosbagError> {
    let truncated = |what: &str| RosbagError::Truncated {
        offset: pos,
        what: what.to_owned(),
    };
    if pos + 4 > file_len {
        return Err(truncated("a record's header length"));
    }
    r.seek(SeekFrom::Start(pos)).map_err(|e| io(&e))?;
    let mut word = [0u8; 4];
    r.read_exact(&mut word).map_err(|e| io(&e))?;
    let header_len = u64::from(u32::from_le_bytes(word));
    if header_len > MAX_HEADER_BYTES {
        return Err(corrupt(
            pos,
            &format!("a record header of {header_len} bytes (at most {MAX_HEADER_BYTES})"),
        ));
    }
    if pos + 8 + header_len > file_len {
        return Err(truncated("a record's header"));
    }
    let mut header = vec![0u8; header_len as usize];
    r.read_exact(&mut header).map_err(|e| io(&e))?;
    r.read_exact(&mut word).map_err(|e| io(&e))?;
    let data_len = u32::from_le_bytes(word);
    let data_pos = pos + 8 + header_len;
    if data_pos + u64::from(data_len) > file_len {
        return Err(truncated("a record's data"));
    }
    let fields = Fields::parse(&header, pos)?;
    let op = fields.u8("op", pos)?;
    Ok(RecordHead {
        pos,
        op,
        fields,
        data_pos,
        data_len,
    })
}

/// Reads a record's data (its length already checked against the file),
/// refusing more than `max` bytes.
pub(crate) fn read_data<R: Read + Seek>(
    r: &mut R,
    head: &RecordHead,
    max: u32,
) -> Result<Vec<u8>, RosbagError> {
    if head.data_len > max {
        return Err(corrupt(
            head.pos,
            &format!("a record of {} bytes (at most {max})", head.data_len),
        ));
    }
    r.seek(SeekFrom::Start(head.data_pos)).map_err(|e| io(&e))?;
    let mut data = vec![0u8; head.data_len as usize];
    r.read_exact(&mut data).map_err(|e| io(&e))?;
    Ok(data)
}

/// A record inside a chunk's (decompressed) bytes.
#[derive(Debug)]
pub(crate) struct InnerRecord<'a> {
    /// Its `op`.
    pub op: u8,
    /// Its header fields.
    pub fields: Fields,
    /// Where its data starts in the chunk, bytes.
    pub data_offset: usize,
    /// Its data.
    pub data: &'a [u8],
}

/// The record at `at` in a chunk's bytes and the offset after it;
/// `chunk_pos` (the chunk record's place in the file) locates errors.
pub(crate) fn inner_record(
    bytes: &[u8],
    at: usize,
    chunk_pos: u64,
) -> Result<(InnerRecord<'_>, usize), RosbagError> {
    let bad = |what: &str| corrupt(chunk_pos, &format!("in the chunk, at byte {at}: {what}"));
    let rest = bytes.get(at..).ok_or_else(|| bad("past the chunk's end"))?;
    let (header_len, rest) = split_u32(rest).ok_or_else(|| bad("a header length cut off"))?;
    let header = rest
        .get(..header_len as usize)
        .ok_or_else(|| bad("a header runs past the chunk"))?;
    let rest = rest.get(header_len as usize..).unwrap_or_default();
    let (data_len, rest) = split_u32(rest).ok_or_else(|| bad("a data length cut off"))?;
    let data = rest
        .get(..data_len as usize)
        .ok_or_else(|| bad("a record's data runs past the chunk"))?;
    let fields = Fields::parse(header, chunk_pos)?;
    let op = fields.u8("op", chunk_pos)?;
    let data_offset = at + 8 + header_len as usize;
    Ok((
        InnerRecord {
            op,
            fields,
            data_offset,
            data,
        },
        data_offset + data_len as usize,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(name: &str, value: &[u8]) -> Vec<u8> {
        let mut f = ((name.len() + 1 + value.len()) as u32)
            .to_le_bytes()
            .to_vec();
        f.extend_from_slice(name.as_bytes());
        f.push(b'=');
        f.extend_from_slice(value);
        f
    }

    #[test]
    fn fields_parse_and_refuse_malformed_headers() {
        let mut h = field("op", &[5]);
        h.extend(field("size", &7u32.to_le_bytes()));
        h.extend(field("compression", b"lz4"));
        let f = Fields::parse(&h, 0).expect("parses");
        assert_eq!(f.u8("op", 0), Ok(5));
        assert_eq!(f.u32("size", 0), Ok(7));
        assert_eq!(f.text("compression", 0).as_deref(), Ok("lz4"));
        assert!(f.u64("size", 0).is_err(), "4 bytes are no u64");
        assert!(f.u32("absent", 0).is_err());
        for cut in 1..h.len() {
            // Every prefix either parses (whole fields) or is refused.
            let _ = Fields::parse(&h[..cut], 0);
        }
        assert!(Fields::parse(&h[..h.len() - 1], 0).is_err());
        assert!(
            Fields::parse(&[3, 0, 0, 0, b'a', b'b', b'c'], 0).is_err(),
            "no '='"
        );
    }
}
