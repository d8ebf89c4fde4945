//! Why a session could not be saved or loaded.

use thiserror::Error;

/// Why a session file was refused (nothing loaded is changed) or could not
/// be written.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SessionError {
    /// The file ends early: it was cut while being written or copied.
    #[error("the session file is truncated: {0}")]
    Truncated(String),
    /// The file is whole but its contents are damaged or do not fit
    /// together (the message names the part).
    #[error("the session file is corrupt: {0}")]
    Corrupt(String),
    /// Written by a newer surfel-slam, in a format version this build does
    /// not read.
    #[error("the session file has format version {found}, newer than this build reads (up to {supported}): open it with a newer surfel-slam")]
    FutureVersion {
        /// The file's format version.
        found: u32,
        /// The newest version this build reads.
        supported: u32,
    },
    /// The session was saved for another camera than the one in use.
    #[error("the session was saved for another camera: {0}")]
    CameraMismatch(String),
    /// Not a session file at all (another kind of file).
    #[error("not a surfel-slam session file: {0}")]
    NotASession(String),
    /// The pipeline is localising in a loaded map (nothing new to save:
    /// the map is the file it was loaded from).
    #[error("a pipeline localising in a loaded map is not saved: the map is the session it was loaded from")]
    Localising,
    /// Writing failed (the message says why: disk full, permissions, ...).
    #[error("could not write the session: {0}")]
    Write(String),
}

impl SessionError {
    /// Short name of the kind, for messages and bindings: `truncated`,
    /// `corrupt`, `future-version`, `camera-mismatch`, `not-a-session`,
    /// `localising`, `write`.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Truncated(_) => "truncated",
            Self::Corrupt(_) => "corrupt",
            Self::FutureVersion { .. } => "future-version",
            Self::CameraMismatch(_) => "camera-mismatch",
            Self::NotASession(_) => "not-a-session",
            Self::Localising => "localising",
            Self::Write(_) => "write",
        }
    }
}
