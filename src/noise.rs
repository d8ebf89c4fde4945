//! Per-pixel depth uncertainty of an RGB-D sensor: how far a measured point
//! may be from the true surface, as a function of its depth and of the angle
//! between its ray and the surface normal.
//!
//! Axial (along the ray) standard deviation, after Nguyen, Izadi and Lovell
//! (2012, "Modeling Kinect sensor noise for improved 3D reconstruction and
//! tracking"):
//!
//! ```text
//! sigma_z(z, theta) = base + quadratic (z - offset)^2 + angle / sqrt(z) * theta^2 / (pi/2 - theta)^2
//! ```
//!
//! metres, `z` the depth in metres, `theta` the angle between the ray and the
//! surface normal. The lateral (across the ray) deviation is `lateral_px`
//! pixels at depth `z`: `lateral_px * z / focal` metres. A point-to-plane
//! residual sees the component of both along the surface normal.
//!
//! Weights are relative: [`SensorNoise::reference_m`] (the axial deviation
//! at 1 m, facing the surface) is the unit, so a measurement as good as the
//! reference counts 1 and residuals keep the meaning of metres at 1 m (the
//! robust thresholds in metres are unchanged). A model with no depth
//! dependence ([`SensorNoise::uniform`]) weighs every pixel 1, which is the
//! tracker and fusion without noise weighting.

use crate::portable_math::{at_least, at_most};

/// Largest angle between ray and normal the angle terms are evaluated at,
/// radians (80 degrees): beyond it `theta / (pi/2 - theta)` explodes, and
/// such grazing pixels are already refused by the normal gates.
const MAX_ANGLE_RAD: f32 = 80.0 * std::f32::consts::PI / 180.0;

/// Depth noise of a sensor, in metres and pixels (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorNoise {
    /// Constant part of the axial deviation, metres.
    pub base_m: f32,
    /// Coefficient of `(z - offset)^2` in the axial deviation, 1/m.
    pub quadratic_per_m: f32,
    /// Depth at which the quadratic term is smallest, metres.
    pub offset_m: f32,
    /// Coefficient of the angle term `theta^2 / (pi/2 - theta)^2 / sqrt(z)`, m^1.5.
    pub angle_m: f32,
    /// Lateral deviation, pixels of the full-resolution image.
    pub lateral_px: f32,
    /// Depth-edge pixels (a 4-neighbour missing or more than 4 % nearer or
    /// farther) have this many times the deviation: structured light
    /// smears depth across discontinuities. 1 = no edge effect.
    pub edge_factor: f32,
}

impl SensorNoise {
    /// Kinect v1 and other PrimeSense structured-light sensors (TUM RGB-D,
    /// 7-Scenes), Nguyen et al. 2012: axial `0.0012 + 0.0019 (z - 0.4)^2`
    /// m plus their angle term, lateral 0.8 px, edges 2x.
    #[must_use]
    pub const fn kinect_v1() -> Self {
        Self {
            base_m: 0.0012,
            quadratic_per_m: 0.0019,
            offset_m: 0.4,
            angle_m: 0.0001,
            lateral_px: 0.8,
            edge_factor: 2.0,
        }
    }

    /// A generic structured-light sensor (custom intrinsics): Khoshelham and
    /// Elberink 2012's axial `1.425e-3 z^2` m from disparity noise, with
    /// Nguyen's angle and lateral terms and edges 2x.
    #[must_use]
    pub const fn structured_light() -> Self {
        Self {
            base_m: 0.0,
            quadratic_per_m: 1.425e-3,
            offset_m: 0.0,
            angle_m: 0.0001,
            lateral_px: 0.8,
            edge_factor: 2.0,
        }
    }

