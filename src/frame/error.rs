//! Why a frame could not be built, and which image it is about.

use thiserror::Error;

/// Which image of a frame an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// The colour image.
    Colour,
    /// The depth image.
    Depth,
    /// The per-pixel depth deviation (a sensor's confidence map).
    DepthDeviation,
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Channel::Colour => "colour",
            Channel::Depth => "depth",
            Channel::DepthDeviation => "depth deviation",
        })
    }
}

/// Why a frame could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FrameError {
    /// The bytes are not a decodable image.
    #[error("{channel} image could not be decoded: {message}")]
    Decode {
        /// Colour or depth.
        channel: Channel,
        /// The decoder's message.
        message: String,
    },
    /// The depth image is not single-channel 16-bit.
    #[error("depth image must be a 16-bit single-channel PNG, found {found} (an 8-bit preview or colour image cannot hold depth)")]
    DepthNot16Bit {
        /// Description of the pixel format found.
        found: String,
    },
    /// Colour and depth sizes differ.
    #[error("colour is {colour_width}x{colour_height} but depth is {depth_width}x{depth_height}")]
    SizeMismatch {
        /// Colour width, pixels.
        colour_width: usize,
        /// Colour height, pixels.
        colour_height: usize,
        /// Depth width, pixels.
        depth_width: usize,
        /// Depth height, pixels.
        depth_height: usize,
    },
    /// The frame size differs from the expected (sequence or intrinsics) size.
    #[error("frame is {width}x{height} but the sequence is {expected_width}x{expected_height}")]
    UnexpectedSize {
        /// Frame width, pixels.
        width: usize,
        /// Frame height, pixels.
        height: usize,
        /// Expected width, pixels.
        expected_width: usize,
        /// Expected height, pixels.
        expected_height: usize,
    },
    /// A raw buffer's length does not match width x height x channels.
    #[error("{channel} buffer has {found} values, expected {expected} for the given size")]
    BufferLength {
        /// Colour or depth.
        channel: Channel,
        /// Values found.
        found: usize,
        /// Values expected.
        expected: usize,
    },
    /// The image is empty or implausibly large.
    #[error("image size {width}x{height} is not supported (1..=16384 per side, at most 16.7 million pixels)")]
    BadDimensions {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A decoded depth value is NaN, infinite or negative (only possible in a
    /// frame built by hand: decoding never produces one).
    #[error("depth must be a finite number of metres >= 0 (0 = no measurement); pixel {pixel} holds {value}")]
    InvalidDepth {
        /// Row-major pixel index.
        pixel: usize,
        /// The offending value, metres.
        value: f32,
    },
    /// A depth deviation multiplier is not a finite number >= 1 (a
    /// frame built by hand).
    #[error("depth deviation must be a finite multiplier >= 1; pixel {pixel} holds {value}")]
    InvalidDepthDeviation {
        /// Row-major pixel index.
        pixel: usize,
        /// The offending value.
        value: f32,
    },
    /// The depth conversion settings are unusable.
    #[error("invalid depth settings: {0}")]
    DepthSettings(String),
}
