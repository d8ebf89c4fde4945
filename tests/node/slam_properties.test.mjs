// Stateful property test of the wasm `Slam` under Node (the same family as
// tests/pipeline_properties.rs natively): seeded random sequences of valid
// frames (the bundled TUM fr3/teddy clip, played forwards and backwards;
// a quarter pushed as their files with pushFiles),
// garbage (truncated or corrupt PNG, wrong size, 8-bit depth, colour/depth
// size mismatch, wrong buffer lengths, NaN or infinite timestamps, a depth
// or confidence image of the wrong size given to pushFiles), reset,
// a new configuration (free + new Slam, as the page does), PLY export,
// changed range, trajectory and depth preview, in any order; one case runs
// 110 frames (past the cleanups, spatial sorting and compaction) and resets.
// After every step: no exception but the expected ones, the surfel arrays
// finite and `surfelCount` long, liveSurfels = surfels with confidence >= 0
// = the PLY's vertex count, verdict counts summing to the frames accepted,
// which equal the trajectory's lines and the timestamps pushed.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, pingPong, PKG } from './long_run.mjs';
import { encodePng } from './png.mjs';
import { CLIP, openSequence, plyVertexCount } from './sequence.mjs';

const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;

/** mulberry32: a seeded generator of floats in [0, 1). */
function rng(seed) {
  let a = seed >>> 0;
  const next = () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
  return { next, below: (n) => Math.floor(next() * n), chance: (p) => next() < p };
}

function randomConfig(r) {
  const config = { preset: 'tum-fr3', tracker: ['icp', 'icp', 'icp', 'joint', 'rgb'][r.below(5)] };
  if (r.chance(0.3)) config.halfResolution = true;
  if (r.chance(0.5)) config.maxSurfels = 40_000 + r.below(160_000);
  return config;
}

/** Every invariant of a Slam at rest. */
function check(slam, model, where) {
  const n = slam.surfelCount;
  const views = { positions: 3, normals: 3, colours: 4, radii: 1, confidences: 1 };
  for (const [name, per] of Object.entries(views)) {
    assert.equal(slam[name]().length, per * n, `${where}: ${name} length`);
  }
  for (const name of ['positions', 'normals', 'radii']) {
    const a = slam[name]();
    for (let i = 0; i < a.length; i++) if (!Number.isFinite(a[i])) assert.fail(`${where}: ${name}[${i}] = ${a[i]}`);
  }
  const c = slam.confidences();
  let live = 0;
  for (let i = 0; i < c.length; i++) {
    if (!Number.isFinite(c[i])) assert.fail(`${where}: confidences[${i}] = ${c[i]}`);
    if (c[i] >= 0) live++;
  }
  assert.equal(slam.liveSurfels, live, `${where}: liveSurfels`);
  assert.ok(n <= model.budget, `${where}: ${n} surfels over the budget ${model.budget}`);
  assert.equal(slam.frames, model.accepted.length, `${where}: frames`);
  const lines = slam.trajectoryTum().split('\n').filter((l) => l.trim() && !l.startsWith('#'));
  assert.deepEqual(lines.map((l) => Number(l.split(' ')[0])), model.accepted, `${where}: trajectory timestamps`);
  assert.ok(lines.every((l) => l.split(' ').every((x) => Number.isFinite(Number(x)))), `${where}: trajectory finite`);
  const r = model.last;
  if (r) {
    assert.equal(r.index + 1, slam.frames, `${where}: report index`);
    assert.equal(r.counts.tracked + r.counts.lost + r.counts.recovered + r.counts.held + r.counts.restarted, slam.frames, `${where}: verdict counts`);
    assert.equal(r.surfels, slam.liveSurfels, `${where}: report surfels`);
    assert.equal(r.surfelSlots, n, `${where}: report surfelSlots`);
    assert.ok(r.pose.every(Number.isFinite), `${where}: pose`);
  } else {
    assert.equal(slam.frames, 0, `${where}: frames without a report`);
  }
}

