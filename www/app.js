// UI wiring: starts the worker, plays the bundled sample on first load, routes
// worker messages to the renderer, the input views and the statistics, and
// keeps window.surfelSlamStatus (read by the browser tests) up to date.
// Beside this file: camera-settings.js (the settings panel), display-frame.js
// (how the map and the ground truth are shown), downloads.js (saved files),
// view-controls.js (the view options and the panel's scroll hint),
// last-session.js (the last session kept in the browser and offered back),
// page-status.js (window.surfelSlamStatus, what the page reports to its tests),
// reference-view.js (what the run is compared with, named; "Reference…"),
// map-notice.js (a run that mapped nothing says so over the map).
import { Renderer } from './renderer.js';
import { InputViews } from './views.js';
import { Stats } from './stats.js';
import { Plots } from './plots.js';
import { fromManifest, readingLine, setupSequenceInput } from './sequence.js';
import { ToWorker, FromWorker } from './protocol.js';
import { MapMirror } from './map-mirror.js';
import { CameraSettings } from './camera-settings.js';
import { DisplayFrame, GroundTruthTrack } from './display-frame.js';
import { downloadMirror, downloadSession, isMeshExport, saveExport } from './downloads.js';
import { wireViewControls } from './view-controls.js';
import { MessageBoard } from './messages.js';
import { LastSession } from './last-session.js';
import { status } from './page-status.js';
import { GROUND_TRUTH, ODOMETRY, ReferenceView, YOUR_REFERENCE } from './reference-view.js';
import { MapNotice } from './map-notice.js';

const $ = (id) => document.getElementById(id);


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
  depthScale: $('depth-scale'),
  saveSession: $('save-session-button'),
  sessionInput: $('session-input'),
  sessionLocalise: $('session-localise'),
};

let sequence = null; // {name, kind, preset, frameCount, groundTruth: GroundTruthTrack (the reference drawn), line}
let framePoses = []; // {index, timestamp, pose (display frame)} of this run's frames: the drift again for a reference loaded later
let workerPlaying = false;
let run = { first: 0, frames: 0 }; // wall clock of this playback run

// ---- messages on the page ------------------------------------------------------

const board = new MessageBoard({ box: $('message'), text: $('message-text'), close: $('message-close') });

function reportError(text) {
  status.error = text;
  status.errors.push(text);
  if (status.errors.length > 50) status.errors.shift();
  board.report(text);
  status.shownErrors = board.texts();
  console.warn(`surfel-slam: ${text}`);
}

/**
 * A camera setting that looks wrong for the data, or (`about` null) what
 * was skipped reading a sequence or a reference file, the message naming
 * the file (a cut-off last row): shown with the errors, kept in
 * status.warnings.
 */
function reportWarning(text, about = 'camera settings') {
  const line = about ? `${about}: ${text}` : text;
  status.warnings.push(line);
  board.report(line, 'warning');
  status.shownErrors = board.texts();
  console.warn(`surfel-slam: ${line}`);
}

/** A new run or new settings: the messages about the old one no longer apply. */
function clearMessages() {
  status.error = null;
  status.warnings = [];
  board.clear();
  // The offer of the last session outlives the run that cleared the rest.
  if (lastSession.offer) board.report(...lastSession.offer);
  status.shownErrors = board.texts();
}

const lastSession = new LastSession(status, board);
$('message-close').addEventListener('click', () => lastSession.withdraw());

// ---- renderer, views, stats ------------------------------------------------------

