// Sessions in the npm package (issue #36) under Node, on the bundled teddy
// clip: `slam.save()` after some frames, `load(bytes)` into a fresh Slam,
// the rest pushed: the same trajectory text as the run that never stopped;
// a cut, damaged or foreign file throws naming its kind and the Slam keeps
// its map; `load(bytes, { localise: true })` places the next frames in the
// saved map without changing it. Save/load time and size for a mid-size
// map: tests/node/session_bench.mjs.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { openSequence, CLIP } from './sequence.mjs';

const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;
/** Frames pushed before the session is saved. */
const SAVED = 20;

async function clip() {
  const m = await loadPackage();
  const { sequence, frame } = await openSequence(m, CLIP);
  const push = (slam, from, to) => {
    const reports = [];
    for (let i = from; i < to; i++) {
      const [colour, depth] = frame(i);
      reports.push(slam.pushFrame(colour, depth, sequence.frames[i].timestamp));
    }
    return reports;
  };
  return { m, sequence, push, n: sequence.frames.length };
}

test('a session saved to bytes and loaded into a fresh Slam continues exactly', { skip }, async () => {
  const { m, sequence, push, n } = await clip();
  assert.ok(n > SAVED + 10, `${n} frames`);
  const straight = new m.Slam({ preset: sequence.preset });
  const first = new m.Slam({ preset: sequence.preset });
  const resumed = new m.Slam({ preset: sequence.preset });
  try {
    push(straight, 0, n);
    push(first, 0, SAVED);
    const bytes = first.save();
    assert.ok(bytes instanceof Uint8Array && bytes.length > 1000, `${bytes.length} bytes`);
    resumed.load(bytes);
    assert.equal(resumed.frames, SAVED);
    assert.equal(resumed.liveSurfels, first.liveSurfels);
    assert.equal(resumed.localising, false);
    push(resumed, SAVED, n);
    assert.equal(resumed.frames, n);
    assert.equal(resumed.trajectoryTum(), straight.trajectoryTum());
    assert.equal(resumed.liveSurfels, straight.liveSurfels);
  } finally {
    straight.free();
    first.free();
    resumed.free();
  }
});

test('a bad session throws naming its kind and the Slam keeps its map', { skip }, async () => {
  const { m, sequence, push } = await clip();
  const source = new m.Slam({ preset: sequence.preset });
  const slam = new m.Slam({ preset: sequence.preset });
  try {
    push(source, 0, SAVED);
    const bytes = source.save();
    push(slam, 0, 8);
    const kept = () => ({
      frames: slam.frames,
      surfels: slam.surfelCount,
      live: slam.liveSurfels,
      trajectory: slam.trajectoryTum(),
      localising: slam.localising,
    });
    const before = kept();
    const damaged = bytes.slice();
    damaged[Math.floor(damaged.length / 3)] ^= 0xff;
    const cases = [
      ['cut', bytes.slice(0, Math.floor(bytes.length / 2)), { message: /^truncated: / }],
      ['damaged', damaged, { message: /^corrupt: / }],
      ['not a session', new Uint8Array([1, 2, 3, 4, 5, 6, 7, 8]), { message: /^not-a-session: / }],
      ['empty', new Uint8Array(0), { message: /^not-a-session: / }],
    ];
    for (const [name, data, kind] of cases) {
      assert.throws(() => slam.load(data), kind, name);
      assert.deepEqual(kept(), before, `${name}: the Slam changed`);
    }
    const other = new m.Slam({ preset: 'icl-nuim' });
    try {
      assert.throws(() => other.load(bytes), { message: /^camera-mismatch: / });
      assert.equal(other.frames, 0);
    } finally {
      other.free();
    }
    assert.throws(() => slam.load(bytes, { localise: 'yes' }), /localise must be a boolean/);
    assert.throws(() => slam.load(bytes, { localize: true }), /unknown load option "localize"; known options: localise/);
    assert.deepEqual(kept(), before, 'bad options: the Slam changed');
    // Still whole: it goes on.
    push(slam, 8, 10);
    assert.equal(slam.frames, 10);
  } finally {
    source.free();
    slam.free();
  }
});

test('load with { localise: true } places the next frames in the saved map without changing it', { skip }, async () => {
  const { m, sequence, push, n } = await clip();
  const source = new m.Slam({ preset: sequence.preset });
  const slam = new m.Slam({ preset: sequence.preset });
  try {
    push(source, 0, SAVED);
    slam.load(source.save(), { localise: true });
    assert.equal(slam.localising, true);
    const surfels = slam.liveSurfels;
    const positions = Float32Array.from(slam.positions());
    const reports = push(slam, SAVED, n);
    assert.equal(reports[0].verdict, 'recovered', 'the first frame is relocalised');
    assert.notEqual(reports[0].relocalisedFrom, null);
    const placed = reports.filter((r) => r.verdict !== 'unplaced');
    assert.ok(placed.length >= reports.length - 2, `${placed.length} of ${reports.length} placed`);
    for (const r of reports) {
      assert.equal(r.pose === null, r.verdict === 'unplaced', `frame ${r.index}: ${r.verdict}`);
      assert.equal(r.surfels, surfels);
    }
    const lines = slam.trajectoryTum().split('\n').filter((l) => l && !l.startsWith('#'));
    assert.equal(lines.length, placed.length);
    // Placed near the truth, with the ground truth aligned on the localised frames.
    const ate = slam.ate(sequence.groundTruthTum);
    assert.ok(ate.rmse < 0.03, `ATE ${ate.rmse} m`);
    assert.equal(slam.frames, SAVED, 'the map keeps its own frame count');
    assert.deepEqual(Float32Array.from(slam.positions()), positions, 'the map changed');
    assert.throws(() => slam.save(), { message: /^localising: / });
    slam.reset();
    assert.equal(slam.localising, false);
  } finally {
    source.free();
    slam.free();
  }
});
