//! Colour registered to depth: each depth pixel back-projected with the
//! depth camera's pinhole intrinsics (as tracking sees it), moved into the
//! colour camera by the depth-to-colour extrinsics, projected with the
//! colour camera's intrinsics and distortion (librealsense's models), and
//! its colour sampled bilinearly.

use glam::{DAffine3, DVec3};

use super::message::CameraInfo;
use super::RosbagError;
use crate::camera::Intrinsics;
use crate::dataset::DEPTH_ONLY_GREY;

/// A lens distortion model, as librealsense projects with it; coefficients
/// `[k1, k2, p1, p2, k3]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    /// No distortion (every coefficient 0, whatever the model's name).
    None,
    /// Brown-Conrady (`Brown Conrady`, ROS's `plumb_bob`): radial and
    /// tangential terms of the undistorted point.
    BrownConrady([f64; 5]),
    /// librealsense's `Modified Brown Conrady` and `Inverse Brown Conrady`:
    /// the tangential terms of the radially scaled point.
    ModifiedBrownConrady([f64; 5]),
}

impl Distortion {
    /// The model a camera info names; an unknown model with non-zero
    /// coefficients is refused by name.
    pub fn from_camera_info(info: &CameraInfo, topic: &str) -> Result<Self, RosbagError> {
        let mut c = [0.0; 5];
        for (to, from) in c.iter_mut().zip(&info.d) {
            *to = *from;
        }
        if info.d.iter().all(|&v| v == 0.0) {
            return Ok(Self::None);
        }
        let name = info.distortion_model.to_ascii_lowercase().replace('_', " ");
        match name.as_str() {
            "brown conrady" | "plumb bob" if info.d.len() <= 5 => Ok(Self::BrownConrady(c)),
            "modified brown conrady" | "inverse brown conrady" if info.d.len() <= 5 => {
                Ok(Self::ModifiedBrownConrady(c))
            }
            _ => Err(RosbagError::UnsupportedDistortion {
                topic: topic.to_owned(),
                model: info.distortion_model.clone(),
                coefficients: info.d.len(),
            }),
        }
    }

    /// The distorted normalised image point of the undistorted `(x, y)`.
    fn apply(self, x: f64, y: f64) -> (f64, f64) {
        match self {
            Self::None => (x, y),
            Self::BrownConrady([k1, k2, p1, p2, k3]) => {
                let r2 = x * x + y * y;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
                (
                    x * f + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                    y * f + 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y),
                )
            }
            Self::ModifiedBrownConrady([k1, k2, p1, p2, k3]) => {
                let r2 = x * x + y * y;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
                let (x, y) = (x * f, y * f);
                (
                    x + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                    y + 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y),
                )
            }
        }
    }
}

/// One camera of a recording: pinhole intrinsics (pixels), image size and
/// distortion, from its `camera_info`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraModel {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The lens distortion.
    pub distortion: Distortion,
}

impl CameraModel {
    /// The model of a camera info (its `K` row-major).
    pub fn from_camera_info(info: &CameraInfo, topic: &str) -> Result<Self, RosbagError> {
        Ok(Self {
            fx: info.k[0],
            fy: info.k[4],
            cx: info.k[2],
            cy: info.k[5],
            width: info.width as usize,
            height: info.height as usize,
            distortion: Distortion::from_camera_info(info, topic)?,
        })
    }

    /// The pinhole part as the pipeline's [`Intrinsics`] (f32).
    #[must_use]
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics::new(
            self.fx as f32,
            self.fy as f32,
            self.cx as f32,
            self.cy as f32,
            self.width,
            self.height,
        )
    }

    /// The pixel where the camera sees point `p` (camera frame, metres),
    /// if in front of it.
    fn project(&self, p: DVec3) -> Option<(f64, f64)> {
        if p.z <= 0.0 {
            return None;
        }
        let (x, y) = self.distortion.apply(p.x / p.z, p.y / p.z);
        Some((x * self.fx + self.cx, y * self.fy + self.cy))
    }
}

/// Colour registered to a depth camera; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// The depth camera (its distortion is not used: tracking's pinhole).
    pub depth: CameraModel,
    /// The colour camera.
    pub colour: CameraModel,
    /// Colour camera from depth camera (`p_colour = T * p_depth`), metres.
    pub colour_from_depth: DAffine3,
}

