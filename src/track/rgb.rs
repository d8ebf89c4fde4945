//! Direct (photometric) alignment, one Gauss-Newton step, frame-to-model.
//!
//! The reference is the model prediction: a selected pixel of it gives a
//! point `p` (world frame) and a grey level `I_ref`. The current estimate
//! `camera_from_world` moves it to `p' = T p = (x, y, z)` in the camera frame;
//! its pinhole projection into the frame's pyramid level is
//! `u = fx x / z + cx`, `v = fy y / z + cy`, where the current image `I_cur`
//! is sampled bilinearly. The residual, in grey levels scaled to `0..1`
//! (divided by 255, so that the joint weight compares metres with a fraction
//! of the grey range), is
//!
//! ```text
//! r = (I_cur(pi(p')) - gain I_ref - bias) / 255
//! ```
//!
//! (the negative of `e = gain I_ref + bias - I_cur`, so `J = -de/dxi = dr/dxi`),
//! with `gain` and `bias` fitted by least squares over the usable pixels at
//! the step's estimate (an auto-exposure change is no motion; 1 and 0 with
//! [`PhotometricConfig::affine_brightness`] off).
//!
//! # Jacobian
//!
//! The increment is applied on the left, in the camera frame, as in the ICP
//! step: `exp(xi) p' ~= p' + w x p' + t` with `xi = [w, t]`. By the chain rule
//! `dr/dxi = (1/255) * g^T * du/dp' * dp'/dxi`, where
//!
//! - `g = [Ix, Iy]` is the current image's gradient at `pi(p')` (central
//!   differences per level, sampled bilinearly), grey levels per pixel;
//! - `du/dp'` is the 2x3 derivative of the projection,
//!   `[[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]]`;
//! - `dp'/dxi = [-[p']_x, I]`, because `w x p' = -[p']_x w`.
//!
//! Multiplying the first two gives a 3-vector `c = g^T du/dp'` (how the
//! intensity changes when `p'` moves): the translation part of the row is
//! `c` itself, and the rotation part is `c . (w x p') = w . (p' x c)`, i.e.
//! `p' x c`. So each selected pixel adds the row `[(p' x c)^T, c^T] / 255`,
//! the same shape as a point-to-plane row `[(p' x n)^T, n^T]` with the plane
//! normal replaced by the intensity-change direction `c`. Stacked with the
//! 2x6 pinhole/SE(3) block written out, `du/dxi` is
//!
//! ```text
//! [ -fx x y / z^2        fx (1 + x^2/z^2)  -fx y / z   fx / z   0       -fx x / z^2 ]
//! [ -fy (1 + y^2/z^2)    fy x y / z^2       fy x / z   0        fy / z  -fy y / z^2 ]
//! ```
//!
//! # Selection and robustness
//!
//! Only reference pixels with a model surfel, a full neighbourhood and a
//! reference gradient of at least `min_gradient` (grey levels per full
//! resolution pixel, per level) are used: flat pixels add cost but no
//! information. They are selected once per frame (the prediction does not
//! change during tracking) into a list reused across frames. A pixel is
//! skipped when its warped depth disagrees with the frame's depth by more than
//! `max_depth_delta_m` (occlusion, or a surfel not yet seen from here), and
//! each residual gets a Huber weight.

use crate::fusion::Prediction;
use crate::ordered_sum::sum_in_blocks;
use crate::preprocess::{FramePyramid, PyramidLevel};
use crate::se3::NormalEquations;
use crate::se3::RigidF32;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Grey levels (0..255) to the residual's unit.
const INTENSITY_SCALE: f32 = 1.0 / 255.0;

/// Reference pixels per parallel task.
const CHUNK: usize = 2048;

/// Where the photometric reference (grey levels and their 3D points) comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum PhotometricReference {
    /// The model prediction's fused colour (frame-to-model).
    #[default]
    Model,
    /// The last tracked frame's own image and depth at its estimated pose
    /// (frame-to-frame, like a keyframe that is renewed every frame).
    LastFrame,
}

/// Settings of the photometric term.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhotometricConfig {
    /// Reference image.
    pub reference: PhotometricReference,
    /// Smallest reference gradient magnitude per level, finest first, grey
    /// levels (0..255) per pixel of that level.
    pub min_gradient: Vec<f32>,
    /// Largest difference between a warped reference depth and the frame's
    /// depth at that pixel, metres.
    pub max_depth_delta_m: f32,
    /// Huber threshold on the residual, in `0..1` grey units.
    pub huber: f32,
    /// Compare the frame with the reference through a gain and bias
    /// (`I_cur ~ gain I_ref + bias`) fitted at every step, as DSO and
    /// ElasticFusion's successors do: an auto-exposure change is then no
    /// motion. Without it a 25 % exposure step leaves residuals of tens of
    /// grey levels that only correlate with the reference's brightness.
    #[serde(default = "affine_brightness_default")]
    pub affine_brightness: bool,
}