let renderer = null;
try {
  renderer = new Renderer($('map-canvas'));
  const splats = new URLSearchParams(location.search).get('splats');
  if (splats !== null && Number.isFinite(Number(splats))) renderer.splatBudget = Math.max(0, Number(splats));
} catch (e) {
  reportError(`cannot draw the map: ${e.message}`);
}
const views = new InputViews($('colour-view'), $('depth-view'), $('depth-caption'));
views.clear();
const stats = new Stats($('stats'));
const plots = new Plots({ timing: $('plot-timing'), surfels: $('plot-surfels'), error: $('plot-error') }, (charts) => {
  status.driftPlotTitle = charts.error?.drawnTitle ?? null;
});
const mapNotice = new MapNotice($('map-notice'));
const referenceView = new ReferenceView(
  { name: $('reference-name'), check: $('show-gt-label'), input: $('reference-input'), plot: $('plot-error') },
  {
    onFile: (name, text) => {
      if (!sequence) reportError(`${name}: open a sequence first: a reference is matched to its frames`);
      else act({ type: ToWorker.REFERENCE, name, text });
    },
    onError: reportError,
    namedIn: [plots, stats, status],
  },
);
const settings = new CameraSettings(
  {
    preset: $('preset'),
    fx: $('fx'),
    fy: $('fy'),
    cx: $('cx'),
    cy: $('cy'),
    depthScale: ui.depthScale,
    tracker: $('tracker'),
    noise: $('noise'),
    half: $('half-resolution'),
    loopClosure: $('loop-closure'),
    apply: $('apply-intrinsics'),
  },
  {
    views,
    hasSequence: () => !!sequence,
    onError: reportError,
    // New camera or tracker settings: the worker restarts the sequence with them and plays.
    onApply: (config) => act({ type: ToWorker.CONFIG, config }),
  },
);

function syncStatus() {
  status.framesProcessed = stats.framesProcessed;
  status.framesLost = stats.framesLost;
  status.framesRecovered = stats.framesRecovered;
  status.framesHeld = stats.framesHeld;
  status.framesFailed = stats.framesFailed;
  status.framesRelocalised = stats.framesRelocalised;
  status.loopClosures = stats.loopClosures;
  status.surfels = stats.surfels; // in the map (the report's count)
  status.surfelSlots = stats.surfelSlots; // the arrays' length (absorbed surfels not yet compacted included)
  status.ate = stats.ate;
  status.fps = Number(stats.fps.toFixed(2));
  status.msPerFrame = Number(stats.msPerFrame.toFixed(2));
  status.stageMedianMs = stats.stageMedians();
  status.workerMedianMs = stats.workerMedians();
  status.frameIndex = stats.frameIndex;
  status.changedSurfels = stats.changed ?? 0;
  status.splatsDrawn = renderer?.splatsDrawn ?? 0;
}

