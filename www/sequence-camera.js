// The camera a newly opened sequence plays with: its layout's preset, the
// folder's own calibration where it has one (RealSense, Stray Scanner), and
// otherwise the preset at the size of the folder's frames.

import { isModuleFailure, toPlain } from './wasm-module.js';

/** A preset given by name or as an object (parseSequence's `preset`): its name. */
const presetName = (p) => (typeof p === 'string' ? p : p?.name ?? null);

/**
 * The Slam config keys of the camera of `parsed` (parseSequence's result),
 * whose files `source` reads: `{ preset, ...intrinsics }`.
 */
export async function sequenceCamera(wasm, parsed, source) {
  const preset = presetName(parsed.preset);
  const config = { preset };
  if (parsed.preset && typeof parsed.preset === 'object') Object.assign(config, parsed.preset);
  delete config.name;
  config.preset = preset;
  // RealSense and Stray Scanner folders carry their own calibration: it wins over the preset's.
  if (parsed.intrinsics) return Object.assign(config, parsed.intrinsics);
  return Object.assign(config, await presetAtFrameSize(wasm, preset, parsed.frames, source));
}

/**
 * The preset's camera for the size of the first frame's depth image: a
 * recording resized from the preset's size plays with its calibration
 * scaled (the library's Intrinsics::for_image_size). Nothing when the image
 * cannot be read: the frames are then refused one by one, each with its error.
 */
async function presetAtFrameSize(wasm, preset, frames, source) {
  const depth = frames[0]?.depth;
  if (!depth) return {};
  try {
    const p = toPlain(wasm.presetForDepthImage(preset, new Uint8Array(await source.read(depth))));
    const { fx, fy, cx, cy, width, height } = p;
    return { fx, fy, cx, cy, width, height };
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return {};
  }
}
