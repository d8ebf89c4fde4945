//! A chunk's data decompressed: `none`, or `lz4` (ROS's roslz4 writes the
//! LZ4 frame format). `bz2` and other compressions are refused by name.

use std::io::Read;

use super::record::{corrupt, RecordHead};
use super::RosbagError;

/// Largest chunk accepted once decompressed, bytes. rosbag closes a chunk
/// past 768 KiB, so a chunk holds one image and what came with it; a
/// forged size must not make us allocate gigabytes (a wasm module has 4 GiB).
pub const MAX_CHUNK_BYTES: u32 = 256 << 20;

/// LZ4 cannot expand its input more than 255 times (a run of one byte).
const LZ4_MAX_RATIO: u64 = 255;

/// The decompressed bytes of the chunk `head`, whose (compressed) data is
/// `data`. Errors: [`RosbagError::UnsupportedCompression`] naming it,
/// [`RosbagError::Corrupt`] for a size that does not match or a stream
/// that does not decode.
pub(crate) fn decompress(head: &RecordHead, data: &[u8]) -> Result<Vec<u8>, RosbagError> {
    let at = head.pos;
    let compression = head.fields.text("compression", at)?;
    let size = head.fields.u32("size", at)?;
    if size > MAX_CHUNK_BYTES {
        return Err(corrupt(
            at,
            &format!("a chunk of {size} bytes (at most {MAX_CHUNK_BYTES})"),
        ));
    }
    let out = match compression.as_str() {
        "none" => data.to_vec(),
        "lz4" => {
            if u64::from(size) > LZ4_MAX_RATIO * data.len() as u64 + 64 {
                return Err(corrupt(
                    at,
                    &format!(
                        "an lz4 chunk of {} bytes cannot hold {size} bytes",
                        data.len()
                    ),
                ));
            }
            let mut out = Vec::new();
            lz4_flex::frame::FrameDecoder::new(data)
                .take(u64::from(size) + 1)
                .read_to_end(&mut out)
                .map_err(|e| corrupt(at, &format!("the lz4 chunk does not decode: {e}")))?;
            out
        }
        other => {
            return Err(RosbagError::UnsupportedCompression {
                compression: other.to_owned(),
            })
        }
    };
    if out.len() != size as usize {
        return Err(corrupt(
            at,
            &format!(
                "the chunk holds {} bytes, its header says {size}",
                out.len()
            ),
        ));
    }
    Ok(out)
}
