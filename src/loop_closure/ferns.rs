//! Keyframe database of randomised ferns (Glocker et al., "Real-time RGB-D
//! camera relocalization via randomized ferns for keyframe encoding", TVCG
//! 2015; the scheme ElasticFusion uses).
//!
//! A frame is reduced to a small RGB-D image (default 80x60, block means of
//! the working image). Each fern is one pixel of that image and four fixed
//! random thresholds (red, green, blue, depth); its code is the 4 bits of
//! the four comparisons, or [`BAD_CODE`] where the pixel has no depth. A
//! frame without colour (every block the same colour: a depth-only
//! sequence, pushed with a constant grey image) is coded by four depth
//! thresholds instead, so that its codes tell more views apart: with one
//! depth test a fern, the depth-only long ICL-NUIM office made 5
//! keyframes in 503 frames (43 with colour) and TUM fr3/teddy 1 (14). Two
//! frames are compared by the fraction of ferns whose codes differ (the
//! block-code dissimilarity), through an inverted index (fern, code) ->
//! keyframes, so a query costs one pass over the ferns plus the keyframes
//! that share codes. A fused frame becomes a keyframe only when no keyframe
//! is similar to it, so the database grows with the places seen, not with
//! time.
//!
//! Keyframes keep their small image (colour, mean and farthest depth per
//! block): enough to render the model as the keyframe saw it and to check a
//! registration photometrically. Poses are `world_from_camera` (metres);
//! times are frame indices.

use crate::random::SplitMix;
use glam::DAffine3;
use rayon::prelude::*;
use thiserror::Error;

/// Code of a fern whose pixel has no depth: it matches nothing.
pub const BAD_CODE: u8 = u8::MAX;

/// Settings of the fern database.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FernConfig {
    /// Number of ferns (pixels tested). ElasticFusion: 500.
    pub ferns: usize,
    /// Width of the small image, pixels.
    pub width: usize,
    /// Height of the small image, pixels.
    pub height: usize,
    /// A fused frame becomes a keyframe when its dissimilarity to every
    /// keyframe is above this (0..1). ElasticFusion: 0.31.
    pub add_above: f32,
    /// Depth thresholds are drawn uniformly from this range, metres.
    pub depth_range_m: (f32, f32),
    /// A frame with fewer ferns on valid depth than this fraction is
    /// neither added nor looked up: too little of it was measured.
    pub min_good_fraction: f32,
    /// Most keyframes kept (about 55 KB each at 80x60); a full database
    /// adds no more.
    pub max_keyframes: usize,
    /// Seed of the fern tests (the same seed gives the same tests).
    pub seed: u64,
}

impl Default for FernConfig {
    fn default() -> Self {
        Self {
            ferns: 500,
            width: 80,
            height: 60,
            add_above: 0.3,
            depth_range_m: (0.4, 4.5),
            min_good_fraction: 0.25,
            max_keyframes: 500,
            seed: 0xfe42,
        }
    }
}

/// Why the fern database refused a configuration or a frame.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FernError {
    /// The configuration is unusable.
    #[error("invalid fern configuration: {0}")]
    InvalidConfig(&'static str),
    /// The frame's buffers do not match its size, or it is smaller than
    /// the small image.
    #[error("fern input of {width}x{height} with {rgb} colour and {depth} depth values does not fit a {small_width}x{small_height} code")]
    BadFrame {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Colour values given (3 per pixel expected).
        rgb: usize,
        /// Depth values given (1 per pixel expected).
        depth: usize,
        /// Width of the small image.
        small_width: usize,
        /// Height of the small image.
        small_height: usize,
    },
}

/// One fern: a pixel of the small image and four thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fern {
    pixel: usize,
    rgb: [u8; 3],
    depth_m: f32,
    /// Thresholds that stand in for the colour ones in a frame without
    /// colour, metres.
    more_depth_m: [f32; 3],
}