function runCase(m, clip, garbage, seed, steps, firstRun, log) {
  const r = rng(seed);
  let config = randomConfig(r);
  let slam = new m.Slam(config);
  const fresh = () => ({ accepted: [], last: null, budget: config.maxSurfels ?? 4_000_000 });
  let model = fresh();
  const order = pingPong(clip.sequence.frames.length, 100_000);
  let cursor = r.below(clip.sequence.frames.length);
  let clock = 0;
  let forced = false;
  const cov = { steps: 0, frames: 0, lost: 0, refused: 0, resets: 0, resetsAfter100: 0, configs: 0, exports: 0, finishes: 0, budgetFull: 0, longestRun: 0 };
  try {
    for (let step = 0; step < steps; step++) {
      const where = `seed ${seed}, step ${step} (${slam.frames} frames)`;
      let roll = r.below(100);
      if (roll >= 84 && roll < 90 && slam.frames < firstRun) roll = 0;
      if (firstRun > 0 && slam.frames === firstRun && !forced) {
        roll = 84;
        forced = true;
      }
      if (roll < 72) {
        const [colour, depth] = clip.frame(order[cursor++]);
        clock = Math.round((clock + 1 / 30) * 1e6) / 1e6; // exact in the trajectory's text
        // A quarter of the frames as their files (pushFiles, the page's path for Stray Scanner): the same decode.
        const report = r.below(4) === 0 ? slam.pushFiles(colour, depth, null, ['c.png', 'd.png', null], clock) : slam.pushFrame(colour, depth, clock);
        model.accepted.push(clock);
        model.last = report;
        cov.frames++;
        if (report.verdict === 'lost') cov.lost++;
        if (report.skipped > 0) cov.budgetFull++;
        cov.longestRun = Math.max(cov.longestRun, slam.frames);
      } else if (roll < 84) {
        const [colour, depth] = clip.frame(order[cursor]);
        const before = [slam.frames, slam.surfelCount, slam.liveSurfels];
        const kind = r.below(10);
        const attempts = [
          () => slam.pushFrame(colour, depth.subarray(0, 1 + r.below(depth.length - 2)), clock + 1),
          () => {
            const bad = colour.slice();
            bad.fill(0, 0, 8);
            slam.pushFrame(bad, depth, clock + 1);
          },
          () => slam.pushFrame(garbage.smallColour, garbage.smallDepth, clock + 1),
          () => slam.pushFrame(colour, garbage.depth8, clock + 1),
          () => slam.pushFrame(garbage.smallColour, depth, clock + 1),
          () => slam.pushRgbaDepthPng(640, 480, new Uint8Array(640 * 480 * 4 - 1), depth, clock + 1),
          () => slam.pushRaw(640, 480, new Uint8Array(640 * 480 * 4), new Uint16Array(640 * 479), clock + 1),
          () => slam.pushFrame(colour, depth, [NaN, Infinity, -Infinity][r.below(3)]),
          () => slam.pushFiles(colour, garbage.smallDepth, null, ['c.png', 'd.png', null], clock + 1),
          () => slam.pushFiles(null, depth, garbage.smallDepth, [null, 'd.png', 'c.png'], clock + 1),
        ];
        assert.throws(attempts[kind], kind === 7 ? /timestamp must be a finite number/ : Error, `${where}: garbage ${kind}`);
        assert.deepEqual([slam.frames, slam.surfelCount, slam.liveSurfels], before, `${where}: garbage ${kind} changed the state`);
        assert.equal(slam.depthPreview(8, 6).length, 0, `${where}: garbage ${kind}: a refused frame's depth is shown`);
        cov.refused++;
      } else if (roll < 88) {
        cov.resets++;
        if (slam.frames >= 100) cov.resetsAfter100++;
        slam.reset();
        model = fresh();
        assert.deepEqual(Array.from(slam.takeChangedRange()), [0, 0], `${where}: range after reset`);
      } else if (roll < 90) {
        cov.configs++;
        slam.free();
        slam = null;
        config = randomConfig(r);
        slam = new m.Slam(config);
        model = fresh();
      } else if (roll < 94) {
        assert.equal(plyVertexCount(slam.exportPly()), slam.liveSurfels, `${where}: PLY vertex count`);
        cov.exports++;
      } else if (roll < 98) {
        const [s, e] = Array.from(slam.takeChangedRange());
        assert.ok(s >= 0 && s <= e && e <= slam.surfelCount, `${where}: changed range [${s}, ${e}] of ${slam.surfelCount}`);
      } else if (roll < 99) {
        const preview = slam.depthPreview(32, 24);
        assert.ok(preview.length === 0 || preview.length === 32 * 24, `${where}: preview length ${preview.length}`);
      } else {
        // The recording "ends" here; more frames may follow.
        const f = slam.finish();
        assert.equal(typeof f.looked, 'boolean', `${where}: finish.looked`);
        assert.ok(f.looked || !f.loopClosed, `${where}: closed without looking`);
        assert.ok(f.globalLoopClosures <= f.loopClosures, `${where}: finish closures`);
        if (model.last) {
          assert.ok(f.loopClosures >= model.last.loopClosures, `${where}: finish lost closures`);
          model.last.loopClosures = f.loopClosures;
        }
        assert.equal(slam.finish().looked, false, `${where}: the last frame looked up twice`);
        cov.finishes++;
      }
      check(slam, model, where);
      cov.steps++;
    }
  } finally {
    slam?.free();
  }
  log(`seed ${seed}: ${JSON.stringify(cov)}`);
  return cov;
}

test('any sequence of Slam calls keeps it consistent (bundled clip)', { skip, timeout: 900_000 }, async (t) => {
  const m = await loadPackage();
  const clip = await openSequence(m, CLIP);
  const garbage = {
    smallColour: new Uint8Array(encodePng(64, 48, 3, 8, 90)),
    smallDepth: new Uint8Array(encodePng(64, 48, 1, 16, 5000)),
    depth8: new Uint8Array(encodePng(640, 480, 1, 8, 100)),
  };
  const log = (s) => t.diagnostic(s);
  // [seed, steps, frames before the first reset may happen (then one is forced)]
  const cases = [
    [1, 190, 110],
    [2, 70, 0],
    [3, 70, 0],
  ];
  const total = cases.map(([seed, steps, firstRun]) => runCase(m, clip, garbage, seed, steps, firstRun, log));
  const sum = (k) => total.reduce((a, c) => a + c[k], 0);
  t.diagnostic(`${cases.length} cases, ${sum('steps')} steps, ${sum('frames')} frames, longest run ${Math.max(...total.map((c) => c.longestRun))}`);
  assert.ok(sum('resetsAfter100') > 0, 'a reset after 100+ frames');
  assert.ok(sum('refused') > 0 && sum('exports') > 0 && sum('finishes') > 0);
});
