//! Deterministic ray-cast renderer of a synthetic indoor scene, with a known
//! camera trajectory: exact answers for unit tests, wasm tests and benchmarks.
//!
//! # Conventions
//!
//! - World axes: **world -y is up** (gravity along +y), matching the camera's
//!   +y-down convention, so a camera with identity rotation is upright. The
//!   floor is the plane `y = 0`, the ceiling `y = -3`.
//! - The default room ([`Scene::room`]) spans `x, z in [-3, 3]`, `y in [-3, 0]`
//!   (6 m x 3 m high x 6 m), seen from inside, with six boxes on the floor: four
//!   axis-aligned, one turned 35 degrees about the vertical and one tilted slab
//!   (a ramp), so that point-to-plane ICP is constrained in all six degrees of
//!   freedom.
//! - Every surface carries a procedural texture that depends only on the world
//!   point and on which face it lies (never on the view): a per-face base
//!   colour, checkerboards at 0.5 m and 0.1 m, and sinusoids of 0.1 to 0.5 m
//!   period, so intensity has strong gradients almost everywhere and fused
//!   colour is consistent between views. A fixed light from above shades faces
//!   by their normal (view-independent too).
//! - Depth is z-depth (along the optical axis) in metres; raw depth is 16-bit
//!   with [`DEPTH_UNITS_PER_METRE`] units per metre, 0 = hole, like TUM RGB-D
//!   and ICL-NUIM.
//!
//! Rendering is per pixel, through the pixel centre, nearest hit over all
//! boxes (slab method), parallel over rows with rayon. Noise is drawn from a
//! SplitMix64 stream seeded per row from `seed`, so a frame depends only on
//! its arguments (not on the thread count).

use std::io::Cursor;

use glam::{DAffine3, DMat3, DQuat, DVec3, Vec3};
use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, Rgb};
use rayon::prelude::*;
use thiserror::Error;

use crate::camera::Intrinsics;
use crate::frame::{Channel, DepthSettings, FrameError, RgbdFrame};

/// Raw depth units per metre of [`RenderedFrame::depth_raw`] (TUM / ICL-NUIM convention).
pub const DEPTH_UNITS_PER_METRE: f32 = 5000.0;

/// Lower corner of the default room ([`Scene::room`]), metres. World -y is up.
pub const ROOM_MIN: DVec3 = DVec3::new(-3.0, -3.0, -3.0);
/// Upper corner of the default room ([`Scene::room`]), metres; `y = 0` is the floor.
pub const ROOM_MAX: DVec3 = DVec3::new(3.0, 0.0, 3.0);

/// Rays closer than this (metres) to their origin do not count as hits.
const MIN_HIT_T: f32 = 1e-4;

/// One box of the scene: a solid block, or the room itself seen from inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBox {
    /// Centre, world frame, metres.
    pub centre: DVec3,
    /// Half of the size along each of the box's own axes, metres.
    pub half_size: DVec3,
    /// Rotation world_from_box (identity for an axis-aligned box).
    pub rotation: DQuat,
    /// `true` for the enclosing room: rays start inside and hit where they leave.
    pub seen_from_inside: bool,
    /// Selects the texture (base colours and pattern phases) of the six faces.
    pub material: u32,
}

impl SceneBox {
    /// A solid axis-aligned box between two corners.
    #[must_use]
    pub fn solid(min: DVec3, max: DVec3, material: u32) -> Self {
        let (lo, hi) = (min.min(max), min.max(max));
        Self {
            centre: 0.5 * (lo + hi),
            half_size: 0.5 * (hi - lo),
            rotation: DQuat::IDENTITY,
            seen_from_inside: false,
            material,
        }
    }

    /// A solid box of the given half size, rotated by `rotation` (world_from_box) about its centre.
    #[must_use]
    pub fn rotated(centre: DVec3, half_size: DVec3, rotation: DQuat, material: u32) -> Self {
        Self {
            centre,
            half_size: half_size.abs(),
            rotation: rotation.normalize(),
            seen_from_inside: false,
            material,
        }
    }

    /// An axis-aligned room between two corners, seen from inside.
    #[must_use]
    pub fn room(min: DVec3, max: DVec3, material: u32) -> Self {
        Self {
            seen_from_inside: true,
            ..Self::solid(min, max, material)
        }
    }

    fn is_axis_aligned(&self) -> bool {
        let q = self.rotation;
        (q.w.abs() - 1.0).abs() < 1e-12
    }

    /// Distance from `point` (world) to the nearest face of the box, metres
    /// (whether the point is inside or outside).
    #[must_use]
    pub fn distance_to_surface(&self, point: DVec3) -> f64 {
        let local = self.rotation.inverse() * (point - self.centre);
        let d = local.abs() - self.half_size;
        let outside = d.max(DVec3::ZERO).length();
        let inside = d.max_element().min(0.0);
        (outside + inside).abs()
    }

    /// Whether `point` (world) lies strictly inside the box volume.
    #[must_use]
    pub fn contains(&self, point: DVec3) -> bool {
        let local = self.rotation.inverse() * (point - self.centre);
        (local.abs() - self.half_size).max_element() < 0.0
    }
}

/// A synthetic scene: boxes, each face with a procedural texture.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// All boxes, the room included.
    pub boxes: Vec<SceneBox>,
}

impl Default for Scene {
    fn default() -> Self {
        Self::room()
    }
}

