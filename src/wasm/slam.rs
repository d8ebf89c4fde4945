//! The `Slam` class: one [`Pipeline`] driven from JavaScript.
//!
//! Frames go in as PNG bytes (decoded inside wasm), as colour pixels decoded
//! by the browser with a depth PNG, or as raw buffers; each push
//! returns a report object. The surfel map comes out as zero-copy typed-array
//! views into wasm memory (see [`Slam::positions`] for when they are valid).

use glam::Vec3;
use js_sys::{Array, Float32Array, Uint8Array};
use wasm_bindgen::prelude::*;

use super::config::slam_config_from_js;
use super::convert::{ate_to_js, finish_to_js, max_dt_from_js, report_to_js};
use super::session::{session_error, LoadOptions};
use crate::camera::CameraPreset;
use crate::dataset::trajectory::{format_tum, parse_tum};
use crate::dataset::{decode_frame_bytes, CalibratedSize, FrameBytes, FrameEntry};
use crate::eval;
use crate::mesh::write_surfel_ply;
use crate::pipeline::Pipeline;
use crate::session;
use glam::DAffine3;
use std::io::Cursor;

/// Dense RGB-D SLAM: camera trajectory and surfel map from RGB-D frames.
#[wasm_bindgen]
#[derive(Debug)]
pub struct Slam {
    pipeline: Pipeline,
    /// Reused by `depthPreview`.
    preview: Vec<f32>,
}

// `Vec3` is `#[repr(C)] { x, y, z: f32 }`: a `[Vec3]` is a `[f32]` three times
// as long. Checked at compile time.
const _: () = assert!(
    std::mem::size_of::<Vec3>() == 12 && std::mem::align_of::<Vec3>() == 4,
    "glam::Vec3 must be three packed f32"
);

fn flatten_vec3(v: &[Vec3]) -> &[f32] {
    // SAFETY: Vec3 is repr(C) with three f32 fields and no padding (asserted
    // above), so `len` Vec3s are `3 * len` initialised, aligned f32s; the
    // returned slice borrows `v`.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f32>(), v.len() * 3) }
}

// Zero-copy views. `Float32Array::view` / `Uint8Array::view` are unsafe
// because the JS array aliases Rust-owned memory without a Rust borrow. It is
// sound here because:
// - wasm is single-threaded per instance as far as this object is concerned
//   (in the threaded build rayon workers only run inside a call), and no Rust
//   code touches the map again until the next call into the module;
// - the only ways the view can become stale are a call that mutates or
//   reallocates the map (pushFrame, pushRaw, reset, free) or grows the
//   memory; growing detaches the old ArrayBuffer (JS then sees length 0,
//   never freed memory), and a reallocation inside the same memory leaves
//   the view pointing at bytes that are still wasm memory (stale values,
//   not undefined behaviour in Rust, which holds no reference across calls).
// The JS contract (docs/js-api.md) therefore says: views are valid until the
// next call into the module; re-take them after every push.
fn f32_view(data: &[f32]) -> Float32Array {
    // SAFETY: see the comment above.
    unsafe { Float32Array::view(data) }
}

/// A push's error naming the frame by its timestamp (the caller's, as in
/// the trajectory), then the problem.
fn frame_error(timestamp: f64, e: &dyn std::fmt::Display) -> JsError {
    JsError::new(&format!("frame at timestamp {timestamp}: {e}"))
}

fn u8_view(data: &[u8]) -> Uint8Array {
    // SAFETY: see the comment above.
    unsafe { Uint8Array::view(data) }
}

#[wasm_bindgen]
impl Slam {
    /// `new Slam(config)`: config is `{ preset, fx, fy, cx, cy, width, height,
    /// depthScale, depthMin, depthMax, ... }` (fields override the preset) or
    /// a preset name. Throws an Error naming the problem on a bad config.
    #[wasm_bindgen(constructor)]
    pub fn new(
        #[wasm_bindgen(unchecked_param_type = "SlamConfig | string")] config: JsValue,
    ) -> Result<Slam, JsError> {
        let cfg = slam_config_from_js(&config)?;
        let pipeline = Pipeline::new(cfg)?;
        Ok(Slam {
            pipeline,
            preview: Vec::new(),
        })
    }

