// Web Worker: owns the wasm module and the Slam instance; runs the frame loop
// (read files, decode the colour image in the browser -> pushRgbaDepthPng:
// decode depth, track, fuse) and posts each result with a copy of the changed
// surfel range (transferred, not cloned). The next frames' files are read and
// their colour decoded by a worker of this worker's (frame-reader.js) while
// wasm works on the current one; where it cannot start, on this thread.
// A colour image the browser cannot decode (or not exactly: translucent or
// 16-bit) goes to pushFrame, which decodes both images in wasm and names the
// problem when there is one.
//
// A failure of the module itself (a trap: a panic in Rust; or an object left
// poisoned by one) stops playback and is reported as MODULE_FAILED; the next
// action that needs the map starts a fresh instance of the module and a new
// Slam. Until then the page serves the downloads from its own copy of what
// it was sent (map-mirror.js).
//
// Messages: ToWorker and FromWorker in protocol.js.
import { ToWorker, FromWorker, ToReader } from './protocol.js';
import { openSource } from './sequence.js';
import { parseGlb } from './mesh-view.js';
import { readAndDecodeColour, PREVIEW_WIDTH, PREVIEW_HEIGHT } from './colour-decode.js';

let wasm = null;
let moduleKind = null;
let threads = 1;
let slam = null;
let config = null; // Slam config currently in use
let seq = null; // { id, name, kind, source, frames, gtTum }
let seqCounter = 0;
let next = 0; // index of the next frame to process
let playing = false;
let pumping = false;
const prefetch = new Map(); // `${seq.id}:${index}` -> promise of the frame's bytes and decoded colour
const PREFETCH_FRAMES = 3; // frames read and decoded ahead of the one in wasm
// The frame reader reads files further ahead, READ_BATCH frames at a time,
// at most 2 * READ_BATCH frames ahead (about 20 MB of PNGs at 640x480).
const READ_BATCH = 16;
let readAheadUntil = 0; // frames before this index have been asked for
let framesOk = 0;
let surfelCount = 0; // the map's size after the last frame (read without calling into the module)
let failure = null; // {message}: the module failed; rebuilt at the next action that needs it
let instance = 0; // module instances started (a failed one is replaced, not reused)
let testBreak = false; // test hook: the next call into the module fails
let testHang = false; // test hook: the next frame never returns
const testHooks = new URL(self.location.href).searchParams.get('testHooks') === '1';
let refreshCursor = 0; // start of the next rolling refresh window (surfel index)
const REFRESH_SURFELS = 65536;

const post = (msg, transfer = []) => self.postMessage(msg, transfer);
const errorText = (e) => (e && e.message ? e.message : String(e));

/**
 * Whether an exception thrown by a call into the module means the module
 * (not the input) failed: a trap (a Rust panic aborts as `unreachable`), or
 * wasm-bindgen's guards on an object a trap left borrowed or freed.
 */
function isModuleFailure(e) {
  if (typeof WebAssembly !== 'undefined' && e instanceof WebAssembly.RuntimeError) return true;
  return /recursive use of an object|null pointer passed to rust|attempted to take ownership|unreachable|memory access out of bounds/i.test(
    errorText(e),
  );
}

/** The module failed: stop and say so (the page keeps what it was sent for the downloads). */
function fail(e) {
  playing = false;
  failure = { message: errorText(e) };
  // The poisoned objects are dropped, not freed (free() would throw too).
  slam = null;
  flow = null;
  post({ type: FromWorker.MODULE_FAILED, message: failure.message, frames: framesOk });
  reportState();
}

/** A download from the Slam; undefined when the module has failed (the page then uses its copy). */
function exportFrom(fromSlam) {
  if (failure) return undefined;
  if (!slam) return fromSlam(null);
  try {
    return fromSlam(slam);
  } catch (e) {
    if (!isModuleFailure(e)) throw e;
    fail(e);
    return undefined;
  }
}

