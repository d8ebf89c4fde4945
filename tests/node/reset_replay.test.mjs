// Issue 19 under Node against the built package: push all 193 frames of TUM
// fr3/teddy into one Slam, reset, push them again. Before the fix the first
// cleanup after the reset panicked (RuntimeError: unreachable) and the object
// was dead; now the second pass must give the same trajectory (ATE equal
// within 1e-4 m) and the same map. Reads ../shared/data (skipped when absent,
// fails when absent with CI=true).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { openSequence, plyVertexCount, requireDir, SHARED } from './sequence.mjs';

const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;

test('teddy: push 193 frames, reset, push again: same trajectory', { skip, timeout: 900_000 }, async (t) => {
  const dir = path.join(SHARED, 'tum_fr3_teddy');
  if (!requireDir(t, dir)) return;
  const m = await loadPackage();
  const { sequence, frame } = await openSequence(m, dir);
  assert.ok(sequence.frames.length >= 150, `${sequence.frames.length} frames`);
  const slam = new m.Slam({ preset: sequence.preset });
  const pass = () => {
    let last = null;
    for (let i = 0; i < sequence.frames.length; i++) {
      const [colour, depth] = frame(i);
      last = slam.pushFrame(colour, depth, sequence.frames[i].timestamp);
    }
    assert.equal(slam.frames, sequence.frames.length);
    assert.equal(last.surfels, slam.liveSurfels);
    assert.equal(last.surfelSlots, slam.surfelCount);
    assert.equal(plyVertexCount(slam.exportPly()), slam.liveSurfels, 'the PLY holds the live surfels');
    const trajectory = slam.trajectoryTum();
    return { trajectory, ate: m.ateTum(trajectory, sequence.groundTruthTum).rmse, surfels: slam.liveSurfels, counts: last.counts };
  };
  try {
    const first = pass();
    slam.reset();
    assert.equal(slam.frames, 0);
    assert.equal(slam.surfelCount, 0);
    assert.deepEqual(Array.from(slam.takeChangedRange()), [0, 0]);
    const second = pass();
    t.diagnostic(
      `${sequence.frames.length} frames: ATE ${(first.ate * 100).toFixed(4)} cm, after reset ${(second.ate * 100).toFixed(4)} cm; ` +
        `${first.surfels} / ${second.surfels} surfels`,
    );
    assert.ok(Math.abs(first.ate - second.ate) <= 1e-4, `ATE ${first.ate} m, after reset ${second.ate} m`);
    assert.deepEqual(second.counts, first.counts);
    // One thread in this build: the same frames give the same numbers.
    assert.equal(second.trajectory, first.trajectory);
    assert.equal(second.surfels, first.surfels);
  } finally {
    slam.free();
  }
});
