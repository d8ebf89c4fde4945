//! One pass over a bag, chunk by chunk: its connections and every
//! message's place, handed to a visitor with the message's bytes while its
//! chunk is in memory (one chunk at a time). A finished bag's index at the
//! end is passed over (its connections are those met in the chunks). An
//! unfinished bag (no index, as a recording stopped without closing
//! leaves it: the bag header's `index_pos` is 0, or lies past the file's
//! end) yields every complete chunk and one warning for the rest.

use std::collections::HashMap;
use std::io::{Read, Seek};

use super::chunk::{decompress, MAX_CHUNK_BYTES};
use super::record::{
    corrupt, inner_record, op, read_data, read_head, Fields, MAGIC, MAX_CONNECTION_BYTES,
};
use super::RosbagError;

/// A connection: one topic with one message type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    /// The bag's id of the connection.
    pub id: u32,
    /// Its topic (`/device_0/sensor_0/Depth_0/image/data`).
    pub topic: String,
    /// Its message type (`sensor_msgs/Image`).
    pub msg_type: String,
}

/// Where a message's bytes lie: in the chunk starting at `chunk_pos`
/// (bytes from the file's start), `offset` bytes into its decompressed data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Location {
    /// The chunk record's position in the file, bytes.
    pub chunk_pos: u64,
    /// The message's offset in the decompressed chunk, bytes.
    pub offset: u32,
    /// The message's length, bytes.
    pub len: u32,
}

/// What a scan found besides the messages.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scanned {
    /// Connections by id.
    pub connections: HashMap<u32, Connection>,
    /// Complete chunks read.
    pub chunks: usize,
    /// Why the bag's end was not read, for an unfinished bag or a damaged
    /// index (one warning).
    pub cut_off: Option<String>,
}

/// Checks the magic and reads the bag header: the index's position (0 in
/// an unfinished bag) and where the first record after the header starts.
fn bag_header<R: Read + Seek>(r: &mut R, file_len: u64) -> Result<(u64, u64), RosbagError> {
    let mut magic = [0u8; 13];
    r.seek(std::io::SeekFrom::Start(0))
        .and_then(|_| r.read_exact(&mut magic))
        .map_err(|_| RosbagError::NotABag)?;
    if &magic != MAGIC {
        return Err(RosbagError::NotABag);
    }
    let head = read_head(r, MAGIC.len() as u64, file_len)?;
    if head.op != op::BAG_HEADER {
        return Err(corrupt(head.pos, "the first record is not the bag header"));
    }
    Ok((head.fields.u64("index_pos", head.pos)?, head.end()))
}

/// The connection a connection record defines (its data is a header with
/// `type`).
fn connection(fields: &Fields, data: &[u8], at: u64) -> Result<Connection, RosbagError> {
    let inner = Fields::parse(data, at)?;
    Ok(Connection {
        id: fields.u32("conn", at)?,
        topic: fields.text("topic", at)?,
        msg_type: inner.text("type", at)?,
    })
}

/// Scans the bag: `visit(connection, location, bytes)` for every message
/// in every complete chunk, in file order. Errors of a finished bag are
/// errors; an unfinished bag stops at the first record it cannot read,
/// with [`Scanned::cut_off`] saying where.
pub(crate) fn scan<R: Read + Seek>(
    r: &mut R,
    file_len: u64,
    mut visit: impl FnMut(&Connection, Location, &[u8]) -> Result<(), RosbagError>,
) -> Result<Scanned, RosbagError> {
    let (index_pos, mut pos) = bag_header(r, file_len)?;
    let unfinished = index_pos == 0 || index_pos > file_len;
    let mut out = Scanned::default();
    while pos < file_len {
        match scan_record(r, pos, file_len, &mut out, &mut visit) {
            Ok(next) => pos = next,
            Err(RosbagError::UnsupportedCompression { compression }) => {
                return Err(RosbagError::UnsupportedCompression { compression })
            }
            Err(e) if unfinished => {
                out.cut_off = Some(format!(
                    "an unfinished recording (no index): the {} complete chunks are read, \
                     the rest, from byte {pos} of {file_len}, is cut off ({e})",
                    out.chunks
                ));
                break;
            }
            // The index is not needed: the chunks before it are whole.
            Err(e) if pos >= index_pos => {
                out.cut_off = Some(format!(
                    "the bag's index (from byte {index_pos}) is damaged or cut off: its {} \
                     chunks are read ({e})",
                    out.chunks
                ));
                return Ok(out);
            }
            Err(e) => return Err(e),
        }
    }
    if unfinished && out.cut_off.is_none() {
        out.cut_off = Some(format!(
            "an unfinished recording (no index): its {} chunks are read",
            out.chunks
        ));
    }
    Ok(out)
}

