// WebGL2 surfel renderer: splats sized by surfel radius (screen-aligned round
// point sprites), colour by RGB / normal / confidence, orbit-pan-zoom camera
// (mouse, wheel, touch) and a follow-the-camera mode, the estimated and the
// ground-truth trajectories, the current camera frustum.
//
// GPU buffers are preallocated with a capacity that grows geometrically (old
// contents copied GPU-side) and are updated with bufferSubData over the
// changed surfel range only.
import { vec3, multiply, invertRigid, transformPoint, column, perspective, lookAt } from './math3d.js';
import { MeshView } from './mesh-view.js';

const SURFEL_VS = `#version 300 es
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 3) in float aRadius;
layout(location = 4) in float aConfidence;
uniform mat4 uView;
uniform mat4 uProj;
uniform float uPixelsPerUnit;   // viewport height / (2 tan(fovy/2))
uniform float uSizeScale;
uniform float uMaxPointSize;
uniform float uConfidenceMax;
uniform int uMode;              // 0 rgb, 1 normal, 2 confidence
out vec3 vColour;

vec3 turbo(float x) {
  x = clamp(x, 0.0, 1.0);
  vec4 kR = vec4(0.13572138, 4.61539260, -42.66032258, 132.13108234);
  vec4 kG = vec4(0.09140261, 2.19418839, 4.84296658, -14.18503333);
  vec4 kB = vec4(0.10667330, 12.64194608, -60.58204836, 110.36276771);
  vec2 kR2 = vec2(-152.94239396, 59.28637943);
  vec2 kG2 = vec2(4.27729857, 2.82956604);
  vec2 kB2 = vec2(-89.90310912, 27.34824973);
  vec4 v4 = vec4(1.0, x, x * x, x * x * x);
  vec2 v2 = v4.zw * v4.z;
  return vec3(dot(v4, kR) + dot(v2, kR2), dot(v4, kG) + dot(v2, kG2), dot(v4, kB) + dot(v2, kB2));
}

void main() {
  // Absorbed into another surfel (negative confidence): gone from the map at
  // the next compaction; hidden as soon as its confidence reaches the GPU.
  if (aConfidence < 0.0) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 0.0;
    vColour = vec3(0.0);
    return;
  }
  vec4 eye = uView * vec4(aPosition, 1.0);
  gl_Position = uProj * eye;
  float z = max(-eye.z, 1e-3);
  gl_PointSize = clamp(2.0 * aRadius * uSizeScale * uPixelsPerUnit / z, 1.0, uMaxPointSize);
  if (uMode == 1) {
    vColour = normalize(aNormal) * 0.5 + 0.5;
  } else if (uMode == 2) {
    vColour = turbo(aConfidence / uConfidenceMax);
  } else {
    vColour = aColour.rgb;
  }
}`;

const SURFEL_FS = `#version 300 es
precision mediump float;
in vec3 vColour;
out vec4 outColour;
void main() {
  vec2 c = gl_PointCoord * 2.0 - 1.0;
  float r2 = dot(c, c);
  if (r2 > 1.0) discard;
  outColour = vec4(vColour * (1.0 - 0.15 * r2), 1.0);
}`;

const LINE_VS = `#version 300 es
layout(location = 0) in vec3 aPosition;
uniform mat4 uView;
uniform mat4 uProj;
void main() { gl_Position = uProj * uView * vec4(aPosition, 1.0); }`;

const LINE_FS = `#version 300 es
precision mediump float;
uniform vec4 uColour;
out vec4 outColour;
void main() { outColour = uColour; }`;

// name, components, GL type, bytes per component, normalised
const ATTRIBUTES = [
  ['positions', 3, 'FLOAT', 4, false],
  ['normals', 3, 'FLOAT', 4, false],
  ['colours', 4, 'UNSIGNED_BYTE', 1, true],
  ['radii', 1, 'FLOAT', 4, false],
  ['confidences', 1, 'FLOAT', 4, false],
];

const MODES = { rgb: 0, normal: 1, confidence: 2 };
const FOVY = (55 * Math.PI) / 180;