/// A frame reduced for the database: small image and fern codes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FernFrame {
    /// Width of the small image, pixels.
    pub width: usize,
    /// Height of the small image, pixels.
    pub height: usize,
    /// Full-resolution pixels per small pixel, horizontally and vertically,
    /// rounded down: the blocks split the input evenly, so at 256x192 they
    /// are 3 or 4 pixels wide (the small image's intrinsics divide by the
    /// exact ratio, the input's width over `width`).
    pub block: (usize, usize),
    /// Mean colour per block, RGB8, row-major.
    pub rgb: Vec<[u8; 3]>,
    /// Mean measured depth per block, metres (camera z); 0 when fewer than
    /// half of the block's pixels have depth.
    pub depth_m: Vec<f32>,
    /// Farthest measured depth per block, metres; 0 as for `depth_m`.
    pub far_m: Vec<f32>,
    /// One code per fern (4 bits, or [`BAD_CODE`]).
    pub codes: Vec<u8>,
    /// Ferns whose code is not [`BAD_CODE`].
    pub good: usize,
}

/// A keyframe: a fused frame, its pose and its reduced image.
#[derive(Debug, Clone, PartialEq)]
pub struct Keyframe {
    /// Index of the frame in the run.
    pub frame_index: u32,
    /// Pose of the frame when it was fused (camera to world, metres);
    /// moved with the map when a loop closure deforms it.
    pub world_from_camera: DAffine3,
    /// The reduced frame.
    pub frame: FernFrame,
}

/// A keyframe found for a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FernMatch {
    /// Index into [`FernDatabase::keyframes`].
    pub keyframe: usize,
    /// Fraction (0..1) of the ferns valid in both frames whose codes differ.
    pub dissimilarity: f32,
}

/// The keyframe database; see the module documentation.
#[derive(Debug, Clone)]
pub struct FernDatabase {
    config: FernConfig,
    ferns: Vec<Fern>,
    /// Per fern, per code (0..16), the keyframes with that code.
    ids: Vec<[Vec<u32>; 16]>,
    keyframes: Vec<Keyframe>,
    /// The last encoded frame.
    current: FernFrame,
    /// Per keyframe, ferns whose code equals the current frame's.
    same: Vec<u32>,
}

