//! Camera settings that look wrong for the data: a warning, not an error.
//!
//! A wrong depth scale or focal length is the commonest mistake with real
//! sensors, and the tracker runs "successfully" on it (a map scaled or
//! mirrored is still rigid from frame to frame). Two kinds of evidence are
//! checked:
//!
//! - the depth image itself ([`depth_scale_warning`]): where the raw values
//!   land in metres for the configured scale, against the depth cut-off;
//! - the dataset's layout ([`layout_warnings`]): the preset the layout
//!   implies against the preset and values in use (a focal length of the
//!   other sign mirrors the map: no geometric test can see that).
//!
//! [`SettingsCheck`] keeps what was found for a [`Pipeline`](super::Pipeline).

use crate::camera::CameraPreset;
use crate::dataset::DatasetKind;
use crate::frame::{decode_depth_raw, DepthSettings};
use crate::pipeline::{Pipeline, SlamConfig};
use std::fmt;

/// Fewer measured depth pixels than this say nothing about the scale.
const MIN_DEPTH_SAMPLES: usize = 1000;
/// More than this fraction of measured pixels beyond one end of the range
/// means the scale, not the scene, put them there.
const CUT_FRACTION: f32 = 0.5;
/// A focal length or depth scale this many times off the layout's preset
/// (either way) is named.
const RATIO_OFF: f32 = 1.25;

/// A camera setting that does not fit the data; `Display` names the setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingsWarning {
    /// Most measured depths fall outside the depth range at this scale.
    DepthScale {
        /// The configured raw units per metre.
        scale: f32,
        /// Median of the measured depths at that scale, metres.
        median_m: f32,
        /// Fraction of measured pixels outside `min_m ..= max_m`.
        cut_fraction: f32,
        /// The configured depth range, metres.
        min_m: f32,
        /// See `min_m`.
        max_m: f32,
    },
    /// The preset belongs to another dataset than the folder's layout.
    Preset {
        /// The preset in use.
        chosen: CameraPreset,
        /// The layout recognised.
        layout: DatasetKind,
        /// The preset of that layout.
        expected: CameraPreset,
    },
    /// The frames have another aspect ratio than the layout preset's
    /// calibrated image: its focal lengths are a guess for them.
    OtherAspect {
        /// The frames' size, pixels.
        width: usize,
        /// See `width`.
        height: usize,
        /// The preset, calibrated at its own size.
        preset: CameraPreset,
    },
    /// A camera value far from (or of the other sign than) the layout's preset.
    Value {
        /// `fx`, `fy` or `depth scale`.
        setting: &'static str,
        /// The value in use (pixels, or units per metre).
        value: f32,
        /// The layout preset's value.
        expected: f32,
        /// That preset.
        preset: CameraPreset,
    },
}

impl fmt::Display for SettingsWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::DepthScale {
                scale,
                median_m,
                cut_fraction,
                min_m,
                max_m,
            } => {
                let side = if median_m > max_m {
                    format!("beyond the {max_m} m cut-off")
                } else if median_m < min_m {
                    format!("nearer than the {min_m} m minimum")
                } else {
                    format!("within {min_m}-{max_m} m")
                };
                write!(
                    f,
                    "depth scale {scale} units/m looks wrong: the median depth would be {median_m:.2} m, {side}, and {:.0}% of the measured pixels are cut (check the depth scale or the preset)",
                    100.0 * cut_fraction
                )
            }
            Self::Preset {
                chosen,
                layout,
                expected,
            } => write!(
                f,
                "preset {} does not match the folder's {} layout (its preset: {}): check the preset",
                chosen.name(),
                layout.name(),
                expected.name()
            ),
            Self::OtherAspect {
                width,
                height,
                preset,
            } => {
                let k = preset.intrinsics();
                write!(
                    f,
                    "the frames are {width}x{height}, but {} is calibrated at {}x{}, another aspect ratio: its focal lengths are a guess for them; give the camera's own fx, fy, cx and cy",
                    preset.name(),
                    k.width,
                    k.height
                )
            }
            Self::Value {
                setting,
                value,
                expected,
                preset,
            } => {
                let why = if value * expected < 0.0 {
                    " (the other sign: the map comes out mirrored, and every frame still tracks)"
                } else {
                    ""
                };
                write!(
                    f,
                    "{setting} = {value} differs from {}'s {expected}{why}: check {setting}",
                    preset.name()
                )
            }
        }
    }
}

/// The layout a preset belongs to.
fn layout_of(preset: CameraPreset) -> DatasetKind {
    match preset {
        CameraPreset::TumFr1 | CameraPreset::TumFr2 | CameraPreset::TumFr3 => DatasetKind::Tum,
        CameraPreset::IclNuim => DatasetKind::IclNuim,
        CameraPreset::SevenScenes => DatasetKind::SevenScenes,
        CameraPreset::RealSenseD400 => DatasetKind::RealSense,
        CameraPreset::StrayLidar => DatasetKind::StrayScanner,
    }
}

