// UI wiring: starts the worker, plays the bundled sample on first load, routes
// worker messages to the renderer, the input views and the statistics, and
// keeps window.surfelSlamStatus (read by the browser tests) up to date.
import { Renderer } from './renderer.js';
import { InputViews } from './views.js';
import { Stats } from './stats.js';
import { Plots, STAGE_COLOURS } from './plots.js';
import { fromManifest, setupSequenceInput } from './sequence.js';
import { poseFromTq, multiply, invertRigid, transformPoint } from './math3d.js';
import { ToWorker, FromWorker } from './protocol.js';
import { MapMirror } from './map-mirror.js';

const $ = (id) => document.getElementById(id);

const status = {
  ready: false,
  framesProcessed: 0,
  framesLost: 0,
  framesRecovered: 0,
  framesFailed: 0,
  surfels: 0,
  threads: 0,
  crossOriginIsolated: self.crossOriginIsolated === true,
  module: null,
  error: null,
  ate: null,
  flowTracks: 0, // Lucas-Kanade tracks drawn on the last colour view (0 = overlay off)
  fps: 0, // frames per second over the last ~15 frames
  fpsAverage: 0, // frames per second from the first to the latest frame of this run
  msPerFrame: 0, // wasm time per frame (decode + preprocess + track + fuse + predict)
  stageMedianMs: null, // median ms per stage and in total over the frames since the last reset
  workerMedianMs: null, // median ms of the worker's steps per frame (read, push, copy, ate, gap, wall)
  colourDecoder: null, // who decoded the last frame's colour image: 'browser' (the worker) or 'wasm'
  frameReader: false, // frames are read and their colour decoded by a worker of their own (www/frame-reader.js)
  framesColourDecodedInBrowser: 0, // since the last reset
  playing: false,
  done: false,
  frameIndex: -1,
  frameCount: 0,
  sequence: null,
  sequenceKind: null,
  errors: [],
  moduleFailures: 0, // times the wasm module failed (each time rebuilt at the next action)
  failed: false, // the module has failed and not been rebuilt yet
  positionErrorCm: null, // last frame's distance to the ground truth (aligned at its first pose), cm
  displayFlipY: false, // the map is shown mirrored in y (negative fy: ICL-NUIM) so that it is upright
  plotFrames: 0, // frames in the plots
  meshView: false, // the view shows the mesh instead of the splats
  meshTriangles: null, // triangles of the mesh in the view (null: none received yet)
  meshProgress: null, // fraction of the meshing under way, null when none
};
window.surfelSlamStatus = status;

const ui = {
  moduleInfo: $('module-info'),
  sequenceInfo: $('sequence-info'),
  play: $('play-button'),
  step: $('step-button'),
  reset: $('reset-button'),
  ply: $('ply-button'),
  trajectory: $('trajectory-button'),
  meshGlb: $('mesh-glb-button'),
  meshPly: $('mesh-ply-button'),
  pointsGlb: $('points-glb-button'),
  meshProgress: $('mesh-progress'),
  viewMesh: $('view-mesh'),
  message: $('message'),
  messageText: $('message-text'),
  preset: $('preset'),
  fx: $('fx'),
  fy: $('fy'),
  cx: $('cx'),
  cy: $('cy'),
  depthScale: $('depth-scale'),
  tracker: $('tracker'),
  half: $('half-resolution'),
};

let presets = [];
let sequence = null; // {name, kind, frameCount, groundTruth}
let gtAnchored = false;
let workerPlaying = false;
let run = { first: 0, frames: 0 }; // wall clock of this playback run

// ---- messages on the page ------------------------------------------------------

function showMessage(text, kind = 'error') {
  ui.messageText.textContent = text;
  ui.message.className = kind;
  ui.message.hidden = false;
}

function reportError(text) {
  status.error = text;
  status.errors.push(text);
  if (status.errors.length > 50) status.errors.shift();
  // Show the latest few errors, newest last, so an earlier one is not hidden by a later one.
  const recent = status.errors.slice(-3);
  const more = status.errors.length > 3 ? `(${status.errors.length - 3} earlier not shown)\n` : '';
  showMessage(more + recent.join('\n'), 'error');
  console.warn(`surfel-slam: ${text}`);
}

$('message-close').addEventListener('click', () => {
  ui.message.hidden = true;
});

// ---- renderer, views, stats ------------------------------------------------------

