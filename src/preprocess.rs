//! Per-frame preprocessing: bilateral filter, depth and intensity pyramids,
//! and vertex and normal maps per level, all in the camera frame (metres).
//!
//! Buffers are allocated once per resolution and reused frame after frame.
//! Invalid pixels carry depth 0, vertex `Vec3::ZERO` and normal `Vec3::ZERO`.

use crate::camera::Intrinsics;
use crate::frame::RgbdFrame;
use crate::noise::SensorNoise;
use glam::Vec3;
use rayon::prelude::*;

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
mod simd128;

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
mod bilateral_simd128;

mod bilateral;
use bilateral::bilateral_into;

mod downsample;
use downsample::{downsample_depth, downsample_deviation, downsample_mean};

pub mod camera_fixed;
mod range_domain;
pub use range_domain::range_knee_m;
use range_domain::{from_range_domain, to_range_domain};

/// Settings of the preprocessing stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PreprocessConfig {
    /// Apply the bilateral filter to the depth used for tracking and normals.
    pub bilateral: bool,
    /// Bilateral spatial sigma, pixels.
    pub sigma_space_px: f32,
    /// Bilateral range sigma, metres (at the depths where the sensor's noise
    /// is below it; see `range_noise_factor`).
    pub sigma_depth_m: f32,
    /// The range sigma follows the sensor's depth noise where this many
    /// axial deviations exceed `sigma_depth_m`: beyond that depth (the
    /// *knee*, [`range_knee_m`]) the filter compares depths in a domain
    /// where steps shrink as `(knee / z)^2`, so its range sigma grows as
    /// disparity noise does. 0 keeps it constant.
    ///
    /// A constant 3 cm does not smooth Kinect-v1 depth beyond 3 m, whose
    /// disparity steps are 3-9 cm there: the normals of far surfaces
    /// scatter past the tracker's 20-degree gate. On the long ICL-NUIM
    /// office with `--simulate-noise kinect-v1`, seeds 1 / 2 / 3, ATE and
    /// tracked frames off the truth's motion by more than 1 cm or 1 degree
    /// (`--frame-log`), by factor: 0 (constant): 0.539 / 0.547 / 0.653 cm,
    /// 4 / 6 / 7 off, 3 / 2 / 3 lost; 2: 0.296 / 0.368 / 0.406 cm,
    /// 1 / 0 / 1 off, none lost; 2.5: 0.386 / 0.378 / 0.372 cm, none off,
    /// none lost; 3: 0.664 / 0.734 / 0.722, 1 off each. The 7-Scenes
    /// kitchen (Kinect v1, knee 2.78 m) 2.582 -> 2.573 cm. Sensors whose
    /// model has no quadratic term (TUM's uniform, clean renderings) are
    /// unchanged (`docs/design.md`, "Defaults per preset").
    #[serde(default = "default_range_noise_factor")]
    pub range_noise_factor: f32,
    /// Bilateral window radius, pixels (6 gives the published 13x13 window).
    pub window_radius: usize,
    /// Bilateral taps every this many pixels across the window: 1 is the
    /// dense published filter; 2 (7x7 taps spread over 13x13) is 3.4x
    /// cheaper for the same smoothing scale (`docs/performance.md#tap-stride`).
    pub tap_stride: usize,
    /// Number of pyramid levels (level 0 = full resolution).
    pub levels: usize,
    /// Near parts of the image that stay put through this many frames in
    /// a row while the camera moves lose their depth (a hand holding the
    /// camera: [`camera_fixed`]); 0 = never.
    #[serde(default = "default_camera_fixed_frames")]
    pub camera_fixed_frames: u8,
}

/// [`PreprocessConfig::camera_fixed_frames`]'s default (also for sessions
/// saved before it existed).
fn default_camera_fixed_frames() -> u8 {
    6
}

