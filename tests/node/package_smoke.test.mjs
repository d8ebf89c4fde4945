// Smoke test of the built npm package (pkg/) under Node: `node --test tests/node/`.
// Uses the package's own entry points (package.json exports), loads the
// module from bytes as a Node user would, and runs ~10 ICL-NUIM frames
// (skipped cleanly when ../shared/data or pkg/ is absent).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFile, readdir } from 'node:fs/promises';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const root = path.resolve(here, '../..');
const pkgDir = path.join(root, 'pkg');
const dataDir = path.join(root, '../shared/data/icl_office_kt0');
const FRAMES = 10;

const built = existsSync(path.join(pkgDir, 'package.json'));
const skipNoPkg = built ? false : 'pkg/ is not built (run scripts/build.sh)';
const skipNoData = skipNoPkg || (existsSync(dataDir) ? false : `${dataDir} is absent (no ../shared/data)`);

let wasmPromise = null;
async function loadPackage() {
  wasmPromise ??= (async () => {
    const pkg = JSON.parse(await readFile(path.join(pkgDir, 'package.json'), 'utf8'));
    const entry = path.join(pkgDir, pkg.exports['.'].default);
    const m = await import(pathToFileURL(entry).href);
    await m.default({ module_or_path: await readFile(path.join(pkgDir, pkg.exports['./surfel_slam_bg.wasm'])) });
    return m;
  })();
  return wasmPromise;
}

async function iclSequence(m) {
  const names = [];
  for (const sub of ['', 'rgb', 'depth']) {
    for (const e of await readdir(path.join(dataDir, sub), { withFileTypes: true })) {
      if (e.isFile()) names.push(sub ? `${sub}/${e.name}` : e.name);
    }
  }
  const layout = m.detectLayout(names);
  const texts = {};
  for (const f of layout.indexFiles) texts[f] = await readFile(path.join(dataDir, f), 'utf8');
  return { layout, sequence: m.parseSequence(names, texts, 'icl_office_kt0') };
}

const frameBytes = async (f) =>
  Promise.all([readFile(path.join(dataDir, f.colour)), readFile(path.join(dataDir, f.depth))]);

test('package.json is complete and its files exist', { skip: skipNoPkg }, async () => {
  const pkg = JSON.parse(await readFile(path.join(pkgDir, 'package.json'), 'utf8'));
  assert.equal(pkg.name, 'surfel-slam');
  assert.equal(pkg.type, 'module');
  assert.match(pkg.version, /^\d+\.\d+\.\d+/);
  for (const target of Object.values(pkg.exports)) {
    for (const file of typeof target === 'string' ? [target] : Object.values(target)) {
      assert.ok(existsSync(path.join(pkgDir, file)), `exports names ${file}, which is missing`);
    }
  }
  assert.ok(existsSync(path.join(pkgDir, pkg.types)));
});

test('module loads from bytes; presets, threadCount and memoryBytes', { skip: skipNoPkg }, async () => {
  const m = await loadPackage();
  const presets = m.presets();
  assert.deepEqual(
    presets.map((p) => p.name),
    ['tum-fr1', 'tum-fr2', 'tum-fr3', 'icl-nuim', '7-scenes', 'realsense-d400', 'stray-lidar'],
  );
  assert.equal(presets[3].fy, -480);
  assert.equal(m.threadCount(), 1);
  // Memory is whole 64 KiB pages, and grows by what a Slam allocates.
  const before = m.memoryBytes();
  assert.ok(before > 0 && before % 65536 === 0, `memoryBytes ${before}`);
  const slam = new m.Slam({ preset: 'tum-fr3' });
  assert.ok(m.memoryBytes() >= before);
  slam.free();
  assert.throws(() => new m.Slam({ preset: 'nope' }), /unknown preset "nope"/);
  assert.throws(() => new m.Slam({ preset: 'tum-fr3', depthScale: 0 }), /depth scale/);
  assert.throws(() => new m.Slam({ presett: 'tum-fr3' }), /unknown config field "presett"/);
  assert.throws(() => new m.Slam({ preset: 'tum-fr3', tracker: 'orb' }), /config.tracker must be/);
  for (const tracker of ['icp', 'rgb', 'joint']) new m.Slam({ preset: 'tum-fr3', tracker, icpWeight: 2 }).free();
});

