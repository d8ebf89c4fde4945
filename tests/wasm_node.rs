//! The wasm bindings under Node (wasm-bindgen-test):
//! `cargo test --release --target wasm32-unknown-unknown --no-default-features --test wasm_node`
//! (`.cargo/config.toml` makes wasm-bindgen-test-runner the runner).
//!
//! - a synthetic sequence tracked through `Slam.pushRaw` has a small ATE and
//!   the same poses as the native reference, bit for bit (`tests/wasm_common`
//!   explains how); so has a noisy one past the active window, and one
//!   through a loop closure (the deformation graph's sparse solve);
//! - real ICL-NUIM frames read from `../shared/data` with Node's `fs` and
//!   pushed as PNG bytes track, have a small ATE and match native
//!   (skipped with a message when `../shared` is absent);
//! - bad bytes and bad configs throw JS errors (no panic) and the pipeline
//!   keeps working afterwards;
//! - views, ranges, exports and the dataset functions have the right shapes.

#![cfg(target_arch = "wasm32")]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod wasm_common;

use std::collections::HashMap;

use glam::DAffine3;
use js_sys::{Array, Object, Reflect};
use surfel_slam::dataset::{detect_layout, parse_sequence};
use surfel_slam::wasm::{self, Slam};
use surfel_slam::{eval, SlamConfig};
use wasm_bindgen::prelude::*;
use wasm_bindgen_test::*;
use wasm_common::*;

#[wasm_bindgen(module = "fs")]
extern "C" {
    #[wasm_bindgen(catch, js_name = readFileSync)]
    fn read_file_sync(path: &str) -> Result<Vec<u8>, JsValue>;
    #[wasm_bindgen(catch, js_name = readdirSync)]
    fn readdir_sync(path: &str, options: &JsValue) -> Result<Array, JsValue>;
    #[wasm_bindgen(js_name = existsSync)]
    fn exists_sync(path: &str) -> bool;
}

fn read_file(path: &str) -> Option<Vec<u8>> {
    read_file_sync(path).ok()
}

fn read_text(path: &str) -> Option<String> {
    read_file(path).and_then(|b| String::from_utf8(b).ok())
}

/// Relative paths of every entry under `dir` ('/' separated, sorted).
fn list_recursive(dir: &str) -> Vec<String> {
    let options = Object::new();
    let _ = Reflect::set(&options, &"recursive".into(), &JsValue::TRUE);
    let mut names: Vec<String> = readdir_sync(dir, &options)
        .map(|a| a.iter().filter_map(|v| v.as_string()).collect())
        .unwrap_or_default();
    names.sort();
    names
}

fn env_var(key: &str) -> Option<String> {
    let process = Reflect::get(&js_sys::global(), &"process".into()).ok()?;
    let env = Reflect::get(&process, &"env".into()).ok()?;
    Reflect::get(&env, &key.into()).ok()?.as_string()
}

fn source_fingerprint() -> String {
    let root = env!("CARGO_MANIFEST_DIR");
    let files = list_recursive(root)
        .into_iter()
        .filter(|n| is_fingerprinted(n))
        .filter_map(|n| read_file(&format!("{root}/{n}")).map(|b| (n, b)))
        .collect();
    fingerprint(files)
}

/// Compares with the native reference when it is fresh (see
/// `wasm_common`): the same bits, every pose.
fn check_parity(name: &str, poses: &[(f64, DAffine3)]) {
    let require = env_var("SURFEL_SLAM_REQUIRE_PARITY").is_some_and(|v| v == "1");
    match read_reference(read_text(&reference_path(name)), &source_fingerprint()) {
        Ok(reference) => {
            if let Some(i) = first_difference(poses, &reference) {
                let (dt, dr) = max_difference(poses, &reference).unwrap_or((f64::NAN, f64::NAN));
                panic!(
                    "{name}: wasm's poses are not native's bits from pose {i} of {} \
                     (largest difference {dt:.3e} m, {dr:.3e} rad)",
                    reference.len()
                );
            }
            console_log!(
                "{name}: wasm and native poses are bit-identical ({} poses)",
                poses.len()
            );
        }
        Err(why) if require => {
            panic!("{name}: {why}; run `cargo test --test wasm_parity_native` first")
        }
        Err(why) => console_log!(
            "{name}: native comparison SKIPPED ({why}); run \
             `cargo test --test wasm_parity_native` first or use scripts/test-wasm.sh"
        ),
    }
}

