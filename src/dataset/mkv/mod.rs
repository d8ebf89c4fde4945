//! Azure Kinect recordings (`k4arecorder`'s `.mkv`, Matroska), read in
//! place through `Read + Seek`: for now their structure only (tracks,
//! attachments such as `calibration.json`, each block's track, time and
//! place), the groundwork of a reader of their frames.
//!
//! - `ebml.rs`: EBML elements, bounded reads.
//! - `structure.rs`: [`MkvFile`], one pass over the element headers.
//! - `calibration.rs`: the cameras of `calibration.json` in the recorded
//!   mode ([`AzureCamera`]).

mod calibration;
mod ebml;
mod structure;

use thiserror::Error;

pub use calibration::{camera, AzureCamera, Purpose};
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
    /// An element is not what the format says.
    #[error("corrupt element at byte {offset}: {reason}")]
    Corrupt {
        /// Where it is, bytes.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
}
