// The worker's copy of the map and the trajectory as last sent to the page,
// so that the downloads still work after the wasm module failed (a panic
// poisons the Slam object: nothing can be read from it any more).
//
// It is fed the same changed ranges and refresh windows the renderer gets, so
// it holds exactly the map the page shows (merges reach it within a refresh
// cycle). The PLY it writes has the layout of the library's
// `mesh::surfel_ply::write_surfel_ply` (binary little-endian; x y z nx ny nz float,
// red green blue uchar, radius confidence float; absorbed surfels, whose
// confidence is negative, left out) and the TUM text that of `format_tum`.
// World frame = the first camera's, metres.

const FIELDS = [
  ['positions', 3, Float32Array],
  ['normals', 3, Float32Array],
  ['colours', 4, Uint8Array],
  ['radii', 1, Float32Array],
  ['confidences', 1, Float32Array],
];

export class MapMirror {
  constructor() {
    this.clear();
  }

  clear() {
    this.count = 0;
    this.capacity = 0;
    this.arrays = Object.fromEntries(FIELDS.map(([name, , T]) => [name, new T(0)]));
    this.poses = []; // TUM lines, one per frame pushed
  }

  /** A chunk as sent to the page: {count, start, end, positions, normals, colours, radii, confidences}. */
  update(chunk) {
    const need = Math.max(chunk.count, chunk.end);
    if (need > this.capacity) {
      const capacity = Math.max(need, 2 * this.capacity, 1 << 16);
      for (const [name, k, T] of FIELDS) {
        const grown = new T(capacity * k);
        grown.set(this.arrays[name].subarray(0, this.count * k));
        this.arrays[name] = grown;
      }
      this.capacity = capacity;
    }
    if (chunk.end > chunk.start) {
      for (const [name, k] of FIELDS) this.arrays[name].set(chunk[name], chunk.start * k);
    }
    this.count = chunk.count;
  }

  /** One frame's report (timestamp, translation [x,y,z], quaternion [x,y,z,w]: world_from_camera). */
  addPose(report) {
    const t = report.translation ?? [];
    const q = report.quaternion ?? [];
    if (t.length !== 3 || q.length !== 4) return;
    this.poses.push(`${report.timestamp.toFixed(6)} ${[...t, ...q].map((v) => v.toFixed(9)).join(' ')}`);
  }

  /** Replaces the poses with `Slam.trajectoryTum()`'s text (a loop closure moved past poses). */
  setTrajectoryTum(tum) {
    this.poses = tum.split('\n').filter((line) => line.trim() && !line.startsWith('#'));
  }

  trajectoryTum() {
    return ['# timestamp tx ty tz qx qy qz qw', ...this.poses, ''].join('\n');
  }

  ply() {
    const { positions, normals, colours, radii, confidences } = this.arrays;
    const kept = [];
    for (let i = 0; i < this.count; i++) if (confidences[i] >= 0) kept.push(i);
    const header = new TextEncoder().encode(
      'ply\nformat binary_little_endian 1.0\ncomment surfel-slam surfel map, world frame, metres\n' +
        `element vertex ${kept.length}\n` +
        ['x', 'y', 'z', 'nx', 'ny', 'nz'].map((p) => `property float ${p}\n`).join('') +
        'property uchar red\nproperty uchar green\nproperty uchar blue\n' +
        'property float radius\nproperty float confidence\nend_header\n',
    );
    const VERTEX = 6 * 4 + 3 + 2 * 4;
    const out = new Uint8Array(header.length + kept.length * VERTEX);
    out.set(header);
    const view = new DataView(out.buffer);
    let o = header.length;
    for (const i of kept) {
      for (let k = 0; k < 3; k++, o += 4) view.setFloat32(o, positions[3 * i + k], true);
      for (let k = 0; k < 3; k++, o += 4) view.setFloat32(o, normals[3 * i + k], true);
      for (let k = 0; k < 3; k++) out[o++] = colours[4 * i + k];
      view.setFloat32(o, radii[i], true);
      view.setFloat32(o + 4, confidences[i], true);
      o += 8;
    }
    return out;
  }
}
