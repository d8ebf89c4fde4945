// How the page shows the map, and the ground truth beside it. Used by app.js.
//
// The map and the poses are in the dataset's convention. With a negative fy
// (ICL-NUIM) the camera's y axis points up in the image, so the map is the
// mirror image of the scene: shown as it is, it is upside down and
// mirrored. The page shows it through F = diag(1, -1, 1) (points p -> F p,
// poses T -> F T F), which is the map a camera with a positive fy would have
// built: upright, right-handed. The downloads keep the dataset's convention.
import { poseFromTq, multiply, invertRigid, transformPoint } from './math3d.js';

const F = new Float64Array([1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
const IDENTITY = new Float64Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);

export class DisplayFrame {
  constructor() {
    this.flipY = false;
  }

  /** config: a Slam config ({preset, fy?, ...}); fy, when absent, is the preset's (from `presets`). */
  setFromConfig(config, presets) {
    const fy = config?.fy ?? presets.find((p) => p.name === config?.preset)?.fy;
    if (Number.isFinite(fy)) this.flipY = fy < 0;
  }

  /** A world_from_camera pose (4x4 column-major) in the display frame. */
  pose(pose) {
    return this.flipY ? multiply(F, multiply(pose, F)) : pose;
  }

  /** A point [x, y, z] of the map in the display frame. */
  point(p) {
    return transformPoint(this.flipY ? F : IDENTITY, p);
  }

  /** Mirrors a surfel chunk's (or mesh's) positions and normals in y, in place (its arrays are this page's own). */
  chunk(chunk) {
    if (!this.flipY || !chunk) return chunk;
    for (const key of ['positions', 'normals']) {
      const a = chunk[key];
      for (let i = 1; i < a.length; i += 3) a[i] = -a[i];
    }
    return chunk;
  }

  /** Intrinsics of the camera drawn in the display frame. */
  intrinsics(k) {
    return this.flipY ? { ...k, fy: Math.abs(k.fy) } : k;
  }
}

/**
 * The ground truth as the page draws it (or, for a sequence without one,
 * the recording device's own odometry): anchored to the estimate at the
 * first frame with a pose (the ATE in the statistics aligns the whole
 * trajectory instead, in the worker).
 */
export class GroundTruthTrack {
  /** rows: [t, tx, ty, tz, qx, qy, qz, qw] (world_from_camera, metres); kind: the dataset's. */
  constructor(rows, kind) {
    this.rows = [...rows].sort((a, b) => a[0] - b[0]); // at() searches by time
    this.tolerance = kind === 'tum' || kind === 'stray-scanner' ? 0.02 : 0.5; // seconds (TUM, Stray Scanner) or frame numbers
    this.align = null; // display-frame transform from the ground truth to the estimate
  }

  get length() {
    return this.rows.length;
  }

  /** Draw again from the next frame (a reset map). */
  unanchor() {
    this.align = null;
  }

  /** The row nearest `timestamp`, within the dataset's tolerance, or null. */
  at(timestamp) {
    const rows = this.rows;
    if (!rows.length) return null;
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
      if (dt <= this.tolerance && (!best || dt < best.dt)) best = { dt, row: rows[i] };
    }
    return best?.row ?? null;
  }

  /**
   * This frame's position error (metres) against the anchored ground truth,
   * or null. `pose`: display frame. The first frame with a ground-truth pose
   * anchors it and hands the whole track to `draw(points)`.
   */
  error(timestamp, pose, display, draw) {
    const row = this.at(timestamp);
    if (!row) return null;
    if (!this.align) {
      const gtPose = display.pose(poseFromTq([row[1], row[2], row[3]], [row[4], row[5], row[6], row[7]]));
      this.align = multiply(pose, invertRigid(gtPose));
      draw(this.rows.map((r) => transformPoint(this.align, display.point([r[1], r[2], r[3]]))));
    }
    const p = transformPoint(this.align, display.point([row[1], row[2], row[3]]));
    return Math.hypot(p[0] - pose[12], p[1] - pose[13], p[2] - pose[14]);
  }
}