/// [`PreprocessConfig::range_noise_factor`]'s default (also for sessions
/// saved before it existed).
fn default_range_noise_factor() -> f32 {
    2.5
}

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self {
            bilateral: true,
            sigma_space_px: 4.5,
            sigma_depth_m: 0.03,
            range_noise_factor: default_range_noise_factor(),
            window_radius: 6,
            tap_stride: 2,
            levels: 3,
            camera_fixed_frames: default_camera_fixed_frames(),
        }
    }
}

/// One pyramid level: depth, vertices, normals and intensity, row-major.
#[derive(Debug, Clone, Default)]
pub struct PyramidLevel {
    /// Intrinsics of this level.
    pub intrinsics: Option<Intrinsics>,
    /// Depth along +z, metres, 0 = invalid.
    pub depth: Vec<f32>,
    /// Back-projected points, camera frame, metres; `ZERO` where invalid.
    pub vertices: Vec<Vec3>,
    /// Unit normals facing the camera, camera frame; `ZERO` where undefined.
    pub normals: Vec<Vec3>,
    /// Grey level in 0..255.
    pub intensity: Vec<f32>,
    /// Multiplier (>= 1) of the sensor model's depth deviation per pixel
    /// ([`RgbdFrame::depth_deviation`]; a coarse pixel's is the mean of its
    /// 2x2 block's); empty = 1 at every pixel.
    pub depth_deviation: Vec<f32>,
}

impl PyramidLevel {
    /// Multiplier of the depth deviation at pixel `i`: 1 where the level
    /// carries none.
    #[inline]
    #[must_use]
    pub fn depth_deviation_at(&self, i: usize) -> f32 {
        self.depth_deviation.get(i).copied().unwrap_or(1.0)
    }
}

/// Narrowest pyramid level [`FramePyramid::check_level`] samples, pixels:
/// the coarsest level of a 640x480 frame, on which the free-space limits
/// were measured.
pub const CHECK_LEVEL_MIN_WIDTH: usize = 160;

/// The preprocessed frame: the pyramid for tracking and fusion.
///
/// Level 0's vertices come from the *unfiltered* depth and its normals from
/// the bilateral-filtered depth: the filter smooths normals well but biases
/// positions on slanted surfaces (depth is convex in pixel coordinates, so a
/// window average over-estimates it), which would show up as drift. Coarser
/// levels are built from the filtered depth; they only seed the finer ones.
#[derive(Debug, Clone, Default)]
pub struct FramePyramid {
    /// Levels, finest first.
    pub levels: Vec<PyramidLevel>,
    /// Full-resolution vertices from the filtered depth (normals are computed from these).
    filtered_vertices: Vec<Vec3>,
    /// Full-resolution colour, RGB8 interleaved.
    pub rgb: Vec<u8>,
    /// Bilateral taps: pixel offset and spatial weight.
    taps: Vec<(isize, isize, f32)>,
    /// Bilateral weight sums, full resolution.
    weights: Vec<f32>,
    /// The input depth in the range domain ([`to_range_domain`]), full resolution.
    range_domain: Vec<f32>,
    /// Whether `build` fills the levels' `intensity` (only the photometric
    /// term reads it). On unless turned off.
    pub with_intensity: bool,
}

impl FramePyramid {
    /// Allocates buffers for frames of the given intrinsics.
    #[must_use]
    pub fn new(intrinsics: &Intrinsics, config: &PreprocessConfig) -> Self {
        let levels = (0..config.levels.max(1))
            .map(|l| {
                let k = intrinsics.level(l);
                let n = k.pixel_count();
                PyramidLevel {
                    intrinsics: Some(k),
                    depth: vec![0.0; n],
                    vertices: vec![Vec3::ZERO; n],
                    normals: vec![Vec3::ZERO; n],
                    intensity: vec![0.0; n],
                    depth_deviation: Vec::new(),
                }
            })
            .collect();
        let r = config.window_radius as isize;
        let step = config.tap_stride.max(1);
        let taps = (-r..=r)
            .step_by(step)
            .flat_map(|dy| (-r..=r).step_by(step).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| {
                let d2 = (dx * dx + dy * dy) as f32;
                (
                    dx,
                    dy,
                    libm::expf(-d2 / (2.0 * config.sigma_space_px.powi(2))),
                )
            })
            .collect();
        let n = intrinsics.pixel_count();
        Self {
            levels,
            filtered_vertices: vec![Vec3::ZERO; n],
            rgb: vec![0; 3 * n],
            taps,
            weights: vec![0.0; n],
            range_domain: Vec::new(),
            with_intensity: true,
        }
    }