fn get(v: &JsValue, key: &str) -> JsValue {
    Reflect::get(v, &key.into()).unwrap_or(JsValue::UNDEFINED)
}

fn num(v: &JsValue, key: &str) -> f64 {
    get(v, key).as_f64().unwrap_or(f64::NAN)
}

fn text(v: &JsValue, key: &str) -> String {
    get(v, key).as_string().unwrap_or_default()
}

fn message(e: JsError) -> String {
    let v: JsValue = e.into();
    text(&v, "message")
}

/// The JS config object for `config` (as a page would write it).
fn config_object(config: &SlamConfig) -> JsValue {
    let k = config.intrinsics;
    let d = config.depth;
    let o = Object::new();
    for (key, value) in [
        ("preset", JsValue::from_str("tum-fr3")),
        ("fx", k.fx.into()),
        ("fy", k.fy.into()),
        ("cx", k.cx.into()),
        ("cy", k.cy.into()),
        ("width", (k.width as f64).into()),
        ("height", (k.height as f64).into()),
        ("depthScale", d.scale.into()),
        ("depthMin", d.min_m.into()),
        ("depthMax", d.max_m.into()),
    ] {
        let _ = Reflect::set(&o, &key.into(), &value);
    }
    o.into()
}

fn trajectory_of(slam: &Slam) -> Vec<(f64, DAffine3)> {
    slam.pipeline().trajectory().to_vec()
}

#[wasm_bindgen_test]
fn synthetic_sequence_tracks_and_matches_native() {
    let (config, frames, ground_truth) = synthetic_sequence();
    let mut slam = Slam::new(config_object(&config)).expect("valid config");
    assert_eq!(
        slam.pipeline().config(),
        &config,
        "JS config maps to the native one"
    );
    for f in &frames {
        let r = slam
            .push_raw(
                f.width as u32,
                f.height as u32,
                &f.rgba,
                &f.depth,
                f.timestamp,
            )
            .map_err(message)
            .expect("frame accepted");
        let verdict = text(&r, "verdict");
        assert!(
            matches!(verdict.as_str(), "tracked" | "held" | "initialised"),
            "{verdict}"
        );
    }
    let trajectory = trajectory_of(&slam);
    check_parity("synthetic", &trajectory);
    let ate = eval::ate(&trajectory, &ground_truth, 1e-3).expect("ATE");
    console_log!(
        "synthetic: wasm ATE rmse {:.6} m over {} frames",
        ate.rmse_m,
        ate.pairs
    );

    // Views have the documented lengths.
    let n = slam.surfel_count();
    assert!(n > 1000, "{n} surfels");
    assert_eq!(slam.positions().length(), 3 * n);
    assert_eq!(slam.normals().length(), 3 * n);
    assert_eq!(slam.colours().length(), 4 * n);
    assert_eq!(slam.radii().length(), n);
    assert_eq!(slam.confidences().length(), n);
    let range = slam.take_changed_range();
    assert!(range.get(1).as_f64().unwrap_or(0.0) <= f64::from(n));
    let ply = slam.export_ply();
    // Surfels absorbed into others and awaiting removal are not exported.
    let kept = slam
        .confidences()
        .to_vec()
        .iter()
        .filter(|&&c| c >= 0.0)
        .count();
    assert!(
        kept > 1000 && kept <= n as usize,
        "{kept} of {n} surfels kept"
    );
    assert_eq!(
        slam.live_surfels() as usize,
        kept,
        "liveSurfels is the PLY's count"
    );
    let header = format!("element vertex {kept}\n");
    assert!(
        ply.starts_with(b"ply\n")
            && ply.windows(header.len()).any(|w| w == header.as_bytes())
            && ply.len() > kept * 35
    );
    assert_eq!(slam.trajectory_tum().lines().count(), frames.len() + 1);
    slam.reset();
    assert_eq!((slam.surfel_count(), slam.frames()), (0, 0));
    assert!(
        ate.rmse_m < SYNTHETIC_ATE_BOUND_M,
        "synthetic ATE {} m",
        ate.rmse_m
    );
}

