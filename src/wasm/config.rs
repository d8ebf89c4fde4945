//! The `Slam` configuration object: one table, [`CONFIG_KEYS`], says which
//! keys exist, how each value is checked and where it goes in
//! [`SlamConfig`]. The parser, the unknown-key error and the key list all
//! read it.
//!
//! Adding a key (see docs/js-api.md, "Adding a config key"): one entry in
//! [`CONFIG_KEYS`], one line in the `SlamConfig` interface below and one row
//! in docs/js-api.md's table; `tests/node/api_contract.test.mjs` fails until
//! the three agree.

use js_sys::{Array, Object, Reflect};
use wasm_bindgen::prelude::*;

use super::convert::InputError;
use crate::camera::CameraPreset;
use crate::frame::DepthSettings;
use crate::noise::SensorNoise;
use crate::pipeline::SlamConfig;
use crate::simulated_noise::{NoiseSimulation, SimulatedSensor};
use crate::track::TrackerMode;

#[wasm_bindgen(typescript_custom_section)]
const TS_SLAM_CONFIG: &'static str = r#"
/** Camera and tracking settings for `new Slam(config)`; fields override the preset. */
export interface SlamConfig {
  preset?: 'tum-fr1' | 'tum-fr2' | 'tum-fr3' | 'icl-nuim' | '7-scenes' | 'realsense-d400' | 'stray-lidar';
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
  /** Frames a surfel stays active (tracked against, fused into) after it was last seen; older ones are the inactive model loop closure registers against. */
  activeWindowFrames?: number;
  /** Local loop closure: bend the map and trajectory when the active model meets the inactive one. */
  loopClosure?: boolean;
  /** Global loop closure (needs loopClosure): look the frame up among keyframes older than the active window and bend the map onto a verified match. */
  globalLoopClosure?: boolean;
  /** Relocalise a lost camera from the fern keyframes. */
  relocalise?: boolean;
  /** After this many frames lost in a row, map on from the last placed pose in a new segment, joined to the map so far once a frame is placed in it (0: stay lost until re-acquired). */
  restartAfterLost?: number;
  /** Depth noise model weighting tracking and fusion (default: the preset's; 'uniform' = no weighting). */
  noise?: 'kinect-v1' | 'structured-light' | 'simulated-kinect' | 'active-stereo' | 'lidar' | 'rendered' | 'uniform';
  /** Simulate a sensor's noise on every pushed frame's (clean) depth: ICL-NUIM's Kinect v1 recipe. */
  simulateNoise?: 'kinect-v1' | null;
  /** With simulateNoise: the draw (an integer; the same seed gives the same noise). Default 1. */
  noiseSeed?: number;
}
"#;

/// How a key's JS value is checked, and where it is stored.
#[derive(Clone, Copy)]
pub enum Setter {
    /// A finite number, stored as `f32`.
    F32(fn(&mut SlamConfig, f32)),
    /// A finite number.
    F64(fn(&mut SlamConfig, f64)),
    /// An integer in `0..=max` (the `f64` is `max`).
    Integer(f64, fn(&mut SlamConfig, usize)),
    /// `true` or `false`.
    Bool(fn(&mut SlamConfig, bool)),
    /// Any other shape: the function reads the value itself and returns the
    /// whole error message.
    Custom(fn(&mut SlamConfig, &JsValue) -> Result<(), String>),
}

/// One key of the JS config object.
#[derive(Clone, Copy)]
pub struct ConfigKey {
    /// The key as JS writes it (camelCase).
    pub name: &'static str,
    /// Checks the value and stores it.
    pub set: Setter,
}

/// Intrinsics that must all be given when there is no `preset`.
const INTRINSICS: [&str; 6] = ["fx", "fy", "cx", "cy", "width", "height"];