fn affine_brightness_default() -> bool {
    true
}

impl Default for PhotometricConfig {
    fn default() -> Self {
        Self {
            reference: PhotometricReference::default(),
            min_gradient: vec![5.0, 3.0, 1.0],
            max_depth_delta_m: 0.07,
            huber: 10.0 / 255.0,
            affine_brightness: affine_brightness_default(),
        }
    }
}

/// A selected reference pixel of the model prediction.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReferencePoint {
    /// Surfel centre, world frame, metres.
    pub point_in_world: Vec3,
    /// Model grey level, 0..255.
    pub intensity: f32,
}

/// Normal equations of one photometric step.
#[derive(Debug, Clone, Copy)]
pub struct RgbStep {
    /// Accumulated system in `0..1` grey units; `count` = residuals used.
    pub system: NormalEquations,
    /// Reference points that projected into the image.
    pub candidates: usize,
    /// The brightness fit the residuals were taken through
    /// (`I_cur ~ gain I_ref + bias`, grey levels); (1, 0) without it.
    pub gain_bias: (f32, f32),
}

impl Default for RgbStep {
    fn default() -> Self {
        Self {
            system: NormalEquations::default(),
            candidates: 0,
            gain_bias: (1.0, 0.0),
        }
    }
}

/// Sums of the brightness fit over the usable reference pixels.
#[derive(Debug, Clone, Copy, Default)]
struct BrightnessSums {
    n: f64,
    reference: f64,
    current: f64,
    reference2: f64,
    cross: f64,
}

impl BrightnessSums {
    fn merged(self, o: Self) -> Self {
        Self {
            n: self.n + o.n,
            reference: self.reference + o.reference,
            current: self.current + o.current,
            reference2: self.reference2 + o.reference2,
            cross: self.cross + o.cross,
        }
    }

    /// Least-squares gain and bias, the gain kept within 0.5..2 (an
    /// exposure step, not a change of scene); (1, mean difference) when the
    /// reference's brightness barely varies.
    fn gain_bias(&self) -> (f32, f32) {
        if self.n < 16.0 {
            return (1.0, 0.0);
        }
        let (mr, mc) = (self.reference / self.n, self.current / self.n);
        let var = self.reference2 / self.n - mr * mr;
        let cov = self.cross / self.n - mr * mc;
        let gain = if var > 1.0 {
            (cov / var).clamp(0.5, 2.0)
        } else {
            1.0
        };
        (gain as f32, (mc - gain * mr) as f32)
    }
}

/// Buffers of one pyramid level, reused frame after frame.
#[derive(Debug, Default, Clone)]
struct LevelBuffers {
    /// Per pixel of the frame's level: grey level, d/du, d/dv (grey levels per pixel).
    image: Vec<[f32; 3]>,
    /// Selected reference pixels of the prediction at this level's stride.
    references: Vec<ReferencePoint>,
}

/// Reusable photometric state of one frame: current-image gradients and the
/// selected reference pixels, per pyramid level.
#[derive(Debug, Default, Clone)]
pub struct RgbWorkspace {
    levels: Vec<LevelBuffers>,
}

impl RgbWorkspace {
    /// Computes the frame's gradients and selects the prediction's reference
    /// pixels for every level; call once per frame before [`Self::step`].
    pub fn prepare(
        &mut self,
        pyramid: &FramePyramid,
        prediction: &Prediction,
        config: &PhotometricConfig,
    ) {
        self.levels
            .resize_with(pyramid.levels.len(), LevelBuffers::default);
        for (l, (level, buffers)) in pyramid.levels.iter().zip(&mut self.levels).enumerate() {
            gradients_into(level, &mut buffers.image);
            if config.reference == PhotometricReference::Model {
                let threshold = level_threshold(config, l);
                select_references_into(prediction, 1 << l, threshold, &mut buffers.references);
            }
        }
    }