let renderer = null;
try {
  renderer = new Renderer($('map-canvas'));
} catch (e) {
  reportError(`cannot draw the map: ${e.message}`);
}
const views = new InputViews($('colour-view'), $('depth-view'), $('depth-caption'));
views.clear();
const stats = new Stats($('stats'));
const plots = new Plots({ timing: $('plot-timing'), surfels: $('plot-surfels'), error: $('plot-error') });

function syncStatus() {
  status.framesProcessed = stats.framesProcessed;
  status.framesLost = stats.framesLost;
  status.framesRecovered = stats.framesRecovered;
  status.framesFailed = stats.framesFailed;
  status.surfels = stats.surfels; // in the map (the report's count)
  status.surfelSlots = stats.surfelSlots; // the arrays' length (absorbed surfels not yet compacted included)
  status.ate = stats.ate;
  status.fps = Number(stats.fps.toFixed(2));
  status.msPerFrame = Number(stats.msPerFrame.toFixed(2));
  status.stageMedianMs = stats.stageMedians();
  status.workerMedianMs = stats.workerMedians();
  status.frameIndex = stats.frameIndex;
  status.changedSurfels = stats.changed ?? 0;
}

function noteColourDecoder(msg) {
  if (!msg.colourDecoder) return;
  status.colourDecoder = msg.colourDecoder;
  if (msg.colourDecoder === 'browser') status.framesColourDecodedInBrowser++;
}

function countRunFrame(msg) {
  const now = msg.timing?.doneAt ?? performance.now() + performance.timeOrigin;
  if (run.frames === 0) run.first = now;
  run.frames++;
  if (run.frames > 1) status.fpsAverage = Number(((run.frames - 1) / ((now - run.first) / 1000)).toFixed(2));
}

// ---- worker ---------------------------------------------------------------------------

// ?threads=0 forces the single-threaded SIMD module (for comparisons).
const workerUrl = new URL('./worker.js', import.meta.url);
if (new URLSearchParams(location.search).get('threads') === '0') workerUrl.searchParams.set('threads', '0');
// ?colour=wasm decodes colour images in wasm instead of the browser (for comparisons).
if (new URLSearchParams(location.search).get('colour') === 'wasm') workerUrl.searchParams.set('colour', 'wasm');
// ?testHooks=1 lets the browser tests make the module fail (ToWorker.TEST_BREAK).
if (new URLSearchParams(location.search).get('testHooks') === '1') workerUrl.searchParams.set('testHooks', '1');
const testHooks = new URLSearchParams(location.search).get('testHooks') === '1';
// No message for this long while playing: the worker is stuck (a panic on
// one of the module's threads leaves the worker's own thread waiting for it
// for ever); the page then starts a new worker.
const STALL_MS = (testHooks && Number(new URLSearchParams(location.search).get('stallMs'))) || 30_000;

let worker = null;
let lastHeard = performance.now(); // the last message to or from the worker
let lastLoad = null; // {name, entries} of the sequence the worker has open
let loading = null; // the same, for the sequence being opened
let pendingReload = null; // {name, entries}: to open in a new worker at the next action

function startWorker() {
  worker = new Worker(workerUrl, { type: 'module' });
  worker.onerror = (e) => {
    reportError(`the worker failed: ${e.message || 'could not start (is www/pkg/ built? run scripts/build.sh)'}`);
  };
  worker.onmessage = onWorkerMessage;
  lastHeard = performance.now();
}

function send(msg) {
  lastHeard = performance.now();
  worker.postMessage(msg);
}

// The map and trajectory as the page was sent them: the downloads after a failure.
const mirror = new MapMirror();

function restartWorker() {
  worker.terminate();
  status.moduleFailures++;
  status.failed = true;
  status.ready = false;
  status.playing = false;
  workerPlaying = false;
  pendingReload = lastLoad;
  reportError(
    `the SLAM worker stopped answering (${Math.round(STALL_MS / 1000)} s without a frame): restarted it. ` +
      'The downloads keep the map and trajectory so far; Play, Step or Reset starts the sequence again.',
  );
  startWorker();
  setControls();
}

setInterval(() => {
  if (workerPlaying && status.ready && performance.now() - lastHeard > STALL_MS) restartWorker();
}, 1000);

