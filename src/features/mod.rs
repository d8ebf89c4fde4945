//! Sparse features for wide-baseline pose estimates: Shi-Tomasi corners
//! with oriented binary descriptors ([`orb`]), lifted to 3D with the
//! frame's depth, matched by Hamming distance (ratio test and mutual
//! check), and a rigid motion fitted by RANSAC ([`rigid`]).
//!
//! Dense tracking converges only from within a few centimetres of the
//! answer; matching descriptors does not depend on where the search starts,
//! so it gives the dense tracker a start when the camera moved far, and an
//! independent opinion on the dense result. Positions are pixels (centres at
//! integers) and 3D points are in the frame's camera frame (+x right, +y
//! down, +z forward), metres.

pub mod orb;
pub mod rigid;

use crate::flow::pyramid::GreyPyramid;
use crate::flow::{shi_tomasi_into, FlowConfig};
use glam::{DAffine3, Vec2, Vec3};
use orb::{orientation, smooth_into, SteeredPattern, PATCH_RADIUS};
use rayon::prelude::*;
pub use rigid::{fit_rigid, ransac_rigid, RansacConfig, RigidFit};
use thiserror::Error;

/// 256-bit binary descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Descriptor(pub [u64; 4]);

impl Descriptor {
    /// Number of differing bits (0..=256).
    #[must_use]
    pub fn distance(&self, other: &Self) -> u32 {
        self.0
            .iter()
            .zip(other.0)
            .map(|(a, b)| (a ^ b).count_ones())
            .sum()
    }
}

/// One corner with depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    /// Position in the full-resolution image, pixels.
    pub pixel: Vec2,
    /// Orientation of the patch, radians (image axes).
    pub angle: f32,
    /// Binary descriptor.
    pub descriptor: Descriptor,
    /// The corner's surface point, camera frame, metres.
    pub point_in_camera: Vec3,
}

/// Settings of detection and matching.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureConfig {
    /// Pyramid level corners are detected and described at (0 = full
    /// resolution, 1 = half). Half: a quarter of the cost, and a 31-pixel
    /// patch there covers 62 pixels of the image, which tolerates blur.
    pub level: usize,
    /// Most corners kept per frame.
    pub max_corners: usize,
    /// At most one corner per square cell of this side, pixels of `level`.
    pub min_distance_px: usize,
    /// Corners weaker than this fraction of the strongest are dropped.
    pub quality: f32,
    /// A match's best Hamming distance must be below this fraction of the
    /// second best (Lowe's ratio test).
    pub ratio: f32,
    /// Largest Hamming distance of a match (of 256 bits).
    pub max_distance: u32,
    /// A corner is lifted to 3D only when the depth around it (the pixels
    /// it covers and their neighbours) spreads less than this fraction of
    /// its depth: corners on depth edges have no single depth.
    pub max_depth_spread: f32,
    /// Robust fit settings.
    pub ransac: RansacConfig,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        Self {
            level: 1,
            max_corners: 600,
            min_distance_px: 6,
            quality: 0.005,
            ratio: 0.85,
            max_distance: 80,
            max_depth_spread: 0.03,
            ransac: RansacConfig::default(),
        }
    }
}