/// Past the active window (the loop stage registers the inactive model on
/// the way back), under Kinect-like noise: the same poses as native, bit for
/// bit. Before the pipeline took its transcendental functions from `libm`
/// (issue #37) this ended 3.68 mm from native (`docs/performance.md#determinism`).
#[wasm_bindgen_test]
fn window_sequence_matches_native() {
    let (config, frames, _) = window_sequence();
    let o = config_object(&config);
    let _ = Reflect::set(
        &o,
        &"activeWindowFrames".into(),
        &f64::from(WINDOW_FRAMES).into(),
    );
    let mut slam = Slam::new(o).expect("valid config");
    assert_eq!(
        slam.pipeline().config(),
        &config,
        "JS config maps to the native one"
    );
    for f in &frames {
        slam.push_raw(
            f.width as u32,
            f.height as u32,
            &f.rgba,
            &f.depth,
            f.timestamp,
        )
        .map_err(message)
        .expect("frame accepted");
    }
    check_parity("window", &trajectory_of(&slam));
}

/// Through a loop closure (the revisit sequence up to just past the global
/// check's closure, `wasm_common::revisit_sequence`): the poses each frame
/// reported and the trajectory the deformation bent are native's bits. The
/// library is driven directly: the sequence's loop settings (a 30-frame
/// window, global looks every 5 frames) have no JS config keys.
#[wasm_bindgen_test]
fn revisit_sequence_through_a_loop_closure_matches_native() {
    let (config, frames) = revisit_sequence();
    let mut pipeline = surfel_slam::Pipeline::new(config).expect("valid config");
    let mut closed_at = Vec::new();
    let mut online = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let r = pipeline.push_frame(f, i as f64).expect("frame accepted");
        if r.loop_outcome.closed {
            closed_at.push(i);
        }
        online.push((r.timestamp, r.world_from_camera));
    }
    console_log!("revisit: wasm closed the loop at frames {closed_at:?}");
    assert!(!closed_at.is_empty(), "no loop closed");
    check_parity("revisit-online", &online);
    check_parity("revisit", pipeline.trajectory());
}

#[wasm_bindgen_test]
fn real_frames_track_and_match_native() {
    let dir = data_dir(REAL_SEQUENCE);
    if !exists_sync(&dir) {
        console_log!("skipping: {dir} is absent (no ../shared/data)");
        return;
    }
    // The same parser as the CLI and the page, on a Node listing.
    let names = list_recursive(&dir);
    let layout = detect_layout(&names).expect("layout");
    let texts: HashMap<String, String> = layout
        .index_files
        .iter()
        .map(|f| {
            (
                f.clone(),
                read_text(&format!("{dir}/{f}")).expect("index file"),
            )
        })
        .collect();
    let sequence = parse_sequence(&layout, &names, &texts, Some(REAL_SEQUENCE)).expect("sequence");

    let mut slam = Slam::new(JsValue::from_str(sequence.preset.name())).expect("preset");
    for entry in sequence.frames.iter().take(REAL_FRAMES) {
        let colour = read_file(&format!(
            "{dir}/{}",
            entry.colour.as_deref().expect("colour")
        ))
        .expect("colour");
        let depth = read_file(&format!("{dir}/{}", entry.depth)).expect("depth");
        let r = slam
            .push_frame(&colour, &depth, entry.timestamp)
            .map_err(message)
            .expect("frame accepted");
        let verdict = text(&r, "verdict");
        assert!(
            matches!(verdict.as_str(), "tracked" | "held" | "initialised"),
            "frame {}: {verdict}",
            entry.index
        );
        assert!(num(&r, "surfels") > 10_000.0);
    }
    let trajectory = trajectory_of(&slam);
    let ate = eval::ate(&trajectory, &sequence.ground_truth, 1e-3).expect("ATE");
    console_log!(
        "{REAL_SEQUENCE}: wasm ATE rmse {:.6} m over {} frames, {} surfels",
        ate.rmse_m,
        ate.pairs,
        slam.surfel_count()
    );
    check_parity(REAL_SEQUENCE, &trajectory);
    assert!(ate.rmse_m < REAL_ATE_BOUND_M, "ATE {} m", ate.rmse_m);
}

fn png(image: image::DynamicImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut out, image::ImageFormat::Png)
        .expect("encode PNG");
    out.into_inner()
}

