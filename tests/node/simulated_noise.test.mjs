// The JS config's simulated noise (`simulateNoise`, `noiseSeed`) on the
// bundled teddy clip: the same seed gives the same trajectory, another seed
// another one, and both differ from the clean run but still track; a seed
// without a sensor, or an unknown sensor, is refused with a message.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { openSequence } from './sequence.mjs';
import { CLIP } from './datasets.mjs';

const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;
const FRAMES = 12;

test('simulateNoise and noiseSeed: seeded, and refused when malformed', { skip, timeout: 300_000 }, async () => {
  const m = await loadPackage();
  const { sequence, frame } = await openSequence(m, CLIP);
  const run = (extra) => {
    const slam = new m.Slam({ preset: sequence.preset, ...extra });
    try {
      let lost = 0;
      for (let i = 0; i < FRAMES; i++) {
        const [colour, depth] = frame(i);
        lost += Number(slam.pushFrame(colour, depth, sequence.frames[i].timestamp).verdict === 'lost');
      }
      return { trajectory: slam.trajectoryTum(), lost };
    } finally {
      slam.free();
    }
  };
  const clean = run({});
  const a = run({ simulateNoise: 'kinect-v1', noiseSeed: 1 });
  const b = run({ simulateNoise: 'kinect-v1', noiseSeed: 1 });
  const c = run({ simulateNoise: 'kinect-v1', noiseSeed: 2 });
  assert.equal(a.trajectory, b.trajectory, 'same seed, same run');
  assert.notEqual(a.trajectory, c.trajectory, 'another seed, another run');
  assert.notEqual(a.trajectory, clean.trajectory, 'noise changes the run');
  assert.equal(a.lost + c.lost, 0, 'a close object at 1-2 m still tracks with Kinect noise');
  assert.equal(run({ simulateNoise: null }).trajectory, clean.trajectory);
  assert.throws(() => new m.Slam({ preset: sequence.preset, noiseSeed: 3 }), /noiseSeed needs config\.simulateNoise/);
  assert.throws(() => new m.Slam({ preset: sequence.preset, simulateNoise: 'kinect-v2' }), /simulateNoise must be 'kinect-v1' or null/);
  assert.throws(() => new m.Slam({ preset: sequence.preset, simulateNoise: 'kinect-v1', noiseSeed: -1 }), /noiseSeed must be an integer/);
});
