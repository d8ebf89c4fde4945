//! The sparse estimate stage: the motion between a reference frame and
//! later frames from matched features, detected only when asked for.

use glam::{DAffine3, Vec3};
use rayon::prelude::*;

use super::{
    check_frame_size, match_features_into, ransac_rigid, Feature, FeatureConfig, FeatureError,
    FeatureExtractor, PreparedFrame,
};

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

/// Makes `dst` a copy of `src`, in parallel: at 640x480 a frame's colour
/// and points are 4.6 MB, copied every frame, and a serial copy left one
/// core idle for it.
fn copy_in_parallel<T: Copy + Default + Send + Sync>(src: &[T], dst: &mut Vec<T>) {
    const PIECE: usize = 1 << 14;
    if dst.len() != src.len() {
        dst.clear();
        dst.resize(src.len(), T::default());
    }
    dst.par_chunks_mut(PIECE)
        .zip(src.par_chunks(PIECE))
        .for_each(|(d, s)| d.copy_from_slice(s));
}

/// A frame held by [`SparseEstimator`]: colour and points as given (a plain
/// copy, cheap), reduced ([`FeatureExtractor::prepare_into`]) and its corners
/// detected only when an estimate asks for its features.
#[derive(Debug, Clone, Default)]
struct HeldFrame {
    /// RGB8, `width x height`.
    rgb: Vec<u8>,
    /// Camera-frame points, metres, `ZERO` where no depth.
    vertices: Vec<Vec3>,
    width: usize,
    height: usize,
    /// A frame is held and its feature level is not empty.
    held: bool,
    prepared: PreparedFrame,
    features: Vec<Feature>,
    /// `features` are this frame's (prepared and detected).
    detected: bool,
}

impl HeldFrame {
    /// Keeps a copy of a frame (sizes checked as [`FeatureExtractor::prepare_into`] does).
    fn keep(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        (width, height): (usize, usize),
        level: usize,
    ) -> Result<(), FeatureError> {
        self.held = false;
        self.detected = false;
        self.features.clear();
        check_frame_size(rgb, vertices, width, height)?;
        copy_in_parallel(rgb, &mut self.rgb);
        copy_in_parallel(vertices, &mut self.vertices);
        (self.width, self.height) = (width, height);
        // A frame smaller than one block at the feature level has nothing
        // to match (an empty prepared frame counted as none before).
        self.held = (width >> level) * (height >> level) > 0;
        Ok(())
    }

    /// Prepares the frame and detects its corners, if a frame is held and
    /// that was not done yet.
    fn detect_with(&mut self, extractor: &mut FeatureExtractor) {
        if !self.held || self.detected {
            return;
        }
        let (w, h) = (self.width, self.height);
        // The sizes were checked by `keep`.
        if extractor
            .prepare_into(&self.rgb, &self.vertices, w, h, &mut self.prepared)
            .is_ok()
        {
            extractor.detect_into(&self.prepared, &mut self.features);
        }
        self.detected = true;
    }

    /// The features detected so far (none when no frame is held).
    fn features(&self) -> &[Feature] {
        if self.held {
            &self.features
        } else {
            &[]
        }
    }

    fn clear(&mut self) {
        self.held = false;
        self.detected = false;
        self.features.clear();
    }
}

/// Estimates the motion between a reference frame and later frames from
/// matched features. Holds the reference and the current frame as given
/// (copies) and reduces, detects and describes either only when an
/// estimate asks for it, at most once per frame: most frames are never
/// asked about (dense tracking alone decides them), and the reduction
/// costs about 1.9 ms per frame at 640x480 where a copy costs a fraction
/// of that (`docs/performance.md#sparse-features`).
#[derive(Debug, Clone)]
pub struct SparseEstimator {
    extractor: FeatureExtractor,
    reference: HeldFrame,
    current: HeldFrame,
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
            reference: HeldFrame::default(),
            current: HeldFrame::default(),
            matches: Vec::new(),
            a: Vec::new(),
            b: Vec::new(),
            inlier: Vec::new(),
        })
    }

    /// Keeps a copy of a frame (see [`FeatureExtractor::extract_into`] for the
    /// arguments) as the current frame; it is reduced and its corners
    /// detected only when an estimate asks for them. On error no current
    /// frame is held.
    pub fn keep_frame(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
    ) -> Result<(), FeatureError> {
        let level = self.extractor.config().level;
        self.current.keep(rgb, vertices, (width, height), level)
    }

    /// [`Self::keep_frame`] and detect at once; returns the number of features.
    pub fn extract(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
    ) -> Result<usize, FeatureError> {
        self.keep_frame(rgb, vertices, width, height)?;
        Ok(self.current().len())
    }

    /// The current frame becomes the reference (its features, if detected,
    /// go with it); no current frame is held until the next
    /// [`Self::keep_frame`].
    pub fn current_becomes_reference(&mut self) {
        std::mem::swap(&mut self.reference, &mut self.current);
        self.current.clear();
    }

    /// The reference frame as kept (RGB8, camera-frame points in metres,
    /// width, height), when one is held: for saving a session.
    #[must_use]
    pub fn reference_frame(&self) -> Option<(&[u8], &[Vec3], usize, usize)> {
        let r = &self.reference;
        r.held
            .then_some((&r.rgb[..], &r.vertices[..], r.width, r.height))
    }

    /// Holds a frame as the reference, as [`Self::reference_frame`] gave
    /// it (restoring a session); no current frame is held.
    pub fn restore_reference(
        &mut self,
        rgb: &[u8],
        vertices: &[Vec3],
        width: usize,
        height: usize,
    ) -> Result<(), FeatureError> {
        self.current.clear();
        let level = self.extractor.config().level;
        let kept = self.reference.keep(rgb, vertices, (width, height), level);
        if kept.is_err() {
            self.reference.clear();
        }
        kept
    }

    /// Forgets both frames.
    pub fn clear(&mut self) {
        self.reference.clear();
        self.current.clear();
    }

    /// Whether a reference frame is held.
    #[must_use]
    pub fn has_reference(&self) -> bool {
        self.reference.held
    }

    /// Features of the current frame (detected now if not yet).
    pub fn current(&mut self) -> &[Feature] {
        self.current.detect_with(&mut self.extractor);
        self.current.features()
    }

    /// Features of the reference frame (detected now if not yet).
    pub fn reference(&mut self) -> &[Feature] {
        self.reference.detect_with(&mut self.extractor);
        self.reference.features()
    }

    /// The motion from the current frame to the reference, or `None` when
    /// too few matches agree on one.
    pub fn estimate(&mut self) -> Option<SparseEstimate> {
        let config = *self.extractor.config();
        self.current.detect_with(&mut self.extractor);
        self.reference.detect_with(&mut self.extractor);
        let (current, reference) = (self.current.features(), self.reference.features());
        match_features_into(reference, current, &config, &mut self.matches);
        self.a.clear();
        self.b.clear();
        for &(i, j) in &self.matches {
            self.a.push(reference[i].point_in_camera);
            self.b.push(current[j].point_in_camera);
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
