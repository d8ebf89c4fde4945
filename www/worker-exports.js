// The SLAM worker's downloads and mesh view: answers ToWorker.EXPORT_PLY,
// EXPORT_TRAJECTORY, EXPORT_MESH and VIEW_MESH (see protocol.js). Used by
// worker.js only, inside its serial job chain.
import { ToWorker, FromWorker } from './protocol.js';
import { parseGlb } from './mesh-view.js';
import { errorText, isModuleFailure } from './wasm-module.js';

const post = (msg, transfer = []) => self.postMessage(msg, transfer);

/** A progress callback for exportMesh: posts MESH_PROGRESS at most every 5 %. */
function meshProgress(purpose) {
  let last = -1;
  return (fraction) => {
    if (fraction < 1 && fraction - last < 0.05) return;
    last = fraction;
    post({ type: FromWorker.MESH_PROGRESS, fraction, purpose });
  };
}

const EMPTY_MESH = () => ({ positions: new Float32Array(0), normals: new Float32Array(0), colours: new Uint8Array(0), indices: new Uint32Array(0) });

/**
 * Answers one export message. `exportFrom(fromSlam)` calls `fromSlam` with
 * the Slam (or null before there is one) and returns its result, or
 * undefined when the module has failed (the page then uses its own copy);
 * `name` is the sequence's.
 */
export function answerExport(msg, exportFrom, name) {
  switch (msg.type) {
    case ToWorker.EXPORT_PLY: {
      const bytes = exportFrom((s) => (s ? s.exportPly().slice() : new Uint8Array()));
      if (bytes) post({ type: FromWorker.EXPORT, what: 'ply', bytes, name }, [bytes.buffer]);
      else post({ type: FromWorker.EXPORT, what: 'ply', unavailable: true, name });
      return;
    }
    case ToWorker.EXPORT_TRAJECTORY: {
      const text = exportFrom((s) => (s ? s.trajectoryTum() : ''));
      if (text !== undefined) post({ type: FromWorker.EXPORT, what: 'trajectory', text, name });
      else post({ type: FromWorker.EXPORT, what: 'trajectory', unavailable: true, name });
      return;
    }
    case ToWorker.EXPORT_MESH: {
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
        post({ type: FromWorker.EXPORT, what, error: errorText(e), name });
        return;
      }
      if (bytes) post({ type: FromWorker.EXPORT, what, bytes, name }, [bytes.buffer]);
      else post({ type: FromWorker.EXPORT, what, unavailable: true, name });
      return;
    }
    case ToWorker.VIEW_MESH: {
      let mesh;
      try {
        mesh = exportFrom((s) => (s ? parseGlb(s.exportMesh({ format: 'glb' }, meshProgress('view'))) : EMPTY_MESH()));
      } catch (e) {
        if (isModuleFailure(e)) throw e;
        post({ type: FromWorker.MESH, error: errorText(e) });
        return;
      }
      if (!mesh) post({ type: FromWorker.MESH, unavailable: true });
      else post({ type: FromWorker.MESH, ...mesh }, [mesh.positions.buffer, mesh.normals.buffer, mesh.colours.buffer, mesh.indices.buffer]);
      return;
    }
    default:
      throw new Error(`answerExport: not an export message: ${msg.type}`);
  }
}
