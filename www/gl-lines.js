// The map view's line geometry: growable line buffers (the estimated and the
// ground-truth camera paths), and the current camera's frustum drawn from its
// pose and intrinsics. Used by renderer.js.
import { transformPoint } from './math3d.js';

/** A growable line buffer (trajectories) or a fixed one (frustum). */
export class Lines {
  constructor(gl, colour, mode) {
    this.gl = gl;
    this.colour = colour;
    this.mode = mode;
    this.count = 0;
    this.capacity = 0;
    this.data = new Float32Array(0);
    this.buffer = gl.createBuffer();
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffer);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
  }

  /** Replaces the points (the ground truth, the frustum, a trajectory moved by a loop closure). */
  set(points) {
    const gl = this.gl;
    // Kept as the CPU copy too: push() grows from it.
    const capacity = Math.max(256, points.length);
    const data = new Float32Array(capacity * 3);
    points.forEach((p, i) => data.set(p, i * 3));
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
    this.data = data;
    this.count = points.length;
    this.capacity = capacity;
  }

  /** Appends one point (trajectory), growing the buffer geometrically. */
  push(p) {
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffer);
    if (this.count + 1 > this.capacity) {
      const capacity = Math.max(256, this.capacity * 2);
      const data = new Float32Array(capacity * 3);
      data.set(this.data.subarray(0, this.count * 3));
      this.data = data;
      this.capacity = capacity;
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
    }
    this.data.set(p, this.count * 3);
    gl.bufferSubData(gl.ARRAY_BUFFER, this.count * 12, this.data, this.count * 3, 3);
    this.count++;
  }

  clear() {
    this.count = 0;
  }
}

/**
 * Line-list points of the camera frustum at `pose` (world_from_camera,
 * column-major), `d` metres deep, for intrinsics `k` ({fx, fy, cx, cy,
 * width, height}, pixels): the four edges from the centre, the image
 * rectangle, and an "up" tick over the image's top edge.
 */
export function frustumPoints(pose, k, d) {
  const corner = (u, v) => transformPoint(pose, [((u - k.cx) / k.fx) * d, ((v - k.cy) / k.fy) * d, d]);
  const o = [pose[12], pose[13], pose[14]];
  const c = [corner(0, 0), corner(k.width, 0), corner(k.width, k.height), corner(0, k.height)];
  const top = transformPoint(pose, [0, ((0 - k.cy) / k.fy) * d * 1.35, d]);
  return [o, c[0], o, c[1], o, c[2], o, c[3], c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0], c[0], top, top, c[1]];
}
