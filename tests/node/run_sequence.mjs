#!/usr/bin/env node
// Runs an RGB-D sequence folder through the built npm package (pkg/, the
// single-threaded SIMD module) headless in Node, the way a Node user would:
// detectLayout / parseSequence (the CLI's parser) pick the frames and camera,
// pushFrame decodes and tracks, ateTum scores against the ground truth.
//
//   node tests/node/run_sequence.mjs [folder] [--frames N] [--trajectory out.txt] [--ply out.ply] [--json]
//
// folder defaults to ../shared/data/icl_office_kt0. Prints median ms per
// stage and per frame, lost frames, surfels and the ATE (when the folder has
// ground truth); the last line is `median_ms_per_frame: N`, as in the CLI's
// `surfel-slam bench`.
// Build the package first: scripts/build.sh.
import { readFile, writeFile } from 'node:fs/promises';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { performance } from 'node:perf_hooks';
import { listFiles } from './files.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const root = path.resolve(here, '../..');
const pkgDir = path.join(root, 'pkg');

function usage(message) {
  if (message) console.error(`run_sequence: ${message}`);
  console.error('usage: node tests/node/run_sequence.mjs [folder] [--frames N] [--trajectory out.txt] [--ply out.ply] [--json]');
  process.exit(2);
}

const args = process.argv.slice(2);
const options = { folder: null, frames: Infinity, trajectory: null, ply: null, json: false };
for (let i = 0; i < args.length; i++) {
  const a = args[i];
  if (a === '--frames') {
    options.frames = Number(args[++i]);
    if (!Number.isInteger(options.frames) || options.frames <= 0) usage('--frames needs a positive integer');
  } else if (a === '--trajectory') options.trajectory = args[++i] ?? usage('--trajectory needs a path');
  else if (a === '--ply') options.ply = args[++i] ?? usage('--ply needs a path');
  else if (a === '--json') options.json = true;
  else if (a === '-h' || a === '--help') usage();
  else if (a.startsWith('--')) usage(`unknown option ${a}`);
  else if (options.folder === null) options.folder = a;
  else usage(`unexpected argument ${a}`);
}
const folder = path.resolve(options.folder ?? path.join(root, '../shared/data/icl_office_kt0'));

if (!existsSync(path.join(pkgDir, 'surfel_slam.js'))) {
  console.error(`run_sequence: ${pkgDir} has no built package; run scripts/build.sh first`);
  process.exit(1);
}
if (!existsSync(folder)) {
  console.error(`run_sequence: ${folder} does not exist`);
  process.exit(1);
}

const { default: init, Slam, detectLayout, parseSequence, ateTum, threadCount } = await import(
  path.join(pkgDir, 'surfel_slam.js')
);
await init({ module_or_path: await readFile(path.join(pkgDir, 'surfel_slam_bg.wasm')) });


const names = (await listFiles(folder)).sort();
const layout = detectLayout(names);
const texts = {};
for (const f of layout.indexFiles) texts[f] = await readFile(path.join(folder, f), 'utf8');
const sequence = parseSequence(names, texts, path.basename(folder));
const frames = sequence.frames.slice(0, Math.min(options.frames, sequence.frames.length));

const slam = new Slam({ preset: sequence.preset });
let lost = 0;
let processMs = 0;
const stages = { decode: [], preprocess: [], track: [], fuse: [], predict: [], total: [] };
const pushMs = [];
const wall0 = performance.now();
for (const frame of frames) {
  const [colour, depth] = await Promise.all([
    readFile(path.join(folder, frame.colour)),
    readFile(path.join(folder, frame.depth)),
  ]);
  const t0 = performance.now();
  const r = slam.pushFrame(colour, depth, frame.timestamp);
  const elapsed = performance.now() - t0;
  processMs += elapsed;
  pushMs.push(elapsed);
  for (const k of Object.keys(stages)) stages[k].push(r.timings[k]);
  if (r.verdict === 'lost') {
    lost++;
    console.error(`frame ${r.index}: lost (${r.lostReason}), ${r.inliers} inliers, residual ${r.residual.toFixed(4)} m`);
  }
}
const wallMs = performance.now() - wall0;

const n = frames.length;
const median = (values) => {
  const sorted = [...values].sort((a, b) => a - b);
  return sorted.length ? sorted[Math.floor(sorted.length / 2)] : 0;
};
const result = {
  folder,
  kind: layout.kind,
  preset: sequence.preset,
  frames: n,
  threads: threadCount(),
  msPerFrame: processMs / n,
  medianMsPerFrame: median(pushMs),
  wallMsPerFrame: wallMs / n,
  stagesMedianMs: Object.fromEntries(Object.entries(stages).map(([k, v]) => [k, median(v)])),
  lost,
  surfels: slam.liveSurfels,
  ate: null,
};
if (sequence.groundTruthTum) {
  result.ate = ateTum(slam.trajectoryTum(), sequence.groundTruthTum);
}
if (options.trajectory) await writeFile(options.trajectory, slam.trajectoryTum());
if (options.ply) await writeFile(options.ply, slam.exportPly());
slam.free();

if (options.json) {
  console.log(JSON.stringify(result));
} else {
  const s = result.stagesMedianMs;
  console.log(`${path.basename(folder)} (${result.kind}, preset ${result.preset}): ${n} frames, wasm single-threaded SIMD, Node ${process.versions.node}`);
  console.log(`  ${result.msPerFrame.toFixed(1)} ms/frame mean in pushFrame (${result.wallMsPerFrame.toFixed(1)} ms/frame with file reads)`);
  console.log(`  median ms: decode ${s.decode.toFixed(1)}, preprocess ${s.preprocess.toFixed(1)}, track ${s.track.toFixed(1)}, fuse ${s.fuse.toFixed(1)}, predict ${s.predict.toFixed(1)}`);
  console.log(`  lost ${lost}, surfels ${result.surfels}`);
  if (result.ate) {
    const a = result.ate;
    console.log(`  ATE rmse ${(a.rmse * 1000).toFixed(3)} mm (mean ${(a.mean * 1000).toFixed(3)}, median ${(a.median * 1000).toFixed(3)}, max ${(a.max * 1000).toFixed(3)} mm, ${a.pairs} poses)`);
  } else {
    console.log('  ATE: the folder has no ground truth');
  }
  console.log(`median_ms_per_frame: ${result.medianMsPerFrame.toFixed(2)}`);
}