/** A progress callback for exportMesh: posts MESH_PROGRESS at most every 5 %. */
function meshProgress(purpose) {
  let last = -1;
  return (fraction) => {
    if (fraction < 1 && fraction - last < 0.05) return;
    last = fraction;
    post({ type: FromWorker.MESH_PROGRESS, fraction, purpose });
  };
}

// All work touching the module runs one job at a time, in message order.
let chain = Promise.resolve();
function serial(job) {
  const run = chain.then(job);
  chain = run.catch((e) => {
    if (isModuleFailure(e)) {
      fail(e);
      return;
    }
    post({ type: FromWorker.FATAL, message: `internal error: ${errorText(e)}` });
    reportState();
  });
  return chain;
}

/**
 * Imports and instantiates the module. Each call makes a new instance (the
 * URL differs, so the import is a new module record): a module that trapped
 * may be left with its stack pointer or a lock wherever the trap hit.
 */
async function importModule(path) {
  const url = new URL(path, import.meta.url);
  if (instance > 0) url.searchParams.set('instance', String(instance));
  const m = await import(url.href);
  await m.default({ module_or_path: new URL(path.replace(/\.js$/, '_bg.wasm'), import.meta.url) });
  return m;
}

async function startModule(notes = []) {
  wasm = null;
  const forceSingle = new URL(self.location.href).searchParams.get('threads') === '0';
  if (forceSingle) {
    notes.push('threads=0 in the page URL: using the single-threaded SIMD module');
  } else if (self.crossOriginIsolated) {
    try {
      const m = await importModule('./pkg/threads/surfel_slam.js');
      const want = Math.max(1, navigator.hardwareConcurrency || 1);
      await m.initThreadPool(want);
      wasm = m;
      moduleKind = 'threads';
      threads = typeof m.threadCount === 'function' ? m.threadCount() : want;
    } catch (e) {
      notes.push(`threaded module unavailable (${errorText(e)}); using the single-threaded SIMD module`);
    }
  } else {
    notes.push('page is not cross-origin isolated: using the single-threaded SIMD module');
  }
  if (!wasm) {
    const m = await importModule('./pkg/surfel_slam.js');
    wasm = m;
    moduleKind = 'simd';
    threads = typeof m.threadCount === 'function' ? m.threadCount() : 1;
  }
  instance++;
  return notes;
}

/** After a failure: a fresh instance of the module (no Slam yet). */
async function freshModule() {
  if (!failure) return;
  await startModule();
  failure = null;
  testBreak = false;
}

/** Before an action on the map: after a failure, a fresh module and a new Slam on the same config, at frame 0. */
async function ensureSlam() {
  await freshModule();
  if (slam || !config) return;
  createSlam(config);
}

async function initModule() {
  const notes = await startModule();
  let presets = [];
  try {
    presets = toPlain(wasm.presets());
  } catch (e) {
    notes.push(`presets(): ${errorText(e)}`);
  }
  startReader();
  post({ type: FromWorker.READY, module: moduleKind, threads, presets, notes, frameReader: reader !== null });
}

/** Deep copy into plain JS values (wasm-bindgen may hand out Maps or class objects). */
function toPlain(v) {
  if (v instanceof Map) return Object.fromEntries([...v].map(([k, x]) => [k, toPlain(x)]));
  if (Array.isArray(v)) return v.map(toPlain);
  if (ArrayBuffer.isView(v)) return v.slice();
  if (v && typeof v === 'object') {
    const o = {};
    for (const k of Object.keys(v)) o[k] = toPlain(v[k]);
    return o;
  }
  return v;
}

const presetName = (p) => (typeof p === 'string' ? p : p?.name ?? null);

// Lucas-Kanade tracks between consecutive colour images, for the live
// view's overlay; only computed while the page asks for them.
let flow = null;
let flowEnabled = false;