/// Reads the record at `pos` (a chunk: every message in it), returns the
/// position after it.
fn scan_record<R: Read + Seek>(
    r: &mut R,
    pos: u64,
    file_len: u64,
    out: &mut Scanned,
    visit: &mut impl FnMut(&Connection, Location, &[u8]) -> Result<(), RosbagError>,
) -> Result<u64, RosbagError> {
    let head = read_head(r, pos, file_len)?;
    match head.op {
        op::CHUNK => {
            let bytes = decompress(&head, &read_data(r, &head, MAX_CHUNK_BYTES)?)?;
            let messages = chunk_records(&bytes, pos, &mut out.connections)?;
            out.chunks += 1;
            for (conn, location) in messages {
                let start = location.offset as usize;
                let data = start
                    .checked_add(location.len as usize)
                    .and_then(|end| bytes.get(start..end))
                    .ok_or_else(|| corrupt(pos, "a message past its chunk"))?;
                visit(&conn, location, data)?;
            }
        }
        op::CONNECTION => {
            let c = connection(
                &head.fields,
                &read_data(r, &head, MAX_CONNECTION_BYTES)?,
                pos,
            )?;
            out.connections.entry(c.id).or_insert(c);
        }
        op::INDEX_DATA | op::CHUNK_INFO => {}
        op::MESSAGE_DATA => {
            return Err(corrupt(pos, "a message outside any chunk"));
        }
        other => {
            return Err(corrupt(
                pos,
                &format!("a record of unknown op {other:#04x}"),
            ))
        }
    }
    Ok(head.end())
}

/// The messages of a chunk (decompressed `bytes` of the chunk at
/// `chunk_pos`) with their connections; the chunk's connection records
/// are added to `connections`.
fn chunk_records(
    bytes: &[u8],
    chunk_pos: u64,
    connections: &mut HashMap<u32, Connection>,
) -> Result<Vec<(Connection, Location)>, RosbagError> {
    let mut at = 0;
    let mut messages = Vec::new();
    while at < bytes.len() {
        let (record, next) = inner_record(bytes, at, chunk_pos)?;
        match record.op {
            op::CONNECTION => {
                let c = connection(&record.fields, record.data, chunk_pos)?;
                connections.entry(c.id).or_insert(c);
            }
            op::MESSAGE_DATA => {
                let id = record.fields.u32("conn", chunk_pos)?;
                let conn = connections.get(&id).ok_or_else(|| {
                    corrupt(
                        chunk_pos,
                        &format!("a message of connection {id}, never defined"),
                    )
                })?;
                let location = Location {
                    chunk_pos,
                    offset: u32::try_from(record.data_offset)
                        .map_err(|_| corrupt(chunk_pos, "a chunk over 4 GiB"))?,
                    len: u32::try_from(record.data.len())
                        .map_err(|_| corrupt(chunk_pos, "a message over 4 GiB"))?,
                };
                messages.push((conn.clone(), location));
            }
            other => {
                return Err(corrupt(
                    chunk_pos,
                    &format!("a record of op {other:#04x} inside a chunk"),
                ))
            }
        }
        at = next;
    }
    Ok(messages)
}

/// Reads the decompressed data of the chunk at `chunk_pos`.
pub(crate) fn read_chunk<R: Read + Seek>(
    r: &mut R,
    chunk_pos: u64,
    file_len: u64,
) -> Result<Vec<u8>, RosbagError> {
    let head = read_head(r, chunk_pos, file_len)?;
    if head.op != op::CHUNK {
        return Err(corrupt(chunk_pos, "a message's chunk is not a chunk"));
    }
    decompress(&head, &read_data(r, &head, MAX_CHUNK_BYTES)?)
}