impl Registration {
    /// Whether the colour image is already registered (same intrinsics and
    /// size, no distortion, identity extrinsics): its pixels are copied.
    fn is_identity(&self) -> bool {
        let (d, c) = (&self.depth, &self.colour);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(1.0);
        let t = &self.colour_from_depth;
        (d.width, d.height) == (c.width, c.height)
            && c.distortion == Distortion::None
            && close(d.fx, c.fx)
            && close(d.fy, c.fy)
            && close(d.cx, c.cx)
            && close(d.cy, c.cy)
            && t.translation.length() < 1e-9
            && (t.matrix3 - glam::DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .all(|v| v.abs() < 1e-9)
    }

    /// The colour (RGB8, `depth.width * depth.height * 3` bytes, into
    /// `out`) of each pixel of `depth_raw` (`units_m` metres per unit, 0 =
    /// none), sampled from `colour_rgb` (RGB8 at the colour camera's size).
    /// A pixel without depth takes the colour where the frame's mean depth
    /// would put it; one the colour camera does not see is grey. Depth of
    /// another length than the depth camera's size gives no colour (`out`
    /// empty).
    pub fn register(&self, depth_raw: &[u16], units_m: f64, colour_rgb: &[u8], out: &mut Vec<u8>) {
        let (w, h) = (self.depth.width, self.depth.height);
        out.clear();
        if w == 0 || depth_raw.len() != w * h {
            return;
        }
        if self.is_identity() && colour_rgb.len() == 3 * w * h {
            out.extend_from_slice(colour_rgb);
            return;
        }
        out.resize(3 * w * h, DEPTH_ONLY_GREY);
        let (sum, n) = depth_raw
            .iter()
            .filter(|&&d| d > 0)
            .fold((0.0, 0usize), |(s, n), &d| (s + f64::from(d), n + 1));
        let mean_m = if n > 0 { sum / n as f64 * units_m } else { 1.0 };
        for (i, (&d, px)) in depth_raw.iter().zip(out.chunks_exact_mut(3)).enumerate() {
            let z = if d > 0 {
                f64::from(d) * units_m
            } else {
                mean_m
            };
            let (u, v) = ((i % w) as f64, (i / w) as f64);
            let p = DVec3::new(
                (u - self.depth.cx) / self.depth.fx * z,
                (v - self.depth.cy) / self.depth.fy * z,
                z,
            );
            if let Some((cu, cv)) = self
                .colour
                .project(self.colour_from_depth.transform_point3(p))
            {
                if let Some(rgb) =
                    bilinear(colour_rgb, self.colour.width, self.colour.height, cu, cv)
                {
                    px.copy_from_slice(&rgb);
                }
            }
        }
    }
}

/// The colour at `(u, v)` (pixel centres at integers) of an RGB8 image
/// `width` x `height`, bilinearly; `None` outside it.
pub fn bilinear(rgb: &[u8], width: usize, height: usize, u: f64, v: f64) -> Option<[u8; 3]> {
    if width == 0 || height == 0 {
        return None;
    }
    if !(u >= 0.0 && v >= 0.0 && u <= (width - 1) as f64 && v <= (height - 1) as f64) {
        return None;
    }
    let (x0, y0) = (u.floor() as usize, v.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (ax, ay) = (u - x0 as f64, v - y0 as f64);
    let at =
        |x: usize, y: usize, c: usize| f64::from(*rgb.get(3 * (y * width + x) + c).unwrap_or(&0));
    let mut out = [0u8; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = at(x0, y0, c) * (1.0 - ax) + at(x1, y0, c) * ax;
        let bottom = at(x0, y1, c) * (1.0 - ax) + at(x1, y1, c) * ax;
        *o = (top * (1.0 - ay) + bottom * ay).round().clamp(0.0, 255.0) as u8;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(fx: f64, w: usize, h: usize) -> CameraModel {
        CameraModel {
            fx,
            fy: fx,
            cx: (w as f64 - 1.0) / 2.0,
            cy: (h as f64 - 1.0) / 2.0,
            width: w,
            height: h,
            distortion: Distortion::None,
        }
    }

    #[test]
    fn a_shifted_colour_camera_sees_the_depth_pixel_where_the_geometry_puts_it() {
        // Colour camera 10 cm to the right (+x) of the depth camera, twice
        // its resolution; a wall at 2 m. Depth pixel u sees x = (u - cx) z /
        // fx; the colour camera sees it at x - 0.1.
        let depth = camera(100.0, 40, 30);
        let colour = camera(200.0, 80, 60);
        let reg = Registration {
            depth,
            colour,
            colour_from_depth: DAffine3::from_translation(DVec3::new(-0.1, 0.0, 0.0)),
        };
        // The colour image: red channel = column, green = row.
        let mut rgb = Vec::new();
        for v in 0..60u8 {
            for u in 0..80u8 {
                rgb.extend([u, v, 7]);
            }
        }
        let raw = vec![2000u16; 40 * 30];
        let mut out = Vec::new();
        reg.register(&raw, 0.001, &rgb, &mut out);
        assert_eq!(out.len(), 40 * 30 * 3);
        for (v, u) in [(15usize, 20usize), (3, 35), (29, 10)] {
            let x = (u as f64 - depth.cx) * 2.0 / depth.fx - 0.1;
            let y = (v as f64 - depth.cy) * 2.0 / depth.fy;
            let (cu, cv) = (
                x / 2.0 * colour.fx + colour.cx,
                y / 2.0 * colour.fy + colour.cy,
            );
            let px = &out[3 * (v * 40 + u)..][..3];
            if cu < 0.0 {
                assert_eq!(px, &[DEPTH_ONLY_GREY; 3], "outside the colour image");
            } else {
                assert_eq!(px, &[cu.round() as u8, cv.round() as u8, 7], "({u}, {v})");
            }
        }
        // Same camera, no motion: the pixels are copied.
        let same = Registration {
            depth,
            colour: depth,
            colour_from_depth: DAffine3::IDENTITY,
        };
        let small: Vec<u8> = (0..40 * 30 * 3).map(|i| (i % 251) as u8).collect();
        same.register(&raw, 0.001, &small, &mut out);
        assert_eq!(out, small);
    }

    #[test]
    fn brown_conrady_moves_points_outward_for_positive_k1() {
        let d = Distortion::BrownConrady([0.1, 0.0, 0.0, 0.0, 0.0]);
        let (x, y) = d.apply(0.5, 0.0);
        assert!((x - 0.5 * (1.0 + 0.1 * 0.25)).abs() < 1e-12 && y == 0.0);
        let m = Distortion::ModifiedBrownConrady([0.0, 0.0, 0.01, 0.0, 0.0]);
        let b = Distortion::BrownConrady([0.0, 0.0, 0.01, 0.0, 0.0]);
        assert_eq!(
            m.apply(0.3, 0.2),
            b.apply(0.3, 0.2),
            "the same without radial terms"
        );
    }
}
