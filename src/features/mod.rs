//! Sparse features for wide-baseline pose estimates: Shi-Tomasi corners
//! with oriented binary descriptors (`orb.rs`), lifted to 3D with the
//! frame's depth, matched by Hamming distance (ratio test and mutual
//! check), and a rigid motion fitted by RANSAC ([`rigid`]); the stage that
//! holds two frames and estimates the motion between them on demand is
//! [`SparseEstimator`] (`estimator.rs`).
//!
//! Dense tracking converges only from within a few centimetres of the
//! answer; matching descriptors does not depend on where the search starts,
//! so it gives the dense tracker a start when the camera moved far, and an
//! independent opinion on the dense result. Positions are pixels (centres at
//! integers) and 3D points are in the frame's camera frame (+x right, +y
//! down, +z forward), metres.

mod estimator;
pub(crate) mod orb;
pub mod rigid;

use crate::flow::pyramid::GreyLevel;
use crate::flow::{shi_tomasi_into, FlowConfig};
pub use estimator::{SparseEstimate, SparseEstimator};
use glam::{Vec2, Vec3};
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
            max_depth_spread: 0.04,
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

/// What detection needs of one frame, at the feature level: grey levels
/// with gradients, and per pixel the mean 3D point of the full-resolution
/// block it covers with that block's depth range. Cheap to make (one pass
/// over the frame), so the pipeline keeps it for every fused frame and
/// detects corners only when a sparse estimate is wanted.
#[derive(Debug, Clone, Default)]
pub struct PreparedFrame {
    grey: GreyLevel,
    /// Mean point of the block, camera frame, metres; `ZERO` when a pixel
    /// of the block has no depth.
    points: Vec<Vec3>,
    /// Nearest and farthest depth of the block, metres.
    depth_range: Vec<[f32; 2]>,
}

impl PreparedFrame {
    /// Whether this holds a frame.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Checks that `rgb` (RGB8) and `vertices` both hold `width x height` pixels.
fn check_frame_size(
    rgb: &[u8],
    vertices: &[Vec3],
    width: usize,
    height: usize,
) -> Result<(), FeatureError> {
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
    Ok(())
}

/// Detects and describes corners with depth; buffers reused between calls.
#[derive(Debug, Clone)]
pub struct FeatureExtractor {
    config: FeatureConfig,
    pattern: SteeredPattern,
    prepared: PreparedFrame,
    smoothed: Vec<f32>,
    smooth_scratch: Vec<f32>,
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
            prepared: PreparedFrame::default(),
            smoothed: Vec::new(),
            smooth_scratch: Vec::new(),
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
    /// strongest first: [`Self::prepare_into`] then [`Self::detect_into`].
    pub fn extract_into(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
        out: &mut Vec<Feature>,
    ) -> Result<(), FeatureError> {
        let mut prepared = std::mem::take(&mut self.prepared);
        let result = self.prepare_into(rgb, vertices, width, height, &mut prepared);
        if result.is_ok() {
            self.detect_into(&prepared, out);
        }
        self.prepared = prepared;
        result
    }

