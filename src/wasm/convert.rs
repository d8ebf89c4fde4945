//! Conversions between JS values and the library's types: frame reports,
//! presets, dataset results, and [`InputError`] for JS arguments of the wrong
//! shape (the `Slam` config object is read in [`super::config`]).
//!
//! Nothing in this file panics on any JS input.

use glam::{DAffine3, DMat4};
use js_sys::{Array, Float64Array, Object, Reflect};
use wasm_bindgen::prelude::*;

use crate::camera::CameraPreset;
use crate::dataset::DatasetKind;
use crate::eval::AteResult;
use crate::loop_closure::LoopOutcome;
use crate::pipeline::{FrameReport, Verdict};
use crate::se3::unit_quaternion;

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r#"
export interface Preset {
  name: string; fx: number; fy: number; cx: number; cy: number; width: number; height: number;
  depthScale: number; depthMin: number; depthMax: number;
}

/** What happened to one frame (`pushFrame` / `pushRaw`). */
export interface FrameReport {
  index: number;
  timestamp: number;
  /** 'recovered': re-acquired against the map after a loss (fused); while localising, placed by relocalisation. 'unplaced' (localising only): not found in the loaded map, no pose (pose, translation and quaternion are null). 'held': fused, but the geometry left some directions of motion free (a flat wall) and the pose was held at the motion prior in those. 'restarted': lost for restartAfterLost frames in a row, fused at the last placed pose as the first frame of a new segment of the map; the map so far is kept but not tracked against until a frame of the segment is placed in it (loopDecision then says 'joined' and loopClosed is true: the segment moved onto it). */
  verdict: 'initialised' | 'tracked' | 'recovered' | 'held' | 'lost' | 'restarted' | 'unplaced';
  lostReason: null | 'too-few-inliers' | 'high-residual' | 'ill-conditioned' | 'implausible-motion' | 'inconsistent';
  /** world_from_camera, 4x4 column-major, metres; null for an 'unplaced' frame. */
  pose: Float64Array | null;
  translation: [number, number, number] | null;
  /** Unit quaternion [x, y, z, w], w >= 0; null for an 'unplaced' frame. */
  quaternion: [number, number, number, number] | null;
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
  counts: { tracked: number; lost: number; recovered: number; held: number; restarted: number; lostStreak: number };
  /** Lost and then placed by relocalisation: the frame index of the keyframe it was placed by; else null. */
  relocalisedFrom: number | null;
  /** A lost frame whose pose the sparse estimate carried on from the frame before. */
  deadReckoned: boolean;
  /** Loop closures of the run so far (map and trajectory bent), this frame included. */
  loopClosures: number;
  /** Of loopClosures, those closed by the global check (a place seen long ago, found among the keyframes). */
  globalLoopClosures: number;
  /** This frame closed a loop: every surfel and past pose may have moved (take the whole changed range and the trajectory again). */
  loopClosed: boolean;
  /** What the loop stage checked and decided on this frame, one line naming the frame; null when it checked nothing. */
  loopDecision: string | null;
  /** A camera setting that looks wrong for the data, first found with this frame (e.g. a depth scale that puts most depths beyond the cut-off); all of them: Slam.settingsWarnings(). null when none. */
  settingsWarning: string | null;
  /** Share (0-1) of the image whose depth was taken out as something carried with the camera (a hand holding it: near, staying put while the rest of the view moves); 0 when nothing was. */
  cameraFixedShare: number;
  /** Milliseconds per stage. */
  timings: { decode: number; preprocess: number; track: number; fuse: number; loop: number; predict: number; total: number };
}

/** What Slam.finish() did: the recording ended, and its last frame was looked up among the old keyframes once more. */
export interface FinishReport {
  /** The global check looked the last frame up (false: no frame yet, the last one lost or already looked up, localising, loop closure off). */
  looked: boolean;
  /** It closed a loop: every surfel and past pose may have moved (take the whole changed range and the trajectory again). */
  loopClosed: boolean;
  /** What the check decided, one line naming the frame; null when it did not look. */
  loopDecision: string | null;
  /** Loop closures of the run so far, and of them the global ones. */
  loopClosures: number;
  globalLoopClosures: number;
}

