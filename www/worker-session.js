// Session files in the SLAM worker (issue #36): the camera a session file
// was saved with (so that a page with no sequence open can make a Slam that
// accepts it), and what the page needs to show a loaded session. Saving and
// loading themselves are the module's (Slam.save / Slam.load). Used by
// worker.js only.
import { copySurfels } from './surfel-copy.js';

/**
 * A Slam config with the camera of the session in `bytes` (its
 * manifest.json, read with the module's ArchiveReader), or null when the
 * manifest cannot be read: Slam.load then names what is wrong with the file.
 */
export function sessionCameraConfig(wasm, bytes, name) {
  let reader = null;
  try {
    reader = new wasm.ArchiveReader(bytes, name);
    const manifest = JSON.parse(new TextDecoder().decode(reader.read('manifest.json')));
    const { intrinsics: k, depth: d } = manifest.camera;
    const config = {
      fx: k.fx,
      fy: k.fy,
      cx: k.cx,
      cy: k.cy,
      width: k.width,
      height: k.height,
      depthScale: d.scale,
      depthMin: d.min_m,
      depthMax: d.max_m,
    };
    if (Number.isInteger(d.invalid_raw)) config.depthInvalid = d.invalid_raw;
    return config;
  } catch {
    return null;
  } finally {
    reader?.free();
  }
}

/**
 * What the page shows of a loaded Slam: frames mapped, the map's surfels
 * (count, and a copy of every slot), the trajectory as TUM text.
 */
export function sessionSnapshot(slam) {
  const slots = slam.surfelCount;
  return {
    frames: slam.frames,
    surfels: slam.liveSurfels,
    localising: slam.localising,
    map: copySurfels(slam, slots, 0, slots),
    trajectoryTum: slam.trajectoryTum(),
  };
}