impl Scene {
    /// The default scene: a 6 x 3 x 6 m room ([`ROOM_MIN`]..[`ROOM_MAX`], world -y up,
    /// floor at y = 0) with six boxes on the floor near the walls, one of them
    /// turned 35 degrees about the vertical and one a slab tilted 25 degrees (a ramp).
    /// Every point within 1.25 m of the room's vertical centre line and 1.3..1.6 m
    /// above the floor is at least 0.95 m from every surface (that is where
    /// [`trajectory`] runs).
    #[must_use]
    pub fn room() -> Self {
        let boxes = vec![
            SceneBox::room(ROOM_MIN, ROOM_MAX, 0),
            // Table-height block.
            SceneBox::solid(DVec3::new(1.4, -0.75, 1.5), DVec3::new(2.5, 0.0, 2.4), 1),
            // Tall cabinet against the -x wall.
            SceneBox::solid(DVec3::new(-2.9, -1.9, 1.5), DVec3::new(-2.1, 0.0, 2.5), 2),
            // Small cube.
            SceneBox::solid(DVec3::new(0.3, -0.5, -2.3), DVec3::new(0.8, 0.0, -1.8), 3),
            // Low wide block.
            SceneBox::solid(DVec3::new(-2.4, -0.4, -2.2), DVec3::new(-1.2, 0.0, -1.4), 4),
            // Pillar turned 35 degrees about the vertical.
            SceneBox::rotated(
                DVec3::new(2.2, -0.6, -1.5),
                DVec3::new(0.3, 0.6, 0.35),
                DQuat::from_rotation_y(35f64.to_radians()),
                5,
            ),
            // Ramp: a thin slab tilted 25 degrees about x, resting on the floor.
            SceneBox::rotated(
                DVec3::new(-0.3, -0.24, 2.3),
                DVec3::new(0.7, 0.03, 0.5),
                DQuat::from_rotation_x(25f64.to_radians()),
                6,
            ),
        ];
        Self { boxes }
    }

    /// Distance from `point` (world) to the nearest box face, metres
    /// (`f64::INFINITY` for an empty scene).
    #[must_use]
    pub fn distance_to_surface(&self, point: DVec3) -> f64 {
        self.boxes
            .iter()
            .map(|b| b.distance_to_surface(point))
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether `point` is in free space: inside every room and outside every solid box.
    #[must_use]
    pub fn is_free(&self, point: DVec3) -> bool {
        self.boxes
            .iter()
            .all(|b| b.contains(point) == b.seen_from_inside)
    }

    /// Casts one ray (world frame); returns the ray parameter `t` of the nearest
    /// hit (the hit is `origin + t * direction`) and the surface normal there
    /// (unit, facing the ray), or `None` when nothing is hit.
    #[must_use]
    pub fn cast_ray(&self, origin: DVec3, direction: DVec3) -> Option<(f64, DVec3)> {
        let prepared = Prepared::new(self, origin);
        let hit = prepared.cast(direction.as_vec3())?;
        let b = &prepared.boxes[hit.box_index];
        let n = b.normal_world(hit.axis, hit.dir_local[hit.axis]);
        Some((f64::from(hit.t), n.as_dvec3()))
    }
}

/// Sensor noise applied by [`render`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Standard deviation of depth noise at 1 m, metres; it grows with z^2 (Kinect-like).
    pub depth_sigma_at_1m: f32,
    /// Fraction of pixels dropped at random (depth 0), 0..1.
    pub hole_fraction: f32,
    /// Drop pixels at depth discontinuities, like a structured-light sensor.
    pub edge_holes: bool,
    /// Standard deviation of colour noise per channel, 0..255 units.
    pub colour_sigma: f32,
}

impl NoiseModel {
    /// No noise: raw depth is the exact depth rounded to 1/5000 m, colour exact.
    #[must_use]
    pub const fn none() -> Self {
        Self {
            depth_sigma_at_1m: 0.0,
            hole_fraction: 0.0,
            edge_holes: false,
            colour_sigma: 0.0,
        }
    }

    /// Kinect-like: depth sigma 1.2 mm x z^2 (m) then 16-bit quantisation, 2 %
    /// random holes, holes at depth edges, colour sigma 2.
    #[must_use]
    pub const fn kinect() -> Self {
        Self {
            depth_sigma_at_1m: 0.0012,
            hole_fraction: 0.02,
            edge_holes: true,
            colour_sigma: 2.0,
        }
    }
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self::none()
    }
}

/// Why a rendered frame could not be encoded.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SyntheticError {
    /// PNG encoding failed (or the buffers do not match the size).
    #[error("{channel} PNG could not be encoded: {message}")]
    Encode {
        /// Colour or depth.
        channel: Channel,
        /// What went wrong.
        message: String,
    },
}

/// One rendered RGB-D frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderedFrame {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Colour, RGB8 interleaved, row-major (`3 * width * height`), noise included.
    pub rgb: Vec<u8>,
    /// Raw depth, [`DEPTH_UNITS_PER_METRE`] units per metre, 0 = hole; noise and holes included.
    pub depth_raw: Vec<u16>,
    /// Exact ray-cast z-depth in metres before noise and holes, 0 where no surface was hit.
    pub depth_m: Vec<f32>,
}

impl RenderedFrame {
    /// Converts to an [`RgbdFrame`] through [`RgbdFrame::from_raw`] (raw depth, so noise and holes included).
    pub fn to_frame(&self, settings: &DepthSettings) -> Result<RgbdFrame, FrameError> {
        RgbdFrame::from_raw(
            self.width,
            self.height,
            &self.rgb,
            &self.depth_raw,
            settings,
        )
    }

