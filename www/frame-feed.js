// The SLAM worker's supply of frames: each frame's files read and its colour
// image decoded by the browser ahead of the frame wasm is working on. The
// reading runs in frame-reader.js's worker when it can start (see there why);
// otherwise on the SLAM worker's own thread. Used by worker.js only.
import { ToReader } from './protocol.js';
import { readAndDecodeColour } from './colour-decode.js';

const PREFETCH_FRAMES = 3; // frames read and decoded ahead of the one in wasm
// The frame reader reads files further ahead, READ_BATCH frames at a time,
// at most 2 * READ_BATCH frames ahead (about 20 MB of PNGs at 640x480).
const READ_BATCH = 16;

export class FrameFeed {
  /** `decodeColour`: whether the browser decodes colour (false: wasm decodes it, pushFrame). */
  constructor(decodeColour) {
    this.decodeColour = decodeColour;
    this.reader = null; // the frame reader's Worker; null: read on this thread
    this.waiting = new Map(); // `${id}:${index}` -> {resolve, reject, source, frame}
    this.prefetched = new Map(); // `${id}:${index}` -> promise of the frame's bytes and decoded colour
    this.readAheadUntil = 0; // frames before this index have been asked for
    this.seq = null; // {id, source, frames, video}
  }

  /** Starts the frame reader's worker; without one, frames are read on this thread. */
  startReader() {
    if (typeof Worker !== 'function') return;
    try {
      this.reader = new Worker(new URL('./frame-reader.js', import.meta.url), { type: 'module' });
    } catch {
      this.reader = null;
      return;
    }
    this.reader.onmessage = ({ data }) => {
      const key = `${data.id}:${data.index}`;
      const waiting = this.waiting.get(key);
      if (!waiting) return; // the sequence was replaced or reset meanwhile
      this.waiting.delete(key);
      if (data.error !== undefined) waiting.reject(new Error(data.error));
      else waiting.resolve({ colourBuf: data.colourBuf, depthBuf: data.depthBuf, confidenceBuf: data.confidenceBuf ?? null, decoded: data.decoded, videoError: data.videoError ?? null });
    };
    this.reader.onerror = (e) => {
      // The reader cannot run (or died): read on this thread from now on.
      e.preventDefault?.();
      this.reader?.terminate();
      this.reader = null;
      for (const [key, w] of this.waiting) {
        this.waiting.delete(key);
        readAndDecodeColour(w.source, w.request, this.decodeColour).then(w.resolve, w.reject);
      }
    };
  }

  /** Whether frames are read by the frame reader's worker. */
  get inReader() {
    return this.reader !== null;
  }

  /**
   * A new sequence: `entries` as for openSource, `source` opened on this
   * thread, `frames` parseSequence's; `video` the path of the video that
   * colours its frames without a colour image (a Stray Scanner rgb.mp4 the
   * browser decodes), or null.
   */
  setSequence(id, entries, source, frames, video = null) {
    this.seq = { id, source, frames, video };
    this.waiting.clear();
    this.restart();
    this.reader?.postMessage({ type: ToReader.SOURCE, id, entries });
  }

  /** Back to frame 0: forget what was read ahead. */
  restart() {
    this.prefetched.clear();
    this.readAheadUntil = 0;
  }

  /** Promise of frame `index`'s `{colourBuf, depthBuf, decoded}`; starts reading the frames after it. */
  read(index) {
    const key = `${this.seq.id}:${index}`;
    let reading = this.prefetched.get(key);
    if (reading) this.prefetched.delete(key);
    else reading = this.load(index);
    this.prefetch(index);
    return reading;
  }

  /** Starts reading (and decoding) the frames after `index` that are not under way yet. */
  prefetch(index) {
    this.readAhead(index);
    for (let i = index + 1; i <= index + PREFETCH_FRAMES && i < this.seq.frames.length; i++) {
      const key = `${this.seq.id}:${i}`;
      if (!this.prefetched.has(key)) this.prefetched.set(key, this.load(i));
    }
  }

  /** Has the reader read the next batch of files once fewer than READ_BATCH frames are left read ahead of `index`. */
  readAhead(index) {
    if (!this.reader || this.readAheadUntil > index + READ_BATCH) return;
    const from = Math.max(this.readAheadUntil, index + 1);
    const to = Math.min(this.seq.frames.length, index + 1 + 2 * READ_BATCH);
    if (from >= to) return;
    const paths = this.seq.frames
      .slice(from, to)
      .flatMap((f) => [f.colour, f.depth, f.confidence])
      .filter((p) => p != null);
    this.reader.postMessage({ type: ToReader.READ_AHEAD, id: this.seq.id, paths });
    this.readAheadUntil = to;
  }

  load(index) {
    const { id, source, frames, video } = this.seq;
    const { colour, depth, confidence } = frames[index];
    // Frame i of the video colours frame i of a sequence without colour images.
    const request = { colour, depth, confidence: confidence ?? null, video: video && colour == null ? { path: video, index } : null };
    let promise;
    if (this.reader) {
      promise = new Promise((resolve, reject) => this.waiting.set(`${id}:${index}`, { resolve, reject, source, request }));
      this.reader.postMessage({ type: ToReader.READ, id, index, ...request, decode: this.decodeColour });
    } else {
      promise = readAndDecodeColour(source, request, this.decodeColour);
    }
    promise.catch(() => {}); // handled by whoever awaits it
    return promise;
  }
}

/** Names the file concerned in an error from pushFrame. */
export function describeFrameError(frame, message) {
  if (message.includes(frame.depth) || message.includes(frame.colour)) return message;
  // The module's messages start with what they are about ("depth image must be ...").
  const head = message.trimStart().toLowerCase();
  if (head.startsWith('depth')) return `${frame.depth}: ${message}`;
  if (head.startsWith('colour') || head.startsWith('color')) return `${frame.colour}: ${message}`;
  const depth = /depth/i.test(message);
  const colour = /colou?r/i.test(message);
  if (depth && !colour) return `${frame.depth}: ${message}`;
  if (colour && !depth) return `${frame.colour}: ${message}`;
  return `${frame.colour} + ${frame.depth}: ${message}`;
}
