//! Sparse optical flow: Shi-Tomasi corners tracked by pyramidal
//! Lucas-Kanade with a forward-backward check.
//!
//! Images are grey levels (any scale, typically 0..255) in row-major `f32`
//! buffers; positions are continuous pixel coordinates with pixel centres at
//! integers (`(0, 0)` is the centre of the top-left pixel), in the
//! full-resolution image. All buffers live in [`OpticalFlow`] and are reused
//! from call to call: tracking a stream of frames allocates only when the
//! image size or the corner count grows.

mod corners;
mod lk;
pub(crate) mod pyramid;

use glam::Vec2;
use rayon::prelude::*;
use thiserror::Error;

pub use corners::shi_tomasi_into;
use pyramid::GreyPyramid;

/// Settings of corner detection and tracking.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowConfig {
    /// Most corners to track.
    pub max_corners: usize,
    /// At most one corner per square cell of this side, pixels.
    pub min_distance_px: usize,
    /// Corners weaker than this fraction of the strongest are dropped.
    pub quality: f32,
    /// Half side of the Lucas-Kanade window, pixels (7 = 15x15).
    pub window_radius: usize,
    /// Pyramid levels (1 = full resolution only).
    pub levels: usize,
    /// Gauss-Newton iterations per level.
    pub iterations: usize,
    /// Stop a level when the update is below this, pixels.
    pub epsilon_px: f32,
    /// Largest forward-backward error of a kept track, pixels.
    pub max_forward_backward_px: f32,
}

impl Default for FlowConfig {
    fn default() -> Self {
        Self {
            max_corners: 500,
            min_distance_px: 10,
            quality: 0.01,
            window_radius: 7,
            levels: 3,
            iterations: 20,
            epsilon_px: 0.01,
            max_forward_backward_px: 1.0,
        }
    }
}

/// One feature tracked from the first image to the second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowTrack {
    /// Position in the first image, pixels.
    pub from: Vec2,
    /// Position in the second image, pixels.
    pub to: Vec2,
    /// Distance between `from` and the backward track of `to`, pixels.
    pub forward_backward_px: f32,
}

/// Why flow could not be computed.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum FlowError {
    /// An image buffer does not hold `width * height` values.
    #[error("image buffer has {got} values, expected {width}x{height}")]
    SizeMismatch {
        /// Values given.
        got: usize,
        /// Expected width, pixels.
        width: usize,
        /// Expected height, pixels.
        height: usize,
    },
    /// The image is too small for the window and pyramid.
    #[error("a {width}x{height} image is too small for the window and pyramid")]
    TooSmall {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// The configuration is unusable.
    #[error("invalid flow configuration: {0}")]
    InvalidConfig(&'static str),
}

/// Sparse Lucas-Kanade tracker with reusable buffers.
#[derive(Debug, Default)]
pub struct OpticalFlow {
    config: FlowConfig,
    first: GreyPyramid,
    second: GreyPyramid,
    corners: Vec<Vec2>,
    scores: Vec<f32>,
    results: Vec<Option<FlowTrack>>,
    tracks: Vec<FlowTrack>,
}

impl OpticalFlow {
    /// A tracker with `config`.
    pub fn new(config: FlowConfig) -> Result<Self, FlowError> {
        if config.levels == 0 || config.levels > 8 {
            return Err(FlowError::InvalidConfig("levels must be 1..=8"));
        }
        if config.window_radius == 0 || config.window_radius > 32 {
            return Err(FlowError::InvalidConfig("window radius must be 1..=32"));
        }
        if !(config.max_forward_backward_px >= 0.0 && config.epsilon_px >= 0.0) {
            return Err(FlowError::InvalidConfig("thresholds must be >= 0"));
        }
        Ok(Self {
            config,
            ..Self::default()
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &FlowConfig {
        &self.config
    }

    /// Detects corners in `first` and tracks them into `second` (both
    /// `width x height` grey images); returns the tracks that passed the
    /// forward-backward check.
    pub fn track(
        &mut self,
        first: &[f32],
        second: &[f32],
        width: usize,
        height: usize,
    ) -> Result<&[FlowTrack], FlowError> {
        self.build(first, second, width, height)?;
        let level0 = self.first.level(0);
        shi_tomasi_into(
            level0,
            &self.config,
            self.margin(),
            &mut self.scores,
            &mut self.corners,
        );
        Ok(self.track_corners())
    }

    /// Tracks the given `points` (pixels in `first`) into `second`.
    pub fn track_points(
        &mut self,
        first: &[f32],
        second: &[f32],
        width: usize,
        height: usize,
        points: &[Vec2],
    ) -> Result<&[FlowTrack], FlowError> {
        self.build(first, second, width, height)?;
        self.corners.clear();
        self.corners
            .extend(points.iter().filter(|p| p.is_finite()).copied());
        Ok(self.track_corners())
    }

    /// Pixels kept clear of the border when detecting corners.
    fn margin(&self) -> usize {
        self.config.window_radius + 2
    }

    fn build(
        &mut self,
        first: &[f32],
        second: &[f32],
        width: usize,
        height: usize,
    ) -> Result<(), FlowError> {
        for image in [first, second] {
            if width.checked_mul(height) != Some(image.len()) {
                return Err(FlowError::SizeMismatch {
                    got: image.len(),
                    width,
                    height,
                });
            }
        }
        let min_side = 2 * self.margin() + 1;
        if (width >> (self.config.levels - 1)) < min_side
            || (height >> (self.config.levels - 1)) < min_side
        {
            return Err(FlowError::TooSmall { width, height });
        }
        self.first.build(first, width, height, self.config.levels);
        self.second.build(second, width, height, self.config.levels);
        Ok(())
    }

    fn track_corners(&mut self) -> &[FlowTrack] {
        let (first, second, config) = (&self.first, &self.second, &self.config);
        self.results.resize(self.corners.len(), None);
        self.results
            .par_iter_mut()
            .zip(self.corners.par_iter())
            .for_each(|(out, &from)| {
                *out = lk::track_point(first, second, from, config).and_then(|to| {
                    let back = lk::track_point(second, first, to, config)?;
                    let forward_backward_px = back.distance(from);
                    (forward_backward_px <= config.max_forward_backward_px).then_some(FlowTrack {
                        from,
                        to,
                        forward_backward_px,
                    })
                });
            });
        self.tracks.clear();
        self.tracks.extend(self.results.iter().flatten());
        &self.tracks
    }
}