    /// Depth with Kinect v1 noise simulated on a rendering (ICL-NUIM's
    /// noisy sequences, `--simulate-noise kinect-v1`): the disparity
    /// noise's `1.425e-3 z^2` m over a floor of 5 mm, axial only (the
    /// structured-light model's angle, lateral and edge terms took seed 1
    /// from 0.56 to 0.90 cm). The floor stands for
    /// what a point-to-plane residual holds besides the frame's disparity
    /// noise and does not shrink near the camera (the fused model's own
    /// scatter, the 0.5 px smear across slanted surfaces): without it near
    /// surfaces outweigh far ones 100:1 and a near plane slides. The long
    /// office, joint tracker, seed 1, ATE by floor: none 21.9 cm, 2 mm
    /// 42.9, 3 mm 0.82, 5 mm 0.56, 10 mm 0.71 (more far views lost); kt0
    /// 0.195, 0.072, 0.058, 0.055 cm. 5 mm: the best of both, away from the
    /// cliff below 3 mm (docs/design.md, "Defaults per preset").
    #[must_use]
    pub const fn simulated_kinect() -> Self {
        Self {
            base_m: 0.005,
            quadratic_per_m: 1.425e-3,
            ..Self::uniform()
        }
    }

    /// Active stereo (Intel RealSense D400): depth error grows with z^2
    /// like any stereo camera's; Intel specifies an RMS error under 2 % at
    /// 2 m (4 cm), `0.01 z^2` m, with Nguyen's angle and lateral terms and
    /// edges 2x (stereo matching smears depth across discontinuities too).
    #[must_use]
    pub const fn active_stereo() -> Self {
        Self {
            base_m: 0.0,
            quadratic_per_m: 0.01,
            offset_m: 0.0,
            angle_m: 0.0001,
            lateral_px: 0.8,
            edge_factor: 2.0,
        }
    }

    /// iPhone / iPad LiDAR depth as ARKit delivers it (time of flight,
    /// upsampled and filtered to 256x192): about 1 cm at 1 m growing slowly
    /// with depth, `0.008 + 0.002 z^2` m, edges 2x (ARKit's filtering
    /// blurs depth edges); lateral 0.5 px of the 256-pixel map.
    #[must_use]
    pub const fn lidar() -> Self {
        Self {
            base_m: 0.008,
            quadratic_per_m: 0.002,
            offset_m: 0.0,
            angle_m: 0.0001,
            lateral_px: 0.5,
            edge_factor: 2.0,
        }
    }

    /// Clean rendered depth (ICL-NUIM's noise-free renderings): only the 1/5000 m quantisation of
    /// the 16-bit depth, the same at every depth, so every pixel counts the
    /// same.
    #[must_use]
    pub const fn rendered() -> Self {
        Self {
            base_m: 0.0002,
            ..Self::uniform()
        }
    }

    /// No weighting: every pixel has the same deviation (1 mm), as before
    /// noise weighting existed.
    #[must_use]
    pub const fn uniform() -> Self {
        Self {
            base_m: 0.001,
            quadratic_per_m: 0.0,
            offset_m: 0.0,
            angle_m: 0.0,
            lateral_px: 0.0,
            edge_factor: 1.0,
        }
    }

    /// Named models for the CLI and the wasm API, in a stable order.
    pub const NAMES: [&'static str; 7] = [
        "kinect-v1",
        "structured-light",
        "simulated-kinect",
        "active-stereo",
        "lidar",
        "rendered",
        "uniform",
    ];