    /// With [`PhotometricReference::LastFrame`], keeps the tracked frame's
    /// pixels (placed in the world by `world_from_camera`) as the next frame's
    /// reference; otherwise does nothing.
    pub fn remember_frame(
        &mut self,
        pyramid: &FramePyramid,
        world_from_camera: &glam::DAffine3,
        config: &PhotometricConfig,
    ) {
        if config.reference != PhotometricReference::LastFrame {
            return;
        }
        let world_from_camera = RigidF32::from_affine(world_from_camera);
        self.levels
            .resize_with(pyramid.levels.len(), LevelBuffers::default);
        for (l, (level, buffers)) in pyramid.levels.iter().zip(&mut self.levels).enumerate() {
            gradients_into(level, &mut buffers.image);
            let threshold2 = level_threshold(config, l).powi(2);
            buffers.references.clear();
            if level.vertices.len() != buffers.image.len() {
                continue;
            }
            for (p, &[i, gx, gy]) in level.vertices.iter().zip(&buffers.image) {
                if p.z > 0.0 && gx * gx + gy * gy >= threshold2 {
                    buffers.references.push(ReferencePoint {
                        point_in_world: world_from_camera.point(*p),
                        intensity: i,
                    });
                }
            }
        }
    }

    /// The reference pixels of every level, coarsest last: with
    /// [`PhotometricReference::LastFrame`] the memory of the last tracked
    /// frame (for saving a session).
    pub fn references(&self) -> impl Iterator<Item = &[ReferencePoint]> {
        self.levels.iter().map(|l| &l.references[..])
    }

    /// Restores the reference pixels of every level as
    /// [`Self::references`] gave them.
    pub fn restore_references(&mut self, levels: Vec<Vec<ReferencePoint>>) {
        self.levels.resize_with(levels.len(), LevelBuffers::default);
        for (buffers, references) in self.levels.iter_mut().zip(levels) {
            buffers.references = references;
        }
    }

    /// Number of reference pixels selected at `level`.
    #[must_use]
    pub fn reference_count(&self, level: usize) -> usize {
        self.levels.get(level).map_or(0, |b| b.references.len())
    }

    /// Builds the photometric normal equations at one level for the estimate
    /// `camera_from_world`; empty when `prepare` has not covered `level`.
    #[must_use]
    pub fn step(
        &self,
        level: usize,
        target: &PyramidLevel,
        camera_from_world: &RigidF32,
        config: &PhotometricConfig,
    ) -> RgbStep {
        let (Some(buffers), Some(k)) = (self.levels.get(level), target.intrinsics) else {
            return RgbStep::default();
        };
        let (w, h) = (k.width, k.height);
        if buffers.image.len() != w * h || target.depth.len() != w * h || w < 3 || h < 3 {
            return RgbStep::default();
        }
        let image = &buffers.image;
        let depth = &target.depth;
        let huber = config.huber;
        let max_delta = config.max_depth_delta_m;
        // Bilinear sampling needs (u, v) and (u + 1, v + 1) inside, and the
        // gradient is zero on the border row and column: stay one pixel in.
        let (u_max, v_max) = ((w - 2) as f32, (h - 2) as f32);
        let references = &buffers.references;
        // The reference's point in the frame, and the frame's grey level and
        // gradient there, where the frame's depth agrees.
        let sample = |reference: &ReferencePoint| {
            let p = camera_from_world.point(reference.point_in_world);
            if p.z <= 0.0 {
                return None;
            }
            let px = k.project(p);
            if !(px.x >= 1.0 && px.y >= 1.0 && px.x < u_max && px.y < v_max) {
                return None;
            }
            let nearest = (px.y + 0.5) as usize * w + (px.x + 0.5) as usize;
            let d = depth.get(nearest).copied().unwrap_or(0.0);
            let agrees = d > 0.0 && (d - p.z).abs() <= max_delta;
            Some((p, agrees.then(|| bilinear(image, w, px))))
        };
        let gain_bias = if config.affine_brightness {
            sum_in_blocks(
                references.len(),
                CHUNK,
                |range| {
                    let mut sums = BrightnessSums::default();
                    for reference in &references[range] {
                        if let Some((_, Some([i, _, _]))) = sample(reference) {
                            let (r, c) = (f64::from(reference.intensity), f64::from(i));
                            sums.n += 1.0;
                            sums.reference += r;
                            sums.current += c;
                            sums.reference2 += r * r;
                            sums.cross += r * c;
                        }
                    }
                    sums
                },
                BrightnessSums::merged,
            )
            .gain_bias()
        } else {
            (1.0, 0.0)
        };
        let (gain, bias) = gain_bias;
        // Fixed chunks summed in order: the same bits on any thread count.
        let mut step = sum_in_blocks(
            references.len(),
            CHUNK,
            |range| {
                let mut acc = RgbStep::default();
                for reference in &references[range] {
                    let Some((p, at)) = sample(reference) else {
                        continue;
                    };
                    acc.candidates += 1;
                    let Some([i, gx, gy]) = at else {
                        continue;
                    };
                    let r = (i - gain * reference.intensity - bias) * INTENSITY_SCALE;
                    let inv_z = 1.0 / p.z;
                    let cu = gx * k.fx * inv_z;
                    let cv = gy * k.fy * inv_z;
                    let c = Vec3::new(cu, cv, -(cu * p.x + cv * p.y) * inv_z) * INTENSITY_SCALE;
                    let rot = p.cross(c);
                    let weight = if r.abs() <= huber {
                        1.0
                    } else {
                        huber / r.abs()
                    };
                    acc.system
                        .add(&[rot.x, rot.y, rot.z, c.x, c.y, c.z], r, weight);
                }
                acc
            },
            |a, b| RgbStep {
                system: a.system.merged(&b.system),
                candidates: a.candidates + b.candidates,
                gain_bias: (1.0, 0.0),
            },
        );
        step.gain_bias = gain_bias;
        step
    }
}

