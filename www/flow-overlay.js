// Lucas-Kanade tracks between consecutive colour images, for the live view's
// overlay (the worker's OpticalFlow object); only computed while the page
// asks for them. An overlay is never worth an error message: a frame whose
// tracks fail gets none, unless the module itself failed.
import { isModuleFailure } from './wasm-module.js';

export class FlowOverlay {
  constructor() {
    this.enabled = false;
    this.flow = null;
  }

  /** Tracks into `colour` ({ tracks, width, height }), or null when off or failed. */
  tracks(wasm, colour, decoded) {
    if (!this.enabled) return null;
    try {
      this.flow ??= new wasm.OpticalFlow(300);
      const tracks = decoded
        ? this.flow.pushRgba(decoded.width, decoded.height, decoded.rgba)
        : this.flow.pushPng(colour);
      const [width, height] = this.flow.imageSize;
      return { tracks, width, height };
    } catch (e) {
      if (isModuleFailure(e)) throw e;
      return null;
    }
  }

  /** Frees the tracker (run in the worker's job order: it calls into the module). */
  free() {
    this.flow?.free();
    this.flow = null;
  }

  /** The module failed: its objects are dropped, not freed (free() would throw too). */
  drop() {
    this.flow = null;
  }
}