    /// The model called `name` (one of [`Self::NAMES`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "kinect-v1" => Some(Self::kinect_v1()),
            "structured-light" => Some(Self::structured_light()),
            "simulated-kinect" => Some(Self::simulated_kinect()),
            "active-stereo" => Some(Self::active_stereo()),
            "lidar" => Some(Self::lidar()),
            "rendered" => Some(Self::rendered()),
            "uniform" | "off" | "none" => Some(Self::uniform()),
            _ => None,
        }
    }

    /// What is wrong with the coefficients, naming the field, or `None`:
    /// every one must be finite and non-negative, `base_m` and the
    /// quadratic term not both zero, `edge_factor` at least 1.
    #[must_use]
    pub fn problem(&self) -> Option<String> {
        let fields = [
            ("base", self.base_m),
            ("quadratic", self.quadratic_per_m),
            ("offset", self.offset_m),
            ("angle", self.angle_m),
            ("lateral", self.lateral_px),
            ("edge", self.edge_factor),
        ];
        if let Some((name, v)) = fields.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            return Some(format!(
                "noise {name} coefficient must be a finite number >= 0, got {v}"
            ));
        }
        if self.base_m <= 0.0 && self.quadratic_per_m <= 0.0 {
            return Some("noise base and quadratic coefficients cannot both be 0".into());
        }
        if self.edge_factor < 1.0 {
            return Some(format!(
                "noise edge factor must be >= 1, got {}",
                self.edge_factor
            ));
        }
        None
    }

    /// Axial deviation at depth `z` (m) facing the surface, metres.
    #[inline]
    #[must_use]
    pub fn axial_m(&self, z: f32) -> f32 {
        let d = z - self.offset_m;
        self.base_m + self.quadratic_per_m * d * d
    }

    /// Depth (m) from which the axial deviation facing the surface reaches
    /// `sigma_m` and grows beyond it (on the far side of `offset_m`): the
    /// offset itself when the constant part alone reaches it; `None` when
    /// the deviation does not grow with depth.
    #[must_use]
    pub fn depth_where_axial_reaches(&self, sigma_m: f32) -> Option<f32> {
        if self.quadratic_per_m.is_nan() || self.quadratic_per_m <= 0.0 {
            return None;
        }
        let excess = (sigma_m - self.base_m).max(0.0);
        Some(self.offset_m + (excess / self.quadratic_per_m).sqrt())
    }

    /// The unit of the weights: the axial deviation at 1 m facing the surface, metres.
    #[inline]
    #[must_use]
    pub fn reference_m(&self) -> f32 {
        at_least(self.axial_m(1.0), 1e-6)
    }

    /// Deviation along the surface normal of a point measured at depth `z`
    /// (m) whose ray makes cosine `cos_ray` with the normal: the axial
    /// deviation along the ray and the lateral one across it, for a camera of
    /// focal length `focal_px` (pixels of the image the point comes from;
    /// lateral noise is given at full resolution, a coarser level's pixel is
    /// wider but holds the average of several, so the metric term is kept).
    #[inline]
    #[must_use]
    pub fn along_normal_m(&self, z: f32, cos_ray: f32, focal_px: f32) -> f32 {
        let z = at_least(z, 1e-3);
        let c = at_most(cos_ray.abs(), 1.0);
        let s2 = at_least(1.0 - c * c, 0.0);
        let mut axial = self.axial_m(z);
        if self.angle_m > 0.0 {
            let theta = at_most(acos_unit(c), MAX_ANGLE_RAD);
            let t = theta / (std::f32::consts::FRAC_PI_2 - theta);
            axial += self.angle_m * t * t / z.sqrt();
        }
        let lateral = self.lateral_px * z / at_least(focal_px.abs(), 1.0);
        // Each error projected onto the normal: the axial one by cos theta,
        // the lateral one by sin theta. The axial part is kept at a quarter
        // at least: a model without lateral and angle terms would otherwise
        // weigh grazing pixels without bound. (Not projecting the axial
        // part at all: ICL-NUIM kt0 with Kinect noise 0.95 cm ATE against
        // 0.29 cm, tests/sensor_noise.rs.)
        let along = axial * at_least(c, 0.25);
        (along * along + lateral * lateral * s2).sqrt()
    }

    /// Inverse-variance weight of a deviation `sigma_m` relative to the
    /// reference: `(reference / sigma)^2` (1 for a uniform model).
    #[inline]
    #[must_use]
    pub fn weight(&self, sigma_m: f32) -> f32 {
        let r = self.reference_m() / at_least(sigma_m, 1e-6);
        r * r
    }

    /// Scale of a residual and its Jacobian row (the square root of
    /// [`Self::weight`]): `reference / sigma`.
    #[inline]
    #[must_use]
    pub fn scale(&self, sigma_m: f32) -> f32 {
        self.reference_m() / at_least(sigma_m, 1e-6)
    }

    /// Whether the model weighs every pixel the same (no depth, angle or
    /// edge dependence): then weighting is skipped and nothing changes.
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        self.quadratic_per_m == 0.0
            && self.angle_m == 0.0
            && self.lateral_px == 0.0
            && self.edge_factor == 1.0
    }
}