function noteColourDecoder(msg) {
  if (msg.videoError) {
    // Said once a run: the frames after it fail alike (a video shorter than the scan, a decoder that gave up).
    if (status.framesVideoFailed++ === 0) {
      const line = `colour: ${msg.videoError}; frames without it play on depth alone`;
      status.warnings.push(line);
      board.report(line, 'warning');
      status.shownErrors = board.texts();
    }
  }
  if (!msg.colourDecoder) return;
  status.colourDecoder = msg.colourDecoder;
  if (msg.colourDecoder === 'browser') status.framesColourDecodedInBrowser++;
  if (msg.colourDecoder === 'video') status.framesColourFromVideo++;
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

function send(msg, transfer = []) {
  lastHeard = performance.now();
  worker.postMessage(msg, transfer);
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

function setControls() {
  const has = !!sequence && status.ready;
  ui.play.disabled = !has;
  ui.step.disabled = !has || workerPlaying;
  ui.reset.disabled = !has;
  ui.ply.disabled = !status.ready && !status.failed;
  ui.trajectory.disabled = !status.ready && !status.failed;
  for (const b of [ui.meshGlb, ui.meshPly, ui.pointsGlb]) b.disabled = !status.ready || status.failed;
  setSaveSession();
  ui.play.textContent = workerPlaying ? 'Pause' : status.done ? 'Replay' : 'Play';
  ui.play.title = workerPlaying ? 'stop after this frame' : status.done ? 'empty the map and play again from the first frame' : '';
}

/** Save session: only with a map to save. */
function setSaveSession() {
  ui.saveSession.disabled = !status.ready || status.failed || !(status.surfels > 0);
}

// ---- display frame -----------------------------------------------------------------

const display = new DisplayFrame();
function setDisplayFrame(config) {
  display.setFromConfig(config, settings.presets);
  status.displayFlipY = display.flipY;
}

function clearMap() {
  renderer?.clear();
  stats.reset();
  syncStatus();
  status.done = false;
  status.fpsAverage = 0;
  status.colourDecoder = null;
  status.framesColourDecodedInBrowser = 0;
  status.framesColourFromVideo = 0;
  status.framesVideoFailed = 0;
  run = { first: 0, frames: 0 };
  sequence?.groundTruth.unanchor();
  framePoses = [];
  mapNotice.hide();
  status.mapNotice = null;
  status.positionErrorCm = null;
  status.relocalisedFrames = [];
  status.trajectoryReplaced = 0;
  status.session = null;
  status.framesUnplaced = 0;
  mirror.clear();
  plots.reset();
  status.plotFrames = 0;
  views.clear();
  // The mesh went with the map: back to the splats that will grow again.
  ui.viewMesh.checked = false;
  status.meshView = false;
  status.meshTriangles = null;
  renderer?.setShowMesh(false);
}

/**
 * A loop closure moved past poses: the worker sent the whole trajectory
 * (TUM text, this frame's pose included); the drawn path and the
 * downloads' copy are replaced by it.
 */
function replaceTrajectory(tum) {
  const points = pathFromTum(tum);
  renderer?.setTrajectory(points.slice(0, -1).map((p) => display.point(p)));
  status.trajectoryReplaced++;
}

/** The camera positions of a TUM trajectory (world frame, metres); the page's copy for the downloads takes the text. */
function pathFromTum(tum) {
  mirror.setTrajectoryTum(tum);
  return tum
    .split('\n')
    .filter((line) => line && !line.startsWith('#'))
    .map((line) => line.trim().split(/\s+/).slice(1, 4).map(Number))
    .filter((p) => p.length === 3 && p.every(Number.isFinite));
}

/**
 * An opened session (FromWorker.SESSION_OPENED's, or a sequence going on
 * in it): the map, the camera path and the statistics are the loaded Slam's.
 */
function showSession(name, snapshot) {
  clearMap();
  stats.onSession(snapshot);
  mirror.update(snapshot.map);
  renderer?.updateSurfels(display.chunk(snapshot.map));
  const points = pathFromTum(snapshot.trajectoryTum);
  if (points.length) renderer?.setTrajectory(points.map((p) => display.point(p)));
  status.session = { name, frames: snapshot.frames, surfels: snapshot.surfels, localising: snapshot.localising };
  syncStatus();
  setControls();
}

const handlers = {
  [FromWorker.READY](msg) {
    status.ready = true;
    if ($('show-flow').checked) send({ type: ToWorker.FLOW, enabled: true });
    status.module = msg.module;
    status.threads = msg.threads;
    status.frameReader = msg.frameReader === true;
    settings.setPresets(msg.presets ?? []);
    const label = msg.module === 'threads' ? `threaded wasm · ${msg.threads} threads` : `single-threaded SIMD wasm · ${msg.threads} thread`;
    ui.moduleInfo.textContent = `${label}${status.crossOriginIsolated ? ' · cross-origin isolated' : ''}`;
    ui.moduleInfo.className = `badge ${msg.module}`;
    ui.moduleInfo.title = (msg.notes ?? []).join('\n');
    for (const n of msg.notes ?? []) console.info(`surfel-slam: ${n}`);
    setControls();
  },

  [FromWorker.SEQUENCE](msg) {
    const openedSession = status.session?.name;
    if (loading?.name === msg.name) lastLoad = loading;
    // Without ground truth, the device's odometry (Stray Scanner) is the reference drawn, named as such.
    const odometry = msg.groundTruth.length ? [] : (msg.odometry ?? []);
    const groundTruth = new GroundTruthTrack(msg.groundTruth.length ? msg.groundTruth : odometry, msg.kind);
    sequence = { name: msg.name, kind: msg.kind, preset: msg.preset, frameCount: msg.frameCount, groundTruth };
    referenceView.show(msg.groundTruth.length ? GROUND_TRUTH : odometry.length ? ODOMETRY : null);
    status.userReference = null;
    settings.sequencePreset = msg.preset;
    const { width, height } = msg.config ?? {};
    settings.sequenceSize = Number.isInteger(width) && Number.isInteger(height) ? { width, height } : null;
    settings.sequencePresets = msg.presets ?? null;
    const frameSize = settings.current();
    views.setAspect(frameSize.width, frameSize.height);
    setDisplayFrame(msg.config);
    status.failed = false;
    status.sequence = msg.name;
    status.sequenceKind = msg.kind;
    status.frameCount = msg.frameCount;
    status.errors = [];
    clearMessages();
    ui.sequenceInfo.classList.remove('failed');
    $('overlay-credit').hidden = msg.name !== 'tum_fr3_teddy_clip';
    clearMap();
    const { preset, ...overrides } = msg.config ?? {};
    settings.show(msg.preset, overrides);
    const gt = msg.groundTruth.length
      ? `, ground truth ${msg.groundTruth.length} poses`
      : odometry.length
        ? `, no ground truth, the device's odometry ${odometry.length} poses`
        : ', no ground truth';
    // A scan without colour images says once where its colour comes from, or that it has none.
    status.colourNote = msg.colourNote ?? null;
    const colour = msg.colourNote ? `; ${msg.colourNote}` : '';
    sequence.line = `${msg.name} — ${msg.kind}, ${msg.frameCount} frames${gt}, camera ${msg.preset}${colour}`;
    ui.sequenceInfo.textContent = sequence.line;
    for (const w of msg.readWarnings ?? []) reportWarning(w, null);
    for (const w of msg.warnings ?? []) reportWarning(w);
    if (msg.session) showSession(openedSession ?? msg.name, msg.session);
    setControls();
  },

  [FromWorker.SESSION_SAVED](msg) {
    if (msg.error) {
      if (!msg.keep) reportError(`cannot save the session: ${msg.error}`);
      return;
    }
    lastSession.keep(msg.bytes, msg.name ?? sequence?.name);
    if (msg.keep) {
      status.sessionKeepSaveMs = Number(msg.ms.toFixed(1));
      return; // kept for "Restore last session" only
    }
    status.sessionSaveMs = Number(msg.ms.toFixed(1));
    status.sessionSaveBytes = msg.bytes.byteLength;
    console.info(`surfel-slam: session saved in ${status.sessionSaveMs} ms, ${msg.bytes.byteLength} bytes`);
    downloadSession(msg.bytes, msg.name ?? sequence?.name);
  },

  [FromWorker.SESSION_OPENED](msg) {
    status.sessionOpenMs = Number(msg.ms.toFixed(1));
    console.info(`surfel-slam: session ${msg.name} opened in ${status.sessionOpenMs} ms`);
    clearMessages();
    if (msg.sequenceClosed) {
      sequence = null;
      lastLoad = null;
      status.sequence = null;
      status.sequenceKind = null;
      status.frameCount = 0;
    }
    if (!sequence) setDisplayFrame(msg.config);
    showSession(msg.name, msg.session);
    const mode = msg.session.localising ? 'the next frames are localised in it' : 'the next frames continue it';
    ui.sequenceInfo.textContent = `session ${msg.name}: ${msg.session.frames} frames, ${msg.session.surfels} surfels; ${mode}${sequence ? ` (${sequence.name}: Play goes on)` : ` (open or drop a sequence${msg.sequenceClosed ? ' of its camera' : ''})`}`;
  },

  [FromWorker.SESSION_ERROR](msg) {
    reportError(`cannot open the session ${msg.name}: ${msg.message}${status.surfels > 0 ? ' (the current map is kept)' : ''}`);
  },

  [FromWorker.FRAME](msg) {
    const t0 = performance.now();
    status.flowTracks = msg.flow?.tracks ? msg.flow.tracks.length / 4 : 0;
    if (Number.isFinite(msg.wasmMemoryBytes)) status.wasmMemoryMiB = Number((msg.wasmMemoryBytes / 2 ** 20).toFixed(1));
    stats.onFrame(msg);
    if (msg.result.settingsWarning) reportWarning(msg.result.settingsWarning);
    countRunFrame(msg);
    noteColourDecoder(msg);
    mirror.update(msg.surfels);
    if (msg.refresh) mirror.update(msg.refresh);
    mirror.addPose(msg.result);
    if (msg.trajectoryTum) replaceTrajectory(msg.trajectoryTum);
    // Localising in an opened session: a frame not found in the map has no pose ('unplaced').
    const pose = msg.result.pose ? display.pose(msg.result.pose) : null;
    if (!pose) status.framesUnplaced++;
    else framePoses.push({ index: msg.index, timestamp: msg.timestamp, pose });
    if (renderer) {
      renderer.updateSurfels(display.chunk(msg.surfels));
      if (msg.refresh) renderer.updateSurfels(display.chunk(msg.refresh));
      if (pose) renderer.setCameraPose(pose, display.intrinsics(settings.current()));
    }
    const error = sequence && pose ? sequence.groundTruth.error(msg.timestamp, pose, display, (points) => renderer?.setGroundTruth(points)) : null;
    status.positionErrorCm = error === null ? status.positionErrorCm : Number((error * 100).toFixed(3));
    const relocalised = Number.isFinite(msg.result.relocalisedFrom);
    if (relocalised) status.relocalisedFrames.push(msg.index);
    plots.add(msg.index, msg.result.timings, stats.surfels, error, {
      verdict: msg.result.verdict,
      relocalised,
      loopClosed: msg.trajectoryTum != null,
    });
    status.plotFrames = plots.frames;
    views.show(msg.input.colour, msg.input.depth, Number(ui.depthScale.value) || msg.input.depthScale || 5000, msg.flow, msg.input.colourPreview, msg.input.depthPreview);
    if (msg.done) status.done = true;
    syncStatus();
    setSaveSession();
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
    reportError(`frame ${msg.index} skipped — ${msg.message}`);
    syncStatus();
  },

  [FromWorker.LOAD_ERROR](msg) {
    const kept = !sequence ? '' : msg.resumed ? ` (the current map is kept; ${sequence.name} plays on)` : ' (the current map is kept)';
    reportError(`cannot open the sequence: ${msg.message}${kept}`);
    openFailed(msg.name);
  },

  [FromWorker.REFERENCE](msg) {
    if (msg.error || !sequence) {
      reportError(`cannot use ${msg.name} as the reference: ${msg.error ?? 'no sequence is open'}`);
      return;
    }
    // Drawn and scored in place of the sequence's own (a sequence opened next has its own again).
    sequence.groundTruth = new GroundTruthTrack(msg.rows, sequence.kind);
    referenceView.show(YOUR_REFERENCE);
    renderer?.setGroundTruth(null);
    plots.setErrors(framePoses.map((f) => [f.index, sequence.groundTruth.error(f.timestamp, f.pose, display, (points) => renderer?.setGroundTruth(points))]));
    const latest = plots.latestErrorCm();
    status.positionErrorCm = latest === null ? null : Number(latest.toFixed(3));
    stats.onScore(msg.ate);
    const by = msg.key === 'frame' ? 'by frame number' : 'by timestamp';
    sequence.line = `${sequence.line.replace(/; your reference .*$/, '')}; your reference ${msg.name}: ${msg.poses} poses, ${msg.matched} of ${sequence.frameCount} frames matched ${by}`;
    ui.sequenceInfo.textContent = sequence.line;
    status.userReference = { name: msg.name, key: msg.key, poses: msg.poses, matched: msg.matched };
    for (const w of msg.warnings ?? []) reportWarning(w, null);
    syncStatus();
  },

  [FromWorker.CONFIG_ERROR](msg) {
    reportError(msg.message);
  },

  [FromWorker.STATE](msg) {
    // Paused or at the end: the map is kept for "Restore last session".
    // Not while the last one is offered: a sample playing after a reload would replace it.
    // (status.playing: the worker's last word; workerPlaying changes on the click.)
    if (status.playing && !msg.playing && !msg.failed && msg.surfels > 0 && !lastSession.offer) send({ type: ToWorker.SAVE_SESSION, keep: true });
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
    // A whole run that left nothing in the map says so over it.
    if (msg.done && !msg.playing && sequence) status.mapNotice = mapNotice.afterRun({ ...status, name: sequence.name });
    setControls();
  },

  [FromWorker.RESET](msg) {
    clearMessages();
    if (sequence) ui.sequenceInfo.textContent = sequence.line;
    ui.sequenceInfo.classList.remove('failed');
    for (const w of msg.warnings ?? []) reportWarning(w);
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
    const mesh = display.chunk({ positions: msg.positions, normals: msg.normals, colours: msg.colours, indices: msg.indices });
    renderer?.setMesh(mesh);
    status.meshTriangles = msg.indices.length / 3;
  },

  [FromWorker.EXPORT](msg) {
    if (isMeshExport(msg)) meshDone();
    const error = saveExport(msg, mirror, sequence?.name);
    if (error) reportError(error);
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
ui.ply.addEventListener('click', () => (status.failed ? downloadMirror(mirror, 'ply', sequence?.name) : send({ type: ToWorker.EXPORT_PLY })));
ui.trajectory.addEventListener('click', () =>
  status.failed ? downloadMirror(mirror, 'trajectory', sequence?.name) : send({ type: ToWorker.EXPORT_TRAJECTORY }),
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

$('show-flow').addEventListener('change', (e) => {
  send({ type: ToWorker.FLOW, enabled: e.target.checked });
  if (!e.target.checked) {
    views.hideFlow();
    status.flowTracks = 0;
  }
});

ui.saveSession.addEventListener('click', () => send({ type: ToWorker.SAVE_SESSION }));

lastSession.offerBack((name, bytes) =>
  send({ type: ToWorker.OPEN_SESSION, name, bytes, localise: ui.sessionLocalise.checked }, [bytes]),
);
ui.sessionInput.addEventListener('change', async () => {
  const file = ui.sessionInput.files?.[0];
  ui.sessionInput.value = ''; // the same file chosen again is a new change
  if (!file) return;
  const bytes = await file.arrayBuffer();
  send({ type: ToWorker.OPEN_SESSION, name: file.name, bytes, localise: ui.sessionLocalise.checked }, [bytes]);
});

wireViewControls({ renderer, plots });

// ---- sequences -----------------------------------------------------------------------

const urlParams = () => new URLSearchParams(location.search);

/** The sequence line after a failed open: says so, and what stays loaded. */
function openFailed(name) {
  const kept = sequence ? `; still loaded: ${sequence.name}` : '';
  ui.sequenceInfo.textContent = `could not open ${name ?? 'the choice'} (see the message over the map)${kept}`;
  ui.sequenceInfo.classList.add('failed');
}

function loadSequence(seq, autoplay) {
  loading = { name: seq.name, entries: seq.entries };
  pendingReload = null;
  ui.sequenceInfo.textContent = readingLine(seq);
  ui.sequenceInfo.classList.remove('failed');
  send({ type: ToWorker.LOAD, name: seq.name, entries: seq.entries, autoplay, options: settings.pageOptions() });
}

setupSequenceInput({
  input: $('folder-input'),
  archiveInput: $('archive-input'),
  dropTarget: document.body,
  onSequence: (seq) => loadSequence(seq, true),
  onError: (m) => {
    reportError(m);
    openFailed(null);
  },
});

async function loadSample(autoplay) {
  try {
    const seq = await fromManifest(new URL('sample/manifest.json', location.href).href);
    loadSequence(seq, autoplay);
  } catch (e) {
    reportError(`cannot load the bundled sample: ${e.message}`);
    openFailed('the bundled sample');
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
