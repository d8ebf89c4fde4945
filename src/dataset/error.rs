//! Why a dataset could not be read: [`DatasetError`], every variant naming
//! the file concerned.

use thiserror::Error;

use super::{db3, mkv, rosbag};
use crate::frame::FrameError;

/// Why a dataset could not be read; every variant names the file concerned.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DatasetError {
    /// A file or directory could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// The path that failed.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// The folder (or the listing) holds no file at all.
    #[error("the folder is empty: no files to read")]
    EmptyFolder,
    /// The files do not match any supported dataset layout.
    #[error("unrecognised dataset layout: {hint}")]
    UnknownLayout {
        /// What was expected and a sample of what was found.
        hint: String,
    },
    /// A file named by an index file (or needed by the layout) is absent.
    #[error("{path} is missing (listed in {listed_in})")]
    MissingFile {
        /// The missing path, as in the listing.
        path: String,
        /// The index file (or step) that asked for it.
        listed_in: String,
    },
    /// A line of a text file could not be parsed.
    #[error("{file}, line {line_number}: {reason}: `{line}`")]
    MalformedLine {
        /// The file being parsed.
        file: String,
        /// 1-based line number.
        line_number: usize,
        /// The offending line (trimmed).
        line: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The last line of a text file is malformed, as a row is that a
    /// recording stopped while writing: skipped, a warning in
    /// [`Sequence::warnings`](super::Sequence::warnings) (never returned as an error).
    #[error("{file}, line {line_number}: the last line is cut off, skipped ({reason}): `{line}`")]
    CutOffLine {
        /// The file being parsed.
        file: String,
        /// 1-based line number.
        line_number: usize,
        /// The cut-off line (trimmed).
        line: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The index files list no usable frame.
    #[error("the sequence has no frames (no colour image could be paired with a depth image)")]
    NoFrames,
    /// Every frame listed misses an image (a half-copied dataset with nothing left to run).
    #[error("none of the {frames} frames listed can be read: {first}, and an image of every other frame is missing too")]
    NoReadableFrame {
        /// How many frames the index lists.
        frames: usize,
        /// Why the first one cannot be read.
        first: Box<DatasetError>,
    },
    /// An archive (`.zip`, `.tar`, `.tar.gz`) could not be read.
    #[error("{path}: {message}")]
    Archive {
        /// The archive file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// A calibration file (RealSense `camera_intrinsic.json`) is not what
    /// its layout writes.
    #[error("{path}: {reason}")]
    Calibration {
        /// The calibration file.
        path: String,
        /// What is wrong with it.
        reason: String,
    },
    /// An image is not the size the layout's calibration file gives.
    #[error("{path} is {width}x{height} pixels, but {calibration} gives {expected_width}x{expected_height}")]
    ImageSize {
        /// The image file.
        path: String,
        /// Its width, pixels.
        width: usize,
        /// Its height, pixels.
        height: usize,
        /// The width expected, pixels.
        expected_width: usize,
        /// The height expected, pixels.
        expected_height: usize,
        /// The calibration file (or the layout) that gives the size.
        calibration: String,
    },
    /// A confidence image (Stray Scanner `confidence/NNNNNN.png`) is not an
    /// 8-bit single-channel image.
    #[error("{path}: {reason}")]
    Confidence {
        /// The confidence image.
        path: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A RealSense `.bag` (or one of its frames) could not be read, or
    /// (in [`Sequence::warnings`](super::Sequence::warnings)) was read with a warning.
    #[error("{path}: {source}")]
    Rosbag {
        /// The bag file.
        path: String,
        /// What is wrong with it.
        #[source]
        source: rosbag::RosbagError,
    },
    /// A RealSense ROS2 `.db3` (or one of its frames) could not be read,
    /// or (in [`Sequence::warnings`](super::Sequence::warnings)) was read with a warning.
    #[error("{path}: {source}")]
    Db3 {
        /// The .db3 file.
        path: String,
        /// What is wrong with it.
        #[source]
        source: db3::Db3Error,
    },
    /// An Azure Kinect `.mkv` (or one of its frames) could not be read,
    /// or (in [`Sequence::warnings`](super::Sequence::warnings)) was read with a warning.
    #[error("{path}: {source}")]
    Mkv {
        /// The .mkv file.
        path: String,
        /// What is wrong with it.
        #[source]
        source: mkv::MkvError,
    },
    /// An image of a frame could not be decoded.
    #[error("{path}: {source}")]
    Frame {
        /// The image file (or both, for a size mismatch).
        path: String,
        /// The decoder's error.
        #[source]
        source: FrameError,
    },
}

impl DatasetError {
    /// Whether this is an image that is there but does not decode (a
    /// truncated or half-written PNG or JPEG, colour, depth or confidence):
    /// what the last image of a recording stopped mid-write looks like.
    /// The CLI skips such a last frame with a warning, not as a failure.
    #[must_use]
    pub fn is_undecodable_image(&self) -> bool {
        matches!(
            self,
            Self::Frame {
                source: FrameError::Decode { .. },
                ..
            } | Self::Confidence { .. }
        )
    }
}