    /// Fills every level from `frame`, which must match the intrinsics' size;
    /// `noise` is the sensor's, for the bilateral filter's range sigma
    /// ([`PreprocessConfig::range_noise_factor`]).
    pub fn build(&mut self, frame: &RgbdFrame, config: &PreprocessConfig, noise: &SensorNoise) {
        let Some(k0) = self.levels.first().and_then(|l| l.intrinsics) else {
            return;
        };
        let w = k0.width;
        self.rgb.copy_from_slice(&frame.rgb);
        {
            let level0 = &mut self.levels[0];
            if config.bilateral {
                let knee = range_knee_m(config, noise);
                let input = match knee {
                    Some(knee) => {
                        self.range_domain.resize(frame.depth_m.len(), 0.0);
                        self.range_domain
                            .par_iter_mut()
                            .zip(frame.depth_m.par_iter())
                            .for_each(|(g, &z)| *g = to_range_domain(z, knee));
                        &self.range_domain
                    }
                    None => &frame.depth_m,
                };
                bilateral_into(
                    input,
                    w,
                    &self.taps,
                    1.0 / (2.0 * config.sigma_depth_m * config.sigma_depth_m),
                    &mut self.weights,
                    &mut level0.depth,
                );
                if let Some(knee) = knee {
                    level0
                        .depth
                        .par_iter_mut()
                        .for_each(|g| *g = from_range_domain(*g, knee));
                }
            } else {
                level0.depth.copy_from_slice(&frame.depth_m);
            }
            level0.depth_deviation.clone_from(&frame.depth_deviation);
            if self.with_intensity {
                level0
                    .intensity
                    .par_iter_mut()
                    .zip(frame.rgb.par_chunks_exact(3))
                    .for_each(|(i, c)| {
                        *i = 0.299 * f32::from(c[0])
                            + 0.587 * f32::from(c[1])
                            + 0.114 * f32::from(c[2]);
                    });
            }
        }
        for l in 1..self.levels.len() {
            let (fine, coarse) = self.levels.split_at_mut(l);
            let fine = &fine[l - 1];
            let coarse = &mut coarse[0];
            let fw = fine.intrinsics.map_or(0, |k| k.width);
            let cw = coarse.intrinsics.map_or(0, |k| k.width);
            downsample_depth(
                &fine.depth,
                fw,
                &mut coarse.depth,
                cw,
                3.0 * config.sigma_depth_m,
            );
            if self.with_intensity {
                downsample_mean(&fine.intensity, fw, &mut coarse.intensity, cw);
            }
            let ch = coarse.intrinsics.map_or(0, |k| k.height);
            downsample_deviation(
                &fine.depth_deviation,
                fw,
                &mut coarse.depth_deviation,
                (cw, ch),
            );
        }
        for (l, level) in self.levels.iter_mut().enumerate() {
            let Some(k) = level.intrinsics else {
                continue;
            };
            if l == 0 {
                back_project_into(&k, &level.depth, &mut self.filtered_vertices);
                normals_into(&self.filtered_vertices, k.width, &mut level.normals);
                back_project_into(&k, &frame.depth_m, &mut level.vertices);
            } else {
                back_project_into(&k, &level.depth, &mut level.vertices);
                normals_into(&level.vertices, k.width, &mut level.normals);
            }
        }
    }

