// Small live views of the current input: the colour image and the depth image
// colour-mapped (near = warm, far = cool, no measurement = black).
//
// Both are decoded by the browser (createImageBitmap, off the main thread);
// the colour view usually draws the thumbnail the frame reader made while
// decoding the frame for SLAM (no second decode).
// The depth view shows the thumbnail wasm made of the frame it decoded
// (metres, full precision). Frames wasm refused are shown from their PNG
// bytes instead: a 16-bit depth PNG decodes to 8 bits per channel in the
// browser (the high byte), a resolution of 256 raw units (~5 cm at 5000
// units/m), enough for a preview.

const VIEW_W = 192;
const VIEW_H = 144;

function turbo(x) {
  // Polynomial fit of Google's Turbo colour map (x in 0..1) -> [r, g, b] 0..255.
  x = Math.min(1, Math.max(0, x));
  const r = 0.13572138 + x * (4.6153926 + x * (-42.66032258 + x * (132.13108234 + x * (-152.94239396 + x * 59.28637943))));
  const g = 0.09140261 + x * (2.19418839 + x * (4.84296658 + x * (-14.18503333 + x * (4.27729857 + x * 2.82956604))));
  const b = 0.1066733 + x * (12.64194608 + x * (-60.58204836 + x * (110.36276771 + x * (-89.90310912 + x * 27.34824973))));
  return [r * 255, g * 255, b * 255];
}

export class InputViews {
  constructor(colourCanvas, depthCanvas, depthLabel) {
    this.colour = colourCanvas;
    this.depth = depthCanvas;
    this.depthLabel = depthLabel;
    for (const c of [colourCanvas, depthCanvas]) {
      c.width = VIEW_W;
      c.height = VIEW_H;
    }
    this.colourCtx = colourCanvas.getContext('2d');
    this.depthCtx = depthCanvas.getContext('2d', { willReadFrequently: true });
    this.busy = false;
    this.pending = null;
    this.range = [0.3, 4.0];
    this.lut = new Uint8ClampedArray(256 * 3);
    this.depthScale = 0;
    this.metreLut = null; // 256 colours over the depth range, for thumbnails in metres
    this.depthImage = this.depthCtx.createImageData(VIEW_W, VIEW_H);
  }

  /** Shows the thumbnails at the aspect of `width` x `height` frames (an 848x480 RealSense recording is 16:9). */
  setAspect(width, height) {
    const aspect = width > 0 && height > 0 ? `${width} / ${height}` : '4 / 3';
    for (const c of [this.colour, this.depth]) c.style.aspectRatio = aspect;
  }

  setDepthRange(min, max) {
    this.range = [min, max];
    this.depthScale = 0; // rebuild the lookup tables
    this.metreLut = null;
  }

  buildLut(depthScale) {
    const [lo, hi] = this.range;
    for (let v = 0; v < 256; v++) {
      const metres = ((v + 0.5) * 256) / depthScale;
      const rgb = v === 0 ? [0, 0, 0] : turbo(1 - (metres - lo) / (hi - lo));
      this.lut.set(rgb, v * 3);
    }
    this.depthScale = depthScale;
    if (this.depthLabel) this.depthLabel.textContent = `depth ${lo.toFixed(1)}-${hi.toFixed(1)} m`;
  }

  /**
   * Shows one frame's input (PNG bytes; `colourPreview`, when given, an
   * ImageBitmap of the colour image that is drawn instead of decoding the
   * bytes again). Drops frames while a decode is in flight.
   */
  show(colourBytes, depthBytes, depthScale = 5000, flow = null, colourPreview = null, depthPreview = null) {
    this.pending?.colourPreview?.close(); // dropped: free its pixels now
    this.pending = { colourBytes, depthBytes, depthScale: depthScale || 5000, flow, colourPreview, depthPreview };
    if (!this.busy) this.drain();
  }

  async drain() {
    this.busy = true;
    while (this.pending) {
      const { colourBytes, depthBytes, depthScale, flow, colourPreview, depthPreview } = this.pending;
      this.pending = null;
      const colour = colourPreview
        ? this.drawPreview(colourPreview)
        : colourBytes
          ? this.drawColour(colourBytes)
          : this.placeholder(this.colourCtx, 'depth only');
      const depth = depthPreview?.metres?.length === VIEW_W * VIEW_H ? this.drawDepthMetres(depthPreview.metres) : this.drawDepth(depthBytes, depthScale);
      await Promise.all([colour, depth]);
      // The thumbnail without the tracks, to take them off when the overlay is switched off.
      this.colourWithoutFlow = flow ? this.colourCtx.getImageData(0, 0, VIEW_W, VIEW_H) : null;
      if (flow) this.drawFlow(flow);
    }
    this.busy = false;
  }