/** Playback and settings messages: after a worker restart, the sequence is opened again first. */
function act(msg) {
  if (pendingReload) {
    const plays = msg.type === ToWorker.PLAY || msg.type === ToWorker.REPLAY;
    loadSequence(pendingReload, plays);
    pendingReload = null;
    if (plays || msg.type === ToWorker.RESET) return;
  }
  send(msg);
}

/** A download from the page's copy (the module has failed). */
function downloadMirror(what) {
  const base = (sequence?.name || 'surfel-slam').replace(/[^\w.-]+/g, '_');
  if (what === 'ply') download(new Blob([mirror.ply()], { type: 'application/octet-stream' }), `${base}_map.ply`);
  else download(new Blob([mirror.trajectoryTum()], { type: 'text/plain' }), `${base}_trajectory.txt`);
}

function setControls() {
  const has = !!sequence && status.ready;
  ui.play.disabled = !has;
  ui.step.disabled = !has || workerPlaying;
  ui.reset.disabled = !has;
  ui.ply.disabled = !status.ready && !status.failed;
  ui.trajectory.disabled = !status.ready && !status.failed;
  for (const b of [ui.meshGlb, ui.meshPly, ui.pointsGlb]) b.disabled = !status.ready || status.failed;
  ui.play.textContent = workerPlaying ? 'Pause' : status.done ? 'Replay' : 'Play';
  ui.play.title = workerPlaying ? 'stop after this frame' : status.done ? 'empty the map and play again from the first frame' : '';
}

function fillPresetSelect() {
  ui.preset.replaceChildren(
    ...presets.map((p) => new Option(`${p.name} (${p.width}×${p.height})`, p.name)),
    new Option('custom', 'custom'),
  );
}

function showIntrinsics(name, overrides = {}) {
  const p = presets.find((x) => x.name === name) ?? {};
  const v = { ...p, ...overrides };
  ui.preset.value = presets.some((x) => x.name === name) ? name : 'custom';
  // Presets arrive as f32 values (535.4000244...): show them as published.
  const tidy = (x) => (Number.isFinite(x) ? String(Number(x.toFixed(4))) : '');
  ui.fx.value = tidy(v.fx);
  ui.fy.value = tidy(v.fy);
  ui.cx.value = tidy(v.cx);
  ui.cy.value = tidy(v.cy);
  ui.depthScale.value = tidy(v.depthScale);
  if (v.depthMin !== undefined && v.depthMax !== undefined) views.setDepthRange(v.depthMin, Math.min(v.depthMax, 6));
}

function currentIntrinsics() {
  const base = presets.find((x) => x.name === ui.preset.value) ?? presets.find((x) => x.name === sequence?.preset) ?? {};
  const num = (el, fallback) => (el.value === '' || !Number.isFinite(Number(el.value)) ? fallback : Number(el.value));
  return {
    preset: base.name,
    width: base.width ?? 640,
    height: base.height ?? 480,
    fx: num(ui.fx, base.fx),
    fy: num(ui.fy, base.fy),
    cx: num(ui.cx, base.cx),
    cy: num(ui.cy, base.cy),
    depthScale: num(ui.depthScale, base.depthScale),
    tracker: ui.tracker.value,
    halfResolution: ui.half.checked,
  };
}

/** The choices on the page that a newly opened sequence keeps. */
const pageOptions = () => ({ tracker: ui.tracker.value, halfResolution: ui.half.checked });

