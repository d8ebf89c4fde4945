//! RealSense recordings as librealsense 2.58 and later writes them: a
//! ROS2 bag, one SQLite `.db3` file (rosbag2's `sqlite3` storage), read in
//! place through `Read + Seek` by a small SQLite reader of our own (pure
//! Rust, so it builds for wasm too), one message in memory at a time.
//!
//! - `sqlite.rs`: the SQLite file format, read only: pages, table
//!   b-trees, records, overflow pages.
//! - `cdr.rs`: the CDR messages needed (`std_msgs/String`,
//!   `sensor_msgs/CompressedImage`, `CameraInfo`, `Imu`).
//! - `scan.rs`: the `topics` and `messages` tables read once: librealsense's
//!   streams, calibration (`key=value` strings), extrinsics, depth units and
//!   each frame's timestamp, assembled as the ROS1 reader does
//!   ([`crate::dataset::rosbag::Recording`], messages placed by row id).
//! - `reader.rs`: [`RealSenseDb3`], a recording opened for reading frames:
//!   depth from `compressedDepth` PNG (after its 12-byte header), colour
//!   from `compressed` PNG, registered to depth by the ROS1 reader's code.
//!
//! Times are the frames' own timestamps (the `image/metadata` messages'
//! `timestamp`, the camera's clock, as the ROS1 bag's header stamps),
//! seconds; depth is in the recording's depth units (metres per unit);
//! extrinsics in metres, camera frames x right, y down, z forward.

mod cdr;
mod reader;
mod scan;
pub mod sqlite;

use thiserror::Error;

use super::rosbag::RosbagError;

pub use reader::RealSenseDb3;
pub use scan::sequence_of;
pub use sqlite::MAGIC;

/// Whether a file's first bytes are an SQLite 3 database's.
#[must_use]
pub fn is_sqlite(head: &[u8]) -> bool {
    head.starts_with(MAGIC)
}

/// Why a `.db3` (or one of its frames) could not be read. The file's name
/// is added by the caller ([`crate::dataset::DatasetError::Db3`]).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Db3Error {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(String),
    /// The file does not start with `SQLite format 3`.
    #[error("not an SQLite database (a ROS2 .db3 starts with `SQLite format 3`)")]
    NotSqlite,
    /// The file ends before a page it declares.
    #[error("truncated: {what} lies past the end of the file (a recording cut short?)")]
    Truncated {
        /// What is cut off.
        what: String,
    },
    /// A page is not what the SQLite format says.
    #[error("corrupt SQLite page {page}: {reason}")]
    Corrupt {
        /// The page (1-based; 0: the file header).
        page: u32,
        /// What is wrong.
        reason: String,
    },
    /// A table rosbag2 writes is missing: not a ROS2 bag.
    #[error("no `{table}` table: not a ROS2 bag (tables: {})", if found.is_empty() { "none".to_owned() } else { found.join(", ") })]
    MissingTable {
        /// The table looked for.
        table: &'static str,
        /// The tables found.
        found: Vec<String>,
    },
    /// A row or a message is shorter than its fields, or holds implausible values.
    #[error("a message of {topic}: {reason}")]
    Message {
        /// The message's topic.
        topic: String,
        /// What is wrong.
        reason: String,
    },
    /// An image compressed otherwise than PNG (`compressedDepth png`,
    /// `png compressed`).
    #[error("{topic}: images in `{format}` are not read (only PNG: `16UC1; compressedDepth png`, `rgb8; png compressed ...`)")]
    UnsupportedCompression {
        /// The image topic.
        topic: String,
        /// Its `format` field.
        format: String,
    },
    /// The streams found do not make a recording (no depth stream, no
    /// calibration), or (in warnings) what the recording lacks.
    #[error("{0}")]
    Recording(#[from] RosbagError),
}