  /** Takes the flow tracks off the colour thumbnail shown (the overlay was switched off while stopped). */
  hideFlow() {
    if (this.colourWithoutFlow) this.colourCtx.putImageData(this.colourWithoutFlow, 0, 0);
    this.colourWithoutFlow = null;
  }

  // Lucas-Kanade tracks from the previous frame: a line per track, a dot at its end.
  drawFlow({ tracks, width, height }) {
    if (!tracks?.length || !width || !height) return;
    const ctx = this.colourCtx;
    const sx = VIEW_W / width;
    const sy = VIEW_H / height;
    ctx.save();
    ctx.strokeStyle = '#3f3';
    ctx.fillStyle = '#ff3';
    ctx.lineWidth = 1;
    ctx.beginPath();
    for (let i = 0; i + 3 < tracks.length; i += 4) {
      ctx.moveTo(tracks[i] * sx, tracks[i + 1] * sy);
      ctx.lineTo(tracks[i + 2] * sx, tracks[i + 3] * sy);
    }
    ctx.stroke();
    for (let i = 0; i + 3 < tracks.length; i += 4) ctx.fillRect(tracks[i + 2] * sx - 1, tracks[i + 3] * sy - 1, 2, 2);
    ctx.restore();
  }

  drawPreview(bitmap) {
    this.colourCtx.drawImage(bitmap, 0, 0, VIEW_W, VIEW_H);
    bitmap.close();
  }

  async drawColour(bytes) {
    try {
      const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }), {
        resizeWidth: VIEW_W,
        resizeHeight: VIEW_H,
        resizeQuality: 'medium',
      });
      this.colourCtx.drawImage(bitmap, 0, 0);
      bitmap.close();
    } catch {
      this.placeholder(this.colourCtx, 'cannot decode');
    }
  }

  /** Draws a VIEW_W x VIEW_H thumbnail of depths in metres (0 = none). */
  drawDepthMetres(metres) {
    const [lo, hi] = this.range;
    if (!this.metreLut) {
      this.metreLut = new Uint8ClampedArray(256 * 3);
      for (let v = 0; v < 256; v++) this.metreLut.set(turbo(1 - (v + 0.5) / 256), v * 3);
      if (this.depthLabel) this.depthLabel.textContent = `depth ${lo.toFixed(1)}-${hi.toFixed(1)} m`;
    }
    const lut = this.metreLut;
    const px = this.depthImage.data;
    const perMetre = 256 / (hi - lo);
    for (let i = 0, p = 0; i < metres.length; i++, p += 4) {
      const m = metres[i];
      if (m > 0) {
        const v = 3 * Math.min(255, Math.max(0, Math.floor((m - lo) * perMetre)));
        px[p] = lut[v];
        px[p + 1] = lut[v + 1];
        px[p + 2] = lut[v + 2];
      } else {
        px[p] = px[p + 1] = px[p + 2] = 0;
      }
      px[p + 3] = 255;
    }
    this.depthCtx.putImageData(this.depthImage, 0, 0);
  }

  async drawDepth(bytes, depthScale) {
    try {
      const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }), {
        resizeWidth: VIEW_W,
        resizeHeight: VIEW_H,
        resizeQuality: 'pixelated',
        colorSpaceConversion: 'none',
        premultiplyAlpha: 'none',
      });
      if (depthScale !== this.depthScale) this.buildLut(depthScale);
      const ctx = this.depthCtx;
      ctx.drawImage(bitmap, 0, 0);
      bitmap.close();
      const image = ctx.getImageData(0, 0, VIEW_W, VIEW_H);
      const px = image.data;
      for (let i = 0; i < px.length; i += 4) {
        const v = px[i] * 3;
        px[i] = this.lut[v];
        px[i + 1] = this.lut[v + 1];
        px[i + 2] = this.lut[v + 2];
        px[i + 3] = 255;
      }
      ctx.putImageData(image, 0, 0);
    } catch {
      this.placeholder(this.depthCtx, 'cannot decode');
    }
  }

  placeholder(ctx, text) {
    ctx.fillStyle = '#222';
    ctx.fillRect(0, 0, VIEW_W, VIEW_H);
    ctx.fillStyle = '#f66';
    ctx.font = '14px sans-serif';
    ctx.fillText(text, 10, VIEW_H / 2);
  }

  clear() {
    this.colourWithoutFlow = null;
    for (const ctx of [this.colourCtx, this.depthCtx]) {
      ctx.fillStyle = '#111';
      ctx.fillRect(0, 0, VIEW_W, VIEW_H);
    }
  }
}
