// The surfels on the GPU: one buffer per attribute, preallocated with a
// capacity that grows geometrically (old contents copied GPU-side), updated
// with bufferSubData over each frame's changed surfel range only; and the
// running bounding box of the map (the view is fitted to it). Used by
// renderer.js.

// name, components, GL type, bytes per component, normalised
export const ATTRIBUTES = [
  ['positions', 3, 'FLOAT', 4, false],
  ['normals', 3, 'FLOAT', 4, false],
  ['colours', 4, 'UNSIGNED_BYTE', 1, true],
  ['radii', 1, 'FLOAT', 4, false],
  ['confidences', 1, 'FLOAT', 4, false],
];

/** A chunk that rewrites every surfel the map has (after a loop closure, every surfel moves). */
export const coversWholeMap = (c) => c.start === 0 && c.end >= c.count && c.count > 0;

export class SurfelBuffers {
  constructor(gl) {
    this.gl = gl;
    this.count = 0;
    this.capacity = 0;
    this.buffers = {};
    this.pending = [];
    this.uploadedSurfels = 0; // surfels written to the GPU since creation
    this.bounds = null; // {min, max, sum, n} of (a sample of) the received positions
    this.vao = gl.createVertexArray();
    this.ensureCapacity(1 << 16);
  }

  ensureCapacity(n) {
    if (n <= this.capacity) return;
    const gl = this.gl;
    const capacity = Math.max(n, this.capacity * 2, 1 << 16);
    gl.bindVertexArray(this.vao);
    ATTRIBUTES.forEach(([name, components, type, bytes, normalised], location) => {
      const old = this.buffers[name];
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, capacity * components * bytes, gl.DYNAMIC_DRAW);
      if (old && this.count > 0) {
        gl.bindBuffer(gl.COPY_READ_BUFFER, old);
        gl.copyBufferSubData(gl.COPY_READ_BUFFER, gl.ARRAY_BUFFER, 0, 0, this.count * components * bytes);
        gl.bindBuffer(gl.COPY_READ_BUFFER, null);
      }
      if (old) gl.deleteBuffer(old);
      this.buffers[name] = buffer;
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, components, gl[type], normalised, 0, 0);
    });
    gl.bindVertexArray(null);
    this.capacity = capacity;
    this.stride = 1;
  }

  /**
   * Queues one frame's changed surfel range ({count, start, end, positions, ...}).
   * Uploads happen in flush(), just before a draw, so frames that arrive
   * while the GPU is still busy are coalesced (a range covered by a later
   * one is skipped).
   */
  queue(chunk) {
    this.pending.push(chunk);
    // The whole map moved: the old box would keep where the map was.
    if (coversWholeMap(chunk)) this.bounds = null;
    if (chunk.end > chunk.start) this.growBounds(chunk.positions);
  }

  flush() {
    const list = this.pending;
    if (list.length === 0) return;
    this.pending = [];
    const gl = this.gl;
    const last = list[list.length - 1];
    this.ensureCapacity(list.reduce((n, c) => Math.max(n, c.count, c.end), 0));
    for (let i = 0; i < list.length; i++) {
      const c = list[i];
      if (c.end <= c.start) continue;
      let covered = false;
      for (let j = i + 1; j < list.length && !covered; j++) covered = list[j].start <= c.start && list[j].end >= c.end;
      if (covered) continue;
      ATTRIBUTES.forEach(([name, components, , bytes]) => {
        gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers[name]);
        gl.bufferSubData(gl.ARRAY_BUFFER, c.start * components * bytes, c[name]);
      });
      this.uploadedSurfels += c.end - c.start;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.count = last.count;
  }

  growBounds(positions) {
    const step = Math.max(1, Math.floor(positions.length / 3 / 2000)) * 3;
    let b = this.bounds;
    for (let i = 0; i + 2 < positions.length; i += step) {
      const p = [positions[i], positions[i + 1], positions[i + 2]];
      if (!Number.isFinite(p[0] + p[1] + p[2])) continue;
      if (!b) b = { min: [...p], max: [...p], sum: [0, 0, 0], n: 0 };
      for (let k = 0; k < 3; k++) {
        b.min[k] = Math.min(b.min[k], p[k]);
        b.max[k] = Math.max(b.max[k], p[k]);
        b.sum[k] += p[k];
      }
      b.n++;
    }
    this.bounds = b;
  }

  /**
   * Points the vertex attributes at every `stride`-th surfel (1: all), for
   * a draw of `ceil(count / stride)` splats; the map's surfels are stored
   * in spatial blocks, so every stride-th one still covers the whole map.
   * Returns how many splats to draw.
   */
  bindEveryNth(stride) {
    const gl = this.gl;
    const n = Math.max(1, Math.floor(stride));
    gl.bindVertexArray(this.vao);
    if (n !== this.stride) {
      ATTRIBUTES.forEach(([name, components, type, bytes, normalised], location) => {
        gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers[name]);
        gl.vertexAttribPointer(location, components, gl[type], normalised, n === 1 ? 0 : n * components * bytes, 0);
      });
      gl.bindBuffer(gl.ARRAY_BUFFER, null);
      this.stride = n;
    }
    return Math.ceil(this.count / n);
  }

  /**
   * Up to `max` positions of the drawn surfels (every n-th, absorbed ones
   * left out), read back from the GPU: what "Fit map" frames. Flush first.
   */
  samplePositions(max = 50_000) {
    const gl = this.gl;
    const count = this.count;
    if (count === 0) return new Float32Array(0);
    const positions = new Float32Array(3 * count);
    const confidences = new Float32Array(count);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.positions);
    gl.getBufferSubData(gl.ARRAY_BUFFER, 0, positions);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.confidences);
    gl.getBufferSubData(gl.ARRAY_BUFFER, 0, confidences);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    const step = Math.max(1, Math.ceil(count / max));
    const out = new Float32Array(3 * Math.ceil(count / step));
    let n = 0;
    for (let i = 0; i < count; i += step) {
      const [x, y, z] = [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]];
      if (!(confidences[i] >= 0) || !Number.isFinite(x + y + z)) continue;
      out.set([x, y, z], 3 * n++);
    }
    return out.subarray(0, 3 * n);
  }

  clear() {
    this.count = 0;
    this.pending = [];
    this.bounds = null;
  }
}