/// True when `value` is of the other sign than `expected`, or more than
/// [`RATIO_OFF`] times off it either way.
fn far_off(value: f32, expected: f32) -> bool {
    if value * expected <= 0.0 {
        return value != expected;
    }
    let ratio = (value / expected).abs();
    !(1.0 / RATIO_OFF..=RATIO_OFF).contains(&ratio)
}

/// What the folder's layout (its preset `detected`) says about `config`
/// (made from preset `chosen`): a preset of another dataset, and focal
/// lengths or a depth scale far from the layout's preset. Certain only
/// about the layout; the values could be a re-calibration, so these are
/// warnings.
#[must_use]
pub fn layout_warnings(
    detected: CameraPreset,
    chosen: CameraPreset,
    config: &SlamConfig,
) -> Vec<SettingsWarning> {
    let mut out = Vec::new();
    let layout = layout_of(detected);
    if layout_of(chosen) != layout {
        out.push(SettingsWarning::Preset {
            chosen,
            layout,
            expected: detected,
        });
    }
    // The preset as it applies to frames of the configured size.
    let (width, height) = (config.intrinsics.width, config.intrinsics.height);
    let preset_k = detected.intrinsics();
    let k = preset_k.for_image_size(width, height);
    // Once fx, fy, cx and cy are all the user's own, there is no guess to warn about.
    let c = &config.intrinsics;
    let guessed = [(c.fx, k.fx), (c.fy, k.fy), (c.cx, k.cx), (c.cy, k.cy)]
        .iter()
        .any(|(value, guess)| value == guess);
    if !detected.calibrated_by_layout() && !preset_k.same_aspect(width, height) && guessed {
        out.push(SettingsWarning::OtherAspect {
            width,
            height,
            preset: detected,
        });
    }
    let d = detected.depth_settings();
    let mut values = vec![("depth scale", config.depth.scale, d.scale)];
    // A layout with its own calibration file: the preset's focal lengths
    // are only typical, the file's are in use.
    if !detected.calibrated_by_layout() {
        values.insert(0, ("fy", config.intrinsics.fy, k.fy));
        values.insert(0, ("fx", config.intrinsics.fx, k.fx));
    }
    for (setting, value, expected) in values {
        if far_off(value, expected) {
            out.push(SettingsWarning::Value {
                setting,
                value,
                expected,
                preset: detected,
            });
        }
    }
    out
}

/// Where raw depth values `raw` land for `depth`'s scale: a warning when
/// more than half of the measured pixels fall beyond one end of the depth
/// range (the scene is not all beyond the cut-off; the scale is off), or
/// the median does. `None` with too few measured pixels to tell.
#[must_use]
pub fn depth_scale_warning(raw: &[u16], depth: &DepthSettings) -> Option<SettingsWarning> {
    let mut metres: Vec<f32> = raw
        .iter()
        .filter(|&&r| r != 0 && Some(r) != depth.invalid_raw)
        .map(|&r| f32::from(r) / depth.scale)
        .collect();
    if metres.len() < MIN_DEPTH_SAMPLES {
        return None;
    }
    let n = metres.len() as f32;
    let far = metres.iter().filter(|&&d| d > depth.max_m).count() as f32 / n;
    let near = metres.iter().filter(|&&d| d < depth.min_m).count() as f32 / n;
    let middle = metres.len() / 2;
    let (_, &mut median_m, _) = metres.select_nth_unstable_by(middle, f32::total_cmp);
    let out_of_range = median_m > depth.max_m || median_m < depth.min_m;
    (out_of_range || far > CUT_FRACTION || near > CUT_FRACTION).then_some(
        SettingsWarning::DepthScale {
            scale: depth.scale,
            median_m,
            cut_fraction: far + near,
            min_m: depth.min_m,
            max_m: depth.max_m,
        },
    )
}

/// The warnings a pipeline has found so far, and whether its depth was
/// looked at yet (once, on the first depth image it was given).
#[derive(Debug, Clone, Default)]
pub struct SettingsCheck {
    warnings: Vec<SettingsWarning>,
    pub(super) depth_checked: bool,
    /// Warnings not yet handed to a frame report.
    unreported: Vec<SettingsWarning>,
}

impl SettingsCheck {
    /// Keeps `warning`; `with_frame`: hand it to the next frame report too
    /// (a caller of a check gets its warnings as the check's result).
    fn add(&mut self, warning: SettingsWarning, with_frame: bool) {
        if !self.warnings.contains(&warning) {
            self.warnings.push(warning);
            if with_frame {
                self.unreported.push(warning);
            }
        }
    }

