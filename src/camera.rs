//! Pinhole intrinsics: projection, back-projection and pyramid scaling.
//!
//! Camera frame: +x right, +y down, +z forward (optical axis), metres.
//! Pixel (u, v) has its centre at integer coordinates; u grows right, v down.
//! `fy` may be negative (ICL-NUIM's convention); every formula here uses it
//! as given, and `focal_abs` is provided where a length in pixels is needed.

use crate::se3::RigidF32;
use glam::{Vec2, Vec3};

/// Pinhole intrinsics of one image, in pixels, with the image size.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels (negative in ICL-NUIM's convention).
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl Intrinsics {
    /// Creates intrinsics from focal lengths and principal point, pixels.
    #[must_use]
    pub const fn new(fx: f32, fy: f32, cx: f32, cy: f32, width: usize, height: usize) -> Self {
        Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        }
    }

    /// Checks that the values are finite, the focal lengths non-zero and the size non-empty.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.problem().is_none()
    }

    /// What is wrong with these intrinsics, naming the field, or `None`.
    /// Refused: non-finite values; an empty or oversized image (1..=16384
    /// px per side); a focal length whose field of view is wider than about
    /// 170 degrees or narrower than about 0.6 degrees (|f| outside 0.05..100
    /// times the larger side); a principal point more than half the image
    /// size outside the image. Such values are typos or unit mix-ups (metres
    /// or millimetres for pixels), never a real RGB-D camera.
    #[must_use]
    pub fn problem(&self) -> Option<String> {
        let fields = [
            ("fx", self.fx),
            ("fy", self.fy),
            ("cx", self.cx),
            ("cy", self.cy),
        ];
        if let Some((name, v)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            return Some(format!("{name} must be a finite number of pixels, got {v}"));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Some(format!(
                "image size {}x{} must be 1..=16384 pixels per side",
                self.width, self.height
            ));
        }
        let side = self.width.max(self.height) as f32;
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.abs() >= (0.05 * side).max(1.0) && f.abs() <= 100.0 * side) {
                return Some(format!(
                    "{name} = {f} px is not a plausible focal length for a {}x{} image \
                     (expected |{name}| between {:.0} and {:.0} px)",
                    self.width,
                    self.height,
                    (0.05 * side).max(1.0),
                    100.0 * side
                ));
            }
        }
        for (name, c, size) in [("cx", self.cx, self.width), ("cy", self.cy, self.height)] {
            let size = size as f32;
            if !(c >= -0.5 * size && c <= 1.5 * size) {
                return Some(format!(
                    "{name} = {c} px puts the principal point far outside the {}x{} image",
                    self.width, self.height
                ));
            }
        }
        None
    }

    /// Mean absolute focal length, pixels: the scale of one pixel at 1 m depth.
    #[must_use]
    pub fn focal_abs(&self) -> f32 {
        0.5 * (self.fx.abs() + self.fy.abs())
    }

    /// Projects a point in the camera frame (metres) to continuous pixel coordinates.
    /// Meaningful only for `point_in_camera.z > 0`.
    #[inline]
    #[must_use]
    pub fn project(&self, point_in_camera: Vec3) -> Vec2 {
        let inv_z = 1.0 / point_in_camera.z;
        Vec2::new(
            self.fx * point_in_camera.x * inv_z + self.cx,
            self.fy * point_in_camera.y * inv_z + self.cy,
        )
    }

    /// Back-projects pixel (u, v) at depth `depth` (metres along +z) to the camera frame.
    #[inline]
    #[must_use]
    pub fn back_project(&self, u: f32, v: f32, depth: f32) -> Vec3 {
        Vec3::new(
            (u - self.cx) * depth / self.fx,
            (v - self.cy) * depth / self.fy,
            depth,
        )
    }

    /// Rounds continuous pixel coordinates to the nearest pixel inside the image.
    #[inline]
    #[must_use]
    pub fn pixel_index(&self, pixel: Vec2) -> Option<usize> {
        let u = pixel.x + 0.5;
        let v = pixel.y + 0.5;
        // Truncation is floor for the non-negative values kept, and unlike
        // `floor` needs no libm call on baseline x86-64 (a hot loop's cost).
        // Through u32: converting to a 64-bit integer costs a branch more.
        if u >= 0.0 && v >= 0.0 && u < self.width as f32 && v < self.height as f32 {
            Some(v as u32 as usize * self.width + u as u32 as usize)
        } else {
            None
        }
    }

    /// Intrinsics of the image downsampled by 2 (pixel centres kept consistent).
    #[must_use]
    pub fn half(&self) -> Self {
        Self {
            fx: self.fx * 0.5,
            fy: self.fy * 0.5,
            cx: (self.cx + 0.5) * 0.5 - 0.5,
            cy: (self.cy + 0.5) * 0.5 - 0.5,
            width: self.width / 2,
            height: self.height / 2,
        }
    }

    /// The intrinsics of this camera's images resized to `width` x
    /// `height` pixels: scaled by `width / self.width` when the aspect
    /// ratio is the same (pixel centres kept consistent, as in
    /// [`Self::half`]); otherwise the focal lengths are kept and the
    /// principal point keeps its place relative to the image, a guess
    /// (another aspect is another camera mode, which needs its own
    /// calibration: [`Self::same_aspect`] tells).
    #[must_use]
    pub fn for_image_size(&self, width: usize, height: usize) -> Self {
        if (width, height) == (self.width, self.height) || self.width == 0 || self.height == 0 {
            return Self {
                width,
                height,
                ..*self
            };
        }
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        let (fx, fy) = if self.same_aspect(width, height) {
            (self.fx * sx, self.fy * sx)
        } else {
            (self.fx, self.fy)
        };
        Self {
            fx,
            fy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            width,
            height,
        }
    }

    /// Whether images of `width` x `height` pixels have this image's aspect ratio.
    #[must_use]
    pub fn same_aspect(&self, width: usize, height: usize) -> bool {
        width as u64 * self.height as u64 == height as u64 * self.width as u64
    }

    /// Intrinsics of pyramid level `level` (0 = full resolution).
    #[must_use]
    pub fn level(&self, level: usize) -> Self {
        (0..level).fold(*self, |k, _| k.half())
    }

    /// Number of pixels, `width * height`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }
}

