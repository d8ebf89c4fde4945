// A change over the whole map (after a loop closure every surfel moves; a
// reset and replay also rewrites it from the first slot) reaches the GPU and
// the page's copy of the map (map-mirror.js) in full, on top of an older,
// larger map, as the worker sends it: the real module in headless Chromium,
// the bundled sample's frames, the worker's copy helpers (surfel-copy.js),
// the renderer's buffers read back from the GPU.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { startBrowser, skipUnlessReady, openModulePage } from './helpers.mjs';

/** Runs in the page: frames of the sample, then a reset and one frame again; returns what the checks need. */
async function replayOverOldMap() {
  const wasm = await import('/pkg/surfel_slam.js');
  await wasm.default({ module_or_path: new URL('/pkg/surfel_slam_bg.wasm', location.href) });
  const { Renderer } = await import('/renderer.js');
  const { MapMirror } = await import('/map-mirror.js');
  const { copyChanged, RollingRefresh } = await import('/surfel-copy.js');
  const { coversWholeMap } = await import('/surfel-buffers.js');

  const manifest = await (await fetch('/sample/manifest.json')).json();
  const paths = manifest.files.map((f) => f.path);
  const read = async (p) => new Uint8Array(await (await fetch(`/sample/${p}`)).arrayBuffer());
  const layout = wasm.detectLayout(paths);
  const texts = {};
  for (const f of layout.indexFiles) texts[f] = new TextDecoder().decode(await read(f));
  const sequence = wasm.parseSequence(paths, texts, manifest.name);
  const slam = new wasm.Slam({ preset: typeof sequence.preset === 'string' ? sequence.preset : sequence.preset.name });

  const canvas = document.createElement('canvas');
  canvas.style.width = '64px';
  canvas.style.height = '64px';
  document.body.append(canvas);
  const renderer = new Renderer(canvas);
  const mirror = new MapMirror();
  const refresh = new RollingRefresh();
  const push = async (i) => {
    const f = sequence.frames[i];
    const report = slam.pushFrame(await read(f.colour), await read(f.depth), f.timestamp);
    const count = slam.surfelCount;
    const changed = copyChanged(slam, count);
    mirror.update(changed);
    renderer.updateSurfels(changed);
    if (!coversWholeMap(changed)) {
      const window = refresh.next(slam, count);
      mirror.update(window);
      renderer.updateSurfels(window);
    }
    mirror.addPose(report);
    renderer.flushUploads();
    return changed;
  };

  for (let i = 0; i < 8; i++) await push(i);
  const before = { count: slam.surfelCount, bounds: structuredClone(renderer.bounds) };
  // Far from the first frame's camera: the map of frame 7 reaches beyond frame 0's.
  slam.reset();
  refresh.restart();
  const whole = await push(0);
  const wholeRange = { start: whole.start, end: whole.end, count: whole.count, covers: coversWholeMap(whole) };

  // The GPU's copy, read back.
  const gl = renderer.gl;
  const n = slam.surfelCount;
  const gpu = {};
  for (const [name, k, T] of [
    ['positions', 3, Float32Array],
    ['normals', 3, Float32Array],
    ['colours', 4, Uint8Array],
    ['radii', 1, Float32Array],
    ['confidences', 1, Float32Array],
  ]) {
    const out = new T(n * k);
    gl.bindBuffer(gl.ARRAY_BUFFER, renderer.surfels.buffers[name]);
    gl.getBufferSubData(gl.ARRAY_BUFFER, 0, out);
    gpu[name] = out;
  }
  gl.bindBuffer(gl.ARRAY_BUFFER, null);
  const slamArrays = {
    positions: slam.positions().slice(),
    normals: slam.normals().slice(),
    colours: slam.colours().slice(),
    radii: slam.radii().slice(),
    confidences: slam.confidences().slice(),
  };
  const differs = (a, b) => {
    if (a.length !== b.length) return `length ${a.length} vs ${b.length}`;
    for (let i = 0; i < a.length; i++) if (!Object.is(a[i], b[i])) return `index ${i}: ${a[i]} vs ${b[i]}`;
    return null;
  };
  const mismatches = {};
  for (const name of Object.keys(slamArrays)) {
    const k = slamArrays[name].length / n;
    mismatches[`gpu.${name}`] = differs(gpu[name], slamArrays[name]);
    mismatches[`mirror.${name}`] = differs(mirror.arrays[name].subarray(0, n * k), slamArrays[name]);
  }
  // The bounds of the new map only (a sample of its positions): inside the box of all its points.
  const p = slamArrays.positions;
  const box = { min: [Infinity, Infinity, Infinity], max: [-Infinity, -Infinity, -Infinity] };
  for (let i = 0; i < p.length; i += 3) {
    for (let k = 0; k < 3; k++) {
      box.min[k] = Math.min(box.min[k], p[i + k]);
      box.max[k] = Math.max(box.max[k], p[i + k]);
    }
  }
  const plyVertices = Number(/element vertex (\d+)/.exec(new TextDecoder().decode(mirror.ply().subarray(0, 400)))[1]);
  const result = {
    before,
    wholeRange,
    n,
    liveSurfels: slam.liveSurfels,
    rendererCount: renderer.count,
    mirrorCount: mirror.count,
    mismatches,
    bounds: renderer.bounds,
    box,
    plyVertices,
  };
  slam.free();
  canvas.remove();
  return result;
}

