// A CI-sized long run under Node: the bundled sample clip (44 frames of TUM
// fr3/teddy, in the repo) looped forwards and backwards with a surfel budget
// that is reached on the second frame. The budget must hold, tracking must
// go on, and the wasm memory must not grow once the map stopped growing
// (tests/node/long_run.mjs runs the full 1500 frames on ICL-NUIM).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, longRun, pingPong, PKG, ROOT } from './long_run.mjs';

const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');
const FRAMES = 130;
const BUDGET = 400_000;

test('ping-pong order keeps the motion continuous', () => {
  assert.deepEqual(pingPong(4, 10), [0, 1, 2, 3, 2, 1, 0, 1, 2, 3]);
  assert.deepEqual(pingPong(1, 3), [0, 0, 0]);
});

test('long looped run: budget holds, memory flat once the map is full', { timeout: 600_000 }, async (t) => {
  if (!existsSync(path.join(PKG, 'surfel_slam.js'))) {
    if (process.env.CI) throw new Error(`${PKG} is not built`);
    return t.skip(`${PKG} is not built: run scripts/build.sh`);
  }
  const pkg = await loadPackage();
  const r = await longRun(pkg, CLIP, { frames: FRAMES, maxSurfels: BUDGET, every: 10, log: (m) => t.diagnostic(m) });
  // The budget bounds the arrays: surfels plus absorbed ones awaiting compaction.
  const full = r.samples.find((s) => s.slots >= BUDGET * 0.95);
  // Steady state: the map is full and every per-frame allocation pattern has
  // been seen once (one pass over the clip); from then on nothing may grow.
  const steady = r.samples.find((s) => full && s.frame >= Math.max(full.frame, r.sequenceFrames));
  t.diagnostic(
    `${r.frames} frames: tracked ${r.counts.tracked}, lost ${r.counts.lost}, recovered ${r.counts.recovered}; ` +
      `adds skipped ${r.skipped}; memory ${r.samples.map((s) => (s.memory / 2 ** 20).toFixed(0)).join(' ')} MiB`,
  );
  assert.ok(r.finiteMap, 'no NaN or infinity in the map');
  assert.equal(r.nonFinitePoses, 0);
  assert.ok(r.samples.every((s) => s.slots <= BUDGET && s.surfels <= s.slots), 'the budget holds');
  assert.ok(r.skipped > 0, 'the budget was reached (otherwise this proves nothing)');
  assert.ok(full, 'the map filled up to the budget');
  assert.ok(r.counts.lost <= 5, `tracking held: ${r.counts.lost} lost`);
  // From then on only the trajectory grows (~100 bytes a frame).
  const grown = r.finalMemory - steady.memory;
  assert.ok(grown <= 1 << 18, `wasm memory grew ${grown} bytes from frame ${steady.frame} (map full at frame ${full.frame})`);
});