/// Depth (metres) and pixel index of a camera-frame point, or `None` when it
/// is behind the camera or outside the image.
#[inline]
#[must_use]
pub fn pixel_of(k: &Intrinsics, p: Vec3) -> Option<(f32, usize)> {
    if p.z <= 0.0 {
        return None;
    }
    k.pixel_index(k.project(p)).map(|i| (p.z, i))
}

/// Writes into `out[i]` the pixel index that `positions[i]` (world frame,
/// metres) projects to from `camera_from_world`, or `u32::MAX` when it lies
/// behind the camera or outside the image; the same pixel as [`pixel_of`].
/// Free of branches, so that the loop vectorises: it is the per-surfel
/// part of association that every visible surfel pays.
pub fn project_to_pixels_into(
    k: &Intrinsics,
    camera_from_world: &RigidF32,
    positions: &[Vec3],
    out: &mut [u32],
) {
    let (w, h) = (k.width as f32, k.height as f32);
    let width = k.width as u32;
    for (p, o) in positions.iter().zip(out.iter_mut()) {
        let q = camera_from_world.point(*p);
        let inv_z = 1.0 / q.z;
        // The arithmetic of `Intrinsics::project` and `pixel_index`, in the same order.
        let u = k.fx * q.x * inv_z + k.cx + 0.5;
        let v = k.fy * q.y * inv_z + k.cy + 0.5;
        let inside = q.z > 0.0 && u >= 0.0 && v >= 0.0 && u < w && v < h;
        // Truncation is floor for the non-negative values kept; others are discarded.
        let pixel = (v as u32).wrapping_mul(width).wrapping_add(u as u32);
        *o = if inside { pixel } else { u32::MAX };
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;
    use glam::{DAffine3, DQuat, DVec3};

    #[test]
    fn intrinsics_follow_a_resized_image() {
        let k = Intrinsics::new(535.4, 539.2, 320.1, 247.6, 640, 480);
        // Half the size: as a pyramid level.
        assert_eq!(k.for_image_size(320, 240), k.half());
        assert_eq!(k.for_image_size(640, 480), k);
        let double = k.for_image_size(1280, 960);
        assert_eq!(
            (double.fx, double.fy, double.width, double.height),
            (1070.8, 1078.4, 1280, 960)
        );
        assert!((double.cx - 640.7).abs() < 1e-3 && (double.cy - 495.7).abs() < 1e-3);
        // Another aspect: the focal lengths kept, the principal point in its place.
        let wide = k.for_image_size(848, 480);
        assert!(!k.same_aspect(848, 480) && k.same_aspect(320, 240));
        assert_eq!(
            (wide.fx, wide.fy, wide.cy, wide.width),
            (535.4, 539.2, 247.6, 848)
        );
        assert!((wide.cx - (320.6 * 848.0 / 640.0 - 0.5)).abs() < 1e-3);
        assert!(wide.is_valid());
    }

    #[test]
    fn project_inverts_back_project() {
        let k = Intrinsics::new(481.2, -480.0, 319.5, 239.5, 640, 480);
        let p = k.back_project(100.25, 300.5, 2.0);
        let px = k.project(p);
        assert!((px.x - 100.25).abs() < 1e-4 && (px.y - 300.5).abs() < 1e-4);
    }

    #[test]
    fn absurd_intrinsics_are_named() {
        let good = Intrinsics::new(535.4, 539.2, 320.1, 247.6, 640, 480);
        assert!(good.is_valid());
        let cases = [
            (
                Intrinsics {
                    fx: f32::NAN,
                    ..good
                },
                "fx",
            ),
            (
                Intrinsics {
                    cy: f32::INFINITY,
                    ..good
                },
                "cy",
            ),
            (Intrinsics { fx: 0.5354, ..good }, "fx"),
            (Intrinsics { fy: 5.4e6, ..good }, "fy"),
            (Intrinsics { cx: 3201.0, ..good }, "cx"),
            (Intrinsics { width: 0, ..good }, "size"),
        ];
        for (k, field) in cases {
            let problem = k.problem().expect("refused");
            assert!(problem.contains(field), "{problem}");
        }
        // ICL-NUIM's negative fy is fine.
        assert!(Intrinsics { fy: -480.0, ..good }.is_valid());
    }

    #[test]
    fn half_keeps_pixel_centres() {
        let k = Intrinsics::new(500.0, 500.0, 319.5, 239.5, 640, 480);
        let h = k.half();
        // Full-res pixel centres 0 and 1 average to half-res pixel 0.
        let p = k.back_project(0.5, 0.5, 1.0);
        let q = h.project(p);
        assert!(q.x.abs() < 1e-5 && q.y.abs() < 1e-5);
        assert_eq!((h.width, h.height), (320, 240));
    }

    #[test]
    fn batch_projection_gives_the_pixels_of_pixel_of() {
        for fy in [525.0, -525.0] {
            let k = Intrinsics::new(525.0, fy, 319.5, 239.5, 640, 480);
            let pose = DAffine3::from_rotation_translation(
                DQuat::from_euler(glam::EulerRot::XYZ, 0.1, -0.3, 0.05),
                DVec3::new(0.2, -0.1, 0.4),
            );
            let camera_from_world = RigidF32::from_affine(&pose.inverse());
            // A grid through the view, behind the camera and beyond the image edges.
            let mut positions: Vec<Vec3> = (0..4000)
                .map(|i| {
                    let (x, y, z) = ((i % 20) as f32, ((i / 20) % 20) as f32, (i / 400) as f32);
                    Vec3::new(x * 0.2 - 2.0, y * 0.15 - 1.5, z * 0.5 - 1.5)
                })
                .collect();
            positions.push(Vec3::NAN);
            let mut pixels = vec![0; positions.len()];
            project_to_pixels_into(&k, &camera_from_world, &positions, &mut pixels);
            let mut inside = 0;
            for (p, &pixel) in positions.iter().zip(&pixels) {
                let expected = pixel_of(&k, camera_from_world.point(*p)).map(|(_, i)| i as u32);
                assert_eq!(expected.unwrap_or(u32::MAX), pixel, "at {p}");
                inside += usize::from(expected.is_some());
            }
            assert!(inside > 500 && inside < 3000, "{inside} inside the image");
        }
    }
}

/// Published camera calibrations, selectable by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraPreset {
    /// TUM RGB-D freiburg1 (Kinect), 640x480, depth 5000 units/m.
    TumFr1,
    /// TUM RGB-D freiburg2 (Kinect), 640x480, depth 5000 units/m.
    TumFr2,
    /// TUM RGB-D freiburg3 (Asus Xtion, undistorted), 640x480, depth 5000 units/m.
    TumFr3,
    /// ICL-NUIM (synthetic), 640x480, depth 5000 units/m, negative fy.
    IclNuim,
    /// Microsoft 7-Scenes (Kinect v1), 640x480, depth millimetres, 65535 invalid.
    SevenScenes,
    /// Intel RealSense D400 (active stereo, depth aligned to colour), as
    /// Open3D's `realsense_recorder.py` records it: depth millimetres (the
    /// default depth unit), 0.2 to 5 m; intrinsics typical of a D435's
    /// colour camera at 640x480, replaced by the folder's
    /// `camera_intrinsic.json` (any size: 640x480, 848x480, 1280x720).
    RealSenseD400,
    /// iPhone / iPad LiDAR as the Stray Scanner app exports it (ARKit
    /// depth): 256x192 depth in millimetres, 0.2 to 5 m; intrinsics typical
    /// of an iPhone Pro scaled to 256x192, replaced by the folder's
    /// `camera_matrix.csv`.
    StrayLidar,
}

