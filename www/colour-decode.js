// Colour images decoded by the browser (its PNG and JPEG decoders run off the
// calling thread and are faster than decoding in wasm). Used by the worker;
// DOM-free, so it works in a worker and on the page alike.
//
// The pixels are the file's own: no colour-space conversion, no alpha
// premultiplication, RGBA8 row-major. Depth stays a 16-bit PNG decoded in
// wasm: browsers reduce 16-bit PNGs to 8 bits.
import { pngSize, videoOf } from './video-colour.js';

/** Whether this context can decode images without a DOM. */
export const browserCanDecode = typeof createImageBitmap === 'function' && typeof OffscreenCanvas === 'function';

let canvas = null;
let context = null;

/** Size of the page's colour thumbnail (views.js draws it scaled to its canvas). */
export const PREVIEW_WIDTH = 192;
export const PREVIEW_HEIGHT = 144;

/**
 * Why the browser's decode of these bytes would differ from the wasm
 * decoder's, or null. 16-bit PNGs are reduced to 8 bits by rounding rules of
 * the browser's own; wasm keeps the reference conversion.
 */
export function browserDecodeCaveat(bytes) {
  const b = new Uint8Array(bytes, 0, Math.min(bytes.byteLength, 32));
  const png = b.length >= 29 && b[0] === 0x89 && b[1] === 0x50 && b[2] === 0x4e && b[3] === 0x47;
  if (png && b[24] === 16) return '16-bit colour PNG';
  return null;
}

/**
 * Decodes colour image bytes (PNG, JPEG) into `{ width, height, rgba }`
 * (`rgba` a Uint8ClampedArray, 4 bytes a pixel), plus `preview`, a
 * PREVIEW_WIDTH x PREVIEW_HEIGHT ImageBitmap of it when `preview` is true
 * (the page's thumbnail: no second decode on the page). Rejects when the
 * browser cannot decode them, or when a pixel is not opaque: the canvas that
 * reads the pixels back stores premultiplied alpha, which would change the
 * colour of translucent pixels (the wasm decoder ignores alpha).
 */
export async function decodeColour(bytes, { preview = false } = {}) {
  const caveat = browserDecodeCaveat(bytes);
  if (caveat) throw new Error(`${caveat}: decoded in wasm`);
  const bitmap = await createImageBitmap(new Blob([bytes]), {
    colorSpaceConversion: 'none',
    premultiplyAlpha: 'none',
  });
  try {
    const { width, height } = bitmap;
    if (!canvas) {
      canvas = new OffscreenCanvas(width, height);
      context = canvas.getContext('2d', { willReadFrequently: true, alpha: true });
    } else if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width; // resets the context's state
      canvas.height = height;
    }
    context.globalCompositeOperation = 'copy'; // replace, never blend with the last image
    context.drawImage(bitmap, 0, 0);
    const rgba = context.getImageData(0, 0, width, height).data;
    if (!opaque(rgba)) throw new Error('translucent pixels: decoded in wasm');
    const thumbnail = preview
      ? await createImageBitmap(bitmap, { resizeWidth: PREVIEW_WIDTH, resizeHeight: PREVIEW_HEIGHT, resizeQuality: 'medium' })
      : null;
    return { width, height, rgba, preview: thumbnail };
  } finally {
    bitmap.close();
  }
}

const LITTLE_ENDIAN = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;

/** Whether every alpha byte of RGBA8 pixels is 255. */
function opaque(rgba) {
  if (LITTLE_ENDIAN && rgba.byteOffset % 4 === 0) {
    // A word a pixel, alpha in its high byte: AND them all, look at alpha once.
    const words = new Uint32Array(rgba.buffer, rgba.byteOffset, rgba.length >> 2);
    let all = -1;
    for (let i = 0; i < words.length; i++) all &= words[i];
    return all >>> 24 === 255;
  }
  for (let i = 3; i < rgba.length; i += 4) if (rgba[i] !== 255) return false;
  return true;
}

/**
 * Whether a frame is pushed as its files (Slam.pushFiles, decoded in wasm as
 * the CLI reads them): a depth-only frame (no colour image) or one with a
 * confidence image (Stray Scanner: colour of another size than depth, low
 * confidence dropped).
 */
export const pushedAsFiles = (frame) => frame.colour == null || frame.confidence != null;

/**
 * Reads a frame's files from a SequenceSource and decodes its colour image:
 * `{ colourBuf, depthBuf, confidenceBuf, decoded, videoError }`, `decoded` =
 * `{ width, height, rgba }` or null when wasm is to decode the colour (the
 * browser could not, or not exactly; pushFrame then decodes it or says what
 * is wrong with it, or the frame is pushed as its files); `colourBuf` null
 * for a depth-only frame, `confidenceBuf` null without a confidence image.
 * `video` (`{path, index}`, a frame without a colour image): its colour is
 * frame `index` of that video, drawn at the depth's size as a PNG
 * (video-colour.js); when it cannot be, the frame stays depth-only and
 * `videoError` says why. Rejects only when a file cannot be read.
 */
export async function readAndDecodeColour(source, { colour, depth, confidence, video }, decode = true) {
  let [colourBuf, depthBuf, confidenceBuf] = await Promise.all([
    colour == null ? null : source.read(colour),
    source.read(depth),
    confidence == null ? null : source.read(confidence),
  ]);
  let videoError = null;
  if (video && colour == null) {
    try {
      const size = pngSize(depthBuf);
      if (!size) throw new Error(`${depth} is not a PNG`);
      colourBuf = await (await videoOf(source, video.path)).png(video.index, size);
    } catch (e) {
      videoError = `${video.path}: ${e && e.message ? e.message : String(e)}`;
    }
  }
  if (videoError) return { colourBuf, depthBuf, confidenceBuf, decoded: null, videoError };
  let decoded = null;
  if (decode && browserCanDecode && colourBuf && !pushedAsFiles({ colour, confidence })) {
    try {
      decoded = await decodeColour(colourBuf, { preview: true });
    } catch {
      decoded = null;
    }
  }
  return { colourBuf, depthBuf, confidenceBuf, decoded, videoError };
}
