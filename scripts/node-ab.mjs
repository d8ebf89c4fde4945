#!/usr/bin/env node
// Two builds of the single-threaded wasm module side by side in one Node
// process, frame by frame: each frame is pushed to build A's pipeline, then
// to B's, then the next frame B first, so a slow spell of the machine falls
// on both alike. Prints per stage the median ms of each and the median of the
// per-frame ratios B / A, and checks that both built the same map.
//
//   node scripts/node-ab.mjs PKG_A PKG_B [folder] [--frames N]
// PKG_*: copies of pkg/ (scripts/build.sh --no-threads); folder defaults to
// the bundled sample.
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { performance } from 'node:perf_hooks';
import { openSequence } from '../tests/node/sequence.mjs';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const args = process.argv.slice(2);
const framesAt = args.indexOf('--frames');
const limit = framesAt >= 0 ? Number(args.splice(framesAt, 2)[1]) : Infinity;
const [pkgA, pkgB, folderArg] = args;
if (!pkgA || !pkgB || !(limit > 0)) {
  console.error('usage: node scripts/node-ab.mjs PKG_A PKG_B [folder] [--frames N]');
  process.exit(2);
}
const folder = path.resolve(folderArg ?? path.join(root, 'www/sample/tum_fr3_teddy_clip'));

async function load(dir) {
  const m = await import(path.join(path.resolve(dir), 'surfel_slam.js'));
  await m.default({ module_or_path: await readFile(path.join(path.resolve(dir), 'surfel_slam_bg.wasm')) });
  return m;
}
const builds = [await load(pkgA), await load(pkgB)];

const { sequence } = await openSequence(builds[0], folder);
const frames = sequence.frames.slice(0, Math.min(limit, sequence.frames.length));

const slams = builds.map((b) => new b.Slam({ preset: sequence.preset }));
const stages = ['decode', 'preprocess', 'track', 'fuse', 'predict', 'total'];
const times = [Object.fromEntries(stages.map((s) => [s, []])), Object.fromEntries(stages.map((s) => [s, []]))];
for (const [i, frame] of frames.entries()) {
  const colour = await readFile(path.join(folder, frame.colour));
  const depth = await readFile(path.join(folder, frame.depth));
  const order = i % 2 === 0 ? [0, 1] : [1, 0];
  for (const b of order) {
    const t0 = performance.now();
    const r = slams[b].pushFrame(colour, depth, frame.timestamp);
    const wall = performance.now() - t0;
    for (const s of stages) times[b][s].push(s === 'total' ? wall : r.timings[s]);
  }
}
const median = (v) => {
  const s = [...v].sort((a, b) => a - b);
  return s.length ? s[Math.floor(s.length / 2)] : NaN;
};
console.log(`${path.basename(folder)}: ${frames.length} frames, A ${pkgA}, B ${pkgB}`);
for (const s of stages) {
  const ratios = times[1][s].map((t, i) => t / times[0][s][i]).filter(Number.isFinite);
  console.log(`${s.padEnd(10)} A ${median(times[0][s]).toFixed(2)} ms  B ${median(times[1][s]).toFixed(2)} ms  B/A ${median(ratios).toFixed(3)}`);
}
const same = slams[0].trajectoryTum() === slams[1].trajectoryTum() && slams[0].liveSurfels === slams[1].liveSurfels;
console.log(`same trajectory and surfels: ${same}`);
for (const s of slams) s.free();