    /// The first warning not yet reported with a frame (the rest stay for the next frames).
    pub(crate) fn take_unreported(&mut self) -> Option<SettingsWarning> {
        (!self.unreported.is_empty()).then(|| self.unreported.remove(0))
    }
}

impl Pipeline {
    /// Every camera-settings warning found so far (see [`SettingsWarning`]).
    #[must_use]
    pub fn settings_warnings(&self) -> &[SettingsWarning] {
        &self.settings_check.warnings
    }

    /// Checks the settings (made from preset `chosen`) against the folder's
    /// layout (its preset `detected`); the warnings found are kept and
    /// returned (not repeated in frame reports).
    pub fn check_layout(
        &mut self,
        detected: CameraPreset,
        chosen: CameraPreset,
    ) -> Vec<SettingsWarning> {
        let found = layout_warnings(detected, chosen, &self.config);
        for w in &found {
            self.settings_check.add(*w, false);
        }
        found
    }

    /// [`Self::check_layout`] for a recording that gives its own depth
    /// units (a RealSense `.bag`): its depth scale is not compared with the
    /// preset's.
    pub fn check_recorded_layout(
        &mut self,
        detected: CameraPreset,
        chosen: CameraPreset,
    ) -> Vec<SettingsWarning> {
        let found: Vec<SettingsWarning> = layout_warnings(detected, chosen, &self.config)
            .into_iter()
            .filter(|w| {
                !matches!(
                    w,
                    SettingsWarning::Value {
                        setting: "depth scale",
                        ..
                    }
                )
            })
            .collect();
        for w in &found {
            self.settings_check.add(*w, false);
        }
        found
    }

    /// Checks the depth scale on raw depth values (the first image given
    /// only); a warning found is kept, returned, and reported with the next
    /// frame.
    pub fn check_depth_raw(&mut self, raw: &[u16]) -> Option<SettingsWarning> {
        if self.settings_check.depth_checked {
            return None;
        }
        self.settings_check.depth_checked = true;
        let found = depth_scale_warning(raw, &self.config.depth);
        if let Some(w) = found {
            // Reported with the frame: `push_png` checks before decoding.
            self.settings_check.add(w, true);
        }
        found
    }

    /// [`check_depth_raw`](Self::check_depth_raw) on a 16-bit depth PNG; an
    /// image that does not decode is left to the frame's own error.
    pub fn check_depth_png(&mut self, depth_png: &[u8]) -> Option<SettingsWarning> {
        if self.settings_check.depth_checked {
            return None;
        }
        let (_, _, raw) = decode_depth_raw(depth_png).ok()?;
        self.check_depth_raw(&raw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scale_five_times_too_small_is_named() {
        // Depths 0.8..2.4 m in TUM units (5000/m), read at 1000/m.
        let raw: Vec<u16> = (0..5000u16).map(|i| 4000 + 2 * (i % 4000)).collect();
        let right = DepthSettings::default();
        assert_eq!(depth_scale_warning(&raw, &right), None);
        let wrong = CameraPreset::SevenScenes.depth_settings();
        let w = depth_scale_warning(&raw, &wrong).expect("a warning");
        assert!(w.to_string().contains("depth scale 1000"), "{w}");
    }

    #[test]
    fn too_few_pixels_say_nothing() {
        let raw = vec![60000u16; 10];
        assert_eq!(depth_scale_warning(&raw, &DepthSettings::default()), None);
    }

    #[test]
    fn fy_of_the_other_sign_is_named() {
        let mut config = SlamConfig::from_preset(CameraPreset::IclNuim);
        let icl = CameraPreset::IclNuim;
        assert!(layout_warnings(icl, icl, &config).is_empty());
        config.intrinsics.fy = 480.0;
        let w = layout_warnings(icl, icl, &config);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].to_string().starts_with("fy = 480"), "{}", w[0]);
    }

    #[test]
    fn another_aspect_warns_until_the_whole_calibration_is_given() {
        let tum = CameraPreset::TumFr3;
        let mut config = SlamConfig::from_preset(tum);
        config.intrinsics = tum.intrinsics().for_image_size(848, 480);
        let aspect = |config: &SlamConfig| {
            layout_warnings(tum, tum, config)
                .iter()
                .any(|w| matches!(w, SettingsWarning::OtherAspect { .. }))
        };
        assert!(aspect(&config), "the guess in use");
        config.intrinsics.fx = 600.0;
        config.intrinsics.fy = 600.0;
        config.intrinsics.cx = 424.0;
        assert!(aspect(&config), "cy is still the guess");
        config.intrinsics.cy = 240.0;
        assert!(!aspect(&config), "all four given");
    }
}