#[wasm_bindgen_test]
fn bad_input_throws_and_the_pipeline_keeps_working() {
    let (config, frames, _) = synthetic_sequence();
    let (w, h) = (frames[0].width as u32, frames[0].height as u32);
    let encode = |f: &RawFrame| {
        let rgba = image::RgbaImage::from_raw(w, h, f.rgba.clone()).expect("rgba");
        let depth = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, f.depth.clone())
            .expect("depth");
        (
            png(image::DynamicImage::ImageRgba8(rgba)),
            png(image::DynamicImage::ImageLuma16(depth)),
        )
    };
    let mut slam = Slam::new(config_object(&config)).expect("valid config");
    let (c0, d0) = encode(&frames[0]);
    slam.push_frame(&c0, &d0, 0.0)
        .map_err(message)
        .expect("first frame");

    let garbage = b"definitely not a PNG".to_vec();
    let mut truncated = d0.clone();
    truncated.truncate(d0.len() / 2);
    let depth8 = png(image::DynamicImage::ImageLuma8(image::GrayImage::new(w, h)));
    let small = png(image::DynamicImage::ImageLuma16(image::ImageBuffer::new(
        8, 8,
    )));
    let cases: [(&str, &[u8], &[u8], &str); 6] = [
        (
            "garbage colour",
            &garbage,
            &d0,
            "colour image could not be decoded",
        ),
        (
            "garbage depth",
            &c0,
            &garbage,
            "depth image could not be decoded",
        ),
        (
            "truncated depth",
            &c0,
            &truncated,
            "depth image could not be decoded",
        ),
        ("8-bit depth", &c0, &depth8, "16-bit"),
        ("empty", &[], &[], "could not be decoded"),
        ("size mismatch", &c0, &small, "but depth is 8x8"),
    ];
    for (what, colour, depth, expected) in cases {
        let err = slam
            .push_frame(colour, depth, 1.0)
            .map(|_| ())
            .map_err(message)
            .expect_err(what);
        console_log!("{what}: {err}");
        assert!(err.contains(expected), "{what}: {err:?} lacks {expected:?}");
    }
    let err = slam
        .push_raw(w, h, &frames[1].rgba[..10], &frames[1].depth, 1.0)
        .map(|_| ())
        .map_err(message)
        .expect_err("short rgba");
    assert!(err.contains("colour buffer has 10 values"), "{err}");
    let err = slam
        .push_raw(w + 2, h, &frames[1].rgba, &frames[1].depth, 1.0)
        .map(|_| ())
        .map_err(message)
        .expect_err("wrong size");
    assert!(err.contains("depth buffer"), "{err}");
    let err = slam
        .push_raw(w, h, &frames[1].rgba, &frames[1].depth, f64::NAN)
        .map(|_| ())
        .map_err(message)
        .expect_err("NaN timestamp");
    assert!(err.contains("timestamp"), "{err}");
    assert_eq!(slam.frames(), 1, "failed pushes change nothing");

    // Still works.
    for (i, f) in frames.iter().enumerate().take(4).skip(1) {
        let (c, d) = encode(f);
        let r = slam
            .push_frame(&c, &d, f.timestamp)
            .map_err(message)
            .expect("frame");
        // Held: fused, with a direction the view left free taken from the
        // feature estimate (TrackerConfig::hold_below_eigenvalue).
        let verdict = text(&r, "verdict");
        assert!(
            verdict == "tracked" || verdict == "held",
            "frame {i}: {verdict}"
        );
        assert_eq!(get(&r, "lostReason"), JsValue::NULL);
        let pose: js_sys::Float64Array = get(&r, "pose").into();
        assert_eq!(pose.length(), 16);
        assert_eq!(pose.get_index(15), 1.0);
    }
    assert_eq!(slam.frames(), 4);
}