function compile(gl, vsSource, fsSource) {
  const program = gl.createProgram();
  for (const [type, source] of [
    [gl.VERTEX_SHADER, vsSource],
    [gl.FRAGMENT_SHADER, fsSource],
  ]) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(`shader: ${gl.getShaderInfoLog(shader)}`);
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(`program: ${gl.getProgramInfoLog(program)}`);
  const uniforms = {};
  const n = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < n; i++) {
    const name = gl.getActiveUniform(program, i).name;
    uniforms[name] = gl.getUniformLocation(program, name);
  }
  return { program, uniforms };
}

/** A growable line buffer (trajectories) or a fixed one (frustum). */
class Lines {
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

  set(points) {
    const gl = this.gl;
    const flat = new Float32Array(points.length * 3);
    points.forEach((p, i) => flat.set(p, i * 3));
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffer);
    gl.bufferData(gl.ARRAY_BUFFER, flat, gl.DYNAMIC_DRAW);
    this.count = points.length;
    this.capacity = points.length;
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
    this.pending = [];
  }
}

export class Renderer {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error('WebGL2 is not available in this browser');
    this.gl = gl;
    this.surfelProgram = compile(gl, SURFEL_VS, SURFEL_FS);
    this.lineProgram = compile(gl, LINE_VS, LINE_FS);
    this.maxPointSize = gl.getParameter(gl.ALIASED_POINT_SIZE_RANGE)[1];

    this.count = 0;
    this.capacity = 0;
    this.buffers = {};
    this.pending = [];
    this.uploadedSurfels = 0;
    this.fence = null;
    this.fenceIssuedAt = 0;
    this.gpuMs = 0; // how long the GPU took for the last frame (issue -> fence signalled)
    this.lastDrawAt = 0;
    this.throttle = false; // while SLAM runs: leave the GPU (often a CPU rasteriser) idle 3/4 of the time
    this.vao = gl.createVertexArray();
    this.ensureCapacity(1 << 16);

    this.trajectory = new Lines(gl, [1.0, 0.55, 0.1, 1], gl.LINE_STRIP);
    this.groundTruth = new Lines(gl, [0.2, 0.9, 0.3, 1], gl.LINE_STRIP);
    this.frustum = new Lines(gl, [1.0, 0.85, 0.2, 1], gl.LINES);
    this.mesh = new MeshView(gl);
    this.showMesh = false; // draw the mesh (setMesh) instead of the splats

    this.mode = 'rgb';
    this.sizeScale = 1;
    this.confidenceMax = 20;
    this.follow = false;
    this.show = { trajectory: true, groundTruth: true, frustum: true };
    this.background = [0.07, 0.08, 0.1];

    // Orbit camera in a basis taken from the first camera pose (up = -y of the camera).
    this.basis = { right: [1, 0, 0], up: [0, -1, 0], back: [0, 0, -1] };
    this.target = [0, 0, 1.5];
    this.distance = 3;
    this.yaw = 0;
    this.pitch = 0.35;
    this.viewInitialised = false;
    this.currentPose = null;
    this.intrinsics = null;
    this.bounds = null; // running bounding box of received surfels

