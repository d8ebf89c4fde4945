// A Stray Scanner scan's colour, decoded from its rgb.mp4 by the browser
// (WebCodecs' VideoDecoder; an iPhone records HEVC, which some browsers
// decode and others do not): one video frame per depth frame, frame i the
// i-th in presentation order, drawn at the depth's size and handed to wasm as
// a PNG, as the CLI reads an `rgb/` folder of extracted frames. Used by the
// frame reader (or the SLAM worker when the reader cannot start); the SLAM
// worker asks colourOfScan when a scan opens, and plays on depth alone when
// the browser cannot decode the video.
import { parseMp4 } from './mp4.js';

/** Whether this context has WebCodecs' video decoder and a canvas to draw its frames on. */
const canDecodeVideo = () => typeof VideoDecoder === 'function' && typeof OffscreenCanvas === 'function';

const decoderConfig = (video) => ({ codec: video.codec, description: video.description, codedWidth: video.width, codedHeight: video.height, optimizeForLatency: true });

/**
 * `{codec, width, height, frames}` of MP4 `bytes` when this browser can
 * decode its video; otherwise throws an Error saying why (not an MP4 file,
 * no WebCodecs, a codec the browser does not decode).
 */
export async function probeVideo(bytes) {
  const video = parseMp4(new Uint8Array(bytes));
  if (!canDecodeVideo()) throw new Error('this browser has no video decoder (WebCodecs)');
  const support = await VideoDecoder.isConfigSupported(decoderConfig(video)).catch(() => ({ supported: false }));
  if (!support.supported) throw new Error(`this browser cannot decode ${video.codec} video`);
  return { codec: video.codec, width: video.width, height: video.height, frames: video.samples.length };
}

/**
 * Where a sequence without colour images (a Stray Scanner scan) gets its
 * colour: `{video, note}`, `video` the path of its rgb.mp4 (beside depth/)
 * when this browser decodes it, else null; `note` says which, or why the
 * scan plays on depth alone (null for a sequence with colour images).
 * `source` a SequenceSource or ArchiveSource holding `paths`.
 */
export async function colourOfScan(frames, paths, source) {
  if (!frames.length || frames.some((f) => f.colour != null)) return { video: null, note: null };
  const folder = frames[0].depth.split('/').slice(0, -2).join('/');
  const path = folder ? `${folder}/rgb.mp4` : 'rgb.mp4';
  const alone = 'playing on depth alone (grey map)';
  if (!paths.includes(path)) return { video: null, note: `no colour images or rgb.mp4: ${alone}` };
  try {
    const video = await probeVideo(await source.read(path));
    const past = video.frames < frames.length ? `; the ${frames.length - video.frames} frames past its end on depth alone` : '';
    return { video: path, note: `colour from ${path} (${video.codec}, ${video.width}x${video.height}, ${video.frames} frames)${past}` };
  } catch (e) {
    return { video: null, note: `${path}: ${e && e.message ? e.message : String(e)}: ${alone}` };
  }
}

/** Width and height of a PNG's bytes (its IHDR), or null. */
export function pngSize(bytes) {
  const b = new Uint8Array(bytes, 0, Math.min(bytes.byteLength, 24));
  if (b.length < 24 || b[0] !== 0x89 || b[1] !== 0x50) return null;
  const view = new DataView(b.buffer, b.byteOffset, 24);
  return [view.getUint32(16), view.getUint32(20)];
}

/** Frames decoded past the one asked for before the decoder is sent back to a key frame instead. */
const SKIP_AHEAD = 120;

/** The decoded frames of one video, asked for in (mostly) increasing order. */
export class VideoColour {
  /** @param bytes the MP4 file's bytes (a Uint8Array) */
  constructor(bytes) {
    this.bytes = bytes;
    this.video = parseMp4(bytes);
    const { samples } = this.video;
    this.decodeIndex = new Array(samples.length); // rank -> decode index
    samples.forEach((s, i) => (this.decodeIndex[s.rank] = i));
    this.size = null; // [width, height] the frames are drawn at (the depth's)
    this.ready = new Map(); // rank -> promise of its ImageBitmap, at `size`
    this.delivered = new Set(); // ranks output since the decoder (re)started
    this.wanted = 0; // the rank draw() waits for: earlier ones are not drawn
    this.queue = Promise.resolve(); // the last png() call's drawing
    this.canvas = null;
    this.decoder = null;
    this.error = null;
  }

  /** Frames in the video. */
  get frames() {
    return this.video.samples.length;
  }

