//! Dataset layouts and trajectory evaluation for JavaScript: the same parsers
//! as the native CLI (`crate::dataset`, `crate::eval`), on file names and
//! texts the page (or a Node script) has read.

use std::collections::HashMap;

use js_sys::{Array, Float64Array, Reflect};
use wasm_bindgen::prelude::*;

use super::convert::{ate_to_js, kind_name, max_dt_from_js, object, strings_from_js, tum_row};
use crate::dataset::{self, trajectory::parse_tum};
use crate::eval;

/// `detectLayout(fileNames)`: recognises the dataset layout from relative
/// file names (e.g. `webkitRelativePath`). Returns `{ kind, indexFiles,
/// rootPrefix }` with kind `'tum' | 'icl-nuim' | '7-scenes' | 'realsense' |
/// 'stray-scanner'`; throws if the layout is not recognised.
#[wasm_bindgen(js_name = detectLayout, unchecked_return_type = "Layout")]
pub fn detect_layout(
    #[wasm_bindgen(js_name = "fileNames", unchecked_param_type = "string[]")] file_names: JsValue,
) -> Result<JsValue, JsError> {
    let names = strings_from_js(&file_names, "fileNames")?;
    let layout = dataset::detect_layout(&names)?;
    let index_files: Array = layout
        .index_files
        .iter()
        .map(|f| JsValue::from_str(f))
        .collect();
    Ok(object(&[
        ("kind", kind_name(layout.kind).into()),
        ("indexFiles", index_files.into()),
        ("rootPrefix", layout.root_prefix.as_str().into()),
    ])
    .into())
}

/// `parseSequence(fileNames, indexTexts, nameHint)`: the frame list and the
/// ground truth. `indexTexts` maps each of `detectLayout(...).indexFiles` to
/// its text (7-Scenes: the per-frame `.pose.txt` files, each optional: a
/// frame whose pose text is not given has no ground truth). Returns `{ kind,
/// preset, intrinsics, frames: [{index, timestamp, colour, depth,
/// confidence, poseFile, missing}], groundTruth: [[t, tx, ty, tz, qx, qy,
/// qz, qw], ...], groundTruthTum, odometry, odometryTum }` (paths as in
/// `fileNames`; `colour` null for a depth-only frame, `confidence` the Stray
/// Scanner confidence image or null; `missing`: null, or the message naming
/// an image the index lists but `fileNames` lacks: skip that frame;
/// `intrinsics` `{fx, fy, cx, cy, width, height}` from the folder's
/// calibration file (RealSense, Stray Scanner) or null; `odometry` the
/// device's own trajectory (Stray Scanner), not ground truth; the `...Tum`
/// fields as TUM text, `''` when empty; `warnings` what was skipped but did
/// not stop the sequence, e.g. a cut-off last row, each naming its file and
/// line). Throws when no frame has all its images.
#[wasm_bindgen(js_name = parseSequence, unchecked_return_type = "Sequence")]
pub fn parse_sequence(
    #[wasm_bindgen(js_name = "fileNames", unchecked_param_type = "string[]")] file_names: JsValue,
    #[wasm_bindgen(
        js_name = "indexTexts",
        unchecked_param_type = "Record<string, string>"
    )]
    index_texts: JsValue,
    #[wasm_bindgen(js_name = "nameHint", unchecked_optional_param_type = "string")]
    name_hint: JsValue,
) -> Result<JsValue, JsError> {
    let name_hint = name_hint.as_string();
    let names = strings_from_js(&file_names, "fileNames")?;
    let layout = dataset::detect_layout(&names)?;
    if !index_texts.is_object() {
        return Err(JsError::new(
            "indexTexts must be an object mapping each index file name to its text",
        ));
    }
    let mut texts = HashMap::new();
    for name in &layout.index_files {
        let value = Reflect::get(&index_texts, &JsValue::from_str(name)).unwrap_or_default();
        if let Some(text) = value.as_string() {
            texts.insert(name.clone(), text);
        } else if !value.is_undefined() && !value.is_null() {
            return Err(JsError::new(&format!(
                "indexTexts[{name:?}] must be the file's text (a string)"
            )));
        }
        // Absent: parse_sequence reports a missing index file by name (a
        // missing 7-Scenes pose file only leaves its frame without ground truth).
    }
    let seq = dataset::parse_sequence(&layout, &names, &texts, name_hint.as_deref())?;

    let frames: Array = seq.frames.iter().map(frame_to_js).collect();
    let ground_truth: Array = seq
        .ground_truth
        .iter()
        .map(|(t, pose)| tum_row(*t, pose))
        .collect();
    let tum_text = |poses: &[(f64, glam::DAffine3)]| {
        if poses.is_empty() {
            String::new()
        } else {
            dataset::trajectory::format_tum(poses)
        }
    };
    let odometry: Array = seq
        .odometry
        .iter()
        .map(|(t, pose)| tum_row(*t, pose))
        .collect();
    Ok(object(&[
        ("kind", kind_name(seq.kind).into()),
        ("preset", seq.preset.name().into()),
        (
            "intrinsics",
            seq.intrinsics.map_or(JsValue::NULL, intrinsics_to_js),
        ),
        ("frames", frames.into()),
        ("groundTruth", ground_truth.into()),
        ("groundTruthTum", tum_text(&seq.ground_truth).into()),
        ("odometry", odometry.into()),
        ("odometryTum", tum_text(&seq.odometry).into()),
        ("warnings", messages(&seq.warnings).into()),
    ])
    .into())
}

