// Every message name exchanged by the page (app.js), the SLAM worker
// (worker.js) and the frame reader (frame-reader.js), in one place: a name
// used on one side and not the other is then a reference error, not a message
// silently dropped. Fields are listed beside each name.

/** Page -> SLAM worker (`{type, ...fields}`). */
export const ToWorker = Object.freeze({
  /** {name, entries: [[path, File|url]], autoplay, options: {tracker, halfResolution, noise?, loopClosure}}: open a sequence. */
  LOAD: 'load',
  /** Play from the next frame (from frame 0 when the sequence is done). */
  PLAY: 'play',
  /** Stop after the frame under way. */
  PAUSE: 'pause',
  /** Process one frame, then stop. */
  STEP: 'step',
  /** Empty map, back to frame 0, stopped. */
  RESET: 'reset',
  /** Empty map, back to frame 0, playing. */
  REPLAY: 'replay',
  /** {config} (a Slam config, docs/js-api.md): new Slam, back to frame 0, playing. */
  CONFIG: 'config',
  /** {name, text}: a reference trajectory file (TUM or `frame, x, y, z, qx, qy, qz, qw` CSV, read by the library's parseReference: www/reference.js) to score the open sequence against, as "your reference"; answered by REFERENCE. */
  REFERENCE: 'reference',
  /** {enabled}: compute Lucas-Kanade tracks for the colour view's overlay. */
  FLOW: 'flow',
  /** Map as binary PLY; answered by EXPORT. */
  EXPORT_PLY: 'exportPly',
  /** Trajectory as TUM text; answered by EXPORT. */
  EXPORT_TRAJECTORY: 'exportTrajectory',
  /** {format: 'glb'|'ply'|'glb-points'}: the map as a mesh file (or the surfels as .glb points); answered by MESH_PROGRESS messages, then EXPORT {what: 'mesh-glb'|'mesh-ply'|'points-glb'}. */
  EXPORT_MESH: 'exportMesh',
  /** Mesh the map for the page's mesh view; answered by MESH_PROGRESS messages, then MESH. */
  VIEW_MESH: 'viewMesh',
  /** {keep}: the Slam as a session file (Slam.save); answered by SESSION_SAVED (keep: for the browser's storage, not a download). */
  SAVE_SESSION: 'saveSession',
  /** {name, bytes (ArrayBuffer of a .slam file), localise}: replace the map by a saved session (Slam.load); answered by SESSION_OPENED or SESSION_ERROR. */
  OPEN_SESSION: 'openSession',
  /** Test hook, honoured only when the worker's URL has testHooks=1: the module fails at the next call. */
  TEST_BREAK: 'test-break',
  /** Test hook (testHooks=1): the next frame never returns, as when one of the module's threads panics. */
  TEST_HANG: 'test-hang',
});

/** SLAM worker -> page (`{type, ...fields}`). */
export const FromWorker = Object.freeze({
  /** {module: 'threads'|'simd', threads, presets, notes, frameReader}: the module is loaded. */
  READY: 'ready',
  /** {name, kind, preset, config, frameCount, groundTruth, odometry, fileCount, warnings, readWarnings, presets, colourNote, session?}: a sequence was opened (session: as SESSION_OPENED's, when it goes on from an opened session) (warnings: camera settings that do not fit its layout; readWarnings: parseSequence's, what was skipped reading it, e.g. a cut-off last row; presets: every preset at the sequence's frame size, or null; colourNote: where a sequence without colour images gets its colour, or that it plays on depth alone and why, else null). */
  SEQUENCE: 'sequence',
  /** {index, frameCount, timestamp, result, surfels, refresh, ate ({rmse, ..., pairs, against: 'ground truth' | "device's odometry" | 'your reference'} or null), wasmMemoryBytes, timing, input, flow, colourDecoder, videoError, done}: one frame processed (wasmMemoryBytes: the module's linear memory, its peak; colourDecoder: 'browser', 'wasm' or 'video'; videoError: why its colour could not be taken from the video). */
  FRAME: 'frame',
  /** {index, message, frameCount, input?}: one frame skipped (unreadable or refused). */
  FRAME_ERROR: 'frame-error',
  /** {name, message, resumed}: a folder could not be opened (the current sequence stays; resumed: it was playing and plays on). */
  LOAD_ERROR: 'load-error',
  /** {name, key ('frame' | 'timestamp'), poses, matched, rows, warnings, ate} or {name, error}: the reference REFERENCE sent, read (rows: [t, tx, ty, tz, qx, qy, qz, qw] at the sequence's timestamps; matched: frames with a pose; warnings: a cut-off last row skipped; ate: the run so far against it, or null) or refused (the old reference stays). */
  REFERENCE: 'reference',
  /** {message}: camera settings refused (the current Slam stays). */
  CONFIG_ERROR: 'config-error',
  /** {playing, next, frameCount, done, surfels, failed}: playback state. */
  STATE: 'state',
  /** {config?, warnings?}: the map was emptied (reset, replay, new config, rebuilt after a failure); warnings: a new config's settings that do not fit the layout. */
  RESET: 'reset',
  /** {what: 'ply'|'trajectory'|'mesh-glb'|'mesh-ply'|'points-glb', bytes|text, name} or {what, unavailable: true} (the module has failed: the page uses its own copy; none for meshes) or {what, error}. */
  EXPORT: 'export',
  /** {fraction (0..1), purpose: 'download'|'view'}: meshing under way. */
  MESH_PROGRESS: 'mesh-progress',
  /** {positions, normals, colours, indices} (parseGlb's arrays, world frame, metres) or {unavailable: true} or {error}: the mesh for the view. */
  MESH: 'mesh',
  /** {message, frames}: the wasm module failed; playback stopped, it is rebuilt at the next action. */
  MODULE_FAILED: 'module-failed',
  /** {keep, bytes, name, ms} or {keep, error}: the session file SAVE_SESSION asked for (ms: time in Slam.save). */
  SESSION_SAVED: 'session-saved',
  /** {name, ms, config, sequenceClosed, session: {frames, surfels, localising, map, trajectoryTum}}: a session replaced the map (ms: time in Slam.load; sequenceClosed: the open sequence had another camera and was closed); map is copySurfels' whole map. */
  SESSION_OPENED: 'session-opened',
  /** {name, message}: a session file was refused (message starts with its kind: 'truncated: ', ...); the map stays. */
  SESSION_ERROR: 'session-error',
  /** {message}: the worker itself cannot go on (module not loadable, internal error). */
  FATAL: 'fatal',
});

/** SLAM worker -> frame reader (`{type, ...fields}`); the reader answers `{id, index, colourBuf, depthBuf, confidenceBuf, decoded, videoError}` or `{id, index, error}`. */
export const ToReader = Object.freeze({
  /** {id, entries}: the current sequence's files: a folder's or one archive (as for openSource). */
  SOURCE: 'source',
  /** {id, index, colour, depth, confidence, video: {path, index} | null, decode}: read (and decode the colour of) one frame (video: its colour is that video's frame). */
  READ: 'read',
  /** {id, paths}: read these files now, keep the bytes for a later READ. */
  READ_AHEAD: 'readAhead',
});
