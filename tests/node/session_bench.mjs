// Session save and load time and size in wasm (single-threaded package, Node):
//   node tests/node/session_bench.mjs [dataset folder] [--frames N] [--repeat R]
// Plays N frames (default all) of the folder (default ../shared/data/tum_fr3_teddy)
// into a Slam, then times `save()` and `load(bytes)` into a fresh Slam R times
// (default 5) and prints the medians, the session's size and the map's.
import path from 'node:path';
import { performance } from 'node:perf_hooks';
import { loadPackage } from './long_run.mjs';
import { openSequence, SHARED } from './sequence.mjs';

const args = process.argv.slice(2);
let dir = path.join(SHARED, 'tum_fr3_teddy');
let frames = Infinity;
let repeat = 5;
for (let i = 0; i < args.length; i++) {
  if (args[i] === '--frames') frames = Number(args[++i]);
  else if (args[i] === '--repeat') repeat = Number(args[++i]);
  else dir = args[i];
}
const m = await loadPackage();
const { sequence, frame } = await openSequence(m, dir);
const n = Math.min(frames, sequence.frames.length);
const slam = new m.Slam({ preset: sequence.preset });
for (let i = 0; i < n; i++) {
  const [colour, depth] = frame(i);
  slam.pushFrame(colour, depth, sequence.frames[i].timestamp);
}
const median = (xs) => xs.slice().sort((a, b) => a - b)[Math.floor(xs.length / 2)];
const saves = [];
const loads = [];
let bytes = null;
for (let r = 0; r < repeat; r++) {
  let t0 = performance.now();
  bytes = slam.save();
  saves.push(performance.now() - t0);
  const fresh = new m.Slam({ preset: sequence.preset });
  t0 = performance.now();
  fresh.load(bytes);
  loads.push(performance.now() - t0);
  if (fresh.liveSurfels !== slam.liveSurfels) throw new Error('the loaded map differs');
  fresh.free();
}
const mb = (b) => (b / 1e6).toFixed(1);
console.log(
  `${path.basename(dir)}, ${n} frames: ${slam.liveSurfels} surfels, session ${mb(bytes.length)} MB; ` +
    `save median ${median(saves).toFixed(0)} ms (${saves.map((t) => t.toFixed(0)).join(', ')}), ` +
    `load median ${median(loads).toFixed(0)} ms (${loads.map((t) => t.toFixed(0)).join(', ')}); wasm memory ${mb(m.memory.buffer.byteLength)} MB`,
);
slam.free();