    /// Encodes as (colour RGB8 PNG, depth 16-bit grey PNG), as a dataset would store them.
    pub fn to_png_bytes(&self) -> Result<(Vec<u8>, Vec<u8>), SyntheticError> {
        let size = |channel| {
            let w = u32::try_from(self.width);
            let h = u32::try_from(self.height);
            match (w, h) {
                (Ok(w), Ok(h)) => Ok((w, h)),
                _ => Err(SyntheticError::Encode {
                    channel,
                    message: format!("size {}x{} too large", self.width, self.height),
                }),
            }
        };
        let (w, h) = size(Channel::Colour)?;
        let mismatch = |channel| SyntheticError::Encode {
            channel,
            message: format!("buffer length does not match {w}x{h}"),
        };
        let colour = ImageBuffer::<Rgb<u8>, Vec<u8>>::from_raw(w, h, self.rgb.clone())
            .ok_or_else(|| mismatch(Channel::Colour))?;
        let depth = ImageBuffer::<Luma<u16>, Vec<u16>>::from_raw(w, h, self.depth_raw.clone())
            .ok_or_else(|| mismatch(Channel::Depth))?;
        let encode = |img: DynamicImage, channel| {
            let mut out = Cursor::new(Vec::new());
            img.write_to(&mut out, ImageFormat::Png)
                .map_err(|e| SyntheticError::Encode {
                    channel,
                    message: e.to_string(),
                })?;
            Ok(out.into_inner())
        };
        Ok((
            encode(DynamicImage::ImageRgb8(colour), Channel::Colour)?,
            encode(DynamicImage::ImageLuma16(depth), Channel::Depth)?,
        ))
    }

    /// Number of pixels with a raw depth measurement.
    #[must_use]
    pub fn valid_depth_count(&self) -> usize {
        self.depth_raw.iter().filter(|&&r| r > 0).count()
    }
}

/// Default intrinsics: 640x480, fx = fy = 525, cx = 319.5, cy = 239.5 (Kinect-like).
#[must_use]
pub fn default_intrinsics() -> Intrinsics {
    Intrinsics::new(525.0, 525.0, 319.5, 239.5, 640, 480)
}