/// Each warning's message, as a JS array of strings.
fn messages(warnings: &[dataset::DatasetError]) -> Array {
    warnings
        .iter()
        .map(|w| JsValue::from_str(&w.to_string()))
        .collect()
}

/// `parseReference(text, fileName = 'reference', frameTimestamps?)`: a
/// reference trajectory the user brings (TUM text, or CSV with a header
/// `frame, x, y, z, qx, qy, qz, qw` or `timestamp, x, ...`), as `run
/// --reference` reads it. Returns `{ key: 'frame' | 'timestamp', poses,
/// tum, warnings }`: `poses` the rows `[key, tx, ty, tz, qx, qy, qz, qw]`;
/// `tum` the poses as TUM text in the sequence's time (with
/// `frameTimestamps`, the sequence's frames' timestamps in order, a frame
/// number becomes its frame's timestamp and rows past the frames are left
/// out; without it, frame numbers stay as they are), for `slam.ate(tum)`;
/// `warnings` a cut-off last row skipped. Throws, naming the file and line,
/// on a file that cannot be read.
#[wasm_bindgen(js_name = parseReference, unchecked_return_type = "ParsedReference")]
pub fn parse_reference(
    text: &str,
    #[wasm_bindgen(js_name = "fileName")] file_name: Option<String>,
    #[wasm_bindgen(
        js_name = "frameTimestamps",
        unchecked_optional_param_type = "ArrayLike<number>"
    )]
    frame_timestamps: JsValue,
) -> Result<JsValue, JsError> {
    let name = file_name.unwrap_or_else(|| "reference".to_owned());
    let reference = dataset::reference::parse_reference(text, &name)?;
    let stamped = if frame_timestamps.is_undefined() || frame_timestamps.is_null() {
        reference.poses.clone()
    } else if Array::is_array(&frame_timestamps)
        || frame_timestamps.is_instance_of::<Float64Array>()
    {
        reference.at_timestamps(&Float64Array::new(&frame_timestamps).to_vec())
    } else {
        return Err(JsError::new(
            "frameTimestamps must be an array of the sequence's frame timestamps",
        ));
    };
    let poses: Array = reference
        .poses
        .iter()
        .map(|(t, pose)| tum_row(*t, pose))
        .collect();
    let tum = if stamped.is_empty() {
        String::new()
    } else {
        dataset::trajectory::format_tum(&stamped)
    };
    Ok(object(&[
        ("key", reference.key.name().into()),
        ("poses", poses.into()),
        ("tum", tum.into()),
        ("warnings", messages(&reference.warnings).into()),
    ])
    .into())
}

/// One frame of `parseSequence`'s `frames`: `{index, timestamp, colour,
/// depth, confidence, poseFile, missing}` (`null` for an absent path).
fn frame_to_js(f: &dataset::FrameEntry) -> JsValue {
    let path = |p: &Option<String>| p.as_deref().map_or(JsValue::NULL, JsValue::from_str);
    object(&[
        ("index", (f.index as f64).into()),
        ("timestamp", f.timestamp.into()),
        ("colour", path(&f.colour)),
        ("depth", f.depth.as_str().into()),
        ("confidence", path(&f.confidence)),
        ("poseFile", path(&f.pose_file)),
        (
            "missing",
            f.missing
                .as_ref()
                .map_or(JsValue::NULL, |e| JsValue::from_str(&e.to_string())),
        ),
    ])
    .into()
}

/// A calibration file's intrinsics: `{fx, fy, cx, cy, width, height}`, pixels.
fn intrinsics_to_js(k: crate::camera::Intrinsics) -> JsValue {
    object(&[
        ("fx", f64::from(k.fx).into()),
        ("fy", f64::from(k.fy).into()),
        ("cx", f64::from(k.cx).into()),
        ("cy", f64::from(k.cy).into()),
        ("width", (k.width as f64).into()),
        ("height", (k.height as f64).into()),
    ])
    .into()
}

/// `ateTum(estimateTum, groundTruthTum, maxDt = 0.02)`: absolute trajectory
/// error after rigid alignment, metres: `{ rmse, mean, median, max, pairs }`.
/// Poses are matched by nearest timestamp within `maxDt` (seconds for TUM;
/// ICL-NUIM and 7-Scenes frame numbers match exactly).
#[wasm_bindgen(js_name = ateTum, unchecked_return_type = "Ate")]
pub fn ate_tum(
    #[wasm_bindgen(js_name = "estimateTum")] estimate_tum: &str,
    #[wasm_bindgen(js_name = "groundTruthTum")] ground_truth_tum: &str,
    #[wasm_bindgen(js_name = "maxDt")] max_dt: Option<f64>,
) -> Result<JsValue, JsError> {
    let max_dt = max_dt_from_js(max_dt)?;
    let estimate = parse_tum(estimate_tum, "estimate")?;
    let truth = parse_tum(ground_truth_tum, "ground truth")?;
    Ok(ate_to_js(&eval::ate(&estimate, &truth, max_dt)?))
}
