//! Conversions between JS values and the library's types: the `Slam`
//! configuration object, frame reports, presets, dataset results.
//!
//! Everything coming from JS is checked here and turned into an error message
//! that names the field; nothing in this file panics on any JS input.

use glam::{DAffine3, DMat4};
use js_sys::{Array, Float64Array, Object, Reflect};
use wasm_bindgen::prelude::*;

use crate::camera::{CameraPreset, Intrinsics};
use crate::dataset::DatasetKind;
use crate::frame::DepthSettings;
use crate::pipeline::{FrameReport, SlamConfig, Verdict};
use crate::track::TrackerMode;

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r#"
/** Camera and tracking settings for `new Slam(config)`; fields override the preset. */
export interface SlamConfig {
  preset?: 'tum-fr1' | 'tum-fr2' | 'tum-fr3' | 'icl-nuim' | '7-scenes';
  fx?: number; fy?: number; cx?: number; cy?: number; width?: number; height?: number;
  /** Raw depth units per metre. */
  depthScale?: number;
  /** Valid depth range, metres. */
  depthMin?: number; depthMax?: number;
  /** Raw depth value meaning "no measurement" besides 0 (7-Scenes: 65535). */
  depthInvalid?: number;
  bilateral?: boolean;
  /** Track and fuse at half the input resolution (about 3x faster, see README). */
  halfResolution?: boolean;
  pyramidLevels?: number;
  /** Gauss-Newton iterations per pyramid level, finest first. */
  iterations?: number[];
  icpDistance?: number; icpNormalDeg?: number;
  minInliers?: number; minInlierRatio?: number; maxResidual?: number;
  stableConfidence?: number;
  /** Surfel budget: when reached, stale unstable surfels are evicted, then new surfels skipped. */
  maxSurfels?: number;
  /** Tracker: geometric ICP, photometric, or both in one system. */
  tracker?: 'icp' | 'rgb' | 'joint';
  /** Joint mode: relative weight of the ICP term (each term normalised by its own residual variance). */
  icpWeight?: number;
}

export interface Preset {
  name: string; fx: number; fy: number; cx: number; cy: number; width: number; height: number;
  depthScale: number; depthMin: number; depthMax: number;
}

/** What happened to one frame (`pushFrame` / `pushRaw`). */
export interface FrameReport {
  index: number;
  timestamp: number;
  /** 'recovered': re-acquired against the map after a loss (fused). */
  verdict: 'initialised' | 'tracked' | 'recovered' | 'lost';
  lostReason: null | 'too-few-inliers' | 'high-residual' | 'ill-conditioned' | 'implausible-motion';
  /** world_from_camera, 4x4 column-major, metres. */
  pose: Float64Array;
  translation: [number, number, number];
  /** Unit quaternion [x, y, z, w], w >= 0. */
  quaternion: [number, number, number, number];
  inliers: number; inlierRatio: number;
  /** RMS point-to-plane residual, metres. */
  residual: number;
  conditioning: number;
  /** Surfels the map holds (Slam.liveSurfels; the PLY's vertex count). */
  surfels: number;
  /** Length of the surfel arrays (Slam.surfelCount): surfels plus those absorbed and not yet compacted away. */
  surfelSlots: number;
  /** This frame: measurements merged, surfels added, surfels removed by a cleanup, surfels absorbed into others. */
  merged: number; added: number; removed: number; absorbed: number;
  /** New surfels not added because the map was at maxSurfels. */
  skipped: number;
  /** Verdict counts of the run so far, this frame included; lostStreak: frames lost in a row. */
  counts: { tracked: number; lost: number; recovered: number; lostStreak: number };
  /** Milliseconds per stage. */
  timings: { decode: number; preprocess: number; track: number; fuse: number; predict: number; total: number };
}

export interface Layout {
  kind: 'tum' | 'icl-nuim' | '7-scenes';
  indexFiles: string[];
  rootPrefix: string;
}

export interface SequenceFrame {
  index: number; timestamp: number; colour: string; depth: string; poseFile: string | null;
  /** Why the frame cannot be read (an image its index lists is absent), or null. */
  missing: string | null;
}

export interface Sequence {
  kind: 'tum' | 'icl-nuim' | '7-scenes';
  preset: string;
  frames: SequenceFrame[];
  /** [t, tx, ty, tz, qx, qy, qz, qw] rows, world_from_camera. */
  groundTruth: number[][];
  /** The ground truth as TUM text, '' when there is none. */
  groundTruthTum: string;
}