function flowTracks(colour, decoded) {
  if (!flowEnabled) return null;
  try {
    flow ??= new wasm.OpticalFlow(300);
    const tracks = decoded ? flow.pushRgba(decoded.width, decoded.height, decoded.rgba) : flow.pushPng(colour);
    const [width, height] = flow.imageSize;
    return { tracks, width, height };
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return null; // an overlay is not worth an error message
  }
}

function createSlam(newConfig) {
  const fresh = new wasm.Slam(newConfig); // throws on a bad config: keep the old one
  if (slam) slam.free();
  slam = fresh;
  config = newConfig;
  restart();
}

/** Back to frame 0 with an empty map (the Slam already is). */
function restart() {
  next = 0;
  framesOk = 0;
  surfelCount = 0;
  refreshCursor = 0;
  prefetch.clear();
  readAheadUntil = 0;
}

/** Never calls into the module: it must work when the module has failed. */
function reportState(extra = {}) {
  post({
    type: FromWorker.STATE,
    playing,
    next,
    frameCount: seq ? seq.frames.length : 0,
    done: !!seq && next >= seq.frames.length,
    surfels: surfelCount,
    failed: failure !== null,
    ...extra,
  });
}

// ---- loading a sequence -----------------------------------------------------

async function load({ name, entries, autoplay, options }) {
  await freshModule();
  let source;
  try {
    source = await openSource(entries, async () => wasm); // a folder, or an archive read by wasm
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    post({ type: FromWorker.LOAD_ERROR, name, message: `${name}: ${errorText(e)}` });
    reportState();
    return;
  }
  const paths = source.paths;
  let parsed;
  try {
    const layout = toPlain(wasm.detectLayout(paths));
    const texts = {};
    // 7-Scenes' index files are its per-frame pose files: one that cannot be
    // read leaves its frame without ground truth, not the sequence unread.
    const optional = layout.kind === '7-scenes';
    for (const f of layout.indexFiles) texts[f] = await source.readText(f).catch((e) => (optional ? undefined : Promise.reject(e)));
    parsed = toPlain(wasm.parseSequence(paths, texts, name));
  } catch (e) {
    // Keep the current sequence and map: only a good sequence replaces them.
    if (isModuleFailure(e)) throw e;
    post({ type: FromWorker.LOAD_ERROR, name, message: `${name}: ${errorText(e)}` });
    reportState();
    return;
  }
  const preset = presetName(parsed.preset);
  const newConfig = { preset };
  if (parsed.preset && typeof parsed.preset === 'object') Object.assign(newConfig, parsed.preset);
  delete newConfig.name;
  newConfig.preset = preset;
  // The page's own choices (tracker, half resolution) carry over to a new sequence.
  for (const key of ['tracker', 'halfResolution']) if (options?.[key] !== undefined) newConfig[key] = options[key];
  try {
    createSlam(newConfig);
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    post({ type: FromWorker.LOAD_ERROR, name, message: `${name}: camera preset ${preset}: ${errorText(e)}` });
    return;
  }
  const groundTruth = (parsed.groundTruth || []).map((row) => Array.from(row));
  seq = {
    id: ++seqCounter,
    name,
    kind: parsed.kind,
    source,
    frames: parsed.frames,
    gtTum: parsed.groundTruthTum || (groundTruth.length ? groundTruth.map((r) => r.join(' ')).join('\n') + '\n' : null),
  };
  readerSource(seq.id, entries);
  post({
    type: FromWorker.SEQUENCE,
    name,
    kind: parsed.kind,
    preset,
    config: newConfig,
    frameCount: seq.frames.length,
    groundTruth,
    fileCount: paths.length,
  });
  playing = !!autoplay;
  reportState();
  if (playing) pump();
}

// ---- the frame loop -----------------------------------------------------------

// ---- reading frames: in frame-reader.js's worker when it runs ----------------

let reader = null; // the frame reader's Worker; null: read on this thread
// ?colour=wasm in the page URL: wasm decodes colour too (pushFrame), for comparisons.
const browserColour = new URL(self.location.href).searchParams.get('colour') !== 'wasm';
const readerWaiting = new Map(); // `${seq.id}:${index}` -> {resolve, reject, source, frame}