    /// The level the free-space checks sample: the coarsest one at least
    /// [`CHECK_LEVEL_MIN_WIDTH`] pixels wide, else the finest. A pixel
    /// straddling a depth edge may land on the far side of the model's
    /// edge, and the band of such pixels grows with the pixel's size: on
    /// the noisy long office tracked at half resolution, sampled at 80x60,
    /// right poses put 8-13 % of the points in free space, over the 10 %
    /// limit (98 cm ATE), against 2-5 % sampled at 160x120.
    #[must_use]
    pub fn check_level(&self) -> Option<&PyramidLevel> {
        self.levels
            .iter()
            .rev()
            .find(|l| {
                l.intrinsics
                    .is_some_and(|k| k.width >= CHECK_LEVEL_MIN_WIDTH)
            })
            .or(self.levels.first())
    }
}

/// Halves a frame's resolution into `out` (buffers reused): depth by the 2x2
/// average of the samples within `gate_m` of the block's first valid one (so
/// edges are not blended into phantom surfaces), colour by the 2x2 mean.
/// Pair with [`Intrinsics::half`].
pub fn half_resolution_into(frame: &RgbdFrame, gate_m: f32, out: &mut RgbdFrame) {
    let (w, h) = (frame.width / 2, frame.height / 2);
    out.width = w;
    out.height = h;
    out.depth_m.resize(w * h, 0.0);
    out.rgb.resize(3 * w * h, 0);
    downsample_depth(&frame.depth_m, frame.width, &mut out.depth_m, w, gate_m);
    downsample_deviation(
        &frame.depth_deviation,
        frame.width,
        &mut out.depth_deviation,
        (w, h),
    );
    let fw = frame.width;
    out.rgb
        .par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(v, row)| {
            for (u, o) in row.chunks_exact_mut(3).enumerate() {
                let a = 3 * ((2 * v) * fw + 2 * u);
                let b = a + 3 * fw;
                for (c, oc) in o.iter_mut().enumerate() {
                    let sum = u16::from(frame.rgb[a + c])
                        + u16::from(frame.rgb[a + 3 + c])
                        + u16::from(frame.rgb[b + c])
                        + u16::from(frame.rgb[b + 3 + c]);
                    *oc = ((sum + 2) / 4) as u8;
                }
            }
        });
}

/// Back-projects a depth image (metres) into camera-frame vertices.
pub fn back_project_into(k: &Intrinsics, depth: &[f32], out: &mut [Vec3]) {
    let w = k.width;
    out.par_chunks_mut(w)
        .zip(depth.par_chunks(w))
        .enumerate()
        .for_each(|(v, (out_row, d_row))| {
            // The wasm module does four pixels at a time up to `from`.
            #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
            let from = simd128::back_project_row(k, v, d_row, out_row);
            #[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
            let from = back_project_blocks(k, v, d_row, out_row);
            for (u, (o, &d)) in out_row.iter_mut().zip(d_row).enumerate().skip(from) {
                *o = if d > 0.0 {
                    k.back_project(u as f32, v as f32, d)
                } else {
                    Vec3::ZERO
                };
            }
        });
}

/// Row `v` of [`back_project_into`] in blocks of eight pixels, the same
/// arithmetic as [`Intrinsics::back_project`] lane by lane (so the same
/// bits); returns the first column left for the scalar loop. Laid out as
/// arrays so that the compiler divides four or eight pixels at once: one
/// pixel at a time, this loop held a fifth of the frame's samples, most
/// on its division ([performance](../docs/performance.md#back-projection)).
#[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
#[inline]
fn back_project_blocks(k: &Intrinsics, v: usize, depth: &[f32], out: &mut [Vec3]) -> usize {
    const LANES: usize = 8;
    let v_cy = v as f32 - k.cy;
    let mut u0 = 0;
    for (o, d) in out.chunks_exact_mut(LANES).zip(depth.chunks_exact(LANES)) {
        let mut x = [0.0f32; LANES];
        let mut y = [0.0f32; LANES];
        for i in 0..LANES {
            x[i] = ((u0 + i) as f32 - k.cx) * d[i] / k.fx;
            y[i] = v_cy * d[i] / k.fy;
        }
        for i in 0..LANES {
            o[i] = if d[i] > 0.0 {
                Vec3::new(x[i], y[i], d[i])
            } else {
                Vec3::ZERO
            };
        }
        u0 += LANES;
    }
    u0
}