/** Absolute trajectory error after rigid alignment, metres. */
export interface Ate { rmse: number; mean: number; median: number; max: number; pairs: number }
"#;

/// Sets `object[key] = value` (cannot fail on a plain object).
pub fn set(object: &Object, key: &str, value: impl Into<JsValue>) {
    let _ = Reflect::set(object, &JsValue::from_str(key), &value.into());
}

/// Builds a plain JS object from `(key, value)` pairs.
pub fn object(fields: &[(&str, JsValue)]) -> Object {
    let out = Object::new();
    for (key, value) in fields {
        set(&out, key, value.clone());
    }
    out
}

/// Short names of the dataset kinds in the JS API: `tum`, `icl-nuim`, `7-scenes`.
#[must_use]
pub fn kind_name(kind: DatasetKind) -> &'static str {
    match kind {
        DatasetKind::Tum => "tum",
        DatasetKind::IclNuim => "icl-nuim",
        DatasetKind::SevenScenes => "7-scenes",
    }
}

/// Reads an array of strings (e.g. file names), naming `what` in errors.
pub fn strings_from_js(value: &JsValue, what: &str) -> Result<Vec<String>, String> {
    if !Array::is_array(value) {
        return Err(format!("{what} must be an array of strings"));
    }
    Array::from(value)
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.as_string()
                .ok_or_else(|| format!("{what}[{i}] must be a string"))
        })
        .collect()
}

/// Config keys understood by [`slam_config_from_js`], for error messages.
const CONFIG_KEYS: &[&str] = &[
    "preset",
    "tracker",
    "icpWeight",
    "fx",
    "fy",
    "cx",
    "cy",
    "width",
    "height",
    "depthScale",
    "depthMin",
    "depthMax",
    "depthInvalid",
    "bilateral",
    "halfResolution",
    "pyramidLevels",
    "iterations",
    "icpDistance",
    "icpNormalDeg",
    "minInliers",
    "minInlierRatio",
    "maxResidual",
    "stableConfidence",
    "maxSurfels",
];

/// A JS config object, read field by field.
struct Fields<'a>(&'a JsValue);

impl Fields<'_> {
    /// The field's value, `None` when absent, `undefined` or `null`.
    fn get(&self, key: &str) -> Option<JsValue> {
        Reflect::get(self.0, &JsValue::from_str(key))
            .ok()
            .filter(|v| !v.is_undefined() && !v.is_null())
    }

    fn number(&self, key: &str) -> Result<Option<f64>, String> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(format!(
                    "config.{key} must be a finite number, got {}",
                    describe(&v)
                )),
            },
        }
    }

    fn f32(&self, key: &str) -> Result<Option<f32>, String> {
        Ok(self.number(key)?.map(|x| x as f32))
    }

    /// A non-negative integer no larger than `max`.
    fn integer(&self, key: &str, max: f64) -> Result<Option<usize>, String> {
        match self.number(key)? {
            None => Ok(None),
            Some(x) if x >= 0.0 && x <= max && x.fract() == 0.0 => Ok(Some(x as usize)),
            Some(x) => Err(format!(
                "config.{key} must be an integer in 0..={max}, got {x}"
            )),
        }
    }

    fn boolean(&self, key: &str) -> Result<Option<bool>, String> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => v
                .as_bool()
                .map(Some)
                .ok_or_else(|| format!("config.{key} must be true or false, got {}", describe(&v))),
        }
    }

    fn string(&self, key: &str) -> Result<Option<String>, String> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => v
                .as_string()
                .map(Some)
                .ok_or_else(|| format!("config.{key} must be a string, got {}", describe(&v))),
        }
    }
}

/// A short description of a JS value for error messages.
fn describe(v: &JsValue) -> String {
    if let Some(s) = v.as_string() {
        format!("{s:?}")
    } else if let Some(x) = v.as_f64() {
        format!("{x}")
    } else {
        v.js_typeof()
            .as_string()
            .unwrap_or_else(|| "a value".into())
    }
}

