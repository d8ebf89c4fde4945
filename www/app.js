// UI wiring: starts the worker, plays the bundled sample on first load, routes
// worker messages to the renderer, the input views and the statistics, and
// keeps window.surfelSlamStatus (read by the browser tests) up to date.
import { Renderer } from './renderer.js';
import { InputViews } from './views.js';
import { Stats } from './stats.js';
import { fromManifest, setupSequenceInput } from './sequence.js';
import { poseFromTq, multiply, invertRigid, transformPoint } from './math3d.js';

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
  message: $('message'),
  messageText: $('message-text'),
  preset: $('preset'),
  fx: $('fx'),
  fy: $('fy'),
  cx: $('cx'),
  cy: $('cy'),
  depthScale: $('depth-scale'),
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

function syncStatus() {
  status.framesProcessed = stats.framesProcessed;
  status.framesLost = stats.framesLost;
  status.framesRecovered = stats.framesRecovered;
  status.framesFailed = stats.framesFailed;
  status.surfels = stats.surfels;
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
const worker = new Worker(workerUrl, { type: 'module' });
worker.onerror = (e) => {
  reportError(`the worker failed: ${e.message || 'could not start (is www/pkg/ built? run scripts/build.sh)'}`);
};

function send(msg) {
  worker.postMessage(msg);
}

function setControls() {
  const has = !!sequence && status.ready;
  ui.play.disabled = !has;
  ui.step.disabled = !has || workerPlaying;
  ui.reset.disabled = !has;
  ui.ply.disabled = !status.ready;
  ui.trajectory.disabled = !status.ready;
  ui.play.textContent = workerPlaying ? 'Pause' : status.done ? 'Replay' : 'Play';
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
    tracker: $('tracker').value,
  };
}

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
  views.clear();
}

/** Draws the ground truth, anchored to the estimate at the first frame with a ground-truth pose. */
function anchorGroundTruth(timestamp, pose) {
  if (gtAnchored || !sequence?.groundTruth?.length || !renderer) return;
  const tolerance = sequence.kind === 'tum' ? 0.02 : 0.5;
  let best = null;
  for (const row of sequence.groundTruth) {
    const dt = Math.abs(row[0] - timestamp);
    if (dt <= tolerance && (!best || dt < best.dt)) best = { dt, row };
  }
  if (!best) return;
  const gtPose = (row) => poseFromTq([row[1], row[2], row[3]], [row[4], row[5], row[6], row[7]]);
  const align = multiply(pose, invertRigid(gtPose(best.row)));
  renderer.setGroundTruth(sequence.groundTruth.map((row) => transformPoint(align, [row[1], row[2], row[3]])));
  gtAnchored = true;
}

const handlers = {
  ready(msg) {
    status.ready = true;
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

  sequence(msg) {
    sequence = { name: msg.name, kind: msg.kind, preset: msg.preset, frameCount: msg.frameCount, groundTruth: msg.groundTruth };
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

  frame(msg) {
    const t0 = performance.now();
    status.flowTracks = msg.flow?.tracks ? msg.flow.tracks.length / 4 : 0;
    stats.onFrame(msg);
    countRunFrame(msg);
    noteColourDecoder(msg);
    if (renderer) {
      renderer.updateSurfels(msg.surfels);
      if (msg.refresh) renderer.updateSurfels(msg.refresh);
      const intr = currentIntrinsics();
      renderer.setCameraPose(msg.result.pose, intr);
      anchorGroundTruth(msg.timestamp, msg.result.pose);
    }
    views.show(msg.input.colour, msg.input.depth, Number(ui.depthScale.value) || msg.input.depthScale || 5000, msg.flow, msg.input.colourPreview, msg.input.depthPreview);
    if (msg.done) status.done = true;
    syncStatus();
    // How far the display trails the worker (main thread busy drawing or uploading).
    status.displayLagMs = Math.round(performance.now() + performance.timeOrigin - msg.timing.doneAt);
    status.uploadMs = Number((performance.now() - t0).toFixed(1));
    status.drawMs = renderer ? Number(renderer.lastDrawMs.toFixed(1)) : 0;
    status.gpuMs = renderer ? Math.round(renderer.gpuMs) : 0;
  },

  'frame-error'(msg) {
    stats.onFailedFrame(msg);
    noteColourDecoder(msg);
    if (msg.input) views.show(msg.input.colour, msg.input.depth, Number(ui.depthScale.value) || 5000, null, msg.input.colourPreview);
    reportError(`frame ${msg.index + 1} skipped — ${msg.message}`);
    syncStatus();
  },

  'load-error'(msg) {
    reportError(`cannot open the sequence: ${msg.message}${sequence ? ' (the current map is kept)' : ''}`);
  },

  'config-error'(msg) {
    reportError(msg.message);
  },

  state(msg) {
    workerPlaying = msg.playing;
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

  reset() {
    clearMap();
    setControls();
  },

  export(msg) {
    const base = (msg.name || 'surfel-slam').replace(/[^\w.-]+/g, '_');
    if (msg.what === 'ply') download(new Blob([msg.bytes], { type: 'application/octet-stream' }), `${base}_map.ply`);
    else download(new Blob([msg.text], { type: 'text/plain' }), `${base}_trajectory.txt`);
  },

  fatal(msg) {
    reportError(msg.message);
  },
};

worker.onmessage = (event) => {
  const msg = event.data;
  const handler = handlers[msg.type];
  try {
    if (handler) handler(msg);
  } catch (e) {
    reportError(`page error while handling ${msg.type}: ${e.message}`);
  }
};

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
  if (workerPlaying) send({ type: 'pause' });
  else send({ type: 'play' });
  workerPlaying = !workerPlaying;
  setControls();
});
ui.step.addEventListener('click', () => send({ type: 'step' }));
ui.reset.addEventListener('click', () => send({ type: 'reset' }));
ui.ply.addEventListener('click', () => send({ type: 'exportPly' }));
ui.trajectory.addEventListener('click', () => send({ type: 'exportTrajectory' }));

ui.preset.addEventListener('change', () => {
  if (ui.preset.value !== 'custom') showIntrinsics(ui.preset.value);
});
for (const el of [ui.fx, ui.fy, ui.cx, ui.cy, ui.depthScale]) {
  el.addEventListener('input', () => {
    ui.preset.value = 'custom';
  });
}
$('apply-intrinsics').addEventListener('click', () => {
  const c = currentIntrinsics();
  if (![c.fx, c.fy, c.cx, c.cy, c.depthScale].every(Number.isFinite)) {
    reportError('intrinsics: fx, fy, cx, cy and depth scale must be numbers');
    return;
  }
  send({ type: 'config', config: c });
});

$('tracker').addEventListener('change', () => send({ type: 'config', config: currentIntrinsics() }));
$('show-flow').addEventListener('change', (e) => send({ type: 'flow', enabled: e.target.checked }));

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

function loadSequence(seq, autoplay) {
  ui.sequenceInfo.textContent = `reading ${seq.name} (${seq.entries.length} files)…`;
  send({ type: 'load', name: seq.name, entries: seq.entries, autoplay });
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

// Autoplay the sample unless the URL says ?sample=0 (tests that upload a folder).
const params = new URLSearchParams(location.search);
if (params.get('sample') !== '0') loadSample(true);
else ui.sequenceInfo.textContent = 'no sequence: open or drop a folder';
