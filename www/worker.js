// Web Worker: owns the wasm module and the Slam instance; runs the frame loop
// (read files, decode the colour image in the browser -> pushRgbaDepthPng:
// decode depth, track, fuse) and posts each result with a copy of the changed
// surfel range (transferred, not cloned). The next frames' files are read and
// their colour decoded ahead by frame-feed.js (in frame-reader.js's worker
// where it can start) while wasm works on the current one.
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
// Messages: ToWorker and FromWorker in protocol.js. Beside this file:
// wasm-module.js (loading the module, telling its failures apart),
// frame-feed.js (frames read ahead), surfel-copy.js (copies out of wasm
// memory), worker-exports.js (downloads and the mesh view), worker-session.js
// (session files: Save session, Open session; a sequence opened after a
// session goes on in it), flow-overlay.js (the live view's optical flow), scoring.js (the ATE).
import { ToWorker, FromWorker } from './protocol.js';
import { openSource } from './sequence.js';
import { PREVIEW_WIDTH, PREVIEW_HEIGHT, pushedAsFiles } from './colour-decode.js';
import { errorText, isModuleFailure, startModule as loadModule, toPlain } from './wasm-module.js';
import { FrameFeed, describeFrameError } from './frame-feed.js';
import { colourOfScan } from './video-colour.js';
import { sequenceCamera } from './sequence-camera.js';
import { copyChanged, RollingRefresh, surfelBuffers } from './surfel-copy.js';
import { coversWholeMap } from './surfel-buffers.js';
import { answerExport } from './worker-exports.js';
import { FlowOverlay } from './flow-overlay.js';
import { sessionCameraConfig, sessionSnapshot } from './worker-session.js';
import { Scoring } from './scoring.js';

let wasm = null;
let moduleKind = null;
let threads = 1;
let slam = null;
let config = null; // Slam config currently in use
let seq = null; // { id, name, kind, source, frames, layoutPreset, video }
const scoring = new Scoring(); // what the run is scored against (seq's own reference, or the user's)
let seqCounter = 0;
let next = 0; // index of the next frame to process
let playing = false;
let pumping = false;
// ?colour=wasm in the page URL: wasm decodes colour too (pushFrame), for comparisons.
const feed = new FrameFeed(new URL(self.location.href).searchParams.get('colour') !== 'wasm');
let framesOk = 0;
let surfelCount = 0; // the map's size after the last frame (read without calling into the module)
let loopClosures = 0; // the report's loop closure count after the last frame
let failure = null; // {message}: the module failed; rebuilt at the next action that needs it
let instance = 0; // module instances started (a failed one is replaced, not reused)
let testBreak = false; // test hook: the next call into the module fails
let testHang = false; // test hook: the next frame never returns
const testHooks = new URL(self.location.href).searchParams.get('testHooks') === '1';
const refresh = new RollingRefresh();
const overlay = new FlowOverlay(); // optical-flow tracks for the live view
// {localise, bytes}: the map is an opened session; the next sequence goes on
// in it (continues mapping, or localises) instead of starting a new map.
let session = null;

const post = (msg, transfer = []) => self.postMessage(msg, transfer);