fn preset_names() -> String {
    CameraPreset::ALL
        .iter()
        .map(|p| format!("'{}'", p.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Builds a [`SlamConfig`] from the JS config object of `new Slam(config)`
/// (see docs/js-api.md), or from a preset name given as a plain string.
/// Fields override the preset; without a preset all six intrinsics are
/// required. Unknown fields are an error (they are usually typos). The result
/// is validated by `Pipeline::new`.
pub fn slam_config_from_js(config: &JsValue) -> Result<SlamConfig, String> {
    if let Some(name) = config.as_string() {
        let preset = CameraPreset::from_name(&name)
            .ok_or_else(|| format!("unknown preset {name:?}; known presets: {}", preset_names()))?;
        return Ok(SlamConfig::from_preset(preset));
    }
    if !config.is_object() || Array::is_array(config) {
        return Err(format!(
            "the Slam config must be an object like {{ preset: 'tum-fr3' }} or a preset name ({})",
            preset_names()
        ));
    }
    for key in Object::keys(config.unchecked_ref::<Object>()).iter() {
        let key = key.as_string().unwrap_or_default();
        if !CONFIG_KEYS.contains(&key.as_str()) {
            return Err(format!(
                "unknown config field {key:?}; known fields: {}",
                CONFIG_KEYS.join(", ")
            ));
        }
    }
    let f = Fields(config);

    let preset = match f.string("preset")? {
        None => None,
        Some(name) => Some(CameraPreset::from_name(&name).ok_or_else(|| {
            format!("unknown preset {name:?}; known presets: {}", preset_names())
        })?),
    };
    let fx = f.f32("fx")?;
    let fy = f.f32("fy")?;
    let cx = f.f32("cx")?;
    let cy = f.f32("cy")?;
    let width = f.integer("width", 16384.0)?;
    let height = f.integer("height", 16384.0)?;
    let mut cfg = match preset {
        Some(p) => SlamConfig::from_preset(p),
        None => {
            let missing: Vec<&str> = [
                ("fx", fx.is_none()),
                ("fy", fy.is_none()),
                ("cx", cx.is_none()),
                ("cy", cy.is_none()),
                ("width", width.is_none()),
                ("height", height.is_none()),
            ]
            .iter()
            .filter(|(_, m)| *m)
            .map(|(k, _)| *k)
            .collect();
            if !missing.is_empty() {
                return Err(format!(
                    "the Slam config needs a preset ({}) or all intrinsics; missing: {}",
                    preset_names(),
                    missing.join(", ")
                ));
            }
            let mut cfg = SlamConfig::from_preset(CameraPreset::TumFr3);
            cfg.depth = DepthSettings::default();
            cfg
        }
    };
    let k = &mut cfg.intrinsics;
    *k = Intrinsics::new(
        fx.unwrap_or(k.fx),
        fy.unwrap_or(k.fy),
        cx.unwrap_or(k.cx),
        cy.unwrap_or(k.cy),
        width.unwrap_or(k.width),
        height.unwrap_or(k.height),
    );
    if let Some(v) = f.f32("depthScale")? {
        cfg.depth.scale = v;
    }
    if let Some(v) = f.f32("depthMin")? {
        cfg.depth.min_m = v;
    }
    if let Some(v) = f.f32("depthMax")? {
        cfg.depth.max_m = v;
    }
    if let Some(v) = f.integer("depthInvalid", 65535.0)? {
        cfg.depth.invalid_raw = u16::try_from(v).ok();
    }
    if let Some(v) = f.boolean("halfResolution")? {
        cfg.half_resolution = v;
    }
    if let Some(v) = f.boolean("bilateral")? {
        cfg.preprocess.bilateral = v;
    }
    if let Some(v) = f.integer("pyramidLevels", 5.0)? {
        cfg.preprocess.levels = v;
    }
    if let Some(v) = f.get("iterations") {
        let list = if Array::is_array(&v) {
            Array::from(&v)
                .iter()
                .map(|x| {
                    x.as_f64()
                        .filter(|n| *n >= 0.0 && *n <= 1000.0 && n.fract() == 0.0)
                        .map(|n| n as usize)
                })
                .collect::<Option<Vec<usize>>>()
        } else {
            None
        };
        cfg.tracker.iterations = list.ok_or_else(|| {
            "config.iterations must be an array of integers (0..=1000) per pyramid level, finest first".to_string()
        })?;
    }
    if let Some(v) = f.f32("icpDistance")? {
        cfg.tracker.gates.distance_gate_m = v;
    }
    if let Some(v) = f.f32("icpNormalDeg")? {
        cfg.tracker.gates.normal_gate_deg = v;
    }
    if let Some(v) = f.integer("minInliers", 1e9)? {
        cfg.tracker.min_inliers = v;
    }
    if let Some(v) = f.number("minInlierRatio")? {
        cfg.tracker.min_inlier_ratio = v;
    }
    if let Some(v) = f.number("maxResidual")? {
        cfg.tracker.max_residual_m = v;
    }
    if let Some(name) = f.string("tracker")? {
        cfg.tracker.mode = TrackerMode::from_name(&name).ok_or_else(|| {
            format!("config.tracker must be 'icp', 'rgb' or 'joint', got {name:?}")
        })?;
    }
    if let Some(v) = f.number("icpWeight")? {
        if !(v.is_finite() && v >= 0.0) {
            return Err(format!(
                "config.icpWeight must be a finite number >= 0, got {v}"
            ));
        }
        cfg.tracker.icp_weight = v;
    }
    if let Some(v) = f.f32("stableConfidence")? {
        cfg.fusion.stable_confidence = v;
    }
    if let Some(v) = f.integer("maxSurfels", 1e9)? {
        cfg.fusion.max_surfels = v;
    }
    Ok(cfg)
}

/// `{name, fx, fy, cx, cy, width, height, depthScale, depthMin, depthMax}`.
#[must_use]
pub fn preset_to_js(preset: CameraPreset) -> JsValue {
    let k = preset.intrinsics();
    let d = preset.depth_settings();
    object(&[
        ("name", preset.name().into()),
        ("fx", k.fx.into()),
        ("fy", k.fy.into()),
        ("cx", k.cx.into()),
        ("cy", k.cy.into()),
        ("width", (k.width as f64).into()),
        ("height", (k.height as f64).into()),
        ("depthScale", d.scale.into()),
        ("depthMin", d.min_m.into()),
        ("depthMax", d.max_m.into()),
    ])
    .into()
}

/// Unit quaternion `[x, y, z, w]` (w >= 0) of a pose's rotation.
#[must_use]
pub fn quaternion(pose: &DAffine3) -> [f64; 4] {
    crate::se3::unit_quaternion(pose)
}

fn numbers(values: &[f64]) -> Array {
    values.iter().map(|&v| JsValue::from_f64(v)).collect()
}

/// The JS result of `pushFrame` / `pushRaw` (see docs/js-api.md).
#[must_use]
pub fn report_to_js(r: &FrameReport) -> JsValue {
    let pose = &r.world_from_camera;
    let t = pose.translation;
    let lost_reason = match r.verdict {
        Verdict::Lost(reason) => JsValue::from_str(reason.name()),
        _ => JsValue::NULL,
    };
    let tm = &r.timings;
    let timings = object(&[
        ("decode", tm.decode_ms.into()),
        ("preprocess", tm.preprocess_ms.into()),
        ("track", tm.track_ms.into()),
        ("fuse", tm.fuse_ms.into()),
        ("predict", tm.predict_ms.into()),
        ("total", tm.total_ms.into()),
    ]);
    let matrix = Float64Array::from(&DMat4::from(*pose).to_cols_array()[..]);
    object(&[
        ("index", r.index.into()),
        ("timestamp", r.timestamp.into()),
        ("verdict", r.verdict.name().into()),
        ("lostReason", lost_reason),
        ("pose", matrix.into()),
        ("translation", numbers(&[t.x, t.y, t.z]).into()),
        ("quaternion", numbers(&quaternion(pose)).into()),
        ("inliers", (r.inliers as f64).into()),
        ("inlierRatio", r.inlier_ratio.into()),
        ("residual", r.residual_rms_m.into()),
        ("conditioning", r.conditioning.into()),
        ("surfels", (r.surfels as f64).into()),
        ("surfelSlots", (r.surfel_slots as f64).into()),
        ("absorbed", (r.fusion.absorbed as f64).into()),
        ("merged", (r.fusion.merged as f64).into()),
        ("added", (r.fusion.added as f64).into()),
        ("removed", (r.fusion.removed as f64).into()),
        ("skipped", (r.fusion.skipped as f64).into()),
        (
            "counts",
            object(&[
                ("tracked", r.counts.tracked.into()),
                ("lost", r.counts.lost.into()),
                ("recovered", r.counts.recovered.into()),
                ("lostStreak", r.counts.lost_streak.into()),
            ])
            .into(),
        ),
        ("timings", timings.into()),
    ])
    .into()
}

/// `[t, tx, ty, tz, qx, qy, qz, qw]` of a timestamped pose.
#[must_use]
pub fn tum_row(t: f64, pose: &DAffine3) -> JsValue {
    let p = pose.translation;
    let [qx, qy, qz, qw] = quaternion(pose);
    numbers(&[t, p.x, p.y, p.z, qx, qy, qz, qw]).into()
}