/** The dataset layouts detectLayout recognises. */
export type LayoutKind = 'tum' | 'icl-nuim' | '7-scenes' | 'realsense' | 'stray-scanner' | 'realsense-bag' | 'realsense-db3' | 'azure-kinect';

export interface Layout {
  kind: LayoutKind;
  indexFiles: string[];
  rootPrefix: string;
}

export interface SequenceFrame {
  /** `colour`: null for a depth-only frame (Stray Scanner without rgb/). `confidence`: the Stray Scanner confidence image (depth of confidence 0 is no measurement), or null. */
  index: number; timestamp: number; colour: string | null; depth: string; confidence: string | null; poseFile: string | null;
  /** Why the frame cannot be read (an image its index lists is absent), or null. */
  missing: string | null;
}

/** The camera presets' names (as SlamConfig.preset takes them). */
export type PresetName = 'tum-fr1' | 'tum-fr2' | 'tum-fr3' | 'icl-nuim' | '7-scenes' | 'realsense-d400' | 'stray-lidar';

export interface Sequence {
  kind: LayoutKind;
  /** The preset the layout implies: pass it as `new Slam({ preset: sequence.preset, ...sequence.intrinsics })`. */
  preset: PresetName;
  /** The depth images' intrinsics from the folder's calibration file (RealSense camera_intrinsic.json, Stray Scanner camera_matrix.csv scaled to 256x192), pixels; null for the other layouts. */
  intrinsics: { fx: number; fy: number; cx: number; cy: number; width: number; height: number } | null;
  frames: SequenceFrame[];
  /** [t, tx, ty, tz, qx, qy, qz, qw] rows, world_from_camera. */
  groundTruth: number[][];
  /** The ground truth as TUM text, '' when there is none. */
  groundTruthTum: string;
  /** The recording device's own trajectory (Stray Scanner odometry.csv, ARKit), rows as groundTruth's: a reference, not ground truth. Empty for the other layouts. */
  odometry: number[][];
  /** The odometry as TUM text, '' when there is none. */
  odometryTum: string;
  /** What was skipped but did not stop the sequence, each naming its file (and line): a cut-off last row of an index or trajectory file (a recording stopped mid-write plays the rows it has), a 7-Scenes pose file unread. Show them; [] when none. */
  warnings: string[];
}

/** A reference trajectory the user brings, parsed by parseReference. */
export interface ParsedReference {
  /** How its rows name frames: 'frame' (a CSV `frame` column: 0-based position in the sequence) or 'timestamp' (TUM text, or a CSV `timestamp` column). */
  key: 'frame' | 'timestamp';
  /** [key, tx, ty, tz, qx, qy, qz, qw] rows, world_from_camera, as in the file. */
  poses: number[][];
  /** The reference as TUM text in the sequence's time (frame numbers turned into `frameTimestamps`' when given), for `slam.ate(tum)` / `ateTum`. */
  tum: string;
  /** A cut-off last row skipped, naming the file and line; [] when none. */
  warnings: string[];
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

/// Short names of the dataset kinds in the JS API: `tum`, `icl-nuim`,
/// `7-scenes`, `realsense`, `stray-scanner`, `realsense-bag`, `realsense-db3`, `azure-kinect`.
#[must_use]
pub fn kind_name(kind: DatasetKind) -> &'static str {
    match kind {
        DatasetKind::Tum => "tum",
        DatasetKind::IclNuim => "icl-nuim",
        DatasetKind::SevenScenes => "7-scenes",
        DatasetKind::RealSense => "realsense",
        DatasetKind::StrayScanner => "stray-scanner",
        DatasetKind::RealSenseBag => "realsense-bag",
        DatasetKind::RealSenseDb3 => "realsense-db3",
        DatasetKind::AzureKinect => "azure-kinect",
    }
}

/// A JS argument that is not what the API takes; the message names the
/// argument (e.g. `config.fx must be a finite number, got "big"`). Thrown to
/// JS as an `Error` with this message.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// Reads an array of strings (e.g. file names), naming `what` in errors.
pub fn strings_from_js(value: &JsValue, what: &str) -> Result<Vec<String>, InputError> {
    if !Array::is_array(value) {
        return Err(InputError(format!("{what} must be an array of strings")));
    }
    Array::from(value)
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.as_string()
                .ok_or_else(|| InputError(format!("{what}[{i}] must be a string")))
        })
        .collect()
}