/** The module failed: stop and say so (the page keeps what it was sent for the downloads). */
function fail(e) {
  playing = false;
  failure = { message: errorText(e) };
  // The poisoned objects are dropped, not freed (free() would throw too).
  slam = null;
  overlay.drop();
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

async function startModule(notes = []) {
  wasm = null;
  ({ wasm, kind: moduleKind, threads } = await loadModule(instance, notes));
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
  feed.startReader();
  post({ type: FromWorker.READY, module: moduleKind, threads, presets, notes, frameReader: feed.inReader });
}

function createSlam(newConfig) {
  const fresh = new wasm.Slam(newConfig); // throws on a bad config: keep the old one
  if (slam) slam.free();
  slam = fresh;
  config = newConfig;
  restart();
}

/** Every settings warning of the current Slam (none when the module lacks the check). */
function settingsWarnings() {
  try {
    return typeof slam?.settingsWarnings === 'function' ? slam.settingsWarnings() : [];
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return [];
  }
}

/**
 * The config's settings against the layout's preset (`layoutPreset`, from
 * parseSequence): warnings naming the setting (a preset of another dataset,
 * a focal length of the other sign, a depth scale far off). The depth
 * check's warning arrives with the first frame's report.
 */
function layoutWarnings(layoutPreset) {
  if (!layoutPreset || typeof slam?.checkLayout !== 'function') return [];
  try {
    return slam.checkLayout(layoutPreset, config?.preset ?? undefined);
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return [];
  }
}

/** Every preset for frames of the config's size (null when the module cannot say). */
function presetsAtSize({ width, height }) {
  if (typeof wasm?.presetsForImageSize !== 'function' || !Number.isInteger(width) || !Number.isInteger(height)) return null;
  try {
    return toPlain(wasm.presetsForImageSize(width, height));
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return null;
  }
}

/** Back to frame 0 with an empty map (the Slam already is). */
function restart() {
  session = null;
  next = 0;
  framesOk = 0;
  surfelCount = 0;
  loopClosures = 0;
  refresh.restart();
  feed.restart();
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

/** A sequence that cannot be opened: the one open stays, and plays on when it was playing (`resume`). */
function refuse(name, message, resume) {
  const resumed = resume && !!seq && !!slam && !failure && next < seq.frames.length;
  post({ type: FromWorker.LOAD_ERROR, name, message, resumed });
  if (resumed) play();
  else reportState();
}

async function load({ name, entries, autoplay, options }, resume) {
  await freshModule();
  let source;
  try {
    source = await openSource(entries, async () => wasm); // a folder, or an archive read by wasm
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    return refuse(name, `${name}: ${errorText(e)}`, resume);
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
    return refuse(name, `${name}: ${errorText(e)}`, resume);
  }
  // Before anything changes: the sequence playing goes on while the video is probed.
  const colour = await colourOfScan(parsed.frames, paths, source);
  const newConfig = await sequenceCamera(wasm, parsed, source);
  const preset = newConfig.preset;
  // The page's own choices carry over to a new sequence.
  for (const key of ['tracker', 'halfResolution', 'noise', 'loopClosure']) if (options?.[key] !== undefined) newConfig[key] = options[key];
  let continued = null;
  try {
    if (session) continued = continueSession(newConfig);
    else createSlam(newConfig);
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    const what = session ? `the opened session does not fit this sequence: ${errorText(e)}` : `camera preset ${preset}: ${errorText(e)}`;
    return refuse(name, `${name}: ${what}`, resume);
  }
  const groundTruth = (parsed.groundTruth || []).map((row) => Array.from(row));
  // The recording device's own trajectory (Stray Scanner: ARKit's), drawn like ground truth but named as what it is.
  const odometry = (parsed.odometry || []).map((row) => Array.from(row));
  seq = { id: ++seqCounter, name, kind: parsed.kind, source, frames: parsed.frames, layoutPreset: preset, video: colour.video };
  scoring.setSequence(parsed);
  // The sequence a session was saved from (its download is <sequence>.slam)
  // continues at the frame after the session's last; another starts at its first.
  if (continued && !session.localise && sessionStem(session.name) === name) next = Math.min(slam.frames, seq.frames.length);
  feed.setSequence(seq.id, entries, source, seq.frames, seq.video);
  post({
    type: FromWorker.SEQUENCE,
    name,
    kind: parsed.kind,
    preset,
    config: newConfig,
    frameCount: seq.frames.length,
    groundTruth,
    odometry,
    fileCount: paths.length,
    warnings: layoutWarnings(preset),
    readWarnings: parsed.warnings ?? [],
    presets: presetsAtSize(newConfig),
    colourNote: colour.note,
    session: continued,
  });
  playing = !!autoplay;
  reportState();
  if (playing) pump();
}

// ---- sessions (Slam.save / Slam.load) ------------------------------------------

/** The sequence name in a session file's name (the page saves `<sequence>.slam`). */
const sessionStem = (fileName) => String(fileName ?? '').replace(/\.(slam|zip)$/i, '');

/** The map as a session file, for the page to download. */
function saveSession({ keep }) {
  if (failure || !slam) {
    post({ type: FromWorker.SESSION_SAVED, keep, error: 'nothing to save: no map (open a sequence or a session first)' });
    return;
  }
  const t0 = performance.now();
  let bytes;
  try {
    bytes = slam.localising && session ? session.bytes.slice() : slam.save();
  } catch (e) {
    if (isModuleFailure(e)) throw e;
    post({ type: FromWorker.SESSION_SAVED, keep, error: errorText(e) });
    return;
  }
  const ms = performance.now() - t0;
  post({ type: FromWorker.SESSION_SAVED, keep, bytes, name: seq?.name ?? null, ms }, [bytes.buffer]);
}

/**
 * Replaces the map by the session in `bytes`: in a new Slam with the
 * session's camera, so that a refused file leaves the current Slam as it was.
 */
async function openSession({ name, bytes, localise }) {
  await freshModule();
  const data = new Uint8Array(bytes);
  const t0 = performance.now();
  const cameraConfig = sessionCameraConfig(wasm, data, name);
  // The open sequence stays when the session has its camera; else the
  // session's camera is taken and the sequence closed (a sequence of that
  // camera is opened next).
  const attempts = seq && config ? [config, cameraConfig] : [cameraConfig ?? config ?? { preset: 'tum-fr3' }];
  let fresh = null;
  let used = null;
  let refusal = null;
  for (const candidate of attempts) {
    if (!candidate) continue;
    try {
      fresh = new wasm.Slam(candidate);
      fresh.load(data, { localise: !!localise });
      used = candidate;
      break;
    } catch (e) {
      if (isModuleFailure(e)) throw e;
      fresh?.free();
      fresh = null;
      refusal = e;
      if (!errorText(e).startsWith('camera-mismatch:')) break;
    }
  }
  if (!fresh) {
    post({ type: FromWorker.SESSION_ERROR, name, message: errorText(refusal) });
    reportState();
    return;
  }
  const ms = performance.now() - t0;
  const sequenceClosed = !!seq && used !== config;
  if (sequenceClosed) seq = null;
  playing = false;
  if (slam) slam.free();
  slam = fresh;
  config = used;
  restart();
  session = { localise: !!localise, bytes: data, name };
  framesOk = slam.frames;
  surfelCount = slam.surfelCount;
  slam.takeChangedRange(); // the page gets the whole map below
  // The sequence the session was saved from goes on at its next frame.
  if (seq && !localise && sessionStem(name) === seq.name) next = Math.min(slam.frames, seq.frames.length);
  post({ type: FromWorker.SESSION_OPENED, name, ms, config: used, sequenceClosed, session: sessionSnapshot(slam) });
  reportState();
}

/**
 * A sequence opened after a session: the session's map (with the frames
 * pushed since) in a Slam with the sequence's camera (Slam.load refuses
 * another camera: 'camera-mismatch: ...'). Returns the page's snapshot.
 */
function continueSession(newConfig) {
  const bytes = slam.localising ? session.bytes : slam.save();
  const fresh = new wasm.Slam(newConfig);
  try {
    fresh.load(bytes, { localise: session.localise });
  } catch (e) {
    fresh.free();
    throw e;
  }
  const kept = session;
  slam.free();
  slam = fresh;
  config = newConfig;
  restart();
  session = { ...kept, bytes: kept.localise ? kept.bytes : bytes };
  framesOk = slam.frames;
  surfelCount = slam.surfelCount;
  slam.takeChangedRange();
  return sessionSnapshot(slam);
}

// ---- the frame loop -----------------------------------------------------------

let lastFrameEnd = null; // performance.now() when the last frame was posted (null: not playing)

/**
 * After the sequence's last frame: the recording ended, so that frame is
 * looked up among the old keyframes too, whatever the global check's
 * schedule (Slam.finish); what it did shows as that frame's loop result.
 */
function finishRecording(r) {
  const f = toPlain(slam.finish());
  if (!f.looked) return;
  r.loopClosures = f.loopClosures;
  r.globalLoopClosures = f.globalLoopClosures;
  r.loopClosed = r.loopClosed || f.loopClosed;
  r.loopDecision = [r.loopDecision, f.loopDecision].filter(Boolean).join('; ') || null;
}

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
  const reading = feed.read(index);
  let colourBuf, depthBuf, confidenceBuf, decoded, videoError;
  try {
    ({ colourBuf, depthBuf, confidenceBuf, decoded, videoError } = await reading);
  } catch (e) {
    post({ type: FromWorker.FRAME_ERROR, index, message: errorText(e), frameCount: seq.frames.length });
    return;
  }
  const tRead = performance.now();
  // A depth-only frame (Stray Scanner without rgb/) has no colour image, or
  // one drawn from the scan's video (seq.video).
  const colour = colourBuf ? new Uint8Array(colourBuf) : null;
  const depth = new Uint8Array(depthBuf);
  const fromVideo = colour !== null && frame.colour == null;
  const colourName = fromVideo ? `${seq.video} frame ${index}` : (frame.colour ?? null);
  const colourDecoder = fromVideo ? 'video' : decoded ? 'browser' : 'wasm';
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
    const report = pushedAsFiles(frame)
      ? slam.pushFiles(colour, depth, confidenceBuf ? new Uint8Array(confidenceBuf) : null, [colourName, frame.depth, frame.confidence ?? null], frame.timestamp)
      : decoded
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
      [colourBuf, depthBuf, decoded?.preview].filter(Boolean),
    );
    return;
  }
  if (next >= seq.frames.length) finishRecording(r);
  const flowOverlay = colour ? overlay.tracks(wasm, colour, decoded) : null;
  // The depth view's thumbnail at full 16-bit precision, without a second PNG decode.
  const depthPreview = { width: PREVIEW_WIDTH, height: PREVIEW_HEIGHT, metres: slam.depthPreview(PREVIEW_WIDTH, PREVIEW_HEIGHT) };
  const tPush = performance.now();
  framesOk++;

  // Copy out only the surfels that changed (the views into wasm memory are
  // invalidated by the next call into the module), and a window of the rest.
  const count = slam.surfelCount;
  surfelCount = count;
  const surfels = copyChanged(slam, count);
  // A range over the whole map (a loop closure moved every surfel) already
  // holds what the rolling window would bring.
  const refreshed = coversWholeMap(surfels) ? null : refresh.next(slam, count);
  // A loop closure also moved the past poses: the whole trajectory, as TUM text.
  const closures = Number.isFinite(r.loopClosures) ? r.loopClosures : 0;
  const trajectoryTum = closures > loopClosures ? slam.trajectoryTum() : null;
  loopClosures = closures;
  const tCopy = performance.now();

  const last = next >= seq.frames.length;
  const ate = scoring.afterFrame(slam, framesOk, seq.frames.length, last);
  const tAte = performance.now();
  post(
    {
      type: FromWorker.FRAME,
      index,
      frameCount: seq.frames.length,
      timestamp: frame.timestamp,
      colourPath: colourName,
      depthPath: frame.depth,
      result: r,
      colourDecoder,
      videoError,
      surfels,
      refresh: refreshed,
      trajectoryTum,
      ate,
      wasmMemoryBytes: typeof wasm.memoryBytes === 'function' ? wasm.memoryBytes() : null,
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
      ...surfelBuffers(surfels),
      ...(refreshed ? surfelBuffers(refreshed) : []),
      ...(colourBuf ? [colourBuf] : []),
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
  // The settings are the same: their warnings still apply to the new run.
  post({ type: FromWorker.RESET, warnings: settingsWarnings() });
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
    case ToWorker.LOAD: {
      const resume = playing; // a refused sequence lets the open one play on
      playing = false;
      serial(() => load(msg, resume));
      break;
    }
    case ToWorker.REFERENCE:
      serial(() => post({ type: FromWorker.REFERENCE, ...scoring.loadUser(msg, seq, slam, wasm) }));
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
        post({ type: FromWorker.RESET, config: msg.config, warnings: layoutWarnings(seq?.layoutPreset) });
      });
      // New settings restart the sequence and play it (the frame loop's job
      // runs after the one above).
      if (seq) play();
      break;
    }
    case ToWorker.FLOW:
      overlay.enabled = Boolean(msg.enabled);
      if (!overlay.enabled) serial(() => overlay.free());
      break;
    case ToWorker.EXPORT_PLY:
    case ToWorker.EXPORT_TRAJECTORY:
    case ToWorker.EXPORT_MESH:
    case ToWorker.VIEW_MESH:
      serial(() => answerExport(msg, exportFrom, seq?.name));
      break;
    case ToWorker.SAVE_SESSION:
      serial(() => saveSession({ keep: !!msg.keep }));
      break;
    case ToWorker.OPEN_SESSION:
      serial(() => openSession(msg));
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