/// Every key `new Slam(config)` accepts, in the order they are applied
/// (after the preset, which `preset` selects and every other key overrides).
pub const CONFIG_KEYS: &[ConfigKey] = &[
    // Read first by `slam_config_from_js`: it chooses the defaults.
    key("preset", Setter::Custom(|_, _| Ok(()))),
    key("fx", Setter::F32(|c, v| c.intrinsics.fx = v)),
    key("fy", Setter::F32(|c, v| c.intrinsics.fy = v)),
    key("cx", Setter::F32(|c, v| c.intrinsics.cx = v)),
    key("cy", Setter::F32(|c, v| c.intrinsics.cy = v)),
    key(
        "width",
        Setter::Integer(16384.0, |c, v| c.intrinsics.width = v),
    ),
    key(
        "height",
        Setter::Integer(16384.0, |c, v| c.intrinsics.height = v),
    ),
    key("depthScale", Setter::F32(|c, v| c.depth.scale = v)),
    key("depthMin", Setter::F32(|c, v| c.depth.min_m = v)),
    key("depthMax", Setter::F32(|c, v| c.depth.max_m = v)),
    key(
        "depthInvalid",
        Setter::Integer(65535.0, |c, v| c.depth.invalid_raw = u16::try_from(v).ok()),
    ),
    key("halfResolution", Setter::Bool(|c, v| c.half_resolution = v)),
    key("bilateral", Setter::Bool(|c, v| c.preprocess.bilateral = v)),
    key(
        "pyramidLevels",
        Setter::Integer(5.0, |c, v| c.preprocess.levels = v),
    ),
    key("iterations", Setter::Custom(set_iterations)),
    key(
        "icpDistance",
        Setter::F32(|c, v| c.tracker.gates.distance_gate_m = v),
    ),
    key(
        "icpNormalDeg",
        Setter::F32(|c, v| c.tracker.gates.normal_gate_deg = v),
    ),
    key(
        "minInliers",
        Setter::Integer(1e9, |c, v| c.tracker.min_inliers = v),
    ),
    key(
        "minInlierRatio",
        Setter::F64(|c, v| c.tracker.min_inlier_ratio = v),
    ),
    key(
        "maxResidual",
        Setter::F64(|c, v| c.tracker.max_residual_m = v),
    ),
    key("tracker", Setter::Custom(set_tracker)),
    key("icpWeight", Setter::Custom(set_icp_weight)),
    key("noise", Setter::Custom(set_noise)),
    key("simulateNoise", Setter::Custom(set_simulate_noise)),
    // After `simulateNoise`: the seed of the simulation it made.
    key("noiseSeed", Setter::Custom(set_noise_seed)),
    key(
        "stableConfidence",
        Setter::F32(|c, v| c.fusion.stable_confidence = v),
    ),
    key(
        "maxSurfels",
        Setter::Integer(1e9, |c, v| c.fusion.max_surfels = v),
    ),
    key(
        "activeWindowFrames",
        Setter::Integer(1e9, |c, v| {
            c.fusion.active_window_frames = u32::try_from(v).unwrap_or(u32::MAX)
        }),
    ),
    key(
        "loopClosure",
        Setter::Bool(|c, v| c.loop_closure.enabled = v),
    ),
    key(
        "globalLoopClosure",
        Setter::Bool(|c, v| c.loop_closure.global.enabled = v),
    ),
    key("relocalise", Setter::Bool(|c, v| c.relocalise.enabled = v)),
    key(
        "restartAfterLost",
        Setter::Integer(1e9, |c, v| {
            c.restart_after_lost = u32::try_from(v).unwrap_or(u32::MAX)
        }),
    ),
];

const fn key(name: &'static str, set: Setter) -> ConfigKey {
    ConfigKey { name, set }
}

fn set_iterations(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    let list = Array::is_array(v)
        .then(|| {
            Array::from(v)
                .iter()
                .map(|x| {
                    x.as_f64()
                        .filter(|n| *n >= 0.0 && *n <= 1000.0 && n.fract() == 0.0)
                        .map(|n| n as usize)
                })
                .collect::<Option<Vec<usize>>>()
        })
        .flatten();
    cfg.tracker.iterations = list.ok_or_else(|| {
        "config.iterations must be an array of integers (0..=1000) per pyramid level, finest first"
            .to_string()
    })?;
    Ok(())
}

fn set_tracker(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    let name = string("tracker", v)?;
    cfg.tracker.mode = TrackerMode::from_name(&name)
        .ok_or_else(|| format!("config.tracker must be 'icp', 'rgb' or 'joint', got {name:?}"))?;
    Ok(())
}

fn set_simulate_noise(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    if v.is_null() {
        cfg.simulate_noise = None;
        return Ok(());
    }
    let name = string("simulateNoise", v)?;
    let sensor = SimulatedSensor::from_name(&name)
        .ok_or_else(|| format!("config.simulateNoise must be 'kinect-v1' or null, got {name:?}"))?;
    cfg.simulate_noise = Some(NoiseSimulation { sensor, seed: 1 });
    Ok(())
}

fn set_noise_seed(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    let seed = v
        .as_f64()
        .filter(|n| (0.0..=9_007_199_254_740_991.0).contains(n) && n.fract() == 0.0)
        .ok_or_else(|| "config.noiseSeed must be an integer from 0 to 2^53 - 1".to_string())?;
    match cfg.simulate_noise.as_mut() {
        Some(simulation) => {
            simulation.seed = seed as u64;
            Ok(())
        }
        None => Err("config.noiseSeed needs config.simulateNoise".to_string()),
    }
}