/// Why features could not be extracted.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum FeatureError {
    /// A buffer does not match `width x height`.
    #[error("feature input has {got} values, expected {expected} for {width}x{height}")]
    SizeMismatch {
        /// Values given.
        got: usize,
        /// Values expected.
        expected: usize,
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// The configuration is unusable.
    #[error("invalid feature configuration: {0}")]
    InvalidConfig(&'static str),
}

/// Detects and describes corners with depth; buffers reused between calls.
#[derive(Debug, Clone)]
pub struct FeatureExtractor {
    config: FeatureConfig,
    pattern: SteeredPattern,
    grey: Vec<f32>,
    pyramid: GreyPyramid,
    level_grey: Vec<f32>,
    smoothed: Vec<f32>,
    tmp: Vec<f32>,
    scores: Vec<f32>,
    corners: Vec<Vec2>,
}

impl FeatureExtractor {
    /// An extractor with `config`.
    pub fn new(config: FeatureConfig) -> Result<Self, FeatureError> {
        if config.level > 3 {
            return Err(FeatureError::InvalidConfig("level must be 0..=3"));
        }
        if !(config.ratio > 0.0 && config.ratio <= 1.0) {
            return Err(FeatureError::InvalidConfig("ratio must be in (0, 1]"));
        }
        if !(config.ransac.inlier_m > 0.0 && config.ransac.inlier_m.is_finite()) {
            return Err(FeatureError::InvalidConfig("inlier distance must be > 0"));
        }
        Ok(Self {
            config,
            pattern: SteeredPattern::new(),
            grey: Vec::new(),
            pyramid: GreyPyramid::default(),
            level_grey: Vec::new(),
            smoothed: Vec::new(),
            tmp: Vec::new(),
            scores: Vec::new(),
            corners: Vec::new(),
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &FeatureConfig {
        &self.config
    }

    /// Corners of the `width x height` RGB8 image `rgb` whose depth is
    /// known and smooth in `vertices` (back-projected points, camera frame,
    /// metres, `ZERO` where no depth, same size), written to `out`,
    /// strongest first.
    pub fn extract(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
        out: &mut Vec<Feature>,
    ) -> Result<(), FeatureError> {
        out.clear();
        let n = width * height;
        for (got, expected) in [(rgb.len(), 3 * n), (vertices.len(), n)] {
            if got != expected {
                return Err(FeatureError::SizeMismatch {
                    got,
                    expected,
                    width,
                    height,
                });
            }
        }
        let level = self.config.level;
        let scale = 1usize << level;
        let margin = PATCH_RADIUS + 2;
        if (width >> level) <= 2 * margin + 1 || (height >> level) <= 2 * margin + 1 {
            return Ok(());
        }
        self.grey.clear();
        self.grey.extend(
            rgb.chunks_exact(3).map(|p| {
                0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2])
            }),
        );
        self.pyramid.build(&self.grey, width, height, level + 1);
        let top = self.pyramid.level(level);
        let (w, h) = (top.width, top.height);
        let flow_config = FlowConfig {
            max_corners: self.config.max_corners * 2,
            min_distance_px: self.config.min_distance_px,
            quality: self.config.quality,
            ..FlowConfig::default()
        };
        shi_tomasi_into(
            top,
            &flow_config,
            margin,
            &mut self.scores,
            &mut self.corners,
        );
        self.level_grey.clear();
        self.level_grey.extend(top.pixels.iter().map(|p| p[0]));
        smooth_into(&self.level_grey, w, h, &mut self.tmp, &mut self.smoothed);
        let (pattern, grey, smoothed) = (&self.pattern, &self.level_grey, &self.smoothed);
        let spread = self.config.max_depth_spread;
        let lifted = self.corners.par_iter().filter_map(|c| {
            let (u, v) = (c.x as usize, c.y as usize);
            let point = lift(
                vertices,
                width,
                height,
                (u * scale, v * scale),
                scale,
                spread,
            )?;
            let angle = orientation(grey, w, (u, v));
            Some(Feature {
                // Level pixel centres sit at (2u + 0.5) in the finer image.
                pixel: Vec2::new(c.x, c.y) * scale as f32 + 0.5 * (scale as f32 - 1.0),
                angle,
                descriptor: pattern.describe(smoothed, w, (u, v), angle),
                point_in_camera: point,
            })
        });
        out.par_extend(lifted);
        out.truncate(self.config.max_corners);
        Ok(())
    }
}

/// The mean point of the `scale x scale` full-resolution block at `(x0, y0)`,
/// when every pixel of the block and its one-pixel ring has depth within
/// `spread` (relative) of the block's mean.
fn lift(
    vertices: &[Vec3],
    width: usize,
    height: usize,
    (x0, y0): (usize, usize),
    scale: usize,
    spread: f32,
) -> Option<Vec3> {
    if x0 == 0 || y0 == 0 || x0 + scale >= width || y0 + scale >= height {
        return None;
    }
    let mut sum = Vec3::ZERO;
    for y in y0..y0 + scale {
        for x in x0..x0 + scale {
            let p = vertices[y * width + x];
            if p.z <= 0.0 {
                return None;
            }
            sum += p;
        }
    }
    let mean = sum / (scale * scale) as f32;
    let limit = spread * mean.z;
    for y in y0 - 1..=y0 + scale {
        for x in x0 - 1..=x0 + scale {
            let z = vertices[y * width + x].z;
            if z <= 0.0 || (z - mean.z).abs() > limit {
                return None;
            }
        }
    }
    Some(mean)
}

/// Matches `a` against `b`: pairs `(i, j)` where `b[j]` is `a[i]`'s nearest
/// descriptor, clearly nearer than its second nearest (`ratio`), within
/// `max_distance`, and `a[i]` is in turn `b[j]`'s nearest.
pub fn match_features(
    a: &[Feature],
    b: &[Feature],
    config: &FeatureConfig,
    out: &mut Vec<(usize, usize)>,
) {
    out.clear();
    let nearest = |d: &Descriptor, set: &[Feature]| {
        let (mut best, mut second, mut index) = (u32::MAX, u32::MAX, usize::MAX);
        for (j, f) in set.iter().enumerate() {
            let dist = d.distance(&f.descriptor);
            if dist < best {
                second = best;
                best = dist;
                index = j;
            } else if dist < second {
                second = dist;
            }
        }
        (best, second, index)
    };
    let backward: Vec<usize> = b.par_iter().map(|f| nearest(&f.descriptor, a).2).collect();
    out.par_extend(a.par_iter().enumerate().filter_map(|(i, f)| {
        let (best, second, j) = nearest(&f.descriptor, b);
        let distinct = (best as f32) < config.ratio * second as f32 || second == u32::MAX;
        (j < b.len() && best <= config.max_distance && distinct && backward[j] == i)
            .then_some((i, j))
    }));
}

/// A rigid motion between two frames from their matched features.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SparseEstimate {
    /// Maps points of the current frame's camera into the reference frame's
    /// camera (`reference_from_current`), metres.
    pub reference_from_current: DAffine3,
    /// Matches consistent with it.
    pub inliers: usize,
    /// Matches found.
    pub matches: usize,
    /// RMS 3D distance of the inliers, metres.
    pub rms_m: f64,
}

/// Estimates the motion between a reference frame and later frames from
/// matched features; keeps the reference's features and all buffers.
#[derive(Debug, Clone)]
pub struct SparseEstimator {
    extractor: FeatureExtractor,
    reference: Vec<Feature>,
    current: Vec<Feature>,
    matches: Vec<(usize, usize)>,
    a: Vec<Vec3>,
    b: Vec<Vec3>,
    inlier: Vec<bool>,
}

impl SparseEstimator {
    /// An estimator with `config`.
    pub fn new(config: FeatureConfig) -> Result<Self, FeatureError> {
        Ok(Self {
            extractor: FeatureExtractor::new(config)?,
            reference: Vec::new(),
            current: Vec::new(),
            matches: Vec::new(),
            a: Vec::new(),
            b: Vec::new(),
            inlier: Vec::new(),
        })
    }

    /// Extracts the features of a frame (see [`FeatureExtractor::extract`])
    /// as the current frame.
    pub fn extract(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
    ) -> Result<usize, FeatureError> {
        self.extractor
            .extract(rgb, vertices, width, height, &mut self.current)?;
        Ok(self.current.len())
    }

    /// The current frame becomes the reference.
    pub fn current_becomes_reference(&mut self) {
        std::mem::swap(&mut self.reference, &mut self.current);
        self.current.clear();
    }

    /// Forgets the reference.
    pub fn clear(&mut self) {
        self.reference.clear();
        self.current.clear();
    }

    /// Whether a reference frame with features is held.
    #[must_use]
    pub fn has_reference(&self) -> bool {
        !self.reference.is_empty()
    }

    /// Features of the current frame.
    #[must_use]
    pub fn current(&self) -> &[Feature] {
        &self.current
    }

    /// Features of the reference frame.
    #[must_use]
    pub fn reference(&self) -> &[Feature] {
        &self.reference
    }

    /// The motion from the current frame to the reference, or `None` when
    /// too few matches agree on one.
    pub fn estimate(&mut self) -> Option<SparseEstimate> {
        let config = *self.extractor.config();
        match_features(&self.reference, &self.current, &config, &mut self.matches);
        self.a.clear();
        self.b.clear();
        for &(i, j) in &self.matches {
            self.a.push(self.reference[i].point_in_camera);
            self.b.push(self.current[j].point_in_camera);
        }
        let fit = ransac_rigid(&self.a, &self.b, &config.ransac, &mut self.inlier)?;
        Some(SparseEstimate {
            reference_from_current: fit.a_from_b,
            inliers: fit.inliers,
            matches: self.matches.len(),
            rms_m: fit.rms_m,
        })
    }
}
