//! JavaScript bindings (wasm-bindgen): a thin shell over [`crate::Pipeline`]
//! and the dataset / evaluation functions. No algorithm lives here.
//!
//! The contract with the page is `docs/js-api.md`; names here follow it
//! exactly (`Slam`, `pushFrame`, `positions`, `detectLayout`, ...).
//!
//! - [`slam`]: the `Slam` class (frames in, reports and zero-copy surfel views out).
//! - [`dataset`]: `detectLayout`, `parseSequence`, `parseReference`, `ateTum` (the CLI's parsers).
//! - [`archive`]: the `ArchiveReader` class (datasets in .zip / .tar / .tar.gz).
//! - [`flow`]: the `OpticalFlow` class (Lucas-Kanade tracks for the page's overlay).
//! - [`session`]: `Slam.load`'s options and session errors as JS errors.
//! - [`config`]: the config object of `new Slam(config)`, one table of keys.
//! - [`convert`]: report / preset / dataset conversions to JS objects, and
//!   the error for JS arguments of the wrong shape.
//!
//! Errors are `JsError`s carrying the library error's `Display` message; a
//! panic would be a bug, and the panic hook installed at start makes it at
//! least readable in the console.

pub mod archive;
pub mod config;
pub mod convert;
pub mod dataset;
pub mod flow;
pub mod mesh;
pub mod session;
pub mod slam;

use wasm_bindgen::prelude::*;

pub use archive::ArchiveReader;
pub use dataset::{ate_tum, detect_layout, parse_reference, parse_sequence};
pub use flow::OpticalFlow;
pub use slam::Slam;

/// Threaded build only: `await initThreadPool(n)` starts `n` web workers
/// sharing this module's memory; rayon then runs on them. Needs a
/// cross-origin isolated page (COOP/COEP headers).
#[cfg(feature = "threads")]
pub use wasm_bindgen_rayon::init_thread_pool;

/// Runs once when the module is instantiated (and once per worker in the
/// threaded build): readable panic messages in the console.
#[wasm_bindgen(start)]
fn start() {
    console_error_panic_hook::set_once();
}

/// Rayon threads in use: 1 in the single-threaded build, the pool size after
/// `initThreadPool` in the threaded one.
#[wasm_bindgen(js_name = threadCount)]
#[must_use]
pub fn thread_count() -> u32 {
    u32::try_from(rayon::current_num_threads()).unwrap_or(u32::MAX)
}

/// Bytes of the module's linear memory: all the module holds (maps,
/// buffers, allocator slack). Wasm memory never shrinks, so this is also
/// the peak.
#[wasm_bindgen(js_name = memoryBytes)]
#[must_use]
pub fn memory_bytes() -> f64 {
    // Pages of 64 KiB; as f64, since JS numbers are exact to 2^53.
    (core::arch::wasm32::memory_size(0) as f64) * 65536.0
}

/// The camera presets with their intrinsics and depth settings:
/// `[{name, fx, fy, cx, cy, width, height, depthScale, depthMin, depthMax}, ...]`.
#[wasm_bindgen(unchecked_return_type = "Preset[]")]
#[must_use]
pub fn presets() -> js_sys::Array {
    crate::CameraPreset::ALL
        .into_iter()
        .map(convert::preset_to_js)
        .collect()
}

/// Every preset as `presets()` gives it, for frames of `width` x `height`
/// pixels: each one's intrinsics scaled as `presetForDepthImage` scales
/// them (the page's preset list for an open sequence of that size). Errors
/// on a size no frame can have.
#[wasm_bindgen(js_name = presetsForImageSize, unchecked_return_type = "Preset[]")]
pub fn presets_for_image_size(width: u32, height: u32) -> Result<js_sys::Array, JsError> {
    let (width, height) = (width as usize, height as usize);
    crate::frame::check_dimensions(width, height).map_err(|e| JsError::new(&e.to_string()))?;
    Ok(crate::CameraPreset::ALL
        .into_iter()
        .map(|p| convert::preset_at_size_to_js(p, &p.intrinsics().for_image_size(width, height)))
        .collect())
}

/// Preset `name` for frames of the size of the depth image `depth_png`
/// (its header alone is read): its intrinsics scaled to that size when the
/// aspect ratio is the same (a resized recording), else its focal lengths
/// kept and its principal point in its place (a guess, which
/// `Slam.checkLayout` warns about); `width` and `height` are the image's.
/// For layouts that state no calibration of their own (TUM, ICL-NUIM,
/// 7-Scenes). Errors on an unknown preset or an unreadable header.
#[wasm_bindgen(js_name = presetForDepthImage, unchecked_return_type = "Preset")]
pub fn preset_for_depth_image(name: &str, depth_png: &[u8]) -> Result<JsValue, JsError> {
    let preset = crate::CameraPreset::from_name(name)
        .ok_or_else(|| JsError::new(&format!("unknown camera preset {name:?}")))?;
    let (width, height) =
        crate::frame::image_dimensions(depth_png, crate::frame::Channel::Depth, true)
            .map_err(|e| JsError::new(&e.to_string()))?;
    let k = preset.intrinsics().for_image_size(width, height);
    Ok(convert::preset_at_size_to_js(preset, &k))
}