    this.dirty = true;
    this.lastDrawMs = 0;
    this.installControls();
    this.frameLoop = this.frameLoop.bind(this);
    requestAnimationFrame(this.frameLoop);
  }

  // ---- GPU buffers ------------------------------------------------------------

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
  }

  /**
   * Queues one frame's changed surfel range ({count, start, end, positions, ...}).
   * Uploads happen just before the next draw, so frames that arrive while the
   * GPU is still busy are coalesced (a range covered by a later one is skipped).
   */
  updateSurfels(chunk) {
    this.pending.push(chunk);
    if (chunk.end > chunk.start) this.growBounds(chunk.positions);
    this.dirty = true;
  }

  flushUploads() {
    const list = this.pending;
    if (list.length === 0) return;
    this.pending = [];
    const gl = this.gl;
    const last = list[list.length - 1];
    this.ensureCapacity(Math.max(...list.map((c) => Math.max(c.count, c.end))));
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

  clear() {
    this.count = 0;
    this.pending = [];
    this.bounds = null;
    this.trajectory.clear();
    this.groundTruth.clear();
    this.frustum.clear();
    this.mesh.clear();
    this.currentPose = null;
    this.firstPose = null;
    this.viewInitialised = false;
    this.dirty = true;
  }

  // ---- scene state --------------------------------------------------------------

  /** pose: column-major world_from_camera (Float64Array(16)). */
  setCameraPose(pose, intrinsics) {
    this.currentPose = pose;
    if (!this.firstPose) this.firstPose = pose;
    if (intrinsics) this.intrinsics = intrinsics;
    this.trajectory.push([pose[12], pose[13], pose[14]]);
    this.updateFrustum();
    if (!this.viewInitialised && this.bounds) this.initialView(pose);
    this.dirty = true;
  }

  setGroundTruth(points) {
    if (points && points.length) this.groundTruth.set(points);
    else this.groundTruth.clear();
    this.dirty = true;
  }

  updateFrustum() {
    const pose = this.currentPose;
    if (!pose) return;
    const k = this.intrinsics ?? { fx: 525, fy: 525, cx: 319.5, cy: 239.5, width: 640, height: 480 };
    const d = Math.max(0.06, Math.min(0.2, this.sceneSize() * 0.04));
    const corner = (u, v) => transformPoint(pose, [((u - k.cx) / k.fx) * d, ((v - k.cy) / k.fy) * d, d]);
    const o = [pose[12], pose[13], pose[14]];
    const c = [corner(0, 0), corner(k.width, 0), corner(k.width, k.height), corner(0, k.height)];
    // the "up" tick marks the image's top edge
    const top = transformPoint(pose, [0, ((0 - k.cy) / k.fy) * d * 1.35, d]);
    this.frustum.set([o, c[0], o, c[1], o, c[2], o, c[3], c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0], c[0], top, top, c[1]]);
  }

  sceneSize() {
    const b = this.bounds;
    if (!b) return 2;
    return Math.max(0.5, vec3.length(vec3.sub(b.max, b.min)));
  }

  /** Looks at the map from just behind and above the first camera. */
  initialView(pose) {
    const right = vec3.normalize(column(pose, 0));
    const up = vec3.normalize(vec3.scale(column(pose, 1), -1));
    const forward = vec3.normalize(column(pose, 2));
    this.basis = { right, up, back: vec3.scale(forward, -1) };
    const b = this.bounds;
    const centroid = vec3.scale(b.sum, 1 / Math.max(1, b.n));
    const cam = [pose[12], pose[13], pose[14]];
    const depth = Math.max(0.5, vec3.dot(vec3.sub(centroid, cam), forward));
    this.target = vec3.add(cam, vec3.scale(forward, depth));
    this.distance = depth * 1.8;
    this.yaw = 0;
    this.pitch = 0.3;
    this.viewInitialised = true;
  }

  /** Frames the whole map (orientation kept). */
  fitView() {
    const b = this.bounds;
    if (!b) return;
    this.target = vec3.scale(vec3.add(b.min, b.max), 0.5);
    this.distance = Math.max(0.5, (this.sceneSize() * 0.5) / Math.tan(FOVY / 2));
    this.follow = false;
    this.dirty = true;
  }

  resetView() {
    if (this.trajectory.count && this.bounds) {
      this.initialView(this.firstPose ?? this.currentPose);
      this.dirty = true;
    }
  }

  /** mesh: parseGlb's arrays (www/mesh-view.js), in the display frame. */
  setMesh(mesh) {
    this.mesh.set(mesh);
    this.dirty = true;
  }

  setShowMesh(on) {
    this.showMesh = Boolean(on);
    this.dirty = true;
  }

  setMode(mode) {
    this.mode = mode in MODES ? mode : 'rgb';
    this.dirty = true;
  }

  // ---- camera -----------------------------------------------------------------------

  eye() {
    const { right, up, back } = this.basis;
    const cp = Math.cos(this.pitch);
    const dir = vec3.add(
      vec3.add(vec3.scale(right, cp * Math.sin(this.yaw)), vec3.scale(up, Math.sin(this.pitch))),
      vec3.scale(back, cp * Math.cos(this.yaw)),
    );
    return vec3.add(this.target, vec3.scale(dir, this.distance));
  }

  viewMatrix() {
    if (this.follow && this.currentPose) {
      // Just behind and above the tracked camera, looking where it looks.
      const glFromCv = new Float64Array([1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1]);
      const back = Math.max(0.2, this.sceneSize() * 0.12);
      const offset = new Float64Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -back * 0.35, -back, 1]);
      return multiply(glFromCv, invertRigid(multiply(this.currentPose, offset)));
    }
    return lookAt(this.eye(), this.target, this.basis.up);
  }

  screenAxes() {
    const view = this.viewMatrix();
    return { right: [view[0], view[4], view[8]], up: [view[1], view[5], view[9]] };
  }

  orbit(dx, dy) {
    this.yaw -= dx * 0.008;
    this.pitch = Math.max(-1.5, Math.min(1.5, this.pitch + dy * 0.008));
    this.dirty = true;
  }

  pan(dx, dy) {
    const { right, up } = this.screenAxes();
    const s = (this.distance * 2 * Math.tan(FOVY / 2)) / Math.max(1, this.canvas.clientHeight);
    this.target = vec3.add(this.target, vec3.add(vec3.scale(right, -dx * s), vec3.scale(up, dy * s)));
    this.dirty = true;
  }

  zoom(factor) {
    this.distance = Math.max(0.05, Math.min(500, this.distance * factor));
    this.dirty = true;
  }

  installControls() {
    const c = this.canvas;
    c.style.touchAction = 'none';
    let drag = null;
    c.addEventListener('contextmenu', (e) => e.preventDefault());
    c.addEventListener('pointerdown', (e) => {
      if (e.pointerType === 'touch') return;
      c.setPointerCapture(e.pointerId);
      drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.button === 1 || e.shiftKey };
    });
    c.addEventListener('pointermove', (e) => {
      if (!drag || e.pointerType === 'touch') return;
      const dx = e.clientX - drag.x;
      const dy = e.clientY - drag.y;
      drag.x = e.clientX;
      drag.y = e.clientY;
      this.leaveFollow();
      if (drag.pan) this.pan(dx, dy);
      else this.orbit(dx, dy);
    });
    const end = () => (drag = null);
    c.addEventListener('pointerup', end);
    c.addEventListener('pointercancel', end);
    c.addEventListener(
      'wheel',
      (e) => {
        e.preventDefault();
        this.leaveFollow();
        this.zoom(Math.exp(Math.sign(e.deltaY) * Math.min(Math.abs(e.deltaY), 200) * 0.0015));
      },
      { passive: false },
    );
    c.addEventListener('dblclick', () => this.fitView());

    // touch: one finger orbits, two fingers pinch-zoom and pan
    let touches = null;
    const snapshot = (list) => [...list].map((t) => ({ x: t.clientX, y: t.clientY }));
    const centre = (t) => ({ x: (t[0].x + t[1].x) / 2, y: (t[0].y + t[1].y) / 2 });
    const spread = (t) => Math.hypot(t[0].x - t[1].x, t[0].y - t[1].y);
    c.addEventListener('touchstart', (e) => {
      e.preventDefault();
      touches = snapshot(e.touches);
    }, { passive: false });
    c.addEventListener('touchmove', (e) => {
      e.preventDefault();
      const now = snapshot(e.touches);
      if (!touches || now.length !== touches.length) {
        touches = now;
        return;
      }
      this.leaveFollow();
      if (now.length === 1) {
        this.orbit(now[0].x - touches[0].x, now[0].y - touches[0].y);
      } else if (now.length >= 2) {
        const a = centre(touches), b = centre(now);
        this.pan(b.x - a.x, b.y - a.y);
        const s0 = spread(touches), s1 = spread(now);
        if (s0 > 0 && s1 > 0) this.zoom(s0 / s1);
      }
      touches = now;
    }, { passive: false });
    c.addEventListener('touchend', (e) => {
      touches = e.touches.length ? snapshot(e.touches) : null;
    });
  }

  leaveFollow() {
    if (!this.follow) return;
    // Continue orbiting from where the follow view was.
    if (this.currentPose) {
      const p = this.currentPose;
      this.basis = {
        right: vec3.normalize(column(p, 0)),
        up: vec3.normalize(vec3.scale(column(p, 1), -1)),
        back: vec3.normalize(vec3.scale(column(p, 2), -1)),
      };
      const forward = vec3.scale(this.basis.back, -1);
      this.target = vec3.add([p[12], p[13], p[14]], vec3.scale(forward, Math.max(0.5, this.sceneSize() * 0.3)));
      this.distance = Math.max(0.6, this.sceneSize() * 0.45);
      this.yaw = 0;
      this.pitch = 0.15;
    }
    this.follow = false;
    this.onFollowChange?.(false);
  }

  // ---- drawing -----------------------------------------------------------------------

  resize() {
    const dpr = Math.min(window.devicePixelRatio || 1, 2);
    const w = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    const h = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
      this.dirty = true;
    }
  }

  frameLoop() {
    requestAnimationFrame(this.frameLoop);
    const gl = this.gl;
    this.resize();
    if (this.fence) {
      // Backpressure: never queue a new frame while the GPU still works on the last one.
      if (gl.getSyncParameter(this.fence, gl.SYNC_STATUS) !== gl.SIGNALED) return;
      gl.deleteSync(this.fence);
      this.fence = null;
      this.gpuMs = performance.now() - this.fenceIssuedAt;
    }
    if (!this.dirty) return;
    const now = performance.now();
    // A software rasteriser (SwiftShader, no GPU) shares the CPU cores with
    // the SLAM threads: while they run, draw at most 10 times a second and
    // leave the rasteriser idle three quarters of the time.
    if (this.throttle && now - this.lastDrawAt < Math.max(100, 4 * this.gpuMs)) return;
    this.dirty = false;
    this.lastDrawAt = now;
    this.flushUploads();
    this.draw();
    this.lastDrawMs = performance.now() - now;
    this.fence = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
    this.fenceIssuedAt = now;
    gl.flush();
  }

  draw() {
    const gl = this.gl;
    const w = this.canvas.width, h = this.canvas.height;
    gl.viewport(0, 0, w, h);
    gl.clearColor(...this.background, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);

    const far = Math.max(50, this.sceneSize() * 20 + this.distance * 4);
    const proj = new Float32Array(perspective(FOVY, w / h, 0.01, far));
    const view = new Float32Array(this.viewMatrix());

    if (this.showMesh) {
      this.mesh.draw(view, proj);
    } else if (this.count > 0) {
      const { program, uniforms: u } = this.surfelProgram;
      gl.useProgram(program);
      gl.uniformMatrix4fv(u.uView, false, view);
      gl.uniformMatrix4fv(u.uProj, false, proj);
      gl.uniform1f(u.uPixelsPerUnit, h / (2 * Math.tan(FOVY / 2)));
      gl.uniform1f(u.uSizeScale, this.sizeScale);
      gl.uniform1f(u.uMaxPointSize, Math.min(this.maxPointSize, 64));
      gl.uniform1f(u.uConfidenceMax, this.confidenceMax);
      gl.uniform1i(u.uMode, MODES[this.mode]);
      gl.bindVertexArray(this.vao);
      gl.drawArrays(gl.POINTS, 0, this.count);
      gl.bindVertexArray(null);
    }

    const { program, uniforms: u } = this.lineProgram;
    gl.useProgram(program);
    gl.uniformMatrix4fv(u.uView, false, view);
    gl.uniformMatrix4fv(u.uProj, false, proj);
    const lines = [
      [this.groundTruth, this.show.groundTruth],
      [this.trajectory, this.show.trajectory],
      [this.frustum, this.show.frustum && !this.follow],
    ];
    for (const [l, visible] of lines) {
      if (!visible || l.count < 2) continue;
      gl.uniform4fv(u.uColour, l.colour);
      gl.bindVertexArray(l.vao);
      gl.drawArrays(l.mode, 0, l.count);
    }
    gl.bindVertexArray(null);
  }
}