test('a change over the whole map replaces the older, larger map on the GPU and in the page copy', { timeout: 180_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env);
    const r = await page.evaluate(replayOverOldMap);
    assert.ok(r.before.count > r.n, `the old map (${r.before.count} surfels) is larger than the new one (${r.n})`);
    assert.ok(r.wholeRange.covers && r.wholeRange.start === 0 && r.wholeRange.end === r.n, `changed range after reset: ${JSON.stringify(r.wholeRange)}`);
    assert.equal(r.rendererCount, r.n, 'surfels drawn');
    assert.equal(r.mirrorCount, r.n, 'surfels in the page copy');
    for (const [what, mismatch] of Object.entries(r.mismatches)) assert.equal(mismatch, null, `${what} equals the module's array`);
    assert.equal(r.plyVertices, r.liveSurfels, "the page copy's PLY has the map's surfels");
    for (let k = 0; k < 3; k++) {
      assert.ok(r.bounds.min[k] >= r.box.min[k] - 1e-6 && r.bounds.max[k] <= r.box.max[k] + 1e-6, `bounds axis ${k}: ${JSON.stringify(r.bounds)} inside ${JSON.stringify(r.box)} (the old map's box is gone)`);
    }
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
  }
});

test('a trajectory replaced after a loop closure keeps growing from the new path', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page } = await openModulePage(env);
    const r = await page.evaluate(async () => {
      const { Renderer } = await import('/renderer.js');
      const { MapMirror } = await import('/map-mirror.js');
      const canvas = document.createElement('canvas');
      document.body.append(canvas);
      const renderer = new Renderer(canvas);
      const pose = (x) => new Float64Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, 0, 0, 1]);
      for (let i = 0; i < 300; i++) renderer.setCameraPose(pose(i));
      // The closure moved the 300 past positions; the next frame appends to them.
      renderer.setTrajectory(Array.from({ length: 300 }, (_, i) => [i, 1, 0]));
      renderer.setCameraPose(pose(300));
      const gl = renderer.gl;
      const out = new Float32Array(renderer.trajectory.count * 3);
      gl.bindBuffer(gl.ARRAY_BUFFER, renderer.trajectory.buffer);
      gl.getBufferSubData(gl.ARRAY_BUFFER, 0, out);
      const mirror = new MapMirror();
      mirror.addPose({ timestamp: 1, translation: [9, 9, 9], quaternion: [0, 0, 0, 1] });
      mirror.setTrajectoryTum('# timestamp tx ty tz qx qy qz qw\n1.000000 0 1 0 0 0 0 1\n2.000000 1 1 0 0 0 0 1\n');
      mirror.addPose({ timestamp: 3, translation: [2, 1, 0], quaternion: [0, 0, 0, 1] });
      canvas.remove();
      return { count: renderer.trajectory.count, points: Array.from(out), tum: mirror.trajectoryTum() };
    });
    assert.equal(r.count, 301);
    assert.deepEqual(r.points.slice(0, 6), [0, 1, 0, 1, 1, 0]);
    assert.deepEqual(r.points.slice(299 * 3), [299, 1, 0, 300, 0, 0]);
    const lines = r.tum.trim().split('\n').slice(1);
    assert.equal(lines.length, 3);
    assert.ok(lines[0].startsWith('1.000000 0 1 0') && lines[2].startsWith('3.000000 2.000000000 1.000000000'), r.tum);
  } finally {
    await env.close();
  }
});