// ---- display frame -----------------------------------------------------------------
// The map and the poses are in the dataset's convention. With a negative fy
// (ICL-NUIM) the camera's y axis points up in the image, so the map is the
// mirror image of the scene: shown as it is, it is upside down and
// mirrored. The page shows it through F = diag(1, -1, 1) (points p -> F p,
// poses T -> F T F), which is the map a camera with a positive fy would have
// built: upright, right-handed. The downloads keep the dataset's convention.
let flipY = false;
const F = new Float64Array([1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
const IDENTITY = new Float64Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);

/** config: a Slam config ({preset, fy?, ...}); fy, when absent, is the preset's. */
function setDisplayFrame(config) {
  const fy = config?.fy ?? presets.find((p) => p.name === config?.preset)?.fy;
  if (Number.isFinite(fy)) flipY = fy < 0;
  status.displayFlipY = flipY;
}

const displayPose = (pose) => (flipY ? multiply(F, multiply(pose, F)) : pose);

/** Mirrors a surfel chunk's positions and normals in y, in place (its arrays are this page's own). */
function displayChunk(chunk) {
  if (!flipY || !chunk) return chunk;
  for (const key of ['positions', 'normals']) {
    const a = chunk[key];
    for (let i = 1; i < a.length; i += 3) a[i] = -a[i];
  }
  return chunk;
}

const displayIntrinsics = (k) => (flipY ? { ...k, fy: Math.abs(k.fy) } : k);

function clearMap() {
  renderer?.clear();
  stats.reset();
  syncStatus();
  status.done = false;
  status.fpsAverage = 0;
  status.colourDecoder = null;
  status.framesColourDecodedInBrowser = 0;
  run = { first: 0, frames: 0 };
  gtAnchored = false;
  gtAlign = null;
  status.positionErrorCm = null;
  mirror.clear();
  plots.reset();
  plots.setGroundTruth(!!sequence?.groundTruth?.length);
  status.plotFrames = 0;
  views.clear();
  // The mesh went with the map: back to the splats that will grow again.
  ui.viewMesh.checked = false;
  status.meshView = false;
  status.meshTriangles = null;
  renderer?.setShowMesh(false);
}

let gtAlign = null; // display-frame transform from the ground truth to the estimate, set at its first pose
const gtPose = (row) => displayPose(poseFromTq([row[1], row[2], row[3]], [row[4], row[5], row[6], row[7]]));

/** The ground-truth row nearest `timestamp` (rows sorted by time), within the dataset's tolerance, or null. */
function groundTruthAt(timestamp) {
  const rows = sequence?.groundTruth;
  if (!rows?.length) return null;
  const tolerance = sequence.kind === 'tum' ? 0.02 : 0.5;
  let lo = 0;
  let hi = rows.length - 1;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (rows[mid][0] < timestamp) lo = mid + 1;
    else hi = mid;
  }
  let best = null;
  for (const i of [lo - 1, lo]) {
    if (i < 0 || i >= rows.length) continue;
    const dt = Math.abs(rows[i][0] - timestamp);
    if (dt <= tolerance && (!best || dt < best.dt)) best = { dt, row: rows[i] };
  }
  return best?.row ?? null;
}

/**
 * Draws the ground truth, anchored to the estimate at the first frame with a
 * ground-truth pose, and returns this frame's position error (metres) against
 * it, or null. `pose`: display frame.
 */
function groundTruthError(timestamp, pose) {
  if (!sequence?.groundTruth?.length) return null;
  const row = groundTruthAt(timestamp);
  if (!row) return null;
  if (!gtAnchored) {
    gtAlign = multiply(pose, invertRigid(gtPose(row)));
    renderer?.setGroundTruth(sequence.groundTruth.map((r) => transformPoint(gtAlign, transformPoint(flipY ? F : IDENTITY, [r[1], r[2], r[3]]))));
    gtAnchored = true;
  }
  const p = transformPoint(gtAlign, transformPoint(flipY ? F : IDENTITY, [row[1], row[2], row[3]]));
  return Math.hypot(p[0] - pose[12], p[1] - pose[13], p[2] - pose[14]);
}