  /** A fresh decoder fed from decode index `from` (a key frame). */
  start(from) {
    if (this.decoder && this.decoder.state !== 'closed') this.decoder.close();
    for (const bitmap of this.ready.values()) bitmap.then((b) => b.close(), () => {});
    this.ready.clear();
    this.delivered.clear();
    this.error = null;
    let fail;
    this.failed = new Promise((_, reject) => (fail = reject));
    this.failed.catch(() => {});
    this.decoder = new VideoDecoder({
      output: (frame) => {
        const rank = frame.timestamp;
        this.delivered.add(rank);
        if (!this.size || rank < this.wanted || this.ready.has(rank)) {
          frame.close();
          return;
        }
        const [resizeWidth, resizeHeight] = this.size;
        const bitmap = createImageBitmap(frame, { resizeWidth, resizeHeight, resizeQuality: 'medium' }).finally(() => frame.close());
        bitmap.catch(() => {});
        this.ready.set(rank, bitmap);
      },
      error: (e) => {
        this.error = new Error(`the video decoder failed: ${e.message}`);
        fail(this.error);
      },
    });
    this.decoder.configure(decoderConfig(this.video));
    this.next = from;
    this.from = from;
    this.flushed = null;
  }

  /** The key frame at or before decode index `d`, one more back where there is one (a frame may lean on the group before its key frame). */
  keyBefore(d) {
    const keys = [];
    for (let i = d; i >= 0 && keys.length < 2; i--) if (this.video.samples[i].key) keys.push(i);
    return keys.length ? keys[keys.length - 1] : 0;
  }

  /** Sends the next sample to the decoder. */
  feed() {
    const s = this.video.samples[this.next++];
    const data = this.bytes.subarray(s.offset, s.offset + s.size);
    this.decoder.decode(new EncodedVideoChunk({ type: s.key ? 'key' : 'delta', timestamp: s.rank, data }));
  }

  /** Resolves once the decoder has taken what it was given (or rejects when it fails). */
  taken() {
    if (this.decoder.decodeQueueSize === 0) return Promise.resolve();
    const dequeued = new Promise((resolve) => this.decoder.addEventListener('dequeue', resolve, { once: true }));
    return Promise.race([dequeued, this.failed]);
  }

  /**
   * Frame `index` (presentation order) drawn at `width` x `height`, as PNG
   * bytes (an ArrayBuffer). Rejects when the video has no such frame or the
   * decoder fails. Calls are served one after the other, in the order made
   * (the frame feed asks for the next frames before the current one is in).
   */
  png(index, size) {
    const drawn = this.queue.then(() => this.draw(index, size));
    this.queue = drawn.catch(() => {});
    return drawn;
  }

  /** What `png` resolves to; one call at a time. */
  async draw(index, [width, height]) {
    if (!(index >= 0 && index < this.frames)) throw new Error(`it has ${this.frames} frames, not a frame ${index}`);
    const d = this.decodeIndex[index];
    const sized = this.size !== null && this.size[0] === width && this.size[1] === height;
    this.size = [width, height];
    this.wanted = index;
    // Back to a key frame: a new size, a failed decoder, a frame already
    // passed (a replay) or far ahead (a continued session).
    const passed = this.delivered.has(index) || d < this.from;
    if (!sized || this.error || (!this.ready.has(index) && (passed || d > this.next + SKIP_AHEAD))) this.start(this.keyBefore(d));
    while (!this.ready.has(index)) {
      if (this.error) throw this.error;
      if (this.next < this.frames) {
        this.feed();
        await this.taken();
      } else {
        this.flushed ??= this.decoder.flush();
        await Promise.race([this.flushed, this.failed]);
        if (!this.ready.has(index)) throw new Error(`frame ${index} did not come out of the decoder`);
      }
    }
    const bitmap = await this.ready.get(index);
    for (const [rank, older] of this.ready) {
      if (rank <= index) {
        this.ready.delete(rank);
        if (rank < index) older.then((b) => b.close(), () => {});
      }
    }
    try {
      this.canvas ??= new OffscreenCanvas(width, height);
      if (this.canvas.width !== width || this.canvas.height !== height) [this.canvas.width, this.canvas.height] = [width, height];
      this.canvas.getContext('2d').drawImage(bitmap, 0, 0);
      return await (await this.canvas.convertToBlob({ type: 'image/png' })).arrayBuffer();
    } finally {
      bitmap.close();
    }
  }
}

/** The VideoColour of `path` in `source` (a SequenceSource or ArchiveSource), opened once per source. */
export function videoOf(source, path) {
  source.videos ??= new Map();
  let opening = source.videos.get(path);
  if (!opening) {
    opening = source.read(path).then((bytes) => new VideoColour(new Uint8Array(bytes)));
    opening.catch(() => {});
    source.videos.set(path, opening);
  }
  return opening;
}
