//! RealSense recordings as librealsense (up to 2.57: the RealSense Viewer,
//! `rs-record`) writes them: a ROS1 bag, format 2.0, read in place through
//! `Read + Seek`, one chunk in memory at a time.
//!
//! - `record.rs`: records (`op`, header fields, data), bounded reads.
//! - `chunk.rs`: a chunk decompressed (`none`, `lz4`; others refused by name).
//! - `scan.rs`: one pass over the chunks: connections and each message's place.
//! - `message.rs`: `sensor_msgs/Image`, `CameraInfo`, `Imu`,
//!   `geometry_msgs/Transform`, `std_msgs/Float32` deserialised.
//! - `recording.rs`: the depth and colour streams, their calibration, the
//!   depth units, the IMU; colour paired with depth by timestamp.
//! - `pixels.rs`: an image's pixels as raw depth or RGB8.
//! - `register.rs`: colour registered to depth (extrinsics, distortion).
//! - `reader.rs`: [`RealSenseBag`], a recording opened for reading frames.
//! - `sequence.rs`: the recording as a [`crate::dataset::Sequence`].
//!
//! Times are the messages' header stamps, seconds (the camera's clock);
//! depth is in the recording's depth units (metres per unit); poses and
//! extrinsics in metres, camera frames x right, y down, z forward.

mod chunk;
mod message;
mod pixels;
mod reader;
mod record;
mod recording;
mod register;
mod scan;
mod sequence;

use thiserror::Error;

pub use chunk::MAX_CHUNK_BYTES;
pub use message::{CameraInfo, ImageHead};
pub use reader::{RawFrame, RealSenseBag};
pub use record::MAGIC;
pub(crate) use recording::Collected;
pub use recording::{BagFrame, ImuSample, Recording, DEFAULT_DEPTH_UNITS_M};
pub use register::{bilinear as sample_bilinear, CameraModel, Distortion, Registration};
pub use scan::{Connection, Location};
pub(crate) use sequence::frames_of;
pub use sequence::{frame_name, sequence_of};

/// Whether a file's first bytes are a ROS bag's (of any version).
#[must_use]
pub fn is_rosbag(head: &[u8]) -> bool {
    head.starts_with(b"#ROSBAG V")
}

/// Why a bag (or one of its frames) could not be read. The file's name is
/// added by the caller ([`crate::dataset::DatasetError::Rosbag`]).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RosbagError {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(String),
    /// The file does not start with `#ROSBAG V2.0` (another version, or no bag).
    #[error("not a ROS bag of format 2.0 (it must start with `#ROSBAG V2.0`; ROS2 bags are .db3)")]
    NotABag,
    /// A record runs past the end of a finished bag.
    #[error("truncated: {what} at byte {offset} runs past the end of the file")]
    Truncated {
        /// Where the record starts, bytes.
        offset: u64,
        /// What is cut off.
        what: String,
    },
    /// A record or a chunk is not what the format says.
    #[error("corrupt record at byte {offset}: {reason}")]
    Corrupt {
        /// Where the record starts, bytes.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A chunk compressed otherwise than `none` or `lz4` (`bz2` among them).
    #[error("chunks compressed with `{compression}` are not read (only `lz4` and `none`; recompress with `rosbag compress --lz4`)")]
    UnsupportedCompression {
        /// The chunk's `compression` field.
        compression: String,
    },
    /// A message is shorter than its fields, or holds implausible values.
    #[error("a message of {topic}: {reason}")]
    Message {
        /// The message's topic.
        topic: String,
        /// What is wrong.
        reason: String,
    },
    /// An image encoding not read here.
    #[error("{topic}: images in `{encoding}` are not read (expected {expected})")]
    UnsupportedEncoding {
        /// The image topic.
        topic: String,
        /// Its encoding.
        encoding: String,
        /// What is read.
        expected: &'static str,
    },
    /// A camera's distortion model not modelled here, with non-zero coefficients.
    #[error("{topic}: the distortion model `{model}` ({coefficients} coefficients) is not modelled (Brown-Conrady, modified or inverse Brown-Conrady, plumb_bob are)")]
    UnsupportedDistortion {
        /// The camera info's topic.
        topic: String,
        /// The model's name.
        model: String,
        /// How many coefficients it has.
        coefficients: usize,
    },
    /// No depth stream: no image topic of 16-bit depth.
    #[error("no depth stream: no image topic of 16-bit depth (mono16 or 16UC1; a sensor_msgs/Image, or a CompressedImage in a .db3) in the messages read; image topics: {}", if image_topics.is_empty() { "none".to_owned() } else { image_topics.join(", ") })]
    NoDepthStream {
        /// The image topics found, with their encodings.
        image_topics: Vec<String>,
    },
    /// The depth stream holds no image.
    #[error("no frame: the depth stream {topic} holds no image")]
    NoFrames {
        /// The depth topic.
        topic: String,
    },
    /// A calibration the depth stream needs is missing or does not fit.
    #[error("no usable calibration: {what}")]
    MissingCalibration {
        /// What is missing.
        what: String,
    },
    /// Warning: the recording was not finished (no index); the complete
    /// chunks are read.
    #[error("{0}")]
    Unfinished(String),
    /// Warning: the colour stream cannot be registered; depth alone is read.
    #[error(
        "the colour stream {topic} is not read ({reason}): the frames play on depth alone, in grey"
    )]
    ColourWithoutCalibration {
        /// The colour topic.
        topic: String,
        /// Why it cannot be registered.
        reason: String,
    },
    /// Warning: some depth frames have no colour image within half a frame period.
    #[error("{unpaired} of {frames} depth frames have no colour image within half a frame period: they play in grey")]
    FramesWithoutColour {
        /// Frames without colour.
        unpaired: usize,
        /// Frames.
        frames: usize,
    },
    /// Warning: the recording gives no depth units option.
    #[error("no depth units option in the recording: taking {assumed_m} m per unit (give --depth-scale otherwise)")]
    NoDepthUnits {
        /// The units taken, metres.
        assumed_m: f64,
    },
    /// The recording could not be used, and its file is cut short (an
    /// unfinished recording): both said.
    #[error("{source}; {cut_off}")]
    CutShort {
        /// Why the recording could not be used.
        source: Box<RosbagError>,
        /// Where the file is cut short.
        cut_off: String,
    },
    /// A frame index past the recording's frames.
    #[error("frame {index} of {frames}")]
    NoSuchFrame {
        /// The index asked for.
        index: usize,
        /// Frames in the recording.
        frames: usize,
    },
}