fn set_noise(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    let name = string("noise", v)?;
    let noise = SensorNoise::from_name(&name).ok_or_else(|| {
        format!(
            "config.noise must be one of {}, got {name:?}",
            SensorNoise::NAMES.map(|n| format!("'{n}'")).join(", ")
        )
    })?;
    cfg.set_noise(noise);
    Ok(())
}

fn set_icp_weight(cfg: &mut SlamConfig, v: &JsValue) -> Result<(), String> {
    let w = number("icpWeight", v)?;
    if w < 0.0 {
        return Err(format!(
            "config.icpWeight must be a finite number >= 0, got {w}"
        ));
    }
    cfg.tracker.icp_weight = w;
    Ok(())
}

impl Setter {
    /// Checks `value` (given for key `name`) and stores it in `cfg`.
    fn apply(self, name: &str, value: &JsValue, cfg: &mut SlamConfig) -> Result<(), String> {
        match self {
            Setter::F32(set) => set(cfg, number(name, value)? as f32),
            Setter::F64(set) => set(cfg, number(name, value)?),
            Setter::Integer(max, set) => set(cfg, integer(name, value, max)?),
            Setter::Bool(set) => set(
                cfg,
                value.as_bool().ok_or_else(|| {
                    format!(
                        "config.{name} must be true or false, got {}",
                        describe(value)
                    )
                })?,
            ),
            Setter::Custom(set) => set(cfg, value)?,
        }
        Ok(())
    }
}

/// The value of `config[key]`, `None` when absent, `undefined` or `null`.
fn field(config: &JsValue, key: &str) -> Option<JsValue> {
    Reflect::get(config, &JsValue::from_str(key))
        .ok()
        .filter(|v| !v.is_undefined() && !v.is_null())
}

fn number(key: &str, v: &JsValue) -> Result<f64, String> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(format!(
            "config.{key} must be a finite number, got {}",
            describe(v)
        )),
    }
}

fn integer(key: &str, v: &JsValue, max: f64) -> Result<usize, String> {
    match number(key, v)? {
        x if x >= 0.0 && x <= max && x.fract() == 0.0 => Ok(x as usize),
        x => Err(format!(
            "config.{key} must be an integer in 0..={max}, got {x}"
        )),
    }
}

fn string(key: &str, v: &JsValue) -> Result<String, String> {
    v.as_string()
        .ok_or_else(|| format!("config.{key} must be a string, got {}", describe(v)))
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

fn preset_named(name: &str) -> Result<CameraPreset, String> {
    CameraPreset::from_name(name)
        .ok_or_else(|| format!("unknown preset {name:?}; known presets: {}", preset_names()))
}

/// Builds a [`SlamConfig`] from the JS config object of `new Slam(config)`
/// (see docs/js-api.md), or from a preset name given as a plain string.
/// Keys ([`CONFIG_KEYS`]) override the preset; without a preset all six
/// intrinsics are required. Unknown keys are an error (they are usually
/// typos). The result is validated by `Pipeline::new`.
pub fn slam_config_from_js(config: &JsValue) -> Result<SlamConfig, InputError> {
    parse(config).map_err(InputError)
}

fn parse(config: &JsValue) -> Result<SlamConfig, String> {
    if let Some(name) = config.as_string() {
        return Ok(SlamConfig::from_preset(preset_named(&name)?));
    }
    if !config.is_object() || Array::is_array(config) {
        return Err(format!(
            "the Slam config must be an object like {{ preset: 'tum-fr3' }} or a preset name ({})",
            preset_names()
        ));
    }
    for name in Object::keys(config.unchecked_ref::<Object>()).iter() {
        let name = name.as_string().unwrap_or_default();
        if !CONFIG_KEYS.iter().any(|k| k.name == name) {
            let known: Vec<&str> = CONFIG_KEYS.iter().map(|k| k.name).collect();
            return Err(format!(
                "unknown config field {name:?}; known fields: {}",
                known.join(", ")
            ));
        }
    }
    let mut cfg = match field(config, "preset") {
        Some(v) => SlamConfig::from_preset(preset_named(&string("preset", &v)?)?),
        None => {
            let missing: Vec<&str> = INTRINSICS
                .into_iter()
                .filter(|k| field(config, k).is_none())
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
            // An unknown camera: the generic structured-light noise model.
            cfg.set_noise(SensorNoise::default());
            cfg
        }
    };
    for key in CONFIG_KEYS {
        if let Some(value) = field(config, key.name) {
            key.set.apply(key.name, &value, &mut cfg)?;
        }
    }
    Ok(cfg)
}