/// world_from_camera of a camera at `eye` looking at `target`: camera +z points
/// at the target, camera +y points as close to world +y (down; world -y is up)
/// as possible, +x completes a right-handed frame (right). When looking
/// straight up or down, camera +y falls back to world +z; when `eye == target`
/// (or either is not finite) the rotation is the identity.
#[must_use]
pub fn look_at(eye: DVec3, target: DVec3) -> DAffine3 {
    let Some(forward) = (target - eye).try_normalize() else {
        return DAffine3::from_translation(eye);
    };
    let down = if forward.cross(DVec3::Y).length_squared() > 1e-12 {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let right = down.cross(forward).normalize();
    let camera_down = forward.cross(right);
    DAffine3 {
        matrix3: DMat3::from_cols(right, camera_down, forward),
        translation: eye,
    }
}

/// Pose `index` of the known trajectory (see [`trajectory`]).
#[must_use]
pub fn trajectory_pose(index: usize) -> DAffine3 {
    let t = index as f64;
    // Slow arc around the vertical axis through the room centre.
    let theta = 0.2 + 0.011 * t;
    let radius = 1.1 + 0.15 * (0.017 * t).sin();
    let height = 1.45 + 0.12 * (0.023 * t).sin();
    let eye = DVec3::new(radius * theta.cos(), -height, radius * theta.sin());
    // Looking ahead along the arc and a little inward (100 degrees from the
    // outward radius), at a point 2 m away horizontally and 0.2..0.6 m above
    // the floor, with a gentle yaw / pitch wobble.
    let look = theta + 1.75 + 0.12 * (0.031 * t).sin();
    let target = DVec3::new(
        eye.x + 2.0 * look.cos(),
        -0.4 - 0.2 * (0.019 * t).sin(),
        eye.z + 2.0 * look.sin(),
    );
    let roll = 3f64.to_radians() * (0.05 * t).sin();
    look_at(eye, target) * DAffine3::from_rotation_z(roll)
}

/// The first `frames` poses (world_from_camera) of a known smooth handheld-like
/// path through [`Scene::room`]: a slow arc of radius 0.95..1.25 m around the
/// room centre, 1.33..1.57 m above the floor, looking ahead along the arc and
/// slightly inward, pitched down 20..35 degrees, with up to 3 degrees of roll
/// and a gentle pitch / yaw wobble. It moves 1.0..1.4 cm and 0.4..0.9 degrees
/// per frame (a handheld Kinect at 30 fps; a full turn takes about 570
/// frames) and stays at least 1.0 m from every surface, so depths lie in about
/// 1.1..4.7 m (about 98 % of them under 4 m). Pose `i` is the same whatever
/// `frames` is.
#[must_use]
pub fn trajectory(frames: usize) -> Vec<DAffine3> {
    (0..frames).map(trajectory_pose).collect()
}

/// Renders `scene` from `world_from_camera` with `intrinsics` and `noise`.
/// Deterministic: the same arguments give the same frame on every platform and
/// thread count. Intrinsics with an empty size or a side above 16384 pixels
/// give an empty 0x0 frame.
#[must_use]
pub fn render(
    scene: &Scene,
    intrinsics: &Intrinsics,
    world_from_camera: &DAffine3,
    noise: &NoiseModel,
    seed: u64,
) -> RenderedFrame {
    let mut frame = RenderedFrame::default();
    render_into(
        &mut frame,
        scene,
        intrinsics,
        world_from_camera,
        noise,
        seed,
    );
    frame
}

/// As [`render`], reusing `frame`'s buffers (no allocation once sized).
pub fn render_into(
    frame: &mut RenderedFrame,
    scene: &Scene,
    intrinsics: &Intrinsics,
    world_from_camera: &DAffine3,
    noise: &NoiseModel,
    seed: u64,
) {
    let (w, h) = (intrinsics.width, intrinsics.height);
    let size_ok = (1..=16384).contains(&w) && (1..=16384).contains(&h);
    let (w, h) = if size_ok { (w, h) } else { (0, 0) };
    let n = w * h;
    frame.width = w;
    frame.height = h;
    frame.rgb.resize(3 * n, 0);
    frame.depth_raw.resize(n, 0);
    frame.depth_m.resize(n, 0.0);
    if n == 0 {
        return;
    }

    let prepared = Prepared::new(scene, world_from_camera.translation);
    let rot = world_from_camera.matrix3.as_mat3();
    let k = *intrinsics;
    let colour_sigma = sanitise(noise.colour_sigma);

    // Pass 1: ray-cast exact depth and colour.
    frame
        .depth_m
        .par_chunks_mut(w)
        .zip(frame.rgb.par_chunks_mut(3 * w))
        .enumerate()
        .for_each(|(v, (depth_row, rgb_row))| {
            let mut rng = SplitMix64::new(row_seed(seed, v, 0x00C0_10E5));
            let y = (v as f32 - k.cy) / k.fy;
            let row_dir = rot * Vec3::new(0.0, y, 1.0);
            for (u, (depth, rgb)) in depth_row
                .iter_mut()
                .zip(rgb_row.chunks_exact_mut(3))
                .enumerate()
            {
                let dir = row_dir + rot.x_axis * ((u as f32 - k.cx) / k.fx);
                let (z, colour) = match prepared.cast(dir) {
                    Some(hit) => (hit.t, prepared.shade(&hit)),
                    None => (0.0, [0.0; 3]),
                };
                *depth = if z.is_finite() { z } else { 0.0 };
                for (out, c) in rgb.iter_mut().zip(colour) {
                    let c = if colour_sigma > 0.0 {
                        c + colour_sigma * rng.gaussian()
                    } else {
                        c
                    };
                    *out = (c.clamp(0.0, 255.0) + 0.5) as u8;
                }
            }
        });

    // Pass 2: depth noise, holes and quantisation.
    let depth_m = &frame.depth_m;
    let sigma1 = sanitise(noise.depth_sigma_at_1m);
    let holes = sanitise(noise.hole_fraction);
    let edge_holes = noise.edge_holes;
    frame
        .depth_raw
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(v, raw_row)| {
            // One stream per noise source, one draw per pixel: turning one
            // source on or off does not reshuffle the others.
            let mut hole_rng = SplitMix64::new(row_seed(seed, v, 0x0401_E500));
            let mut depth_rng = SplitMix64::new(row_seed(seed, v, 0xDE97_4000));
            let row = &depth_m[v * w..(v + 1) * w];
            for (u, raw) in raw_row.iter_mut().enumerate() {
                let z = row[u];
                let dropout = holes > 0.0 && hole_rng.next_f32() < holes;
                let gauss = if sigma1 > 0.0 {
                    depth_rng.gaussian()
                } else {
                    0.0
                };
                if z <= 0.0 || dropout || (edge_holes && is_depth_edge(depth_m, w, h, u, v)) {
                    *raw = 0;
                    continue;
                }
                let noisy = z + sigma1 * z * z * gauss;
                let units = (noisy * DEPTH_UNITS_PER_METRE).round();
                *raw = if units >= 1.0 {
                    units.min(f32::from(u16::MAX)) as u16
                } else {
                    0
                };
            }
        });
}

/// Relative depth jump between 4-neighbours that counts as a discontinuity.
const EDGE_RELATIVE_JUMP: f32 = 0.04;

fn is_depth_edge(depth: &[f32], w: usize, h: usize, u: usize, v: usize) -> bool {
    let z = depth[v * w + u];
    let limit = EDGE_RELATIVE_JUMP * z;
    let jump = |zn: f32| zn <= 0.0 || (zn - z).abs() > limit;
    (u > 0 && jump(depth[v * w + u - 1]))
        || (u + 1 < w && jump(depth[v * w + u + 1]))
        || (v > 0 && jump(depth[(v - 1) * w + u]))
        || (v + 1 < h && jump(depth[(v + 1) * w + u]))
}

/// Non-finite or negative noise parameters mean "no noise".
fn sanitise(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

fn row_seed(seed: u64, row: usize, stream: u64) -> u64 {
    let mut s = SplitMix64::new(seed ^ stream.wrapping_mul(0xA076_1D64_78BD_642F));
    s.next_u64() ^ (row as u64).wrapping_mul(0xE703_7ED1_A0B4_28DB)
}

/// SplitMix64 (Steele, Lea, Flood 2014): tiny, fast, good enough for noise.
#[derive(Debug, Clone)]
struct SplitMix64 {
    state: u64,
    spare: Option<f32>,
}

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare: None,
        }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Standard normal (Box-Muller; the second value of each pair is kept for the next call).
    fn gaussian(&mut self) -> f32 {
        if let Some(g) = self.spare.take() {
            return g;
        }
        let bits = self.next_u64();
        // u1 in (0, 1] so that ln(u1) is finite.
        let u1 = ((bits >> 40) as f32 + 1.0) * (1.0 / (1u64 << 24) as f32);
        let u2 = (bits & 0xFF_FFFF) as f32 * (1.0 / (1u64 << 24) as f32);
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (sin_turns(u2), sin_turns(u2 + 0.25));
        self.spare = Some(r * s);
        r * c
    }
}

