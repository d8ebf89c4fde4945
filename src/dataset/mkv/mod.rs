//! Azure Kinect recordings (`k4arecorder`'s `.mkv`, Matroska), read in
//! place through `Read + Seek`, one frame's blocks in memory at a time.
//!
//! - `ebml.rs`: EBML elements, bounded reads.
//! - `structure.rs`: [`MkvFile`], one pass over the element headers
//!   (tracks, attachments, each block's track, time and place).
//! - `recording.rs`: [`AzureRecording`]: depth undistorted, colour
//!   registered to it, paired by time.
//! - `sequence.rs`: the recording as a [`crate::dataset::Sequence`].
//! - `calibration.rs`: the cameras of `calibration.json` in the recorded
//!   mode ([`AzureCamera`]).

mod calibration;
mod ebml;
mod recording;
mod sequence;
mod structure;

use thiserror::Error;

pub use calibration::{camera, AzureCamera, Purpose};
pub use recording::{AzureRecording, MkvFrame};
pub use sequence::sequence_of;
pub use structure::{Block, MkvFile, Track};

/// Why a Matroska file could not be read.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum MkvError {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(String),
    /// The file does not start with an EBML header of a Matroska document.
    #[error("not a Matroska (.mkv) file")]
    NotMatroska,
    /// An element runs past the end of the file.
    #[error("truncated: the element at byte {offset} runs past the end of the file")]
    Truncated {
        /// Where the element starts, bytes.
        offset: u64,
    },
    /// The calibration attachment is missing something or does not fit
    /// the recording's mode.
    #[error("calibration.json: {0}")]
    Calibration(String),
    /// No `DEPTH` track of 16-bit depth (`b16g`).
    #[error("no depth track: no DEPTH track of 16-bit depth (b16g); tracks: {}", if tracks.is_empty() { "none".to_owned() } else { tracks.join(", ") })]
    NoDepthTrack {
        /// The tracks found, with their formats.
        tracks: Vec<String>,
    },
    /// The depth track holds no frame.
    #[error("no frame: the DEPTH track holds no block")]
    NoFrames,
    /// A track's format not read here.
    #[error("the {track} track's format `{format}` is not read (colour: MJPG)")]
    UnsupportedFormat {
        /// The track's name.
        track: String,
        /// Its FOURCC or codec.
        format: String,
    },
    /// A frame's image could not be read.
    #[error("a {track} frame: {reason}")]
    Image {
        /// The track's name.
        track: String,
        /// What is wrong.
        reason: String,
    },
    /// Warning: the file is cut short; the frames before the cut are read.
    #[error("{0}")]
    CutShort(String),
    /// Warning: some depth frames have no colour frame within half a frame period.
    #[error("{unpaired} of {frames} depth frames have no colour image within half a frame period: they play in grey")]
    FramesWithoutColour {
        /// Frames without colour.
        unpaired: usize,
        /// Frames.
        frames: usize,
    },
    /// A frame index past the recording's frames.
    #[error("frame {index} of {frames}")]
    NoSuchFrame {
        /// The index asked for.
        index: usize,
        /// Frames in the recording.
        frames: usize,
    },
    /// An element is not what the format says.
    #[error("corrupt element at byte {offset}: {reason}")]
    Corrupt {
        /// Where it is, bytes.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
}
