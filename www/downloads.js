// Files the page saves: the worker's exports (FromWorker.EXPORT), or, when
// the module has failed, the page's own copy of the map and trajectory
// (map-mirror.js). Used by app.js.

/** Saves `blob` as a download named `name`. */
export function download(blob, name) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

const baseName = (name) => (name || 'surfel-slam').replace(/[^\w.-]+/g, '_');

/** 'ply' or 'trajectory' from the page's copy (the module has failed). */
export function downloadMirror(mirror, what, sequenceName) {
  const base = baseName(sequenceName);
  if (what === 'ply') download(new Blob([mirror.ply()], { type: 'application/octet-stream' }), `${base}_map.ply`);
  else download(new Blob([mirror.trajectoryTum()], { type: 'text/plain' }), `${base}_trajectory.txt`);
}

/** Saves a session file (FromWorker.SESSION_SAVED's bytes) as `<sequence>.slam`. */
export function downloadSession(bytes, sequenceName) {
  download(new Blob([bytes], { type: 'application/zip' }), `${baseName(sequenceName)}.slam`);
}

/** Whether an EXPORT message answers a mesh (or point cloud) request. */
export const isMeshExport = (msg) => msg.what.startsWith('mesh-') || msg.what === 'points-glb';

/**
 * Saves what a FromWorker.EXPORT message carries (the page's copy when the
 * module could not answer). Returns the error to show, or null.
 */
export function saveExport(msg, mirror, sequenceName) {
  const base = baseName(msg.name);
  if (isMeshExport(msg)) {
    if (msg.unavailable || msg.error) return `${msg.what}: ${msg.error || 'the SLAM module failed; Play, Step or Reset starts again'}`;
    const [kind, ext] = msg.what.split('-');
    download(new Blob([msg.bytes], { type: ext === 'glb' ? 'model/gltf-binary' : 'application/octet-stream' }), `${base}_${kind}.${ext}`);
  } else if (msg.unavailable) {
    downloadMirror(mirror, msg.what, sequenceName);
  } else if (msg.what === 'ply') {
    download(new Blob([msg.bytes], { type: 'application/octet-stream' }), `${base}_map.ply`);
  } else {
    download(new Blob([msg.text], { type: 'text/plain' }), `${base}_trajectory.txt`);
  }
  return null;
}