/// A box ready for ray casting in f32, in its own frame.
#[derive(Debug, Clone, Copy)]
struct PreparedBox {
    /// Lower corner minus the ray origin, box frame (the box is `-half..half`).
    lo_rel: Vec3,
    /// Upper corner minus the ray origin, box frame.
    hi_rel: Vec3,
    /// Ray origin in the box frame.
    origin_local: Vec3,
    /// Rows of box_from_world (identity for axis-aligned boxes).
    box_from_world: glam::Mat3,
    /// world_from_box.
    world_from_box: glam::Mat3,
    axis_aligned: bool,
    inside: bool,
    material: u32,
    /// Centre used to express texture coordinates: world origin for
    /// axis-aligned boxes (so textures are plain world functions), the box
    /// centre for rotated ones.
    texture_offset: Vec3,
}

impl PreparedBox {
    fn normal_world(&self, axis: usize, dir_component: f32) -> Vec3 {
        let mut n = Vec3::ZERO;
        n[axis] = if dir_component > 0.0 { -1.0 } else { 1.0 };
        self.world_from_box * n
    }
}

struct Prepared {
    boxes: Vec<PreparedBox>,
}

#[derive(Debug, Clone, Copy)]
struct Hit {
    t: f32,
    box_index: usize,
    axis: usize,
    dir_local: Vec3,
}

#[inline(always)]
fn safe_recip(d: Vec3) -> Vec3 {
    let fix = |x: f32| {
        if x.abs() < 1e-20 {
            1e20f32.copysign(x)
        } else {
            1.0 / x
        }
    };
    Vec3::new(fix(d.x), fix(d.y), fix(d.z))
}

impl Prepared {
    fn new(scene: &Scene, origin: DVec3) -> Self {
        let mut boxes: Vec<PreparedBox> = scene
            .boxes
            .iter()
            .map(|b| {
                let world_from_box = DMat3::from_quat(b.rotation);
                let box_from_world = world_from_box.transpose();
                let origin_local = box_from_world * (origin - b.centre);
                PreparedBox {
                    lo_rel: (-b.half_size - origin_local).as_vec3(),
                    hi_rel: (b.half_size - origin_local).as_vec3(),
                    origin_local: origin_local.as_vec3(),
                    box_from_world: box_from_world.as_mat3(),
                    world_from_box: world_from_box.as_mat3(),
                    axis_aligned: b.is_axis_aligned(),
                    inside: b.seen_from_inside,
                    material: b.material,
                    texture_offset: if b.is_axis_aligned() {
                        b.centre.as_vec3()
                    } else {
                        Vec3::ZERO
                    },
                }
            })
            .collect();
        // Axis-aligned boxes first: cheaper, and most hits.
        boxes.sort_by_key(|b| !b.axis_aligned);
        Self { boxes }
    }

    /// Nearest hit along `dir` (world), `t` in units of `dir`.
    #[inline]
    fn cast(&self, dir: Vec3) -> Option<Hit> {
        let inv_world = safe_recip(dir);
        let mut best: Option<Hit> = None;
        let mut best_t = f32::INFINITY;
        for (i, b) in self.boxes.iter().enumerate() {
            let (dir_local, inv) = if b.axis_aligned {
                (dir, inv_world)
            } else {
                let d = b.box_from_world * dir;
                (d, safe_recip(d))
            };
            let t0 = b.lo_rel * inv;
            let t1 = b.hi_rel * inv;
            let near = t0.min(t1);
            let far = t0.max(t1);
            let (t, axis) = if b.inside {
                let exit = far.min_element();
                if exit < near.max_element() {
                    continue;
                }
                (exit, argmin(far))
            } else {
                let enter = near.max_element();
                if enter > far.min_element() {
                    continue;
                }
                (enter, argmax(near))
            };
            if t > MIN_HIT_T && t < best_t {
                best_t = t;
                best = Some(Hit {
                    t,
                    box_index: i,
                    axis,
                    dir_local,
                });
            }
        }
        best
    }

    /// Colour (0..255 floats) of the surface at a hit.
    #[inline]
    fn shade(&self, hit: &Hit) -> [f32; 3] {
        let b = &self.boxes[hit.box_index];
        let local = b.origin_local + hit.t * hit.dir_local + b.texture_offset;
        let positive_side = (hit.dir_local[hit.axis] > 0.0) == b.inside;
        let face = 2 * hit.axis as u32 + u32::from(positive_side);
        let a = local[(hit.axis + 1) % 3];
        let c = local[(hit.axis + 2) % 3];
        let normal = b.normal_world(hit.axis, hit.dir_local[hit.axis]);
        // Light from above (world -y is up), plus a little from +x +z.
        let light = Vec3::new(0.3, -0.85, 0.4).normalize();
        let shading = 0.8 + 0.2 * normal.dot(light);
        let rgb = texture(b.material, face, a, c);
        [rgb[0] * shading, rgb[1] * shading, rgb[2] * shading]
    }
}

#[inline(always)]
fn argmax(v: Vec3) -> usize {
    if v.x >= v.y && v.x >= v.z {
        0
    } else if v.y >= v.z {
        1
    } else {
        2
    }
}

#[inline(always)]
fn argmin(v: Vec3) -> usize {
    if v.x <= v.y && v.x <= v.z {
        0
    } else if v.y <= v.z {
        1
    } else {
        2
    }
}

fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846C_A68B);
    x ^= x >> 16;
    x
}