const handlers = {
  [FromWorker.READY](msg) {
    status.ready = true;
    if ($('show-flow').checked) send({ type: ToWorker.FLOW, enabled: true });
    status.module = msg.module;
    status.threads = msg.threads;
    status.frameReader = msg.frameReader === true;
    presets = msg.presets ?? [];
    fillPresetSelect();
    const label = msg.module === 'threads' ? `threaded wasm · ${msg.threads} threads` : `single-threaded SIMD wasm · ${msg.threads} thread`;
    ui.moduleInfo.textContent = `${label}${status.crossOriginIsolated ? ' · cross-origin isolated' : ''}`;
    ui.moduleInfo.className = `badge ${msg.module}`;
    ui.moduleInfo.title = (msg.notes ?? []).join('\n');
    for (const n of msg.notes ?? []) console.info(`surfel-slam: ${n}`);
    setControls();
  },

  [FromWorker.SEQUENCE](msg) {
    if (loading?.name === msg.name) lastLoad = loading;
    // Sorted by time: groundTruthAt searches it.
    const groundTruth = [...msg.groundTruth].sort((a, b) => a[0] - b[0]);
    sequence = { name: msg.name, kind: msg.kind, preset: msg.preset, frameCount: msg.frameCount, groundTruth };
    setDisplayFrame(msg.config);
    status.failed = false;
    status.sequence = msg.name;
    status.sequenceKind = msg.kind;
    status.frameCount = msg.frameCount;
    status.error = null;
    status.errors = [];
    ui.message.hidden = true;
    $('overlay-credit').hidden = msg.name !== 'tum_fr3_teddy_clip';
    clearMap();
    const { preset, ...overrides } = msg.config ?? {};
    showIntrinsics(msg.preset, overrides);
    const gt = msg.groundTruth.length ? `, ground truth ${msg.groundTruth.length} poses` : ', no ground truth';
    ui.sequenceInfo.textContent = `${msg.name} — ${msg.kind}, ${msg.frameCount} frames${gt}, camera ${msg.preset}`;
    setControls();
  },

  [FromWorker.FRAME](msg) {
    const t0 = performance.now();
    status.flowTracks = msg.flow?.tracks ? msg.flow.tracks.length / 4 : 0;
    stats.onFrame(msg);
    countRunFrame(msg);
    noteColourDecoder(msg);
    mirror.update(msg.surfels);
    if (msg.refresh) mirror.update(msg.refresh);
    mirror.addPose(msg.result);
    const pose = displayPose(msg.result.pose);
    if (renderer) {
      renderer.updateSurfels(displayChunk(msg.surfels));
      if (msg.refresh) renderer.updateSurfels(displayChunk(msg.refresh));
      renderer.setCameraPose(pose, displayIntrinsics(currentIntrinsics()));
    }
    const error = groundTruthError(msg.timestamp, pose);
    status.positionErrorCm = error === null ? status.positionErrorCm : Number((error * 100).toFixed(3));
    plots.add(msg.index, msg.result.timings, stats.surfels, error);
    status.plotFrames = plots.frames;
    views.show(msg.input.colour, msg.input.depth, Number(ui.depthScale.value) || msg.input.depthScale || 5000, msg.flow, msg.input.colourPreview, msg.input.depthPreview);
    if (msg.done) status.done = true;
    syncStatus();
    // How far the display trails the worker (main thread busy drawing or uploading).
    status.displayLagMs = Math.round(performance.now() + performance.timeOrigin - msg.timing.doneAt);
    status.uploadMs = Number((performance.now() - t0).toFixed(1));
    status.drawMs = renderer ? Number(renderer.lastDrawMs.toFixed(1)) : 0;
    status.gpuMs = renderer ? Math.round(renderer.gpuMs) : 0;
  },

  [FromWorker.FRAME_ERROR](msg) {
    stats.onFailedFrame(msg);
    noteColourDecoder(msg);
    if (msg.input) views.show(msg.input.colour, msg.input.depth, Number(ui.depthScale.value) || 5000, null, msg.input.colourPreview);
    reportError(`frame ${msg.index + 1} skipped — ${msg.message}`);
    syncStatus();
  },

  [FromWorker.LOAD_ERROR](msg) {
    reportError(`cannot open the sequence: ${msg.message}${sequence ? ' (the current map is kept)' : ''}`);
  },

  [FromWorker.CONFIG_ERROR](msg) {
    reportError(msg.message);
  },

  [FromWorker.STATE](msg) {
    workerPlaying = msg.playing;
    status.failed = msg.failed === true;
    if (renderer) renderer.throttle = msg.playing;
    status.playing = msg.playing;
    status.done = msg.done;
    status.frameCount = msg.frameCount;
    if (!msg.playing) {
      stats.onIdle();
      run = { first: 0, frames: 0 };
    }
    setControls();
  },

  [FromWorker.RESET](msg) {
    if (msg.config) setDisplayFrame(msg.config);
    status.failed = false;
    clearMap();
    setControls();
  },

  [FromWorker.MODULE_FAILED](msg) {
    status.moduleFailures++;
    status.failed = true;
    workerPlaying = false;
    status.playing = false;
    reportError(
      `the SLAM module failed after ${msg.frames} frames (${msg.message}). Playback stopped; ` +
        'the downloads keep the map and trajectory so far; Play, Step or Reset starts again on a fresh module.',
    );
    setControls();
  },

  [FromWorker.MESH_PROGRESS](msg) {
    status.meshProgress = msg.fraction;
    ui.meshProgress.textContent = `meshing ${Math.round(100 * msg.fraction)} %`;
  },

  [FromWorker.MESH](msg) {
    meshDone();
    if (msg.unavailable || msg.error) {
      reportError(`mesh: ${msg.error || 'the SLAM module failed; Play, Step or Reset starts again'}`);
      return;
    }
    const mesh = displayChunk({ positions: msg.positions, normals: msg.normals, colours: msg.colours, indices: msg.indices });
    renderer?.setMesh(mesh);
    status.meshTriangles = msg.indices.length / 3;
  },

  [FromWorker.EXPORT](msg) {
    if (msg.what.startsWith('mesh-') || msg.what === 'points-glb') {
      meshDone();
      if (msg.unavailable || msg.error) {
        reportError(`${msg.what}: ${msg.error || 'the SLAM module failed; Play, Step or Reset starts again'}`);
        return;
      }
      const base = (msg.name || 'surfel-slam').replace(/[^\w.-]+/g, '_');
      const [kind, ext] = msg.what.split('-');
      download(new Blob([msg.bytes], { type: ext === 'glb' ? 'model/gltf-binary' : 'application/octet-stream' }), `${base}_${kind}.${ext}`);
      return;
    }
    if (msg.unavailable) {
      downloadMirror(msg.what);
      return;
    }
    const base = (msg.name || 'surfel-slam').replace(/[^\w.-]+/g, '_');
    if (msg.what === 'ply') download(new Blob([msg.bytes], { type: 'application/octet-stream' }), `${base}_map.ply`);
    else download(new Blob([msg.text], { type: 'text/plain' }), `${base}_trajectory.txt`);
  },

  [FromWorker.FATAL](msg) {
    reportError(msg.message);
  },
};