function startReader() {
  if (typeof Worker !== 'function') return;
  try {
    reader = new Worker(new URL('./frame-reader.js', import.meta.url), { type: 'module' });
  } catch {
    reader = null;
    return;
  }
  reader.onmessage = ({ data }) => {
    const key = `${data.id}:${data.index}`;
    const waiting = readerWaiting.get(key);
    if (!waiting) return; // the sequence was replaced or reset meanwhile
    readerWaiting.delete(key);
    if (data.error !== undefined) waiting.reject(new Error(data.error));
    else waiting.resolve({ colourBuf: data.colourBuf, depthBuf: data.depthBuf, decoded: data.decoded });
  };
  reader.onerror = (e) => {
    // The reader cannot run (or died): read on this thread from now on.
    e.preventDefault?.();
    reader?.terminate();
    reader = null;
    for (const [key, w] of readerWaiting) {
      readerWaiting.delete(key);
      readAndDecodeColour(w.source, w.frame, browserColour).then(w.resolve, w.reject);
    }
  };
}

/** Tells the reader about a new sequence (before any read of it). */
function readerSource(id, entries) {
  readerWaiting.clear();
  readAheadUntil = 0;
  reader?.postMessage({ type: ToReader.SOURCE, id, entries });
}

/** Has the reader read the next batch of files once fewer than READ_BATCH frames are left read ahead of `index`. */
function readAhead(index) {
  if (!reader || readAheadUntil > index + READ_BATCH) return;
  const from = Math.max(readAheadUntil, index + 1);
  const to = Math.min(seq.frames.length, index + 1 + 2 * READ_BATCH);
  if (from >= to) return;
  const paths = seq.frames.slice(from, to).flatMap((f) => [f.colour, f.depth]);
  reader.postMessage({ type: ToReader.READ_AHEAD, id: seq.id, paths });
  readAheadUntil = to;
}

function loadFrame(index) {
  const frame = seq.frames[index];
  let promise;
  if (reader) {
    const key = `${seq.id}:${index}`;
    const source = seq.source;
    promise = new Promise((resolve, reject) => readerWaiting.set(key, { resolve, reject, source, frame }));
    const { colour, depth } = frame;
    reader.postMessage({ type: ToReader.READ, id: seq.id, index, colour, depth, decode: browserColour });
  } else {
    promise = readAndDecodeColour(seq.source, frame, browserColour);
  }
  promise.catch(() => {}); // handled by whoever awaits it
  return promise;
}

function readFrame(index) {
  const key = `${seq.id}:${index}`;
  const ahead = prefetch.get(key);
  if (ahead) {
    prefetch.delete(key);
    return ahead;
  }
  return loadFrame(index);
}

/** Starts reading (and decoding) the frames after `index` that are not under way yet. */
function startPrefetch(index) {
  if (!seq) return;
  readAhead(index);
  for (let i = index + 1; i <= index + PREFETCH_FRAMES && i < seq.frames.length; i++) {
    const key = `${seq.id}:${i}`;
    if (!prefetch.has(key)) prefetch.set(key, loadFrame(i));
  }
}