test('optical flow follows a shifted texture', { skip: skipNoPkg }, async () => {
  const m = await loadPackage();
  const [w, h, dx, dy] = [160, 120, 2.5, -1.25];
  const image = (sx, sy) => {
    const rgba = new Uint8Array(4 * w * h);
    for (let v = 0; v < h; v++) {
      for (let u = 0; u < w; u++) {
        const [x, y] = [u - sx, v - sy];
        const g = 128 + 50 * Math.sin(0.3 * x) * Math.cos(0.23 * y) + 40 * Math.exp(-(((x % 20) - 10) ** 2) / 8 - (((y % 20) - 10) ** 2) / 8);
        rgba.fill(Math.max(0, Math.min(255, Math.round(g))), 4 * (v * w + u), 4 * (v * w + u) + 3);
        rgba[4 * (v * w + u) + 3] = 255;
      }
    }
    return rgba;
  };
  const flow = new m.OpticalFlow(200);
  try {
    const t = flow.track(w, h, image(0, 0), image(dx, dy));
    assert.ok(t.length >= 4 * 20, `${t.length / 4} tracks`);
    let sum = 0;
    for (let i = 0; i < t.length; i += 4) sum += Math.hypot(t[i + 2] - t[i] - dx, t[i + 3] - t[i + 1] - dy);
    assert.ok(sum / (t.length / 4) < 0.3, `mean end-point error ${sum / (t.length / 4)} px`);
    assert.throws(() => flow.track(w, h, new Uint8Array(7), image(0, 0)), /RGBA8 or RGB8/);
  } finally {
    flow.free();
  }
});

test(`${FRAMES} ICL-NUIM frames track; views; bad bytes throw and the pipeline continues`, { skip: skipNoData }, async () => {
  const m = await loadPackage();
  const { layout, sequence } = await iclSequence(m);
  assert.equal(layout.kind, 'icl-nuim');
  assert.equal(sequence.preset, 'icl-nuim');
  const slam = new m.Slam({ preset: sequence.preset });
  try {
    const frames = sequence.frames.slice(0, FRAMES);
    for (const [i, f] of frames.entries()) {
      const [colour, depth] = await frameBytes(f);
      const r = slam.pushFrame(colour, depth, f.timestamp);
      assert.equal(r.index, i);
      assert.ok(i === 0 ? r.verdict === 'initialised' : ['tracked', 'held'].includes(r.verdict), `frame ${i}: ${r.verdict} ${r.lostReason}`);
      assert.equal(r.lostReason, null);
      assert.ok(r.pose instanceof Float64Array && r.pose.length === 16);
      assert.equal(r.quaternion.length, 4);
      assert.ok(r.surfels > 0 && r.timings.total > 0);

      // Garbage in the middle of the sequence: throws, changes nothing.
      if (i === 4) {
        const before = slam.surfelCount;
        assert.throws(() => slam.pushFrame(new Uint8Array([1, 2, 3]), depth, 99), /colour image could not be decoded/);
        assert.throws(() => slam.pushFrame(colour, depth.subarray(0, depth.length >> 1), 99), /depth image could not be decoded/);
        assert.throws(() => slam.pushFrame(colour, colour, 99), /16-bit/);
        assert.throws(() => slam.pushRaw(640, 480, new Uint8Array(10), new Uint16Array(640 * 480), 99), /colour buffer/);
        assert.equal(slam.surfelCount, before);
        assert.equal(slam.frames, i + 1);
      }
    }
    const n = slam.surfelCount;
    assert.ok(n > 0);
    assert.equal(slam.frames, FRAMES);
    const positions = slam.positions();
    assert.ok(positions instanceof Float32Array);
    assert.equal(positions.length, 3 * n);
    assert.equal(slam.normals().length, 3 * n);
    assert.ok(slam.colours() instanceof Uint8Array);
    assert.equal(slam.colours().length, 4 * n);
    assert.equal(slam.radii().length, n);
    assert.equal(slam.confidences().length, n);
    assert.ok(positions.every(Number.isFinite));
    const [start, end] = slam.takeChangedRange();
    assert.ok(start >= 0 && start <= end && end <= n);
    assert.deepEqual(slam.takeChangedRange(), [0, 0]);

    const ate = m.ateTum(slam.trajectoryTum(), sequence.groundTruthTum);
    assert.equal(ate.pairs, FRAMES - 1); // ICL frame 1 has no ground truth
    assert.ok(ate.rmse < 0.005, `ATE ${ate.rmse} m`);
    const ply = slam.exportPly();
    assert.equal(new TextDecoder().decode(ply.subarray(0, 4)), 'ply\n');

    slam.reset();
    assert.equal(slam.surfelCount, 0);
    assert.equal(slam.frames, 0);
    const [colour, depth] = await frameBytes(frames[0]);
    assert.equal(slam.pushFrame(colour, depth, 0).verdict, 'initialised');
  } finally {
    slam.free();
  }
});
