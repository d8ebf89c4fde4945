// What the page reports about itself, as window.surfelSlamStatus: the
// browser tests read it (frames and verdicts, timings, messages, sessions).
// app.js updates it; nothing here reads the page.
export const status = {
  ready: false,
  framesProcessed: 0,
  framesLost: 0,
  framesRecovered: 0,
  framesHeld: 0, // fused with some directions held at the motion prior
  framesFailed: 0,
  framesRelocalised: 0, // frames placed by relocalisation (report.relocalisedFrom set)
  relocalisedFrames: [], // their indices
  loopClosures: null, // loop closures so far (null: the module reports none)
  trajectoryReplaced: 0, // times a loop closure's whole trajectory replaced the drawn one
  surfels: 0,
  splatsDrawn: 0, // splats in the map view's last draw (bounded while SLAM runs: ?splats=N, 0 = all)
  threads: 0,
  crossOriginIsolated: self.crossOriginIsolated === true,
  module: null,
  error: null,
  ate: null, // RMS after rigid alignment against `reference`, metres
  flowTracks: 0, // Lucas-Kanade tracks drawn on the last colour view (0 = overlay off)
  fps: 0, // frames per second over the last ~15 frames
  fpsAverage: 0, // frames per second from the first to the latest frame of this run
  msPerFrame: 0, // wasm time per frame (decode + preprocess + track + fuse + predict)
  wasmMemoryMiB: null, // the module's linear memory after the last frame, MiB (it never shrinks: the peak)
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
  errors: [], // every message since the sequence was opened, oldest first
  shownErrors: [], // the messages on the page now, newest first (cleared by a new run or a good Apply)
  warnings: [], // camera-settings warnings of the current run (layout check, first frame's depth check), and what was skipped reading its sequence or reference (a cut-off last row)
  moduleFailures: 0, // times the wasm module failed (each time rebuilt at the next action)
  failed: false, // the module has failed and not been rebuilt yet
  positionErrorCm: null, // last frame's distance to the ground truth (aligned at its first pose), cm
  displayFlipY: false, // the map is shown mirrored in y (negative fy: ICL-NUIM) so that it is upright
  plotFrames: 0, // frames in the plots
  meshView: false, // the view shows the mesh instead of the splats
  meshTriangles: null, // triangles of the mesh in the view (null: none received yet)
  meshProgress: null, // fraction of the meshing under way, null when none
  framesUnplaced: 0, // localising in an opened session: frames not found in the map (no pose)
  session: null, // {name, frames, surfels, localising}: the session file last opened (null: none since the last new map)
  sessionSaveMs: null, // time of the last Slam.save in the worker, ms
  sessionSaveBytes: null, // size of the last session saved, bytes
  sessionOpenMs: null, // time of the last Slam.load in the worker (manifest read included), ms
  lastSessionStored: null, // {name, bytes} of the last session kept in IndexedDB by this page (null: none yet)
  sessionKeepSaveMs: null, // time of Slam.save in the worker for the last session kept on pause or end, ms
  sessionStoreMs: null, // time of the last IndexedDB write of that session (after the save), ms
  lastSessionOffered: null, // name of the session "Restore last session" offers (null: none)
  colourNote: null, // how a scan without colour images gets its colour (a Stray Scanner scan's rgb.mp4), null: not such a scan
  framesColourFromVideo: 0, // frames whose colour came from the scan's rgb.mp4, since the last reset
  framesVideoFailed: 0, // frames whose rgb.mp4 picture could not be had, since the last reset
  reference: null, // what the run is compared with: 'ground truth', "device's odometry", 'your reference' or null (www/scoring.js); ate is against it
  userReference: null, // {name, key: 'frame' | 'timestamp', poses, matched}: the reference file loaded with "Reference…" for this sequence (null: none)
  driftPlotTitle: null, // {text, fits}: the drift plot's title as last drawn, and whether it fits the plot's width
  mapNotice: null, // what the page says over the map after a whole run that mapped nothing (null: nothing to say)
};
window.surfelSlamStatus = status;