/** Names the file concerned in an error from pushFrame. */
function describeFrameError(frame, message) {
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

let lastFrameEnd = null; // performance.now() when the last frame was posted (null: not playing)

async function processNext() {
  if (!seq || !slam || next >= seq.frames.length) return;
  const index = next++;
  const frame = seq.frames[index];
  if (frame.missing) {
    // An image the index lists is absent (a half-copied dataset): parseSequence named it.
    post({ type: FromWorker.FRAME_ERROR, index, message: frame.missing, frameCount: seq.frames.length });
    return;
  }
  const t0 = performance.now();
  const reading = readFrame(index);
  startPrefetch(index);
  let colourBuf, depthBuf, decoded;
  try {
    ({ colourBuf, depthBuf, decoded } = await reading);
  } catch (e) {
    post({ type: FromWorker.FRAME_ERROR, index, message: errorText(e), frameCount: seq.frames.length });
    return;
  }
  const tRead = performance.now();
  const colour = new Uint8Array(colourBuf);
  const depth = new Uint8Array(depthBuf);
  const colourDecoder = decoded ? 'browser' : 'wasm';
  let r;
  try {
    if (testBreak) {
      // Test hook: what a panic leaves behind (the object freed under wasm-bindgen's feet).
      testBreak = false;
      slam.free();
    }
    if (testHang) {
      // Test hook: what a panic on one of the module's threads leaves behind
      // (this thread waits for it for ever).
      if (typeof SharedArrayBuffer === 'function') Atomics.wait(new Int32Array(new SharedArrayBuffer(4)), 0, 0);
      for (;;);
    }
    const report = decoded
      ? slam.pushRgbaDepthPng(decoded.width, decoded.height, decoded.rgba, depth, frame.timestamp)
      : slam.pushFrame(colour, depth, frame.timestamp);
    r = toPlain(report);
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    post(
      {
        type: FromWorker.FRAME_ERROR,
        index,
        message: describeFrameError(frame, errorText(e)),
        frameCount: seq.frames.length,
        colourDecoder,
        input: { colour: colourBuf, depth: depthBuf, depthScale: config.depthScale ?? null, colourPreview: decoded?.preview ?? null },
      },
      decoded?.preview ? [colourBuf, depthBuf, decoded.preview] : [colourBuf, depthBuf],
    );
    return;
  }
  const flowOverlay = flowTracks(colour, decoded);
  // The depth view's thumbnail at full 16-bit precision, without a second PNG decode.
  const depthPreview = { width: PREVIEW_WIDTH, height: PREVIEW_HEIGHT, metres: slam.depthPreview(PREVIEW_WIDTH, PREVIEW_HEIGHT) };
  const tPush = performance.now();
  framesOk++;

  // Copy out only the surfels that changed (the views into wasm memory are
  // invalidated by the next call into the module).
  const count = slam.surfelCount;
  surfelCount = count;
  let [start, end] = Array.from(slam.takeChangedRange());
  start = Math.max(0, Math.min(start, count));
  end = Math.max(start, Math.min(end, count));
  const surfels = {
    count,
    start,
    end,
    positions: slam.positions().slice(3 * start, 3 * end),
    normals: slam.normals().slice(3 * start, 3 * end),
    colours: slam.colours().slice(4 * start, 4 * end),
    radii: slam.radii().slice(start, end),
    confidences: slam.confidences().slice(start, end),
  };
  // Merges are not in the changed range (they refine surfels by less than the
  // noise): refresh a rolling window so merged colours and positions reach
  // the GPU within count / REFRESH_SURFELS frames.
  const refreshStart = refreshCursor < count ? refreshCursor : 0;
  const refreshEnd = Math.min(count, refreshStart + REFRESH_SURFELS);
  refreshCursor = refreshEnd >= count ? 0 : refreshEnd;
  const refresh = {
    count,
    start: refreshStart,
    end: refreshEnd,
    positions: slam.positions().slice(3 * refreshStart, 3 * refreshEnd),
    normals: slam.normals().slice(3 * refreshStart, 3 * refreshEnd),
    colours: slam.colours().slice(4 * refreshStart, 4 * refreshEnd),
    radii: slam.radii().slice(refreshStart, refreshEnd),
    confidences: slam.confidences().slice(refreshStart, refreshEnd),
  };
  const tCopy = performance.now();

  let ate = null;
  const last = next >= seq.frames.length;
  const every = seq.frames.length > 200 ? 10 : 1;
  if (seq.gtTum && (framesOk % every === 0 || last)) {
    try {
      ate = toPlain(wasm.ateTum(slam.trajectoryTum(), seq.gtTum));
    } catch (e) {
      if (isModuleFailure(e)) throw e;
      ate = null; // too few associated poses yet
    }
  }
  const tAte = performance.now();
  post(
    {
      type: FromWorker.FRAME,
      index,
      frameCount: seq.frames.length,
      timestamp: frame.timestamp,
      colourPath: frame.colour,
      depthPath: frame.depth,
      result: r,
      colourDecoder,
      surfels,
      refresh,
      ate,
      timing: {
        read: tRead - t0,
        push: tPush - tRead,
        copy: tCopy - tPush,
        ate: tAte - tCopy,
        gap: lastFrameEnd === null ? 0 : t0 - lastFrameEnd, // between frames: the loop's own yield
        wall: performance.now() - t0,
        doneAt: performance.now() + performance.timeOrigin, // fps is measured where the work happens
      },
      // The thumbnail the browser made while decoding (the page need not decode the colour again).
      input: {
        colour: colourBuf,
        depth: depthBuf,
        depthScale: config.depthScale ?? null,
        colourPreview: decoded?.preview ?? null,
        depthPreview,
      },
      flow: flowOverlay,
      done: last,
    },
    [
      surfels.positions.buffer,
      surfels.normals.buffer,
      surfels.colours.buffer,
      surfels.radii.buffer,
      surfels.confidences.buffer,
      refresh.positions.buffer,
      refresh.normals.buffer,
      refresh.colours.buffer,
      refresh.radii.buffer,
      refresh.confidences.buffer,
      colourBuf,
      depthBuf,
      depthPreview.metres.buffer,
      ...(decoded?.preview ? [decoded.preview] : []),
    ],
  );
  lastFrameEnd = playing ? performance.now() : null;
}

// Lets queued messages (pause, step, reset) in between frames. A message to
// ourselves rather than setTimeout(0), which browsers clamp to 4 ms once
// timers nest (each frame is scheduled from the last one's).
const yieldChannel = new MessageChannel();
const yielded = [];
yieldChannel.port1.onmessage = () => yielded.shift()?.();
const tick = () =>
  new Promise((resolve) => {
    yielded.push(resolve);
    yieldChannel.port2.postMessage(null);
  });

async function pump() {
  if (pumping) return;
  pumping = true;
  lastFrameEnd = null;
  try {
    while (playing) {
      // Checked inside the serial job: a reset or replay queued before it has run by then.
      const more = await serial(async () => {
        if (!playing || failure) return false;
        if (!seq || !slam || next >= seq.frames.length) {
          playing = false;
          return false;
        }
        await processNext();
        return true;
      });
      if (!more) break;
      await tick(); // let pause / step / reset messages in
    }
  } finally {
    pumping = false;
    serial(() => reportState());
  }
}

/** Empty map, frame 0 (a new Slam after a failure). */
async function resetMap() {
  if (failure || !slam) {
    await ensureSlam();
  } else {
    slam.reset();
    restart();
  }
  post({ type: FromWorker.RESET });
}

function play() {
  playing = true;
  serial(() => reportState());
  pump();
}

// ---- messages -----------------------------------------------------------------

const ready = initModule().catch((e) => {
  post({ type: FromWorker.FATAL, message: `cannot load the wasm module: ${errorText(e)}` });
  throw e;
});

self.onmessage = async (event) => {
  const msg = typeof event.data === 'string' ? { type: event.data } : event.data;
  try {
    await ready;
  } catch {
    return;
  }
  switch (msg.type) {
    case ToWorker.LOAD:
      playing = false;
      serial(() => load(msg));
      break;
    case ToWorker.PLAY:
      serial(async () => {
        if (failure || !slam) await resetMap();
        // Play after the end starts again from an empty map.
        else if (seq && next >= seq.frames.length) await resetMap();
      });
      play();
      break;
    case ToWorker.REPLAY:
      playing = false;
      serial(resetMap);
      play();
      break;
    case ToWorker.PAUSE:
      playing = false;
      serial(() => reportState());
      break;
    case ToWorker.STEP:
      playing = false;
      serial(async () => {
        if (failure) await resetMap();
        await processNext();
        reportState();
      });
      break;
    case ToWorker.RESET:
      playing = false;
      serial(async () => {
        await resetMap();
        reportState();
      });
      break;
    case ToWorker.CONFIG: {
      const wasPlaying = playing;
      serial(async () => {
        await freshModule();
        try {
          createSlam(msg.config);
        } catch (e) {
          if (isModuleFailure(e)) throw e;
          playing = wasPlaying; // the old Slam goes on as it was
          post({ type: FromWorker.CONFIG_ERROR, message: `camera settings rejected: ${errorText(e)}` });
          reportState();
          return;
        }
        post({ type: FromWorker.RESET, config: msg.config });
      });
      // New settings restart the sequence and play it (the frame loop's job
      // runs after the one above).
      if (seq) play();
      break;
    }
    case ToWorker.FLOW:
      flowEnabled = Boolean(msg.enabled);
      if (!flowEnabled && flow) {
        serial(() => {
          flow?.free();
          flow = null;
        });
      }
      break;
    case ToWorker.EXPORT_PLY:
      serial(() => {
        const bytes = exportFrom((s) => (s ? s.exportPly().slice() : new Uint8Array()));
        if (bytes) post({ type: FromWorker.EXPORT, what: 'ply', bytes, name: seq?.name }, [bytes.buffer]);
        else post({ type: FromWorker.EXPORT, what: 'ply', unavailable: true, name: seq?.name });
      });
      break;
    case ToWorker.EXPORT_TRAJECTORY:
      serial(() => {
        const text = exportFrom((s) => (s ? s.trajectoryTum() : ''));
        if (text !== undefined) post({ type: FromWorker.EXPORT, what: 'trajectory', text, name: seq?.name });
        else post({ type: FromWorker.EXPORT, what: 'trajectory', unavailable: true, name: seq?.name });
      });
      break;
    case ToWorker.EXPORT_MESH:
      serial(() => {
        const format = msg.format;
        const what = format === 'glb-points' ? 'points-glb' : `mesh-${format}`;
        let bytes;
        try {
          bytes = exportFrom((s) => {
            if (!s) return new Uint8Array();
            if (format === 'glb-points') return s.exportGlbPoints().slice();
            return s.exportMesh({ format }, meshProgress('download')).slice();
          });
        } catch (e) {
          if (isModuleFailure(e)) throw e;
          post({ type: FromWorker.EXPORT, what, error: errorText(e), name: seq?.name });
          return;
        }
        if (bytes) post({ type: FromWorker.EXPORT, what, bytes, name: seq?.name }, [bytes.buffer]);
        else post({ type: FromWorker.EXPORT, what, unavailable: true, name: seq?.name });
      });
      break;
    case ToWorker.VIEW_MESH:
      serial(() => {
        let mesh;
        try {
          mesh = exportFrom((s) => (s ? parseGlb(s.exportMesh({ format: 'glb' }, meshProgress('view'))) : { positions: new Float32Array(0), normals: new Float32Array(0), colours: new Uint8Array(0), indices: new Uint32Array(0) }));
        } catch (e) {
          if (isModuleFailure(e)) throw e;
          post({ type: FromWorker.MESH, error: errorText(e) });
          return;
        }
        if (!mesh) post({ type: FromWorker.MESH, unavailable: true });
        else post({ type: FromWorker.MESH, ...mesh }, [mesh.positions.buffer, mesh.normals.buffer, mesh.colours.buffer, mesh.indices.buffer]);
      });
      break;
    case ToWorker.TEST_BREAK:
    case ToWorker.TEST_HANG:
      if (!testHooks) post({ type: FromWorker.FATAL, message: 'test hooks are off (testHooks=1 in the worker URL)' });
      else if (msg.type === ToWorker.TEST_BREAK) testBreak = true;
      else testHang = true;
      break;
    default:
      post({ type: FromWorker.FATAL, message: `unknown message ${msg.type}` });
  }
};