impl FernDatabase {
    /// An empty database with `config` (its ferns drawn from `config.seed`).
    pub fn new(config: FernConfig) -> Result<Self, FernError> {
        if config.ferns == 0 || config.ferns > 1 << 16 {
            return Err(FernError::InvalidConfig("ferns must be 1..=65536"));
        }
        if config.width == 0 || config.height == 0 || config.width * config.height > 1 << 20 {
            return Err(FernError::InvalidConfig(
                "small image must be 1..=2^20 pixels",
            ));
        }
        let (near, far) = config.depth_range_m;
        if !(near.is_finite() && far.is_finite() && 0.0 <= near && near < far) {
            return Err(FernError::InvalidConfig(
                "depth range must be 0 <= near < far",
            ));
        }
        if !(0.0..=1.0).contains(&config.add_above)
            || !(0.0..=1.0).contains(&config.min_good_fraction)
        {
            return Err(FernError::InvalidConfig(
                "add_above and min_good_fraction must be in 0..=1",
            ));
        }
        let mut rng = SplitMix::new(config.seed);
        // A stream of its own, so that the colour ferns' tests stay those
        // of the seed.
        let mut depth_rng = SplitMix::new(config.seed ^ DEPTH_ONLY_SEED);
        let pixels = config.width * config.height;
        let ferns = (0..config.ferns)
            .map(|_| Fern {
                pixel: (rng.next_u64() % pixels as u64) as usize,
                rgb: [0, 0, 0].map(|_: u8| (rng.next_u64() >> 56) as u8),
                depth_m: near + (far - near) * rng.next_f32(),
                more_depth_m: [0.0; 3].map(|_: f32| near + (far - near) * depth_rng.next_f32()),
            })
            .collect();
        Ok(Self {
            ids: vec![Default::default(); config.ferns],
            config,
            ferns,
            keyframes: Vec::new(),
            current: FernFrame::default(),
            same: Vec::new(),
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &FernConfig {
        &self.config
    }

    /// The keyframes, oldest first.
    #[must_use]
    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keyframes
    }

    /// The last frame encoded by [`Self::encode`].
    #[must_use]
    pub fn current(&self) -> &FernFrame {
        &self.current
    }

    /// Moves every keyframe's pose by `update(frame_index, pose)` (after a
    /// loop closure bends the trajectory).
    pub fn update_poses(&mut self, mut update: impl FnMut(u32, &DAffine3) -> DAffine3) {
        for k in &mut self.keyframes {
            k.world_from_camera = update(k.frame_index, &k.world_from_camera);
        }
    }

    /// Replaces the keyframes by `keyframes` (oldest first, as
    /// [`Self::keyframes`] gave them: restoring a session) and rebuilds the
    /// index. Refuses, leaving the database empty, keyframes whose codes
    /// or small image do not fit this configuration.
    pub fn restore_keyframes(&mut self, keyframes: Vec<Keyframe>) -> Result<(), FernError> {
        self.clear();
        let (w, h) = (self.config.width, self.config.height);
        let fits = |k: &Keyframe| {
            let f = &k.frame;
            f.codes.len() == self.ferns.len()
                && (f.width, f.height) == (w, h)
                && f.rgb.len() == w * h
                && f.depth_m.len() == w * h
                && f.far_m.len() == w * h
                && f.good == f.codes.iter().filter(|&&c| c != BAD_CODE).count()
                && f.codes.iter().all(|&c| c == BAD_CODE || c < 16)
                && k.world_from_camera.is_finite()
        };
        if keyframes.len() > self.config.max_keyframes || !keyframes.iter().all(fits) {
            return Err(FernError::InvalidConfig(
                "saved keyframes do not fit the fern configuration",
            ));
        }
        self.keyframes = keyframes;
        self.index_keyframes();
        Ok(())
    }

    /// Forgets the keyframes taken at frame `first` or later (their poses
    /// were found wrong); the others and their order stay.
    pub fn forget_from(&mut self, first: u32) {
        if self.keyframes.iter().all(|k| k.frame_index < first) {
            return;
        }
        let kept: Vec<Keyframe> = std::mem::take(&mut self.keyframes)
            .into_iter()
            .filter(|k| k.frame_index < first)
            .collect();
        self.keyframes = kept;
        self.index_keyframes();
    }

    /// Rebuilds the lists of keyframes by fern code from `self.keyframes`.
    fn index_keyframes(&mut self) {
        for lists in &mut self.ids {
            lists.iter_mut().for_each(Vec::clear);
        }
        for (id, k) in self.keyframes.iter().enumerate() {
            for (lists, &c) in self.ids.iter_mut().zip(&k.frame.codes) {
                if let Some(list) = lists.get_mut(usize::from(c)) {
                    list.push(id as u32);
                }
            }
        }
    }

    /// Forgets every keyframe (the ferns stay: codes stay comparable).
    pub fn clear(&mut self) {
        self.keyframes.clear();
        for lists in &mut self.ids {
            lists.iter_mut().for_each(Vec::clear);
        }
        self.current.codes.clear();
        self.current.good = 0;
    }

    /// Reduces a `width x height` frame (RGB8 `rgb`, depth `depth_m` in
    /// metres with 0 = none) to the small image and its fern codes, kept as
    /// the current frame. On error the current frame is empty.
    pub fn encode(
        &mut self,
        rgb: &[u8],
        depth_m: &[f32],
        width: usize,
        height: usize,
    ) -> Result<(), FernError> {
        let (w, h) = (self.config.width, self.config.height);
        let n = width * height;
        if rgb.len() != 3 * n || depth_m.len() != n || width < w || height < h {
            self.current.codes.clear();
            self.current.good = 0;
            return Err(FernError::BadFrame {
                width,
                height,
                rgb: rgb.len(),
                depth: depth_m.len(),
                small_width: w,
                small_height: h,
            });
        }
        downsample_into(rgb, depth_m, (width, height), &mut self.current, (w, h));
        let frame = &mut self.current;
        frame.codes.clear();
        let (small_rgb, small_depth) = (&frame.rgb, &frame.depth_m);
        let colourless = small_rgb.windows(2).all(|pair| pair[0] == pair[1]);
        if colourless {
            frame
                .codes
                .extend(self.ferns.iter().map(|f| depth_code(f, small_depth)));
        } else {
            frame
                .codes
                .extend(self.ferns.iter().map(|f| code(f, small_rgb, small_depth)));
        }
        frame.good = frame.codes.iter().filter(|&&c| c != BAD_CODE).count();
        Ok(())
    }

    /// Whether the current frame has enough ferns on valid depth to be
    /// compared (see `FernConfig::min_good_fraction`).
    #[must_use]
    pub fn current_is_usable(&self) -> bool {
        self.current.codes.len() == self.ferns.len()
            && self.current.good > 0
            && self.current.good as f32 >= self.config.min_good_fraction * self.ferns.len() as f32
    }

    /// Keyframes no more dissimilar to the current frame than
    /// `max_dissimilarity`, taken at a frame in `frames` (a loop closure
    /// wants old places; a camera lost in a restarted segment of the map,
    /// the segment's), most similar first, at most `max` of them, into
    /// `out`. Nothing when the current frame is not usable.
    pub fn query_into(
        &mut self,
        max_dissimilarity: f32,
        frames: std::ops::Range<u32>,
        max: usize,
        out: &mut Vec<FernMatch>,
    ) {
        out.clear();
        if !self.current_is_usable() {
            return;
        }
        self.count_same_codes();
        let good = self.current.good;
        out.extend(
            self.keyframes
                .iter()
                .zip(&self.same)
                .enumerate()
                .filter(|(_, (k, _))| frames.contains(&k.frame_index))
                .map(|(i, (k, &same))| FernMatch {
                    keyframe: i,
                    dissimilarity: dissimilarity(good, k.frame.good, same),
                })
                .filter(|m| m.dissimilarity <= max_dissimilarity),
        );
        out.sort_by(|a, b| {
            a.dissimilarity
                .total_cmp(&b.dissimilarity)
                .then(b.keyframe.cmp(&a.keyframe))
        });
        out.truncate(max);
    }

    /// The keyframe most similar to the current frame, if any (and the
    /// current frame is usable).
    pub fn best(&mut self) -> Option<FernMatch> {
        let mut out = Vec::with_capacity(1);
        self.query_into(1.0, 0..u32::MAX, 1, &mut out);
        out.first().copied()
    }

    /// Adds the current frame as a keyframe taken at `world_from_camera`
    /// (frame `frame_index`) when it is usable, the database is not full,
    /// and every keyframe is more dissimilar to it than
    /// `FernConfig::add_above`. Returns the new keyframe's index.
    pub fn add_if_novel(
        &mut self,
        world_from_camera: &DAffine3,
        frame_index: u32,
    ) -> Option<usize> {
        if self.keyframes.len() >= self.config.max_keyframes || !world_from_camera.is_finite() {
            return None;
        }
        if let Some(best) = self.best() {
            if best.dissimilarity <= self.config.add_above {
                return None;
            }
        } else if !self.current_is_usable() {
            return None;
        }
        let id = self.keyframes.len();
        for (lists, &c) in self.ids.iter_mut().zip(&self.current.codes) {
            if let Some(list) = lists.get_mut(usize::from(c)) {
                list.push(id as u32);
            }
        }
        self.keyframes.push(Keyframe {
            frame_index,
            world_from_camera: *world_from_camera,
            frame: self.current.clone(),
        });
        Some(id)
    }

    /// Fills `same[k]` with the ferns whose code in keyframe `k` equals the
    /// current frame's (valid codes only).
    fn count_same_codes(&mut self) {
        self.same.clear();
        self.same.resize(self.keyframes.len(), 0);
        for (lists, &c) in self.ids.iter().zip(&self.current.codes) {
            for &id in lists.get(usize::from(c)).map_or(&[][..], Vec::as_slice) {
                if let Some(s) = self.same.get_mut(id as usize) {
                    *s += 1;
                }
            }
        }
    }
}

/// Block-code dissimilarity: of the ferns that could agree (the fewer of
/// the two frames' valid ones), the fraction that do not.
fn dissimilarity(good_a: usize, good_b: usize, same: u32) -> f32 {
    let possible = good_a.min(good_b);
    if possible == 0 {
        return 1.0;
    }
    (possible as f32 - same as f32).max(0.0) / possible as f32
}

/// Mixed into the seed for the depth-only thresholds.
const DEPTH_ONLY_SEED: u64 = 0xd0_d0_d0_d0;

/// The code of a fern in a frame without colour: four depth comparisons.
fn depth_code(fern: &Fern, depth_m: &[f32]) -> u8 {
    let Some(&z) = depth_m.get(fern.pixel) else {
        return BAD_CODE;
    };
    if z <= 0.0 {
        return BAD_CODE;
    }
    let [a, b, c] = fern.more_depth_m;
    (u8::from(z > a) << 3)
        | (u8::from(z > b) << 2)
        | (u8::from(z > c) << 1)
        | u8::from(z > fern.depth_m)
}

fn code(fern: &Fern, rgb: &[[u8; 3]], depth_m: &[f32]) -> u8 {
    let (Some(&c), Some(&z)) = (rgb.get(fern.pixel), depth_m.get(fern.pixel)) else {
        return BAD_CODE;
    };
    if z <= 0.0 {
        return BAD_CODE;
    }
    (u8::from(c[0] > fern.rgb[0]) << 3)
        | (u8::from(c[1] > fern.rgb[1]) << 2)
        | (u8::from(c[2] > fern.rgb[2]) << 1)
        | u8::from(z > fern.depth_m)
}

/// Block means of colour and depth (and the farthest depth) of a
/// `width x height` frame into the `w x h` small image; blocks split the
/// image evenly (`width >= w`, `height >= h`). Blocks wider than 4 pixels
/// are sampled on a 4x4-ish grid: 640x480 in 0.25 ms rather than 0.9 ms
/// (2 cores), and a mean of 16 samples is as good a fern input as 64.
fn downsample_into(
    rgb: &[u8],
    depth_m: &[f32],
    (width, height): (usize, usize),
    out: &mut FernFrame,
    (w, h): (usize, usize),
) {
    out.width = w;
    out.height = h;
    out.block = (width / w, height / h);
    let step = ((out.block.0 / 4).max(1), (out.block.1 / 4).max(1));
    out.rgb.resize(w * h, [0; 3]);
    out.depth_m.resize(w * h, 0.0);
    out.far_m.resize(w * h, 0.0);
    out.rgb
        .par_chunks_mut(w)
        .zip(out.depth_m.par_chunks_mut(w))
        .zip(out.far_m.par_chunks_mut(w))
        .enumerate()
        .for_each(|(v, ((rgb_row, depth_row), far_row))| {
            let (y0, y1) = (v * height / h, (v + 1) * height / h);
            for u in 0..w {
                let (x0, x1) = (u * width / w, (u + 1) * width / w);
                let (mut sum, mut z_sum, mut far, mut valid) = ([0u32; 3], 0.0f32, 0.0f32, 0usize);
                let mut area = 0usize;
                for y in (y0..y1).step_by(step.1) {
                    let row = y * width;
                    for (x, &z) in depth_m[row + x0..row + x1]
                        .iter()
                        .enumerate()
                        .step_by(step.0)
                    {
                        area += 1;
                        let i = 3 * (row + x0 + x);
                        for (s, &c) in sum.iter_mut().zip(&rgb[i..i + 3]) {
                            *s += u32::from(c);
                        }
                        if z > 0.0 && z.is_finite() {
                            z_sum += z;
                            far = far.max(z);
                            valid += 1;
                        }
                    }
                }
                let area = area.max(1);
                rgb_row[u] = sum.map(|s| (s / area as u32) as u8);
                let enough = 2 * valid >= area && valid > 0;
                depth_row[u] = if enough { z_sum / valid as f32 } else { 0.0 };
                far_row[u] = if enough { far } else { 0.0 };
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(width: usize, height: usize, colour: [u8; 3], z: f32) -> (Vec<u8>, Vec<f32>) {
        let rgb = (0..width * height).flat_map(|_| colour).collect();
        (rgb, vec![z; width * height])
    }

    #[test]
    fn identical_frames_have_zero_dissimilarity_and_are_added_once() {
        let mut db = FernDatabase::new(FernConfig::default()).expect("config");
        let (rgb, depth) = flat(160, 120, [120, 60, 200], 1.7);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        assert_eq!(db.current().good, 500);
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 0), Some(0));
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        let best = db.best().expect("a match");
        assert_eq!(best.keyframe, 0);
        assert_eq!(best.dissimilarity, 0.0);
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 1), None);
        // Another colour and depth: every fern's code differs in some bit
        // unless its thresholds lie outside both values.
        let (rgb2, depth2) = flat(160, 120, [10, 250, 20], 3.9);
        db.encode(&rgb2, &depth2, 160, 120).expect("encode");
        assert!(db.best().expect("a match").dissimilarity > 0.9);
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 2), Some(1));
        // Only keyframes before frame 2 count; the old one is far.
        let mut out = Vec::new();
        db.query_into(0.5, 0..2, 5, &mut out);
        assert!(out.is_empty());
        db.clear();
        assert!(db.keyframes().is_empty());
        db.encode(&rgb2, &depth2, 160, 120).expect("encode");
        assert_eq!(db.best(), None);
    }

    #[test]
    fn frames_without_depth_or_of_the_wrong_size_are_refused() {
        let mut db = FernDatabase::new(FernConfig::default()).expect("config");
        let (rgb, depth) = flat(160, 120, [1, 2, 3], 0.0);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        assert!(!db.current_is_usable());
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 0), None);
        assert!(db.encode(&rgb, &depth, 161, 120).is_err());
        assert!(db.encode(&rgb[..30], &depth[..10], 5, 2).is_err());
        assert!(!db.current_is_usable());
        let (rgb, depth) = flat(160, 120, [1, 2, 3], f32::NAN);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        assert_eq!(db.current().good, 0);
        for bad in [
            FernConfig {
                ferns: 0,
                ..FernConfig::default()
            },
            FernConfig {
                width: 0,
                ..FernConfig::default()
            },
            FernConfig {
                depth_range_m: (2.0, 1.0),
                ..FernConfig::default()
            },
            FernConfig {
                add_above: f32::NAN,
                ..FernConfig::default()
            },
        ] {
            assert!(FernDatabase::new(bad).is_err());
        }
    }

    /// A grey frame of a depth ramp from 1 m (left) to 4 m (right),
    /// turned so that the ramp starts `shift` of the width to the left.
    fn grey_ramp(width: usize, height: usize, shift: f32) -> (Vec<u8>, Vec<f32>) {
        let rgb = vec![128; 3 * width * height];
        let depth = (0..width * height)
            .map(|i| {
                let x = (i % width) as f32 / width as f32 + shift;
                1.0 + 3.0 * x.clamp(0.0, 1.0)
            })
            .collect();
        (rgb, depth)
    }

    #[test]
    fn frames_without_colour_are_told_apart_by_depth_alone() {
        let mut db = FernDatabase::new(FernConfig::default()).expect("config");
        let (rgb, depth) = grey_ramp(160, 120, 0.0);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 0), Some(0));
        // The depths move by 0.45 m: one depth test a fern flips for about
        // 11 % of the ferns, four for about 37 %, over `add_above`.
        let (rgb, depth) = grey_ramp(160, 120, 0.15);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        let turned = db.best().expect("a match").dissimilarity;
        assert!(turned > db.config().add_above, "dissimilarity {turned}");
        assert_eq!(db.add_if_novel(&DAffine3::IDENTITY, 1), Some(1));
        // The first view again finds its keyframe, exactly.
        let (rgb, depth) = grey_ramp(160, 120, 0.0);
        db.encode(&rgb, &depth, 160, 120).expect("encode");
        let best = db.best().expect("a match");
        assert_eq!((best.keyframe, best.dissimilarity), (0, 0.0));
        // The colour tests' bits carry depth tests: the ramp shows more
        // than the two codes a fern could take with one depth test.
        let distinct = (0..16u8).filter(|c| db.current().codes.contains(c)).count();
        assert!(distinct > 2, "{distinct} distinct codes");
    }

    #[test]
    fn block_means_follow_the_image() {
        let mut db = FernDatabase::new(FernConfig {
            width: 2,
            height: 1,
            ferns: 4,
            ..FernConfig::default()
        })
        .expect("config");
        // 4x2: left half red at 1 m, right half blue, depth only on one row.
        let mut rgb = Vec::new();
        let mut depth = Vec::new();
        for y in 0..2 {
            for x in 0..4 {
                rgb.extend(if x < 2 { [200, 0, 0] } else { [0, 0, 100] });
                depth.push(if x < 2 {
                    1.0 + x as f32
                } else if y == 0 {
                    3.0
                } else {
                    0.0
                });
            }
        }
        db.encode(&rgb, &depth, 4, 2).expect("encode");
        let f = db.current();
        assert_eq!(f.rgb, vec![[200, 0, 0], [0, 0, 100]]);
        assert_eq!(f.depth_m, vec![1.5, 3.0]);
        assert_eq!(f.far_m, vec![2.0, 3.0]);
        assert_eq!(f.block, (2, 2));
    }
}