/// +1 / -1 checkerboard of square size `cell` (metres) in the face plane.
#[inline(always)]
fn checker(a: f32, b: f32, cell: f32) -> f32 {
    let i = floor_i32(a / cell).wrapping_add(floor_i32(b / cell));
    if i & 1 == 0 {
        1.0
    } else {
        -1.0
    }
}

/// floor(x) as an integer without a libm call (saturates far outside the room; NaN gives 0).
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x {
        i - 1
    } else {
        i
    }
}

/// sin(2 pi x), x in turns, to about 1e-3: a polynomial, so it is cheap and
/// gives bit-identical results on every platform (no libm).
#[inline(always)]
fn sin_turns(x: f32) -> f32 {
    let t = x - floor_i32(x + 0.5) as f32; // -0.5..0.5 turns
    let y = 8.0 * t - 16.0 * t * t.abs();
    0.225 * (y * y.abs() - y) + y
}

/// Procedural texture of face `face` (0..6) of material `material` at in-plane
/// coordinates (a, b), metres; returns linear 0..255 RGB before shading.
#[inline]
fn texture(material: u32, face: u32, a: f32, b: f32) -> [f32; 3] {
    let hsh = hash32(material.wrapping_mul(16) + face + 1);
    // Base colour: each channel 90..200 from the hash.
    let base = [
        90.0 + (hsh & 0xFF) as f32 * (110.0 / 255.0),
        90.0 + ((hsh >> 8) & 0xFF) as f32 * (110.0 / 255.0),
        90.0 + ((hsh >> 16) & 0xFF) as f32 * (110.0 / 255.0),
    ];
    // Phases in turns (cycles).
    let phase = ((hsh >> 24) & 0xFF) as f32 * (1.0 / 256.0);
    let coarse = checker(a, b, 0.5);
    let fine = checker(a + 0.037, b - 0.021, 0.1);
    let wave1 = sin_turns(a * (1.0 / 0.23) + phase) * sin_turns(b * (1.0 / 0.31) - phase);
    let wave2 = sin_turns((a + 0.6 * b) * (1.0 / 0.47) + 2.0 * phase);
    let wave3 = sin_turns((0.8 * a - b) * (1.0 / 0.13) + phase);
    let gain = 1.0 + 0.22 * coarse + 0.08 * fine;
    let mut out = [0.0; 3];
    for (ch, (o, base)) in out.iter_mut().zip(base).enumerate() {
        let w = [1.0, 0.6, 0.8][ch];
        let v = base * gain + 30.0 * w * wave1 + 18.0 * wave2 + 12.0 * (1.6 - w) * wave3;
        *o = v.clamp(0.0, 255.0);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Intrinsics {
        Intrinsics::new(131.25, 131.25, 79.5, 59.5, 160, 120)
    }

    fn settings() -> DepthSettings {
        DepthSettings {
            scale: 5000.0,
            min_m: 0.3,
            max_m: 8.0,
            invalid_raw: None,
        }
    }

    #[test]
    fn depth_to_a_wall_is_exact() {
        let scene = Scene::room();
        // Looking along +z at the wall z = 3 from z = 0.5: depth 2.5 everywhere on it.
        let eye = DVec3::new(0.1, -1.5, 0.5);
        let pose = look_at(eye, eye + DVec3::Z);
        for k in [
            default_intrinsics(),
            small(),
            Intrinsics::new(481.2, -480.0, 319.5, 239.5, 640, 480),
        ] {
            let f = render(&scene, &k, &pose, &NoiseModel::none(), 1);
            let centre = (k.height / 2) * k.width + k.width / 2;
            assert!(
                (f.depth_m[centre] - 2.5).abs() < 1e-4,
                "{}",
                f.depth_m[centre]
            );
            assert_eq!(f.depth_raw[centre], 12500);
        }
        // Looking straight down at the floor from 1.2 m above it.
        let eye = DVec3::new(-0.4, -1.2, 0.3);
        let pose = look_at(eye, eye + DVec3::Y);
        let k = small();
        let f = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let centre = (k.height / 2) * k.width + k.width / 2;
        assert!(
            (f.depth_m[centre] - 1.2).abs() < 1e-4,
            "{}",
            f.depth_m[centre]
        );
        // And through the public single-ray API.
        let (t, n) = scene.cast_ray(eye, DVec3::Y).expect("floor is hit");
        assert!((t - 1.2).abs() < 1e-4 && (n - DVec3::NEG_Y).length() < 1e-6);
    }

    #[test]
    fn back_projected_depth_lies_on_surfaces() {
        let scene = Scene::room();
        let ks = [
            small(),
            Intrinsics::new(120.3, -120.0, 79.5, 59.5, 160, 120),
        ];
        for (i, pose) in trajectory(300).iter().enumerate().step_by(37) {
            for k in &ks {
                let f = render(&scene, k, pose, &NoiseModel::none(), 7);
                let mut checked = 0;
                for v in (0..k.height).step_by(3) {
                    for u in (0..k.width).step_by(3) {
                        let z = f.depth_m[v * k.width + u];
                        assert!(z > 0.0, "closed room: every ray hits");
                        let p_cam = k.back_project(u as f32, v as f32, z).as_dvec3();
                        let p = pose.transform_point3(p_cam);
                        let d = scene.distance_to_surface(p);
                        assert!(d < 1e-3, "frame {i} pixel ({u},{v}) is {d} m off");
                        checked += 1;
                    }
                }
                assert!(checked > 2000);
            }
        }
    }

    #[test]
    fn noise_none_is_deterministic_and_exact() {
        let scene = Scene::room();
        let k = small();
        let pose = trajectory_pose(42);
        let a = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let b = render(&scene, &k, &pose, &NoiseModel::none(), 99);
        assert_eq!(a, b);
        for (&raw, &z) in a.depth_raw.iter().zip(&a.depth_m) {
            assert_eq!(raw, (z * 5000.0).round() as u16);
        }
        // Reusing buffers gives the same frame.
        let mut c = render(
            &scene,
            &default_intrinsics(),
            &pose,
            &NoiseModel::kinect(),
            3,
        );
        render_into(&mut c, &scene, &k, &pose, &NoiseModel::none(), 5);
        assert_eq!(a, c);
    }

    #[test]
    fn kinect_noise_has_the_right_size() {
        let scene = Scene::room();
        let k = default_intrinsics();
        let pose = trajectory_pose(100);
        let exact = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let noisy = render(&scene, &k, &pose, &NoiseModel::kinect(), 1);
        assert_eq!(noisy, render(&scene, &k, &pose, &NoiseModel::kinect(), 1));
        assert_ne!(noisy, render(&scene, &k, &pose, &NoiseModel::kinect(), 2));
        assert_eq!(noisy.depth_m, exact.depth_m);

        let n = k.pixel_count() as f64;
        let holes = noisy.depth_raw.iter().filter(|&&r| r == 0).count() as f64 / n;
        assert!((0.02..0.10).contains(&holes), "hole fraction {holes}");

        // Normalised depth error (error / z^2) should have std ~ 1.2 mm.
        let (mut sum, mut sum2, mut count) = (0.0f64, 0.0f64, 0.0f64);
        for (&raw, &z) in noisy.depth_raw.iter().zip(&noisy.depth_m) {
            if raw > 0 {
                let e = f64::from(f32::from(raw) / 5000.0 - z) / f64::from(z * z);
                sum += e;
                sum2 += e * e;
                count += 1.0;
            }
        }
        let mean = sum / count;
        let std = (sum2 / count - mean * mean).sqrt();
        assert!(mean.abs() < 2e-4, "bias {mean}");
        assert!((0.0009..0.0016).contains(&std), "sigma at 1 m {std}");

        let diffs: Vec<f64> = noisy
            .rgb
            .iter()
            .zip(&exact.rgb)
            .map(|(&a, &b)| f64::from(a) - f64::from(b))
            .collect();
        let colour_std = (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64).sqrt();
        assert!(
            (1.5..2.5).contains(&colour_std),
            "colour sigma {colour_std}"
        );
    }

    #[test]
    fn png_round_trip_keeps_depth() {
        let scene = Scene::room();
        let k = small();
        let f = render(&scene, &k, &trajectory_pose(5), &NoiseModel::kinect(), 11);
        let (colour, depth) = f.to_png_bytes().expect("encodes");
        let decoded = RgbdFrame::from_png_bytes(&colour, &depth, &settings()).expect("decodes");
        let direct = f.to_frame(&settings()).expect("valid");
        assert_eq!(decoded, direct);
        assert_eq!(decoded.rgb, f.rgb);
        for (&d, &raw) in decoded.depth_m.iter().zip(&f.depth_raw) {
            assert_eq!(d, settings().to_metres(raw));
        }
        for (&d, &exact) in direct.depth_m.iter().zip(&f.depth_m) {
            assert!(d == 0.0 || (d - exact).abs() < 6e-3 * exact * exact + 2e-4);
        }
    }

    #[test]
    fn trajectory_stays_inside_with_valid_depth() {
        let scene = Scene::room();
        let poses = trajectory(300);
        assert_eq!(poses.len(), 300);
        assert_eq!(trajectory(10)[..], poses[..10]);
        for pair in poses.windows(2) {
            let step = (pair[1].translation - pair[0].translation).length();
            assert!((0.005..0.025).contains(&step), "step {step} m");
            let rel = pair[0].matrix3.transpose() * pair[1].matrix3;
            let angle = DQuat::from_mat3(&rel).to_axis_angle().1.to_degrees();
            assert!((0.2..1.5).contains(&angle), "rotation {angle} deg");
        }
        for pose in trajectory(2000).iter().step_by(7) {
            assert!(scene.is_free(pose.translation));
            assert!(scene.distance_to_surface(pose.translation) >= 0.8);
            assert!((pose.matrix3.determinant() - 1.0).abs() < 1e-9);
        }
        let k = small();
        for (i, pose) in poses.iter().enumerate().step_by(10) {
            let f = render(&scene, &k, pose, &NoiseModel::kinect(), i as u64);
            let frame = f.to_frame(&settings()).expect("valid");
            let valid = frame.valid_depth_count() as f64 / k.pixel_count() as f64;
            assert!(valid >= 0.9, "frame {i}: {valid}");
            let (lo, hi) = f
                .depth_m
                .iter()
                .fold((f32::MAX, 0.0f32), |(lo, hi), &z| (lo.min(z), hi.max(z)));
            assert!(lo > 0.5 && hi < 5.0, "frame {i}: depth {lo}..{hi}");
        }
    }

    /// Smallest and largest eigenvalues of a symmetric 6x6 matrix (cyclic Jacobi).
    fn eigen_range(mut a: [[f64; 6]; 6]) -> (f64, f64) {
        for _ in 0..30 {
            for p in 0..6 {
                for q in p + 1..6 {
                    if a[p][q].abs() < 1e-300 {
                        continue;
                    }
                    let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for row in a.iter_mut() {
                        let (x, y) = (row[p], row[q]);
                        row[p] = c * x - s * y;
                        row[q] = s * x + c * y;
                    }
                    let (rp, rq) = (a[p], a[q]);
                    a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                    a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                }
            }
        }
        (0..6).fold((f64::INFINITY, 0.0f64), |(lo, hi), i| {
            (lo.min(a[i][i]), hi.max(a[i][i]))
        })
    }

    #[test]
    fn views_constrain_all_six_degrees_of_freedom() {
        // Point-to-plane ICP information matrix sum J J^T, J = [p x n, n] in
        // the camera frame: well conditioned along the whole trajectory.
        let mut known = [[0.0f64; 6]; 6];
        for (i, row) in known.iter_mut().enumerate() {
            row[i] = i as f64 + 1.0;
            row[(i + 1) % 6] = 0.1;
        }
        let sym: [[f64; 6]; 6] =
            std::array::from_fn(|i| std::array::from_fn(|j| known[i][j] + known[j][i]));
        let (lo, hi) = eigen_range(sym);
        assert!(lo > 1.5 && lo < 2.5 && hi > 11.5 && hi < 12.5, "{lo} {hi}");

        let scene = Scene::room();
        let k = small();
        for pose in trajectory(600).iter().step_by(30) {
            let f = render(&scene, &k, pose, &NoiseModel::none(), 0);
            let camera_from_world = pose.inverse();
            let mut info = [[0.0f64; 6]; 6];
            for v in (0..k.height).step_by(3) {
                for u in (0..k.width).step_by(3) {
                    let z = f.depth_m[v * k.width + u];
                    let p = k.back_project(u as f32, v as f32, z).as_dvec3();
                    let (_, n_world) = scene
                        .cast_ray(pose.translation, pose.transform_vector3(p))
                        .expect("closed room");
                    let n = camera_from_world.transform_vector3(n_world);
                    let r = p.cross(n);
                    let j = [r.x, r.y, r.z, n.x, n.y, n.z];
                    for (row, &ja) in info.iter_mut().zip(&j) {
                        for (x, &jb) in row.iter_mut().zip(&j) {
                            *x += ja * jb;
                        }
                    }
                }
            }
            let (lo, hi) = eigen_range(info);
            assert!(lo / hi > 2e-3, "ill-conditioned view: {lo} / {hi}");
        }
    }

    #[test]
    fn look_at_conventions() {
        let eye = DVec3::new(0.5, -1.5, -0.2);
        let target = DVec3::new(2.0, -0.5, 1.0);
        let pose = look_at(eye, target);
        let forward = pose.transform_vector3(DVec3::Z);
        assert!((forward - (target - eye).normalize()).length() < 1e-12);
        assert!(
            pose.transform_vector3(DVec3::Y).y > 0.0,
            "camera down is world down"
        );
        assert!(pose.transform_vector3(DVec3::X).y.abs() < 1e-12, "no roll");
        assert!((pose.matrix3.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(pose.transform_point3(DVec3::ZERO), eye);
        // Degenerate inputs do not panic.
        let straight_down = look_at(eye, eye + DVec3::Y);
        assert!((straight_down.matrix3.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(look_at(eye, eye).matrix3, DMat3::IDENTITY);
        let _ = look_at(DVec3::NAN, eye);
    }

    #[test]
    fn odd_arguments_do_not_panic() {
        let scene = Scene::room();
        let pose = trajectory_pose(0);
        let empty = render(
            &scene,
            &Intrinsics::new(1.0, 1.0, 0.0, 0.0, 0, 10),
            &pose,
            &NoiseModel::kinect(),
            0,
        );
        assert_eq!((empty.width, empty.height, empty.rgb.len()), (0, 0, 0));
        assert!(empty.to_frame(&settings()).is_err());
        let nan = Intrinsics::new(f32::NAN, 0.0, f32::INFINITY, 1.0, 8, 4);
        let f = render(&scene, &nan, &pose, &NoiseModel::kinect(), 0);
        assert_eq!(f.depth_m.len(), 32);
        let noise = NoiseModel {
            depth_sigma_at_1m: f32::NAN,
            hole_fraction: -1.0,
            edge_holes: true,
            colour_sigma: f32::INFINITY,
        };
        let f = render(
            &scene,
            &small(),
            &DAffine3::from_translation(DVec3::splat(100.0)),
            &noise,
            0,
        );
        assert_eq!(
            f.valid_depth_count(),
            0,
            "outside the room nothing faces the camera"
        );
        let empty_scene = Scene { boxes: Vec::new() };
        let f = render(&empty_scene, &small(), &pose, &NoiseModel::none(), 0);
        assert!(f.depth_m.iter().all(|&z| z == 0.0));
        let bad = RenderedFrame {
            width: 4,
            height: 4,
            ..RenderedFrame::default()
        };
        assert!(bad.to_png_bytes().is_err());
    }

    #[test]
    fn texture_has_gradients_everywhere() {
        let scene = Scene::room();
        let k = default_intrinsics();
        let f = render(&scene, &k, &trajectory_pose(0), &NoiseModel::none(), 0);
        let grey: Vec<f32> = f
            .rgb
            .chunks_exact(3)
            .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
            .collect();
        let w = k.width;
        let mut strong = 0;
        let mut total = 0;
        for v in 1..k.height - 1 {
            for u in 1..w - 1 {
                let gx = 0.5 * (grey[v * w + u + 1] - grey[v * w + u - 1]);
                let gy = 0.5 * (grey[(v + 1) * w + u] - grey[(v - 1) * w + u]);
                if gx.hypot(gy) > 1.0 {
                    strong += 1;
                }
                total += 1;
            }
        }
        let fraction = f64::from(strong) / f64::from(total);
        assert!(
            fraction > 0.8,
            "only {fraction} of pixels have gradient > 1"
        );
    }
}