/// Normals from central differences of the vertex map, oriented towards the camera.
///
/// Undefined (ZERO) at the border, next to invalid pixels, and across depth
/// jumps larger than 5% of the depth plus 2 cm, so that silhouettes get no
/// normal rather than a wrong one.
pub fn normals_into(vertices: &[Vec3], w: usize, out: &mut [Vec3]) {
    let h = vertices.len() / w;
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        // The wasm module does the interior four pixels at a time up to `from`.
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        let from = if v > 0 && v + 1 < h {
            simd128::normals_row(vertices, w, v, row)
        } else {
            0
        };
        #[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
        let from = 0;
        for (u, o) in row.iter_mut().enumerate().skip(from) {
            *o = normal_at(vertices, w, h, u, v);
        }
    });
}

/// The normal of pixel `(u, v)` for [`normals_into`].
#[inline(always)]
fn normal_at(vertices: &[Vec3], w: usize, h: usize, u: usize, v: usize) -> Vec3 {
    if u == 0 || v == 0 || u + 1 >= w || v + 1 >= h {
        return Vec3::ZERO;
    }
    let c = vertices[v * w + u];
    if c.z <= 0.0 {
        return Vec3::ZERO;
    }
    let l = vertices[v * w + u - 1];
    let r = vertices[v * w + u + 1];
    let t = vertices[(v - 1) * w + u];
    let b = vertices[(v + 1) * w + u];
    let jump = 0.05 * c.z + 0.02;
    if [l, r, t, b]
        .iter()
        .any(|p| p.z <= 0.0 || (p.z - c.z).abs() > jump)
    {
        return Vec3::ZERO;
    }
    let n = (r - l).cross(b - t);
    let len = n.length();
    if len <= 1e-12 || !len.is_finite() {
        return Vec3::ZERO;
    }
    let n = n / len;
    if n.dot(c) > 0.0 {
        -n
    } else {
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_check_level_samples_at_least_160_pixels_across() {
        let config = PreprocessConfig::default();
        let width_of = |w: usize, h: usize| {
            let k = Intrinsics::new(500.0, 500.0, w as f32 / 2.0, h as f32 / 2.0, w, h);
            let pyramid = FramePyramid::new(&k, &config);
            pyramid
                .check_level()
                .and_then(|l| l.intrinsics)
                .map(|k| k.width)
        };
        // 640x480: its coarsest level; at half resolution one finer; an
        // iPhone's 256x192 depth: the finest.
        assert_eq!(width_of(640, 480), Some(160));
        assert_eq!(width_of(320, 240), Some(160));
        assert_eq!(width_of(256, 192), Some(256));
    }

    fn plane_frame(k: &Intrinsics) -> RgbdFrame {
        // Plane z = 2 + 0.5 x, seen head-on: exact depth per pixel.
        let mut depth = vec![0.0; k.pixel_count()];
        for v in 0..k.height {
            for u in 0..k.width {
                let rx = (u as f32 - k.cx) / k.fx;
                depth[v * k.width + u] = 2.0 / (1.0 - 0.5 * rx);
            }
        }
        RgbdFrame {
            width: k.width,
            height: k.height,
            rgb: vec![128; 3 * k.pixel_count()],
            depth_deviation: Vec::new(),
            depth_m: depth,
        }
    }

    #[test]
    fn plane_normals_are_exact_at_every_level() {
        let k = Intrinsics::new(200.0, 200.0, 79.5, 59.5, 160, 120);
        let frame = plane_frame(&k);
        let cfg = PreprocessConfig::default();
        let mut pyr = FramePyramid::new(&k, &cfg);
        pyr.build(&frame, &cfg, &SensorNoise::uniform());
        let expected = Vec3::new(0.5, 0.0, -1.0).normalize();
        for level in &pyr.levels {
            let k = level.intrinsics.expect("intrinsics");
            let i = (k.height / 2) * k.width + k.width / 2;
            assert!(
                (level.normals[i] - expected).length() < 1e-3,
                "{:?}",
                level.normals[i]
            );
            let p = level.vertices[i];
            assert!(
                (p.z - (2.0 + 0.5 * p.x)).abs() < 2e-3,
                "vertex off plane: {p:?}"
            );
        }
    }

    /// A plane 5 m away tilted 30 degrees about the camera's y axis, its
    /// depth quantised as a Kinect v1 measures it (disparity in steps of
    /// 1/8 px, focal 481 px, baseline 7.5 cm: terraces 8.7 cm deep at 5 m),
    /// and its true normal.
    fn far_terraced_plane(k: &Intrinsics) -> (RgbdFrame, Vec3) {
        let tilt = libm::tanf(30f32.to_radians());
        let fb = 481.0 * 0.075;
        let mut frame = plane_frame(k);
        for v in 0..k.height {
            for u in 0..k.width {
                let rx = (u as f32 - k.cx) / k.fx;
                let z = 5.0 / (1.0 - tilt * rx);
                let disparity = (fb / z * 8.0).round() / 8.0;
                frame.depth_m[v * k.width + u] = fb / disparity;
            }
        }
        (frame, Vec3::new(tilt, 0.0, -1.0).normalize())
    }

    /// Median angle (degrees) between `normals` and `truth` over the pixels
    /// at least `margin` from the border.
    fn median_normal_error_deg(
        normals: &[Vec3],
        k: &Intrinsics,
        truth: Vec3,
        margin: usize,
    ) -> f32 {
        let mut errors: Vec<f32> = (margin..k.height - margin)
            .flat_map(|v| (margin..k.width - margin).map(move |u| v * k.width + u))
            .map(|i| libm::acosf(normals[i].dot(truth).clamp(-1.0, 1.0)).to_degrees())
            .collect();
        errors.sort_by(f32::total_cmp);
        errors[errors.len() / 2]
    }

    #[test]
    fn far_terraced_depth_is_smoothed_where_the_range_sigma_follows_the_noise() {
        let k = Intrinsics::new(200.0, 200.0, 79.5, 59.5, 160, 120);
        let (frame, truth) = far_terraced_plane(&k);
        let noise = SensorNoise::simulated_kinect();
        let error = |factor: f32| {
            let cfg = PreprocessConfig {
                range_noise_factor: factor,
                ..PreprocessConfig::default()
            };
            let mut pyr = FramePyramid::new(&k, &cfg);
            pyr.build(&frame, &cfg, &noise);
            median_normal_error_deg(&pyr.levels[0].normals, &k, truth, 8)
        };
        let (constant, following) = (error(0.0), error(2.5));
        eprintln!(
            "median normal error: constant {constant} deg, following the noise {following} deg"
        );
        assert!(
            following < 5.0 && constant > 20.0,
            "{constant} vs {following}"
        );
    }

    #[test]
    fn depth_nearer_than_the_knee_and_noise_that_does_not_grow_filter_as_a_constant_sigma() {
        let k = Intrinsics::new(200.0, 200.0, 79.5, 59.5, 160, 120);
        let constant = PreprocessConfig {
            range_noise_factor: 0.0,
            ..PreprocessConfig::default()
        };
        let following = PreprocessConfig::default();
        let build = |frame: &RgbdFrame, cfg: &PreprocessConfig, noise: &SensorNoise| {
            let mut pyr = FramePyramid::new(&k, cfg);
            pyr.build(frame, cfg, noise);
            pyr.levels[0].depth.clone()
        };
        // The plane of `plane_frame` lies at 1.7-2.4 m, nearer than the knee (2.2 m) in part only.
        let near = plane_frame(&k);
        let knee = range_knee_m(&following, &SensorNoise::simulated_kinect()).expect("a knee");
        let mut nearer = near.clone();
        nearer
            .depth_m
            .iter_mut()
            .for_each(|z| *z *= 0.9 * knee / 2.4);
        assert_eq!(
            build(&nearer, &constant, &SensorNoise::simulated_kinect()),
            build(&nearer, &following, &SensorNoise::simulated_kinect())
        );
        let (far, _) = far_terraced_plane(&k);
        for model in [SensorNoise::uniform(), SensorNoise::rendered()] {
            assert_eq!(range_knee_m(&following, &model), None);
            assert_eq!(
                build(&far, &constant, &model),
                build(&far, &following, &model)
            );
        }
        assert_ne!(
            build(&far, &constant, &SensorNoise::simulated_kinect()),
            build(&far, &following, &SensorNoise::simulated_kinect())
        );
    }

    #[test]
    fn depth_deviation_reaches_every_level_as_block_means_and_halves_with_the_frame() {
        let k = Intrinsics::new(50.0, 50.0, 31.5, 23.5, 64, 48);
        let mut frame = plane_frame(&k);
        // The right quarter of the image twice as uncertain.
        frame.depth_deviation = (0..k.pixel_count())
            .map(|i| if i % k.width >= 48 { 2.0 } else { 1.0 })
            .collect();
        let config = PreprocessConfig::default();
        let mut pyramid = FramePyramid::new(&k, &config);
        pyramid.build(&frame, &config, &SensorNoise::default());
        assert_eq!(pyramid.levels[0].depth_deviation, frame.depth_deviation);
        for level in &pyramid.levels[1..] {
            let lk = level.intrinsics.expect("intrinsics");
            assert_eq!(level.depth_deviation.len(), lk.pixel_count());
            for (i, &f) in level.depth_deviation.iter().enumerate() {
                let expected = if (i % lk.width) * k.width / lk.width >= 48 {
                    2.0
                } else {
                    1.0
                };
                assert_eq!(f, expected, "level {}x{} pixel {i}", lk.width, lk.height);
            }
        }
        let mut half = RgbdFrame::default();
        half_resolution_into(&frame, 0.09, &mut half);
        assert!(half.validate().is_ok());
        assert_eq!(half.depth_deviation_at(31), 2.0);
        assert_eq!(half.depth_deviation_at(23), 1.0);
        // A frame without a map leaves none in the pyramid or the half frame.
        frame.depth_deviation.clear();
        pyramid.build(&frame, &config, &SensorNoise::default());
        assert!(pyramid.levels.iter().all(|l| l.depth_deviation.is_empty()));
        half_resolution_into(&frame, 0.09, &mut half);
        assert!(half.depth_deviation.is_empty());
    }

    #[test]
    fn invalid_depth_stays_invalid() {
        let k = Intrinsics::new(200.0, 200.0, 79.5, 59.5, 160, 120);
        let mut frame = plane_frame(&k);
        frame
            .depth_m
            .iter_mut()
            .take(160 * 10)
            .for_each(|d| *d = 0.0);
        let cfg = PreprocessConfig::default();
        let mut pyr = FramePyramid::new(&k, &cfg);
        pyr.build(&frame, &cfg, &SensorNoise::uniform());
        assert!(pyr.levels[0].depth[..160 * 10].iter().all(|&d| d == 0.0));
        assert!(pyr.levels[0].normals.iter().all(|n| n.is_finite()));
    }
}