function onWorkerMessage(event) {
  lastHeard = performance.now();
  const msg = event.data;
  const handler = handlers[msg.type];
  try {
    if (handler) handler(msg);
  } catch (e) {
    reportError(`page error while handling ${msg.type}: ${e.message}`);
  }
}
startWorker();

function download(blob, name) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

// ---- controls ------------------------------------------------------------------------

ui.play.addEventListener('click', () => {
  if (workerPlaying) send({ type: ToWorker.PAUSE });
  else act({ type: status.done ? ToWorker.REPLAY : ToWorker.PLAY });
  workerPlaying = !workerPlaying;
  if (workerPlaying) status.done = false;
  setControls();
});
ui.step.addEventListener('click', () => act({ type: ToWorker.STEP }));
ui.reset.addEventListener('click', () => act({ type: ToWorker.RESET }));
ui.ply.addEventListener('click', () => (status.failed ? downloadMirror('ply') : send({ type: ToWorker.EXPORT_PLY })));
ui.trajectory.addEventListener('click', () =>
  status.failed ? downloadMirror('trajectory') : send({ type: ToWorker.EXPORT_TRAJECTORY }),
);

function meshDone() {
  status.meshProgress = null;
  ui.meshProgress.textContent = '';
}
ui.meshGlb.addEventListener('click', () => send({ type: ToWorker.EXPORT_MESH, format: 'glb' }));
ui.meshPly.addEventListener('click', () => send({ type: ToWorker.EXPORT_MESH, format: 'ply' }));
ui.pointsGlb.addEventListener('click', () => send({ type: ToWorker.EXPORT_MESH, format: 'glb-points' }));
// Meshed once each time the view is switched on (not every frame: it takes
// about as long as a few frames).
ui.viewMesh.addEventListener('change', () => {
  status.meshView = ui.viewMesh.checked;
  renderer?.setShowMesh(status.meshView);
  if (status.meshView) send({ type: ToWorker.VIEW_MESH });
});

/** New camera or tracker settings: the worker restarts the sequence with them and plays. */
function applySettings() {
  const c = currentIntrinsics();
  if (![c.fx, c.fy, c.cx, c.cy, c.depthScale].every(Number.isFinite)) {
    reportError('intrinsics: fx, fy, cx, cy and depth scale must be numbers');
    return;
  }
  act({ type: ToWorker.CONFIG, config: c });
}

ui.preset.addEventListener('change', () => {
  if (ui.preset.value === 'custom') return;
  showIntrinsics(ui.preset.value);
  if (sequence) applySettings();
});
for (const el of [ui.fx, ui.fy, ui.cx, ui.cy, ui.depthScale]) {
  el.addEventListener('input', () => {
    ui.preset.value = 'custom';
  });
}
$('apply-intrinsics').addEventListener('click', applySettings);
ui.tracker.addEventListener('change', () => {
  if (sequence) applySettings();
});
ui.half.addEventListener('change', () => {
  if (sequence) applySettings();
});
$('show-flow').addEventListener('change', (e) => send({ type: ToWorker.FLOW, enabled: e.target.checked }));

