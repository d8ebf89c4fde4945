//! The `OpticalFlow` class: sparse Lucas-Kanade tracks between two colour
//! images, for the page's flow overlay. A thin shell over [`crate::flow`].

use js_sys::Float32Array;
use wasm_bindgen::prelude::*;

use crate::flow::{FlowConfig, OpticalFlow as Flow};

/// Shi-Tomasi corners of one image tracked into the next (pyramidal LK with
/// a forward-backward check). Buffers are reused between calls.
#[wasm_bindgen]
#[derive(Debug)]
pub struct OpticalFlow {
    flow: Flow,
    first: Vec<f32>,
    second: Vec<f32>,
    /// Size of the image in `second` kept by `pushPng` (0 x 0 = none yet).
    kept: (usize, usize),
}

/// Grey levels 0..255 of an RGBA8 (or RGB8) image into `out`.
fn grey_into(pixels: &[u8], count: usize, out: &mut Vec<f32>) -> Result<(), JsError> {
    let channels = if pixels.len() == 4 * count {
        4
    } else if pixels.len() == 3 * count {
        3
    } else {
        return Err(JsError::new(&format!(
            "image must be RGBA8 or RGB8 with {count} pixels, got {} bytes",
            pixels.len()
        )));
    };
    out.clear();
    out.extend(
        pixels
            .chunks_exact(channels)
            .map(|c| 0.299 * f32::from(c[0]) + 0.587 * f32::from(c[1]) + 0.114 * f32::from(c[2])),
    );
    Ok(())
}

#[wasm_bindgen]
impl OpticalFlow {
    /// `new OpticalFlow(maxCorners = 500)`.
    #[wasm_bindgen(constructor)]
    pub fn new(
        #[wasm_bindgen(js_name = "maxCorners")] max_corners: Option<u32>,
    ) -> Result<OpticalFlow, JsError> {
        let mut config = FlowConfig::default();
        if let Some(n) = max_corners {
            config.max_corners = n as usize;
        }
        let flow = Flow::new(config)?;
        Ok(Self {
            flow,
            first: Vec::new(),
            second: Vec::new(),
            kept: (0, 0),
        })
    }

    /// Decodes a colour image (PNG or JPEG) and tracks corners of the
    /// previously pushed image into it: `[fromX, fromY, toX, toY, ...]`,
    /// empty for the first image or after a size change. Throws on bad bytes.
    #[wasm_bindgen(js_name = pushPng)]
    pub fn push_png(&mut self, colour: &[u8]) -> Result<Float32Array, JsError> {
        let (w, h, rgb) = crate::frame::decode_colour(colour)?;
        self.push_pixels(w, h, &rgb)
    }

    /// As `pushPng`, for an image decoded by the caller: `rgba` is RGBA8 (or
    /// RGB8), `width` x `height`. Throws on a wrong buffer length.
    #[wasm_bindgen(js_name = pushRgba)]
    pub fn push_rgba(
        &mut self,
        width: u32,
        height: u32,
        rgba: &[u8],
    ) -> Result<Float32Array, JsError> {
        self.push_pixels(width as usize, height as usize, rgba)
    }

    /// Width and height of the last image given to `pushPng` or `pushRgba`,
    /// pixels (0 before).
    #[wasm_bindgen(getter, js_name = imageSize, unchecked_return_type = "[number, number]")]
    #[must_use]
    pub fn image_size(&self) -> js_sys::Array {
        js_sys::Array::of2(
            &JsValue::from_f64(self.kept.0 as f64),
            &JsValue::from_f64(self.kept.1 as f64),
        )
    }

    /// Tracks corners of `first` into `second` (RGBA8 or RGB8, `width x
    /// height`). Returns `[fromX, fromY, toX, toY, ...]`, 4 floats per
    /// track, pixels (pixel centres at integers). Throws on wrong sizes.
    pub fn track(
        &mut self,
        width: u32,
        height: u32,
        first: &[u8],
        second: &[u8],
    ) -> Result<Float32Array, JsError> {
        let (w, h) = (width as usize, height as usize);
        let count = w
            .checked_mul(h)
            .ok_or_else(|| JsError::new("image size overflows"))?;
        grey_into(first, count, &mut self.first)?;
        grey_into(second, count, &mut self.second)?;
        let tracks = self.flow.track(&self.first, &self.second, w, h)?;
        Ok(flatten(tracks))
    }
}

impl OpticalFlow {
    /// Makes the kept image the first and `pixels` (RGBA8 or RGB8, `w` x `h`)
    /// the second, then tracks (nothing for the first image or after a size
    /// change). A wrong length keeps the previous image.
    fn push_pixels(&mut self, w: usize, h: usize, pixels: &[u8]) -> Result<Float32Array, JsError> {
        let count = w
            .checked_mul(h)
            .ok_or_else(|| JsError::new("image size overflows"))?;
        grey_into(pixels, count, &mut self.first)?;
        std::mem::swap(&mut self.first, &mut self.second);
        let previous = std::mem::replace(&mut self.kept, (w, h));
        if previous != (w, h) {
            return Ok(Float32Array::new_with_length(0));
        }
        let tracks = self.flow.track(&self.first, &self.second, w, h)?;
        Ok(flatten(tracks))
    }
}

/// `[fromX, fromY, toX, toY, ...]`.
fn flatten(tracks: &[crate::flow::FlowTrack]) -> Float32Array {
    let flat: Vec<f32> = tracks
        .iter()
        .flat_map(|t| [t.from.x, t.from.y, t.to.x, t.to.y])
        .collect();
    Float32Array::from(flat.as_slice())
}
