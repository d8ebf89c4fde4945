// WebGL2 surfel renderer: splats sized by surfel radius (screen-aligned round
// point sprites), colour by RGB / normal / confidence, orbit-pan-zoom camera
// (mouse, wheel, touch) and a follow-the-camera mode, the estimated and the
// ground-truth trajectories, the current camera frustum.
//
// Beside this file: gl-shaders.js (shader sources), surfel-buffers.js (the
// surfels' GPU buffers, updated over each frame's changed range),
// gl-lines.js (camera paths and frustum), pointer-controls.js (mouse and
// touch input).
import { vec3, multiply, invertRigid, column, perspective, lookAt } from './math3d.js';
import { MeshView } from './mesh-view.js';
import { MODES, SURFEL_VS, SURFEL_FS, LINE_VS, LINE_FS, compile } from './gl-shaders.js';
import { SurfelBuffers } from './surfel-buffers.js';
import { Lines, frustumPoints } from './gl-lines.js';
import { installPointerControls } from './pointer-controls.js';
import { fitPoints } from './view-fit.js';

const FOVY = (55 * Math.PI) / 180;
// About the surfels of a 200-frame sequence (teddy: 346 k; the 500-frame
// kitchen: 1.3 M): a short run is drawn whole even while it plays.
const DEFAULT_SPLAT_BUDGET = 400_000;

export class Renderer {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error('WebGL2 is not available in this browser');
    this.gl = gl;
    this.surfelProgram = compile(gl, SURFEL_VS, SURFEL_FS);
    this.lineProgram = compile(gl, LINE_VS, LINE_FS);
    this.maxPointSize = gl.getParameter(gl.ALIASED_POINT_SIZE_RANGE)[1];

    this.surfels = new SurfelBuffers(gl);
    this.fence = null;
    this.fenceIssuedAt = 0;
    this.gpuMs = 0; // how long the GPU took for the last frame (issue -> fence signalled)
    this.lastDrawAt = 0;
    this._throttle = false; // while SLAM runs: leave the GPU (often a CPU rasteriser) idle 3/4 of the time
    this.splatBudget = DEFAULT_SPLAT_BUDGET; // splats drawn at most while SLAM runs (0: no limit)
    this.splatsDrawn = 0; // splats of the last draw

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

    this.dirty = true;
    this.lastDrawMs = 0;
    installPointerControls(canvas, this);
    this.frameLoop = this.frameLoop.bind(this);
    requestAnimationFrame(this.frameLoop);
  }

  /** Whether SLAM runs: draws are rarer and bounded by `splatBudget`. */
  get throttle() {
    return this._throttle;
  }

  set throttle(on) {
    // Stopping redraws the whole map at once.
    if (this._throttle !== on) this.dirty = true;
    this._throttle = on;
  }

  // ---- surfels -------------------------------------------------------------------

  /** Surfels drawn (the map's arrays' length, absorbed ones included). */
  get count() {
    return this.surfels.count;
  }

  /** Surfels written to the GPU since creation. */
  get uploadedSurfels() {
    return this.surfels.uploadedSurfels;
  }

  /** Running bounding box of the received surfels, null when none. */
  get bounds() {
    return this.surfels.bounds;
  }

  /**
   * Queues one frame's changed surfel range ({count, start, end, positions,
   * normals, colours, radii, confidences}); uploaded just before the next
   * draw. A range over the whole map (a loop closure moved every surfel)
   * replaces the map and its bounds.
   */
  updateSurfels(chunk) {
    this.surfels.queue(chunk);
    this.dirty = true;
  }

  flushUploads() {
    this.surfels.flush();
  }

  /**
   * Empties the scene and draws the empty view now: not at the next throttled
   * draw, which a big old map's slow GPU time (4x gpuMs) would put seconds
   * away, leaving the old map on screen into the new sequence.
   */
  clear() {
    this.surfels.clear();
    this.trajectory.clear();
    this.groundTruth.clear();
    this.frustum.clear();
    this.mesh.clear();
    this.currentPose = null;
    this.firstPose = null;
    this.viewInitialised = false;
    this.splatsDrawn = 0;
    this.gpuMs = 0; // measured on the old map
    this.lastDrawAt = 0;
    this.dirty = false;
    this.resize();
    this.draw();
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

  /**
   * Replaces the estimated path (world positions of every camera so far, in
   * the display frame), e.g. after a loop closure moved past poses.
   */
  setTrajectory(points) {
    this.trajectory.set(points);
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
    this.frustum.set(frustumPoints(pose, k, d));
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

  /**
   * Fills the view with the map, orientation kept: its robust bounds (2nd to
   * 98th percentile of a sample of the surfels, so that a few stray ones far
   * off do not shrink it) as seen along the current view direction.
   */
  fitView() {
    this.flushUploads();
    const fit = fitPoints(this.surfels.samplePositions(), this.screenAxesAt(), FOVY, this.canvas.clientWidth / Math.max(1, this.canvas.clientHeight));
    if (!fit) return;
    this.target = fit.target;
    this.distance = Math.max(0.05, fit.distance);
    this.follow = false;
    this.onFollowChange?.(false);
    this.dirty = true;
  }

  /** The orbit view's axes (right, up, towards the eye), follow mode left out. */
  screenAxesAt() {
    const { right, up, back } = this.basis;
    const cp = Math.cos(this.pitch);
    const toEye = vec3.add(vec3.add(vec3.scale(right, cp * Math.sin(this.yaw)), vec3.scale(up, Math.sin(this.pitch))), vec3.scale(back, cp * Math.cos(this.yaw)));
    const r = vec3.normalize(vec3.cross(this.basis.up, toEye));
    return { right: r, up: vec3.cross(toEye, r), toEye };
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
      // While SLAM runs, a map past the budget is drawn as every n-th surfel,
      // each splat sqrt(n) times wider so the surfaces stay closed: drawing
      // then costs the same at frame 1000 as at frame 100. Idle: all of it.
      const budget = this.throttle ? this.splatBudget : 0;
      const stride = budget > 0 && this.count > budget ? Math.ceil(this.count / budget) : 1;
      gl.uniform1f(u.uSizeScale, this.sizeScale * Math.sqrt(stride));
      gl.uniform1f(u.uMaxPointSize, Math.min(this.maxPointSize, 64));
      gl.uniform1f(u.uConfidenceMax, this.confidenceMax);
      gl.uniform1i(u.uMode, MODES[this.mode]);
      const splats = this.surfels.bindEveryNth(stride);
      gl.drawArrays(gl.POINTS, 0, splats);
      gl.bindVertexArray(null);
      this.splatsDrawn = splats;
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