/// `acos(c)` for `c` in `0..=1`, within 7e-5 rad (Abramowitz and Stegun
/// 4.4.45): the weights run per pixel and per ICP correspondence, where
/// the library `acos` cost a third of the weighted tracker's time.
#[inline]
fn acos_unit(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    (1.0 - c).sqrt() * (1.570_728_8 + c * (-0.212_114_4 + c * (0.074_261 - 0.018_729_3 * c)))
}

/// Whether `depth` (metres, `width` columns, 0 = no measurement) is clean,
/// as rendered depth is: the 75th percentile of the second differences of
/// depth along rows, over valid triples that are not depth edges (under
/// 5 cm), at most [`CLEAN_DEPTH_MAX_M`]. On a plane depth is nearly linear
/// over three pixels (the curvature of `1 / (a u + b)` is micrometres), so
/// what remains is noise and quantisation: ICL-NUIM's clean renderings read
/// a few tenths of a millimetre (1/5000 m steps), Kinect-class depth and
/// its simulations millimetres. `None` with fewer than 1000 triples.
#[must_use]
pub fn depth_is_clean(depth: &[f32], width: usize) -> Option<bool> {
    if width < 3 {
        return None;
    }
    let mut second: Vec<f32> = Vec::new();
    for row in depth.chunks_exact(width).step_by(2) {
        for t in row.windows(3).step_by(2) {
            if t.iter().all(|z| *z > 0.0 && z.is_finite()) {
                let d2 = (t[0] - 2.0 * t[1] + t[2]).abs();
                if d2 < 0.05 {
                    second.push(d2);
                }
            }
        }
    }
    if second.len() < 1000 {
        return None;
    }
    let at = second.len() * 3 / 4;
    let (_, p75, _) = second.select_nth_unstable_by(at, f32::total_cmp);
    Some(*p75 <= CLEAN_DEPTH_MAX_M)
}

/// Largest 75th percentile of depth's second differences (metres) that
/// [`depth_is_clean`] calls clean: two 1/5000 m quantisation steps.
pub const CLEAN_DEPTH_MAX_M: f32 = 0.0004;