/// The page's path: colour decoded by the browser (RGBA pixels), depth as a
/// PNG decoded in wasm. Same poses and map as `pushFrame` with both PNGs;
/// bad input throws the same messages and changes nothing.
#[wasm_bindgen_test]
fn rgba_with_depth_png_matches_push_frame() {
    let (config, frames, _) = synthetic_sequence();
    let (w, h) = (frames[0].width as u32, frames[0].height as u32);
    let depth_png = |f: &RawFrame| {
        let depth = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, f.depth.clone())
            .expect("depth");
        png(image::DynamicImage::ImageLuma16(depth))
    };
    let colour_png = |f: &RawFrame| {
        let rgba = image::RgbaImage::from_raw(w, h, f.rgba.clone()).expect("rgba");
        png(image::DynamicImage::ImageRgba8(rgba))
    };
    let mut by_png = Slam::new(config_object(&config)).expect("valid config");
    let mut by_pixels = Slam::new(config_object(&config)).expect("valid config");
    assert_eq!(by_pixels.depth_preview(4, 3).length(), 0, "no frame yet");
    for f in frames.iter().take(5) {
        let d = depth_png(f);
        let a = by_png
            .push_frame(&colour_png(f), &d, f.timestamp)
            .map_err(message)
            .expect("PNG frame");
        let b = by_pixels
            .push_rgba_depth_png(w, h, &f.rgba, &d, f.timestamp)
            .map_err(message)
            .expect("pixels + depth PNG frame");
        assert_eq!(text(&a, "verdict"), text(&b, "verdict"));
        let timings = get(&b, "timings");
        assert!(num(&timings, "decode") >= 0.0);
    }
    assert_eq!(trajectory_of(&by_png), trajectory_of(&by_pixels));
    assert_eq!(by_png.surfel_count(), by_pixels.surfel_count());
    assert_eq!(
        by_png.pipeline().map().colours(),
        by_pixels.pipeline().map().colours()
    );

    // The preview is the last frame's depth under each thumbnail pixel centre, in metres.
    let last = &frames[4];
    let preview = by_pixels.depth_preview(4, 3).to_vec();
    assert_eq!(preview.len(), 12);
    let scale = f64::from(config.depth.scale);
    for (i, &m) in preview.iter().enumerate() {
        let (x, y) = (i % 4, i / 4);
        let (sx, sy) = ((2 * x + 1) * w as usize / 8, (2 * y + 1) * h as usize / 6);
        let raw = f64::from(last.depth[sy * w as usize + sx]);
        assert!(
            (f64::from(m) - raw / scale).abs() < 1e-6 || m == 0.0,
            "{i}: {m} vs {raw}"
        );
    }
    assert!(preview.iter().any(|&m| m > 0.0));
    assert_eq!(by_pixels.depth_preview(5000, 2).length(), 2048, "clamped");

    let f = &frames[5];
    let d = depth_png(f);
    let small = png(image::DynamicImage::ImageLuma16(image::ImageBuffer::new(
        8, 8,
    )));
    let depth8 = png(image::DynamicImage::ImageLuma8(image::GrayImage::new(w, h)));
    let rgba_small = vec![0_u8; 4 * 8 * 8];
    /// (what, width, height, rgba, depth PNG, expected message part)
    type Case<'a> = (&'a str, u32, u32, &'a [u8], &'a [u8], &'a str);
    let cases: [Case; 6] = [
        (
            "short rgba",
            w,
            h,
            &f.rgba[..10],
            &d,
            "colour buffer has 10 values",
        ),
        (
            "garbage depth",
            w,
            h,
            &f.rgba,
            b"not a PNG",
            "depth image could not be decoded",
        ),
        ("8-bit depth", w, h, &f.rgba, &depth8, "16-bit"),
        ("size mismatch", w, h, &f.rgba, &small, "but depth is 8x8"),
        (
            "frame of another size",
            8,
            8,
            &rgba_small,
            &small,
            "frame is 8x8 but the sequence is",
        ),
        ("zero size", 0, h, &[], &d, "image size 0x"),
    ];
    for (what, width, height, rgba, depth, expected) in cases {
        let err = by_pixels
            .push_rgba_depth_png(width, height, rgba, depth, 1.0)
            .map(|_| ())
            .map_err(message)
            .expect_err(what);
        console_log!("{what}: {err}");
        assert!(err.contains(expected), "{what}: {err:?} lacks {expected:?}");
    }
    let err = by_pixels
        .push_rgba_depth_png(w, h, &f.rgba, &d, f64::INFINITY)
        .map(|_| ())
        .map_err(message)
        .expect_err("infinite timestamp");
    assert!(err.contains("timestamp"), "{err}");
    assert_eq!(by_pixels.frames(), 5, "failed pushes change nothing");
    assert_eq!(
        by_pixels.depth_preview(4, 3).length(),
        0,
        "the last push failed"
    );
    by_pixels
        .push_rgba_depth_png(w, h, &f.rgba, &d, f.timestamp)
        .map_err(message)
        .expect("still works");
}