    /// Decodes a colour image (PNG or JPEG) and a 16-bit depth PNG and
    /// processes the frame. Throws (and changes nothing) on bad bytes; the
    /// message starts `frame at timestamp T:`.
    #[wasm_bindgen(js_name = pushFrame, unchecked_return_type = "FrameReport")]
    pub fn push_frame(
        &mut self,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<JsValue, JsError> {
        let report = self
            .pipeline
            .push_png(colour, depth, timestamp)
            .map_err(|e| frame_error(timestamp, &e))?;
        Ok(report_to_js(&report))
    }

    /// Decodes a dataset frame's files and processes it, as the CLI reads
    /// them: `colour` a PNG or JPEG (null for a depth-only frame: the map
    /// is then grey), scaled to the depth's size when it differs (phone
    /// scans); `depth` a 16-bit PNG of the camera's size; `confidence` an
    /// 8-bit confidence PNG (Stray Scanner: depth where it is 0 is dropped)
    /// or null. `paths` names the three files for messages (`[colour or
    /// null, depth, confidence or null]`). Throws (and changes nothing) on
    /// bad bytes or sizes, naming the file; the message starts `frame at
    /// timestamp T:`.
    #[wasm_bindgen(js_name = pushFiles, unchecked_return_type = "FrameReport")]
    pub fn push_files(
        &mut self,
        colour: Option<Vec<u8>>,
        depth: &[u8],
        confidence: Option<Vec<u8>>,
        #[wasm_bindgen(unchecked_param_type = "[string | null, string, string | null]")] paths: Vec<
            JsValue,
        >,
        timestamp: f64,
    ) -> Result<JsValue, JsError> {
        let name = |i: usize, fallback: &str| {
            paths
                .get(i)
                .and_then(JsValue::as_string)
                .unwrap_or_else(|| fallback.to_owned())
        };
        let config = self.pipeline.config();
        let entry = FrameEntry {
            index: 0,
            timestamp,
            colour: colour.as_ref().map(|_| name(0, "colour image")),
            depth: name(1, "depth image"),
            confidence: confidence.as_ref().map(|_| name(2, "confidence image")),
            calibrated_size: Some(CalibratedSize {
                width: config.intrinsics.width,
                height: config.intrinsics.height,
                file: "the camera settings".to_owned(),
            }),
            pose_file: None,
            missing: None,
        };
        let bytes = FrameBytes {
            colour: colour.as_deref(),
            depth,
            confidence: confidence.as_deref(),
        };
        let decoded = decode_frame_bytes(&entry, &bytes, &config.depth)
            .map_err(|e| frame_error(timestamp, &e));
        let report = self.pipeline.push_decoded(decoded, timestamp)?;
        Ok(report_to_js(&report))
    }

    /// Processes a frame whose colour image was decoded by the caller (the
    /// page decodes it in the browser: `rgba` is RGBA8 from `getImageData`,
    /// or RGB8, `width` x `height`) with a 16-bit depth PNG, decoded here
    /// (browsers reduce 16-bit PNGs to 8 bits). Throws (and changes nothing)
    /// on a wrong buffer length, a colour/depth size mismatch or bad depth
    /// bytes, with the messages of `pushFrame`.
    #[wasm_bindgen(js_name = pushRgbaDepthPng, unchecked_return_type = "FrameReport")]
    pub fn push_rgba_depth_png(
        &mut self,
        width: u32,
        height: u32,
        rgba: &[u8],
        #[wasm_bindgen(js_name = "depthPng")] depth_png: &[u8],
        timestamp: f64,
    ) -> Result<JsValue, JsError> {
        // No frame prefix here: the page's worker names the files itself.
        let report = self.pipeline.push_rgba_depth_png(
            width as usize,
            height as usize,
            rgba,
            depth_png,
            timestamp,
        )?;
        Ok(report_to_js(&report))
    }

    /// Processes a decoded frame: `rgba` is RGBA8 (or RGB8) row-major,
    /// `depth` raw units (`depthScale` per metre, 0 = none). Throws (and
    /// changes nothing) on wrong sizes.
    #[wasm_bindgen(js_name = pushRaw, unchecked_return_type = "FrameReport")]
    pub fn push_raw(
        &mut self,
        width: u32,
        height: u32,
        rgba: &[u8],
        depth: &[u16],
        timestamp: f64,
    ) -> Result<JsValue, JsError> {
        let report =
            self.pipeline
                .push_raw(width as usize, height as usize, rgba, depth, timestamp)?;
        Ok(report_to_js(&report))
    }

    /// Depth of the last frame pushed with `pushFrame`, `pushRgbaDepthPng` or `pushFiles`,
    /// if that push was accepted (else empty), resampled to `width` x
    /// `height` (each clamped to 1024): metres, 0 = no measurement,
    /// row-major. For live previews: browsers decode 16-bit PNGs to 8 bits.
    #[wasm_bindgen(js_name = depthPreview)]
    pub fn depth_preview(&mut self, width: u32, height: u32) -> Float32Array {
        let (w, h) = (width.min(1024) as usize, height.min(1024) as usize);
        match self.pipeline.last_decoded_frame() {
            Some(frame) => frame.depth_thumbnail_into(w, h, &mut self.preview),
            None => self.preview.clear(),
        }
        Float32Array::from(self.preview.as_slice())
    }

    /// Length of the surfel arrays (`positions()` holds `3 * surfelCount`
    /// floats): what a renderer draws and uploads. It includes surfels
    /// absorbed into others and not yet compacted away (negative
    /// confidence: skip them when drawing); `liveSurfels` is the map's size.
    #[wasm_bindgen(getter, js_name = surfelCount)]
    #[must_use]
    pub fn surfel_count(&self) -> u32 {
        u32::try_from(self.pipeline.map().len()).unwrap_or(u32::MAX)
    }

    /// Surfels the map holds: `surfelCount` without the absorbed ones
    /// awaiting removal. Equals the vertex count of `exportPly()` and the
    /// last report's `surfels`; show this one to users.
    #[wasm_bindgen(getter, js_name = liveSurfels)]
    #[must_use]
    pub fn live_surfels(&self) -> u32 {
        u32::try_from(self.pipeline.map().live_len()).unwrap_or(u32::MAX)
    }

    /// Frames pushed (accepted) since creation or the last reset, those
    /// of a loaded session included. While localising: the map's frames
    /// (the localised ones are in the reports' `counts`).
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn frames(&self) -> u32 {
        self.pipeline.frames()
    }

    /// Whether frames are being localised in a loaded map
    /// (`load(bytes, { localise: true })`) rather than mapped.
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn localising(&self) -> bool {
        self.pipeline.is_localising()
    }

    /// The session as bytes (a zip: map, keyframes, trajectory, settings;
    /// `load` continues from it exactly). Throws (`localising: ...`) while
    /// localising: the map is the session loaded.
    pub fn save(&self) -> Result<Vec<u8>, JsError> {
        session::save(&self.pipeline, Cursor::new(Vec::new()))
            .map(Cursor::into_inner)
            .map_err(|e| session_error(&e))
    }

    /// Replaces this Slam's map, trajectory and settings by the session in
    /// `bytes` (from `save()`); the camera must be this Slam's. Pushed
    /// frames then continue it exactly, or with `{ localise: true }` are
    /// placed in its map without changing it. Throws an Error whose
    /// message starts with the kind (`truncated`, `corrupt`,
    /// `future-version`, `camera-mismatch`, `not-a-session`) on a bad file,
    /// or on bad options, and then keeps everything it held.
    pub fn load(
        &mut self,
        bytes: &[u8],
        #[wasm_bindgen(unchecked_param_type = "LoadOptions | undefined")] options: JsValue,
    ) -> Result<(), JsError> {
        let options = LoadOptions::from_js(&options)?;
        session::load_into(&mut self.pipeline, Cursor::new(bytes))
            .map_err(|e| session_error(&e))?;
        if options.localise {
            self.pipeline.start_localising();
        }
        Ok(())
    }

    /// Surfel centres, `3 * surfelCount` floats, world frame, metres.
    /// Zero-copy view: valid until the next call into the module.
    #[must_use]
    pub fn positions(&self) -> Float32Array {
        f32_view(flatten_vec3(self.pipeline.map().positions()))
    }

    /// Surfel unit normals, `3 * surfelCount` floats, world frame.
    /// Zero-copy view: valid until the next call into the module.
    #[must_use]
    pub fn normals(&self) -> Float32Array {
        f32_view(flatten_vec3(self.pipeline.map().normals()))
    }

    /// Surfel colours, `4 * surfelCount` bytes, RGBA.
    /// Zero-copy view: valid until the next call into the module.
    #[must_use]
    pub fn colours(&self) -> Uint8Array {
        u8_view(self.pipeline.map().colours().as_flattened())
    }

    /// Surfel radii, `surfelCount` floats, metres.
    /// Zero-copy view: valid until the next call into the module.
    #[must_use]
    pub fn radii(&self) -> Float32Array {
        f32_view(self.pipeline.map().radii())
    }

    /// Surfel confidences, `surfelCount` floats.
    /// Zero-copy view: valid until the next call into the module.
    #[must_use]
    pub fn confidences(&self) -> Float32Array {
        f32_view(self.pipeline.map().confidences())
    }

    /// `[start, end]`: surfel slots filled by new surfels, or by surfels
    /// moved by a cleanup or a spatial sort, since the last call (re-upload
    /// this range and draw `surfelCount` surfels). Merges are not included:
    /// they refine surfels by less than the sensor noise, so refresh the
    /// rest of the arrays in a rolling window to show them.
    #[wasm_bindgen(js_name = takeChangedRange, unchecked_return_type = "[number, number]")]
    pub fn take_changed_range(&mut self) -> Array {
        let range = self.pipeline.take_changed_range();
        Array::of2(
            &JsValue::from_f64(range.start as f64),
            &JsValue::from_f64(range.end as f64),
        )
    }

    /// The trajectory so far as TUM lines `timestamp tx ty tz qx qy qz qw`
    /// (camera to world), with a `#` header line. While localising: the
    /// frames placed in the loaded map (unplaced ones are absent).
    #[wasm_bindgen(js_name = trajectoryTum)]
    #[must_use]
    pub fn trajectory_tum(&self) -> String {
        format_tum(self.trajectory())
    }

    /// Absolute trajectory error of the trajectory so far against
    /// `groundTruthTum` (TUM text, e.g. `parseSequence(...).groundTruthTum`)
    /// after rigid alignment, metres: `{ rmse, mean, median, max, pairs }`.
    /// Poses match by nearest timestamp within `maxDt` (default 0.02 s).
    /// The same as `ateTum(slam.trajectoryTum(), groundTruthTum, maxDt)`
    /// without writing and re-reading the trajectory as text. Throws on bad
    /// ground truth text or when too few poses match yet.
    #[wasm_bindgen(unchecked_return_type = "Ate")]
    pub fn ate(
        &self,
        #[wasm_bindgen(js_name = "groundTruthTum")] ground_truth_tum: &str,
        #[wasm_bindgen(js_name = "maxDt")] max_dt: Option<f64>,
    ) -> Result<JsValue, JsError> {
        let max_dt = max_dt_from_js(max_dt)?;
        let truth = parse_tum(ground_truth_tum, "ground truth")?;
        Ok(ate_to_js(&eval::ate(self.trajectory(), &truth, max_dt)?))
    }

    /// The surfel map as a binary little-endian PLY file.
    #[wasm_bindgen(js_name = exportPly)]
    #[must_use]
    pub fn export_ply(&self) -> Vec<u8> {
        write_surfel_ply(self.pipeline.map())
    }

    /// The recording ended: looks its last frame up among the old
    /// keyframes when the global check's schedule skipped it, and on a
    /// verified match corrects the map and the trajectory as any global
    /// closure does. Callable at any time; a second call does nothing, and
    /// frames pushed after it go on from the corrected pose.
    #[wasm_bindgen(unchecked_return_type = "FinishReport")]
    pub fn finish(&mut self) -> JsValue {
        let outcome = self.pipeline.finish();
        let frame = self.pipeline.frames().saturating_sub(1);
        let counts = (
            self.pipeline.loop_closures(),
            self.pipeline.global_loop_closures(),
        );
        finish_to_js(&outcome, frame, counts)
    }

    /// Forgets the map and the trajectory; keeps the configuration. Pushing
    /// the same frames again gives the same trajectory (in the threaded
    /// build to rounding: its parallel sums vary in the last digits).
    pub fn reset(&mut self) {
        self.pipeline.reset();
    }

    /// Checks the settings against the dataset's layout: `layoutPreset` is
    /// the preset `parseSequence` gave (`sequence.preset`), `chosenPreset`
    /// the one the config was made from (default: the same). Returns the
    /// warnings found (each names the setting); also in `settingsWarnings()`.
    #[wasm_bindgen(js_name = checkLayout, unchecked_return_type = "string[]")]
    pub fn check_layout(
        &mut self,
        #[wasm_bindgen(js_name = "layoutPreset", unchecked_param_type = "PresetName")]
        layout_preset: &str,
        #[wasm_bindgen(js_name = "chosenPreset", unchecked_optional_param_type = "PresetName")]
        chosen_preset: Option<String>,
    ) -> Result<Array, JsError> {
        let named = |name: &str| {
            CameraPreset::from_name(name)
                .ok_or_else(|| JsError::new(&format!("unknown preset {name:?}")))
        };
        let detected = named(layout_preset)?;
        let chosen = match chosen_preset {
            Some(name) => named(&name)?,
            None => detected,
        };
        let found = self.pipeline.check_layout(detected, chosen);
        Ok(found.iter().map(|w| JsValue::from(w.to_string())).collect())
    }

    /// Every camera-settings warning found so far: the depth check on the
    /// first frame and `checkLayout`'s (each names the setting).
    #[wasm_bindgen(js_name = settingsWarnings, unchecked_return_type = "string[]")]
    #[must_use]
    pub fn settings_warnings(&self) -> Array {
        self.pipeline
            .settings_warnings()
            .iter()
            .map(|w| JsValue::from(w.to_string()))
            .collect()
    }
}

impl Slam {
    /// The trajectory `trajectoryTum` and `ate` read: the mapped one, or
    /// while localising the placed frames.
    fn trajectory(&self) -> &[(f64, DAffine3)] {
        self.pipeline
            .localisation()
            .map_or(self.pipeline.trajectory(), |l| l.trajectory())
    }

    /// The pipeline, for Rust callers (tests).
    #[must_use]
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }
}
