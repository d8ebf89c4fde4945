//! Entry points for encoded or raw frames: decode into reused buffers, then
//! [`Pipeline::push_frame`].

use super::{check_timestamp, FrameReport, Pipeline, PipelineError};
use crate::clock::now_ms;
use crate::frame::{DecodeScratch, DepthSettings, FrameError, RgbdFrame};

impl Pipeline {
    /// Decodes colour and depth image bytes and processes the frame.
    pub fn push_png(
        &mut self,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.check_depth_png(depth);
        self.decode_and_push(timestamp, |frame, settings, scratch| {
            frame.decode_into(colour, depth, settings, scratch)
        })
    }

    /// Processes a frame whose colour was decoded by the caller (RGBA8 or
    /// RGB8 pixels, `width` x `height`: a browser decodes colour PNGs and
    /// JPEGs faster than wasm) with a 16-bit depth PNG decoded here (a
    /// browser would reduce it to 8 bits). `decode_ms` counts the depth.
    pub fn push_rgba_depth_png(
        &mut self,
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u8],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.check_depth_png(depth);
        self.decode_and_push(timestamp, |frame, settings, scratch| {
            frame.decode_rgba_depth_png_into(width, height, colour, depth, settings, scratch)
        })
    }

    /// Processes a frame given as buffers: `colour` RGBA8 or RGB8 and
    /// `depth` in raw units (`config.depth.scale` per metre, 0 = none), both
    /// row-major `width` x `height` (see [`RgbdFrame::from_raw`]).
    pub fn push_raw(
        &mut self,
        width: usize,
        height: usize,
        colour: &[u8],
        depth: &[u16],
        timestamp: f64,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        if depth.len() == width * height {
            self.check_depth_raw(depth);
        }
        let frame = RgbdFrame::from_raw(width, height, colour, depth, &self.config.depth)?;
        self.push_frame(&frame, timestamp)
    }

    /// Runs `decode` into the reused frame buffers, then [`Pipeline::push_frame`];
    /// the report's `decode_ms` is `decode`'s time.
    fn decode_and_push(
        &mut self,
        timestamp: f64,
        decode: impl FnOnce(
            &mut RgbdFrame,
            &DepthSettings,
            &mut DecodeScratch,
        ) -> Result<(), FrameError>,
    ) -> Result<FrameReport, PipelineError> {
        self.decoded_was_pushed = false;
        check_timestamp(timestamp)?;
        let t0 = now_ms();
        // Decoded into buffers kept from frame to frame; taken out of `self`
        // for the call below and put back whatever its outcome.
        let mut frame = std::mem::take(&mut self.decoded);
        let decoded = decode(&mut frame, &self.config.depth, &mut self.scratch);
        let decode_ms = now_ms() - t0;
        let pushed = decoded
            .map_err(PipelineError::from)
            .and_then(|()| self.push_frame(&frame, timestamp));
        self.decoded = frame;
        self.decoded_was_pushed = pushed.is_ok();
        let mut report = pushed?;
        report.timings.decode_ms = decode_ms;
        report.timings.total_ms += decode_ms;
        Ok(report)
    }

    /// Processes a frame the caller decoded (a dataset frame's files, see
    /// `dataset::decode_frame_bytes`): `decoded` is the decode's outcome, an
    /// error handed back as it is. An accepted frame is kept afterwards as
    /// [`Pipeline::last_decoded_frame`] (the page's depth preview) like the
    /// frames of [`Self::push_png`]; after a refused one (its decode or its
    /// push) there is none. Otherwise a refusal changes nothing.
    pub fn push_decoded<E: From<PipelineError>>(
        &mut self,
        decoded: Result<RgbdFrame, E>,
        timestamp: f64,
    ) -> Result<FrameReport, E> {
        self.decoded_was_pushed = false;
        let frame = decoded?;
        let report = self.push_frame(&frame, timestamp)?;
        self.decoded = frame;
        self.decoded_was_pushed = true;
        Ok(report)
    }
}