#[wasm_bindgen_test]
fn bad_configs_throw_clear_errors() {
    let obj = |pairs: &[(&str, JsValue)]| -> JsValue {
        let o = Object::new();
        for (k, v) in pairs {
            let _ = Reflect::set(&o, &(*k).into(), v);
        }
        o.into()
    };
    let cases = [
        (JsValue::UNDEFINED, "must be an object"),
        (JsValue::from_str("kinect-9"), "unknown preset \"kinect-9\""),
        (obj(&[("preset", "nope".into())]), "unknown preset"),
        (
            obj(&[("fx", 500.0.into())]),
            "missing: fy, cx, cy, width, height",
        ),
        (
            obj(&[("preset", "tum-fr3".into()), ("depthscale", 1.0.into())]),
            "unknown config field \"depthscale\"",
        ),
        (
            obj(&[("preset", "tum-fr3".into()), ("depthScale", (-1.0).into())]),
            "depth scale must be a positive",
        ),
        (
            obj(&[("preset", "tum-fr3".into()), ("fx", "big".into())]),
            "config.fx must be a finite number",
        ),
        (
            obj(&[("preset", "tum-fr3".into()), ("width", 10.5.into())]),
            "config.width must be an integer",
        ),
        (
            obj(&[
                ("preset", "tum-fr3".into()),
                ("width", 20.0.into()),
                ("height", 20.0.into()),
            ]),
            "pyramid levels do not fit",
        ),
        (
            obj(&[
                ("preset", "icl-nuim".into()),
                ("iterations", Array::of1(&3.into()).into()),
            ]),
            "tracker needs iterations",
        ),
    ];
    for (config, expected) in cases {
        let err = Slam::new(config)
            .map(|_| ())
            .map_err(message)
            .expect_err(expected);
        assert!(err.contains(expected), "{err:?} lacks {expected:?}");
    }
    let presets = wasm::presets();
    assert_eq!(presets.length(), 7);
    assert_eq!(text(&presets.get(0), "name"), "tum-fr1");
    assert_eq!(wasm::thread_count(), 1);
}

#[wasm_bindgen_test]
fn dataset_functions_from_js() {
    let names: Array = [
        "seq/rgb.txt",
        "seq/depth.txt",
        "seq/groundtruth.txt",
        "seq/rgb/1.0.png",
        "seq/depth/1.0.png",
    ]
    .iter()
    .map(|s| JsValue::from_str(s))
    .collect();
    let layout = wasm::detect_layout(names.clone().into())
        .map_err(message)
        .expect("layout");
    assert_eq!(text(&layout, "kind"), "tum");
    let texts = Object::new();
    let _ = Reflect::set(&texts, &"seq/rgb.txt".into(), &"1.0 rgb/1.0.png\n".into());
    let _ = Reflect::set(
        &texts,
        &"seq/depth.txt".into(),
        &"1.0 depth/1.0.png\n".into(),
    );
    let _ = Reflect::set(
        &texts,
        &"seq/groundtruth.txt".into(),
        &"1.0 1 2 3 0 0 0 1\n".into(),
    );
    let seq = wasm::parse_sequence(names.into(), texts.into(), "freiburg1_desk".into())
        .map_err(message)
        .expect("sequence");
    assert_eq!(text(&seq, "preset"), "tum-fr1");
    let frames: Array = get(&seq, "frames").into();
    assert_eq!(frames.length(), 1);
    assert_eq!(text(&frames.get(0), "colour"), "seq/rgb/1.0.png");
    let gt: Array = get(&seq, "groundTruth").into();
    assert_eq!(Array::from(&gt.get(0)).get(1).as_f64(), Some(1.0));

    let err = wasm::detect_layout(JsValue::from_f64(3.0))
        .map(|_| ())
        .map_err(message)
        .expect_err("not an array");
    assert!(err.contains("array of strings"), "{err}");
    let err = wasm::detect_layout(Array::of1(&"a.jpg".into()).into())
        .map(|_| ())
        .map_err(message)
        .expect_err("unknown");
    assert!(err.contains("rgb.txt"), "{err}");

    let tum = "1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n3 2 0 0 0 0 0 1\n";
    let ate = wasm::ate_tum(tum, tum, None).map_err(message).expect("ATE");
    assert!(num(&ate, "rmse") < 1e-9 && num(&ate, "pairs") == 3.0);
    let err = wasm::ate_tum("1 2 3", tum, None)
        .map(|_| ())
        .map_err(message)
        .expect_err("malformed");
    assert!(err.contains("estimate, line 1"), "{err}");
}