/// `{name, fx, fy, cx, cy, width, height, depthScale, depthMin, depthMax}`.
#[must_use]
pub fn preset_to_js(preset: CameraPreset) -> JsValue {
    preset_at_size_to_js(preset, &preset.intrinsics())
}

/// A preset as `preset_to_js` gives it, with intrinsics `k` (its own,
/// scaled to another image size).
#[must_use]
pub fn preset_at_size_to_js(preset: CameraPreset, k: &crate::Intrinsics) -> JsValue {
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
        ("loop", tm.loop_ms.into()),
        ("predict", tm.predict_ms.into()),
        ("total", tm.total_ms.into()),
    ]);
    let placed = r.pose().is_some();
    let or_null = |value: JsValue| if placed { value } else { JsValue::NULL };
    let matrix = Float64Array::from(&DMat4::from(*pose).to_cols_array()[..]);
    object(&[
        ("index", r.index.into()),
        ("timestamp", r.timestamp.into()),
        ("verdict", r.verdict.name().into()),
        ("lostReason", lost_reason),
        ("pose", or_null(matrix.into())),
        ("translation", or_null(numbers(&[t.x, t.y, t.z]).into())),
        (
            "quaternion",
            or_null(numbers(&unit_quaternion(pose)).into()),
        ),
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
                ("held", r.counts.held.into()),
                ("restarted", r.counts.restarted.into()),
                ("lostStreak", r.counts.lost_streak.into()),
            ])
            .into(),
        ),
        (
            "relocalisedFrom",
            r.checks
                .relocalised_from
                .map_or(JsValue::NULL, |frame| frame.into()),
        ),
        ("deadReckoned", r.checks.dead_reckoned.into()),
        ("loopClosures", r.loop_closures.into()),
        ("globalLoopClosures", r.global_loop_closures.into()),
        ("loopClosed", r.loop_outcome.closed.into()),
        (
            "loopDecision",
            r.loop_outcome.decision().map_or(JsValue::NULL, |d| {
                (d + &format!(" (frame {})", r.index)).into()
            }),
        ),
        (
            "settingsWarning",
            r.settings_warning
                .map_or(JsValue::NULL, |w| w.to_string().into()),
        ),
        ("cameraFixedShare", r.camera_fixed_share.into()),
        ("timings", timings.into()),
    ])
    .into()
}

/// The JS result of `finish` (see docs/js-api.md): `outcome` of the last
/// frame (`frame`), with the run's closure counts.
#[must_use]
pub fn finish_to_js(outcome: &LoopOutcome, frame: u32, (closures, global): (u32, u32)) -> JsValue {
    object(&[
        ("looked", outcome.global_looked.into()),
        ("loopClosed", outcome.closed.into()),
        (
            "loopDecision",
            outcome.decision().map_or(JsValue::NULL, |d| {
                (d + &format!(" (frame {frame}, the last)")).into()
            }),
        ),
        ("loopClosures", closures.into()),
        ("globalLoopClosures", global.into()),
    ])
    .into()
}

/// The `maxDt` argument of `ateTum` / `Slam.ate`: seconds, default 0.02.
pub fn max_dt_from_js(max_dt: Option<f64>) -> Result<f64, InputError> {
    match max_dt.unwrap_or(0.02) {
        dt if dt.is_finite() && dt >= 0.0 => Ok(dt),
        dt => Err(InputError(format!(
            "maxDt must be a non-negative number of seconds, got {dt}"
        ))),
    }
}

/// `{ rmse, mean, median, max, pairs }`, metres (the `Ate` typing).
#[must_use]
pub fn ate_to_js(r: &AteResult) -> JsValue {
    object(&[
        ("rmse", r.rmse_m.into()),
        ("mean", r.mean_m.into()),
        ("median", r.median_m.into()),
        ("max", r.max_m.into()),
        ("pairs", (r.pairs as f64).into()),
    ])
    .into()
}

/// `[t, tx, ty, tz, qx, qy, qz, qw]` of a timestamped pose.
#[must_use]
pub fn tum_row(t: f64, pose: &DAffine3) -> JsValue {
    let p = pose.translation;
    let [qx, qy, qz, qw] = unit_quaternion(pose);
    numbers(&[t, p.x, p.y, p.z, qx, qy, qz, qw]).into()
}