// The stage colours of the timing chart.
$('plot-legend').replaceChildren(
  ...Object.entries(STAGE_COLOURS).flatMap(([name, colour]) => {
    const swatch = document.createElement('span');
    swatch.style.background = colour;
    return [swatch, document.createTextNode(name)];
  }),
);

// A hint naming the panel's sections below the fold (at 1280x800 the
// camera and view settings are); a click scrolls to the first.
const panel = $('panel');
const moreBelow = $('more-below');
function updateMoreBelow() {
  const bottom = panel.getBoundingClientRect().bottom - moreBelow.offsetHeight;
  const hidden = [...panel.querySelectorAll('section h2')].filter((h) => h.getBoundingClientRect().top > bottom);
  moreBelow.hidden = hidden.length === 0;
  $('more-below-text').textContent = `below: ${hidden.map((h) => h.textContent).join(' · ')}`;
  moreBelow.onclick = () => hidden[0]?.scrollIntoView({ behavior: 'smooth', block: 'start' });
}
panel.addEventListener('scroll', updateMoreBelow, { passive: true });
window.addEventListener('resize', updateMoreBelow);
const panelObserver = new ResizeObserver(updateMoreBelow); // messages and stats change the sections' heights
for (const el of panel.children) panelObserver.observe(el);
$('show-plots').addEventListener('change', (e) => {
  $('plots').hidden = !e.target.checked;
  plots.setVisible(e.target.checked);
});

$('colour-mode').addEventListener('change', (e) => renderer?.setMode(e.target.value));
$('splat-size').addEventListener('input', (e) => {
  if (renderer) {
    renderer.sizeScale = Number(e.target.value);
    renderer.dirty = true;
  }
});
const follow = $('follow');
follow.addEventListener('change', () => {
  if (!renderer) return;
  if (follow.checked) renderer.follow = true;
  else renderer.leaveFollow();
  renderer.dirty = true;
});
if (renderer) renderer.onFollowChange = (on) => (follow.checked = on);
for (const [id, key] of [['show-trajectory', 'trajectory'], ['show-gt', 'groundTruth'], ['show-frustum', 'frustum']]) {
  $(id).addEventListener('change', (e) => {
    if (!renderer) return;
    renderer.show[key] = e.target.checked;
    renderer.dirty = true;
  });
}
$('fit-button').addEventListener('click', () => renderer?.fitView());
$('view-button').addEventListener('click', () => {
  if (!renderer) return;
  follow.checked = false;
  renderer.follow = false;
  renderer.resetView();
});

// ---- sequences -----------------------------------------------------------------------

const urlParams = () => new URLSearchParams(location.search);

function loadSequence(seq, autoplay) {
  loading = { name: seq.name, entries: seq.entries };
  pendingReload = null;
  ui.sequenceInfo.textContent = `reading ${seq.name} (${seq.entries.length} files)…`;
  send({ type: ToWorker.LOAD, name: seq.name, entries: seq.entries, autoplay, options: pageOptions() });
}

setupSequenceInput({
  input: $('folder-input'),
  archiveInput: $('archive-input'),
  dropTarget: document.body,
  onSequence: (seq) => loadSequence(seq, true),
  onError: (m) => reportError(m),
});

async function loadSample(autoplay) {
  try {
    const seq = await fromManifest(new URL('sample/manifest.json', location.href).href);
    loadSequence(seq, autoplay);
  } catch (e) {
    reportError(`cannot load the bundled sample: ${e.message}`);
    ui.sequenceInfo.textContent = 'no sequence: open or drop a folder';
  }
}
$('sample-button').addEventListener('click', () => loadSample(true));

// ?testHooks=1: the browser tests can make the module fail, as a panic would.
if (testHooks) {
  window.surfelSlamTest = {
    breakModule: () => send({ type: ToWorker.TEST_BREAK }),
    hangModule: () => send({ type: ToWorker.TEST_HANG }),
  };
}

// Autoplay the sample unless the URL says ?sample=0 (tests that upload a folder).
if (urlParams().get('sample') !== '0') loadSample(true);
else ui.sequenceInfo.textContent = 'no sequence: open or drop a folder';