/// The gradient threshold of level `l` (the last one given for coarser levels).
fn level_threshold(config: &PhotometricConfig, l: usize) -> f32 {
    config
        .min_gradient
        .get(l)
        .or(config.min_gradient.last())
        .copied()
        .unwrap_or(0.0)
}

/// Bilinear sample of `[grey, d/du, d/dv]` at `px`; the caller keeps `px`
/// at least one pixel inside the image.
#[inline]
fn bilinear(image: &[[f32; 3]], w: usize, px: Vec2) -> [f32; 3] {
    let (u0, v0) = (px.x.floor(), px.y.floor());
    let (fu, fv) = (px.x - u0, px.y - v0);
    let i = v0 as usize * w + u0 as usize;
    let at = |j: usize| image.get(j).copied().unwrap_or([0.0; 3]);
    let (a, b, c, d) = (at(i), at(i + 1), at(i + w), at(i + w + 1));
    let mut out = [0.0; 3];
    for ch in 0..3 {
        let top = a[ch] + fu * (b[ch] - a[ch]);
        let bottom = c[ch] + fu * (d[ch] - c[ch]);
        out[ch] = top + fv * (bottom - top);
    }
    out
}

/// Grey level and central-difference gradient of a level (zero gradient on the border).
fn gradients_into(level: &PyramidLevel, out: &mut Vec<[f32; 3]>) {
    let Some(k) = level.intrinsics else {
        out.clear();
        return;
    };
    let (w, h) = (k.width, k.height);
    let grey = &level.intensity;
    out.resize(w * h, [0.0; 3]);
    if grey.len() != w * h {
        out.iter_mut().for_each(|p| *p = [0.0; 3]);
        return;
    }
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        let base = v * w;
        for (u, px) in row.iter_mut().enumerate() {
            let i = grey[base + u];
            if u == 0 || v == 0 || u + 1 == w || v + 1 == h {
                *px = [i, 0.0, 0.0];
                continue;
            }
            let gx = 0.5 * (grey[base + u + 1] - grey[base + u - 1]);
            let gy = 0.5 * (grey[base + u + w] - grey[base + u - w]);
            *px = [i, gx, gy];
        }
    });
}

/// Prediction pixels on a grid of step `stride` whose grey-level gradient
/// (central differences over `stride` pixels, in grey levels per grid step)
/// is at least `threshold`.
fn select_references_into(
    prediction: &Prediction,
    stride: usize,
    threshold: f32,
    out: &mut Vec<ReferencePoint>,
) {
    out.clear();
    let Some(k) = prediction.intrinsics else {
        return;
    };
    let (w, h) = (k.width, k.height);
    let n = w * h;
    if prediction.vertices.len() != n
        || prediction.normals.len() != n
        || prediction.intensity.len() != n
        || w <= 2 * stride
        || h <= 2 * stride
    {
        return;
    }
    let valid = |j: usize| prediction.normals[j] != Vec3::ZERO;
    let grey = &prediction.intensity;
    let threshold2 = threshold * threshold;
    let row = |v: usize| {
        (stride..w - stride)
            .step_by(stride)
            .map(move |u| v * w + u)
            .filter(move |&j| {
                let (l, r, t, b) = (j - stride, j + stride, j - stride * w, j + stride * w);
                if !(valid(j) && valid(l) && valid(r) && valid(t) && valid(b)) {
                    return false;
                }
                let gx = 0.5 * (grey[r] - grey[l]);
                let gy = 0.5 * (grey[b] - grey[t]);
                gx * gx + gy * gy >= threshold2
            })
            .map(|j| ReferencePoint {
                point_in_world: prediction.vertices[j],
                intensity: grey[j],
            })
    };
    // Rows on the pool: the finest level's scan was a serial stretch of the
    // joint tracker's frame; `par_extend` keeps the rows' order.
    let rows = (stride..h - stride).into_par_iter().step_by(stride);
    out.par_extend(rows.flat_map_iter(row));
}