impl Default for SensorNoise {
    /// The structured-light model: most RGB-D cameras with custom
    /// intrinsics are structured-light or stereo, whose noise grows with z^2.
    fn default() -> Self {
        Self::structured_light()
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    #[test]
    fn the_depth_where_the_axial_deviation_reaches_a_value() {
        use super::SensorNoise;
        let at = |m: SensorNoise, sigma| m.depth_where_axial_reaches(sigma).expect("grows");
        // 0.005 + 1.425e-3 z^2 = 0.012 at z = 2.216 m; 0.0012 + 0.0019 (z - 0.4)^2 at 2.784 m.
        assert!((at(SensorNoise::simulated_kinect(), 0.012) - 2.2164).abs() < 1e-3);
        assert!((at(SensorNoise::kinect_v1(), 0.012) - 2.7841).abs() < 1e-3);
        for (model, sigma) in [
            (SensorNoise::kinect_v1(), 0.012),
            (SensorNoise::active_stereo(), 0.02),
        ] {
            let z = at(model, sigma);
            assert!((model.axial_m(z) - sigma).abs() < 1e-6, "{z}");
        }
        // The constant part alone reaches it: from the offset.
        assert_eq!(at(SensorNoise::kinect_v1(), 0.001), 0.4);
        assert_eq!(
            SensorNoise::uniform().depth_where_axial_reaches(0.012),
            None
        );
        assert_eq!(
            SensorNoise::rendered().depth_where_axial_reaches(0.012),
            None
        );
    }

    #[test]
    fn rendered_depth_is_clean_and_noisy_depth_is_not() {
        let (w, h) = (160, 120);
        // A slanted plane, quantised to 1/5000 m as ICL-NUIM stores it.
        let plane: Vec<f32> = (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f32, (i / w) as f32);
                let z = 1.0 / (0.4 + 0.0009 * u + 0.0004 * v);
                (z * 5000.0).round() / 5000.0
            })
            .collect();
        assert_eq!(super::depth_is_clean(&plane, w), Some(true));
        // The same with 2 mm of deterministic pseudo-noise.
        let noisy: Vec<f32> = plane
            .iter()
            .enumerate()
            .map(|(i, z)| {
                let x = (i as u32).wrapping_mul(2_654_435_761) as f32 / u32::MAX as f32;
                z + 0.004 * (x - 0.5) * 1.7
            })
            .collect();
        assert_eq!(super::depth_is_clean(&noisy, w), Some(false));
        assert_eq!(super::depth_is_clean(&plane[..100], w), None);
    }

    use super::*;

    #[test]
    fn published_values() {
        let k = SensorNoise::kinect_v1();
        // Nguyen et al. Fig. 7: about 1.5 mm at 0.8 m, 1.9 mm at 1 m, 6 mm at 2 m.
        assert!((k.axial_m(1.0) - 0.001_884).abs() < 1e-6);
        assert!((k.axial_m(2.0) - 0.006_064).abs() < 1e-6);
        let s = SensorNoise::structured_light();
        assert!((s.axial_m(4.0) - 0.0228).abs() < 1e-6);
        // Facing the surface only the axial part counts. Oblique, the axial
        // part is projected on the normal (by cos theta) and the angle and
        // lateral parts add to it: more than the projection alone, and
        // growing towards grazing.
        let facing = s.along_normal_m(2.0, 1.0, 525.0);
        assert!((facing - s.axial_m(2.0)).abs() < 1e-7);
        let oblique = s.along_normal_m(2.0, 0.3, 525.0);
        assert!(oblique > 0.3 * s.axial_m(2.0) * 1.5, "{oblique}");
        assert!(s.along_normal_m(2.0, 0.1, 525.0) > oblique);
        assert!((s.weight(s.reference_m()) - 1.0).abs() < 1e-6);
        assert!(s.weight(s.axial_m(4.0)) < 0.01);
    }

    #[test]
    fn fast_acos_matches_the_library() {
        for i in 0..=1000 {
            let c = i as f32 / 1000.0;
            assert!((acos_unit(c) - c.acos()).abs() < 1e-4, "{c}");
        }
    }

    #[test]
    fn uniform_weighs_everything_one() {
        // Uniform models are not weighted at all (`is_uniform` skips the
        // weights in ICP and fusion); facing the surface their weight is 1
        // at every depth.
        for noise in [SensorNoise::uniform(), SensorNoise::rendered()] {
            assert!(noise.is_uniform());
            for z in [0.5, 3.0, 7.0] {
                let w = noise.weight(noise.along_normal_m(z, 1.0, 480.0));
                assert!((w - 1.0).abs() < 1e-5, "{w}");
            }
        }
        assert!(!SensorNoise::kinect_v1().is_uniform());
    }

    #[test]
    fn names_and_problems() {
        for name in SensorNoise::NAMES {
            let noise = SensorNoise::from_name(name).expect("named");
            assert_eq!(noise.problem(), None, "{name}");
        }
        assert_eq!(SensorNoise::from_name("sonar"), None);
        let bad = SensorNoise {
            angle_m: f32::NAN,
            ..SensorNoise::kinect_v1()
        };
        assert!(bad.problem().expect("refused").contains("angle"));
        let zero = SensorNoise {
            base_m: 0.0,
            quadratic_per_m: 0.0,
            ..SensorNoise::uniform()
        };
        assert!(zero.problem().is_some());
        // Odd inputs never give NaN.
        let n = SensorNoise::kinect_v1();
        for (z, c) in [(0.0, 0.0), (-1.0, 2.0), (1e9, -1.0)] {
            assert!(n.along_normal_m(z, c, 0.0).is_finite());
        }
    }
}