    /// Reduces a frame (as for [`Self::extract_into`]) to what detection needs.
    pub fn prepare_into(
        &self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
        out: &mut PreparedFrame,
    ) -> Result<(), FeatureError> {
        check_frame_size(rgb, vertices, width, height)?;
        let scale = 1usize << self.config.level;
        let (w, h) = (width / scale, height / scale);
        out.grey.width = w;
        out.grey.height = h;
        out.grey.pixels.resize(w * h, [0.0; 3]);
        out.points.resize(w * h, Vec3::ZERO);
        out.depth_range.resize(w * h, [0.0; 2]);
        let inv = 1.0 / (scale * scale) as f32;
        out.grey
            .pixels
            .par_chunks_mut(w.max(1))
            .zip(out.points.par_chunks_mut(w.max(1)))
            .zip(out.depth_range.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(v, ((grey_row, point_row), range_row))| {
                for u in 0..w {
                    let (mut grey, mut sum, mut near, mut far) =
                        (0.0f32, Vec3::ZERO, f32::MAX, 0.0f32);
                    let mut holes = false;
                    for y in v * scale..(v + 1) * scale {
                        for x in u * scale..(u + 1) * scale {
                            let i = y * width + x;
                            let c = &rgb[3 * i..3 * i + 3];
                            grey += 0.299 * f32::from(c[0])
                                + 0.587 * f32::from(c[1])
                                + 0.114 * f32::from(c[2]);
                            let p = vertices[i];
                            holes |= p.z <= 0.0;
                            sum += p;
                            near = near.min(p.z);
                            far = far.max(p.z);
                        }
                    }
                    grey_row[u] = [grey * inv, 0.0, 0.0];
                    point_row[u] = if holes { Vec3::ZERO } else { sum * inv };
                    range_row[u] = [near, far];
                }
            });
        let pixels = &mut out.grey.pixels;
        for v in 1..h.saturating_sub(1) {
            for u in 1..w - 1 {
                let i = v * w + u;
                pixels[i][1] = 0.5 * (pixels[i + 1][0] - pixels[i - 1][0]);
                pixels[i][2] = 0.5 * (pixels[i + w][0] - pixels[i - w][0]);
            }
        }
        Ok(())
    }

    /// Corners of a prepared frame with smooth depth, strongest first, into `out`.
    pub fn detect_into(&mut self, prepared: &PreparedFrame, out: &mut Vec<Feature>) {
        out.clear();
        let scale = 1usize << self.config.level;
        let margin = PATCH_RADIUS + 2;
        let level = &prepared.grey;
        let (w, h) = (level.width, level.height);
        if w <= 2 * margin + 1 || h <= 2 * margin + 1 || prepared.points.len() != w * h {
            return;
        }
        let flow_config = FlowConfig {
            // Corners on depth edges or holes are dropped below.
            max_corners: self.config.max_corners * 2,
            min_distance_px: self.config.min_distance_px,
            quality: self.config.quality,
            ..FlowConfig::default()
        };
        shi_tomasi_into(
            level,
            &flow_config,
            margin,
            &mut self.scores,
            &mut self.corners,
        );
        self.tmp.clear();
        self.tmp.extend(level.pixels.iter().map(|p| p[0]));
        let grey = std::mem::take(&mut self.tmp);
        smooth_into(&grey, w, h, &mut self.smooth_scratch, &mut self.smoothed);
        let (pattern, smoothed) = (&self.pattern, &self.smoothed);
        let spread = self.config.max_depth_spread;
        let lifted = self.corners.par_iter().filter_map(|c| {
            let (u, v) = (c.x as usize, c.y as usize);
            let point = lift(prepared, (u, v), spread)?;
            let angle = orientation(&grey, w, (u, v));
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
        self.tmp = grey;
    }
}

/// The point of feature-level pixel `(u, v)` when the depth of its own
/// block and the mean depths of its 8 neighbours all lie within `spread`
/// (relative) of its own depth: a corner on a depth edge has no one depth.
fn lift(prepared: &PreparedFrame, (u, v): (usize, usize), spread: f32) -> Option<Vec3> {
    let w = prepared.grey.width;
    let point = prepared.points[v * w + u];
    if point.z <= 0.0 || u == 0 || v == 0 || u + 1 >= w || v + 1 >= prepared.grey.height {
        return None;
    }
    let limit = spread * point.z;
    let [near, far] = prepared.depth_range[v * w + u];
    if far - near > limit {
        return None;
    }
    for y in v - 1..=v + 1 {
        for x in u - 1..=u + 1 {
            let z = prepared.points[y * w + x].z;
            if z <= 0.0 || (z - point.z).abs() > limit {
                return None;
            }
        }
    }
    Some(point)
}

/// Matches `a` against `b`: pairs `(i, j)` where `b[j]` is `a[i]`'s nearest
/// descriptor, clearly nearer than its second nearest (`ratio`), within
/// `max_distance`, and `a[i]` is in turn `b[j]`'s nearest.
pub fn match_features_into(
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