impl CameraPreset {
    /// All presets, in a stable order.
    pub const ALL: [CameraPreset; 7] = [
        Self::TumFr1,
        Self::TumFr2,
        Self::TumFr3,
        Self::IclNuim,
        Self::SevenScenes,
        Self::RealSenseD400,
        Self::StrayLidar,
    ];

    /// Short name used by the CLI, the wasm API and the page (`tum-fr3`, `icl-nuim`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::TumFr1 => "tum-fr1",
            Self::TumFr2 => "tum-fr2",
            Self::TumFr3 => "tum-fr3",
            Self::IclNuim => "icl-nuim",
            Self::SevenScenes => "7-scenes",
            Self::RealSenseD400 => "realsense-d400",
            Self::StrayLidar => "stray-lidar",
        }
    }

    /// Looks a preset up by its short name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Intrinsics at the preset's image size (640x480, Stray Scanner's
    /// depth 256x192), pixels. For the presets whose folders carry their
    /// own calibration ([`Self::calibrated_by_layout`]) these are only
    /// typical values: the sequence's [`crate::dataset::Sequence::intrinsics`] win.
    #[must_use]
    pub fn intrinsics(self) -> Intrinsics {
        let (fx, fy, cx, cy, width, height) = match self {
            Self::TumFr1 => (517.3, 516.5, 318.6, 255.3, 640, 480),
            Self::TumFr2 => (520.9, 521.0, 325.1, 249.7, 640, 480),
            Self::TumFr3 => (535.4, 539.2, 320.1, 247.6, 640, 480),
            // ICL-NUIM's ground truth is expressed for fy = -480: using it as
            // given makes the estimate directly comparable with the dataset's poses.
            Self::IclNuim => (481.20, -480.0, 319.5, 239.5, 640, 480),
            Self::SevenScenes => (585.0, 585.0, 320.0, 240.0, 640, 480),
            // A D435's colour camera at 640x480 (depth aligned to it).
            Self::RealSenseD400 => (615.0, 615.0, 320.0, 240.0, 640, 480),
            // An iPhone 13 Pro's colour camera at 1920x1440 (fx 1597,
            // cx 960, cy 720) scaled by 256 / 1920.
            Self::StrayLidar => (213.0, 213.0, 128.0, 96.0, 256, 192),
        };
        Intrinsics::new(fx, fy, cx, cy, width, height)
    }

    /// Whether the folders of this preset's layout carry their own
    /// calibration (RealSense's `camera_intrinsic.json`, Stray Scanner's
    /// `camera_matrix.csv`): then [`Self::intrinsics`] is only a typical
    /// value and focal lengths far from it are no sign of a mistake.
    #[must_use]
    pub fn calibrated_by_layout(self) -> bool {
        matches!(self, Self::RealSenseD400 | Self::StrayLidar)
    }

    /// Depth noise model this preset's sequences are tracked and fused with
    /// by default.
    ///
    /// - ICL-NUIM: simulated Kinect (Khoshelham and Elberink's z^2 over a
    ///   5 mm floor) for the Kinect-noised renderings, where it keeps far
    ///   walls from dominating and near planes from sliding
    ///   ([`SensorNoise::simulated_kinect`](crate::noise::SensorNoise::simulated_kinect));
    ///   the clean renderings are recognised on their first frame and
    ///   tracked unweighted ([`Self::clean_depth_noise`]).
    /// - 7-Scenes: the Kinect v1 model (Nguyen et al. 2012,
    ///   [`SensorNoise::kinect_v1`](crate::noise::SensorNoise::kinect_v1)):
    ///   the redkitchen loop, whose far walls and counters are 2-4 m away,
    ///   went from 3.75 to 2.58 cm ATE (every other frame of 1000; 4.09 to
    ///   3.21 cm at the full rate).
    /// - TUM: uniform (no weighting). The Kinect v1 model took fr3/teddy
    ///   (a close object, 1-2 m) from 0.673 to 0.767 cm ATE at stride 1
    ///   (strides 2/3/5/8: 0.822/0.828/0.823/0.802 cm); choose it with
    ///   `--noise kinect-v1`.
    /// - RealSense D400: active stereo
    ///   ([`SensorNoise::active_stereo`](crate::noise::SensorNoise::active_stereo)),
    ///   depth error growing with z^2 like any stereo camera's.
    /// - Stray Scanner (ARKit LiDAR):
    ///   [`SensorNoise::lidar`](crate::noise::SensorNoise::lidar).
    #[must_use]
    pub fn sensor_noise(self) -> crate::noise::SensorNoise {
        use crate::noise::SensorNoise;
        match self {
            Self::TumFr1 | Self::TumFr2 | Self::TumFr3 => SensorNoise::uniform(),
            Self::SevenScenes => SensorNoise::kinect_v1(),
            Self::IclNuim => SensorNoise::simulated_kinect(),
            Self::RealSenseD400 => SensorNoise::active_stereo(),
            Self::StrayLidar => SensorNoise::lidar(),
        }
    }

    /// The noise model used instead of [`Self::sensor_noise`] when the
    /// first frame's depth is clean (see `SlamConfig::clean_depth_noise`):
    /// ICL-NUIM's clean renderings are tracked unweighted.
    #[must_use]
    pub fn clean_depth_noise(self) -> Option<crate::noise::SensorNoise> {
        match self {
            Self::IclNuim => Some(crate::noise::SensorNoise::rendered()),
            _ => None,
        }
    }

    /// Depth conversion for this camera: units per metre, valid range (m), invalid raw value.
    ///
    /// RealSense D400: millimetres (the recorder's default depth unit),
    /// 0.2 to 5 m. Its minimum distance is 0.1 to 0.3 m depending on the
    /// resolution (0.2 m at 848x480), and its RMS error, about 2 % at 2 m,
    /// grows with z^2: 4 cm at 2 m, 16 cm at 4 m, 25 cm at 5 m; beyond 5 m
    /// a measurement is worth less than the surfels it would disturb (the
    /// recorder's own reconstruction stops at 3 m).
    /// Stray Scanner (ARKit LiDAR): millimetres, 0.2 to 5 m, the LiDAR's
    /// specified range (ARKit fills the 256x192 map beyond it with guesses).
    #[must_use]
    pub fn depth_settings(self) -> crate::frame::DepthSettings {
        use crate::frame::DepthSettings;
        match self {
            Self::TumFr1 | Self::TumFr2 | Self::TumFr3 => DepthSettings {
                scale: 5000.0,
                min_m: 0.3,
                max_m: 4.0,
                invalid_raw: None,
            },
            Self::IclNuim => DepthSettings {
                scale: 5000.0,
                min_m: 0.3,
                max_m: 8.0,
                invalid_raw: None,
            },
            Self::SevenScenes => DepthSettings {
                scale: 1000.0,
                min_m: 0.3,
                max_m: 4.0,
                invalid_raw: Some(65535),
            },
            Self::RealSenseD400 | Self::StrayLidar => DepthSettings {
                scale: 1000.0,
                min_m: 0.2,
                max_m: 5.0,
                invalid_raw: None,
            },
        }
    }
}
