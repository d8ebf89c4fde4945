#!/usr/bin/env node
// Long run under Node with the built npm package (pkg/, single-threaded SIMD
// module): a real sequence looped forwards then backwards (so the motion
// stays continuous: 0..n-1, n-2..1, 0..) for N frames, reporting the surfel
// count and the wasm memory along the way. Shows that memory stops growing
// once the map does (the surfel budget bounds the map; buffers are reused).
//
//   node tests/node/long_run.mjs [folder] [--frames 1500] [--max-surfels N] [--every 100] [--json]
//
// folder defaults to ../shared/data/icl_office_kt0. Build the package first:
// scripts/build.sh --no-threads. tests/node/long_run.test.mjs runs a short
// version on the bundled sample clip.
import { readFile } from 'node:fs/promises';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import { performance } from 'node:perf_hooks';
import { listFiles } from './files.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
export const ROOT = path.resolve(here, '../..');
export const PKG = path.join(ROOT, 'pkg');

/** Loads the package; returns its exports and the wasm memory. */
export async function loadPackage() {
  const mod = await import(pathToFileURL(path.join(PKG, 'surfel_slam.js')).href);
  const exports = await mod.default({ module_or_path: await readFile(path.join(PKG, 'surfel_slam_bg.wasm')) });
  return { ...mod, memory: exports.memory };
}


/** Frame order going forwards then backwards: 0..n-1, n-2..1, 0.. */
export function pingPong(n, count) {
  const period = Math.max(1, 2 * n - 2);
  return Array.from({ length: count }, (_, i) => {
    const k = i % period;
    return k < n ? k : period - k;
  });
}

/**
 * Runs `frames` frames of `folder` looped forwards and backwards.
 * Returns {samples: [{frame, surfels, slots, memory}], counts, skipped, lost, ...}
 * (surfels: what the map holds; slots: the arrays' length, which the budget bounds).
 */
export async function longRun(pkg, folder, { frames, maxSurfels = null, every = 100, log = null }) {
  const names = (await listFiles(folder)).sort();
  const layout = pkg.detectLayout(names);
  const texts = {};
  for (const f of layout.indexFiles) texts[f] = await readFile(path.join(folder, f), 'utf8');
  const sequence = pkg.parseSequence(names, texts, path.basename(folder));
  const config = { preset: sequence.preset };
  if (maxSurfels !== null) config.maxSurfels = maxSurfels;
  const slam = new pkg.Slam(config);
  const order = pingPong(sequence.frames.length, frames);
  const samples = [];
  let skipped = 0;
  let last = null;
  let maxSeen = 0;
  let stoppedGrowingAt = 0;
  let nonFinite = 0;
  const t0 = performance.now();
  for (let i = 0; i < order.length; i++) {
    const f = sequence.frames[order[i]];
    const [colour, depth] = await Promise.all([readFile(path.join(folder, f.colour)), readFile(path.join(folder, f.depth))]);
    const r = slam.pushFrame(colour, depth, i);
    skipped += r.skipped;
    if (!r.pose.every(Number.isFinite)) nonFinite++;
    // The arrays (and the budget) hold the surfels plus absorbed ones awaiting compaction.
    if (r.surfelSlots > maxSeen) {
      maxSeen = r.surfelSlots;
      stoppedGrowingAt = i + 1;
    }
    last = r;
    const n = i + 1;
    if (n % every === 0 || n === order.length) {
      const sample = { frame: n, surfels: r.surfels, slots: r.surfelSlots, memory: pkg.memory.buffer.byteLength, counts: r.counts };
      samples.push(sample);
      if (log) {
        log(
          `frame ${n}: ${r.surfels} surfels (${r.surfelSlots} slots), wasm memory ${(sample.memory / 2 ** 20).toFixed(1)} MiB, ` +
            `tracked ${r.counts.tracked} lost ${r.counts.lost} recovered ${r.counts.recovered}, ` +
            `${((performance.now() - t0) / n).toFixed(0)} ms/frame`,
        );
      }
    }
  }
  // Ground truth in the looped order, stamped like the estimate (frame count).
  const truth = new Map((sequence.groundTruth ?? []).map((row) => [row[0], row.slice(1)]));
  const gtLines = order.flatMap((k, i) => {
    const row = truth.get(sequence.frames[k].timestamp);
    return row ? [`${i} ${row.join(' ')}`] : [];
  });
  let ate = null;
  if (gtLines.length >= 3) {
    try {
      ate = pkg.ateTum(slam.trajectoryTum(), gtLines.join('\n') + '\n', 0);
    } catch {
      ate = null;
    }
  }
  const positions = slam.positions();
  let finiteMap = true;
  for (let i = 0; i < positions.length; i++) {
    if (!Number.isFinite(positions[i])) {
      finiteMap = false;
      break;
    }
  }
  const result = {
    folder,
    frames: order.length,
    sequenceFrames: sequence.frames.length,
    maxSurfels,
    samples,
    counts: last.counts,
    skipped,
    nonFinitePoses: nonFinite,
    finiteMap,
    maxSurfelsSeen: maxSeen,
    stoppedGrowingAt,
    finalMemory: pkg.memory.buffer.byteLength,
    ate,
    msPerFrame: (performance.now() - t0) / order.length,
  };
  slam.free();
  return result;
}

function usage(message) {
  if (message) console.error(`long_run: ${message}`);
  console.error('usage: node tests/node/long_run.mjs [folder] [--frames 1500] [--max-surfels N] [--every 100] [--json]');
  process.exit(2);
}

async function main() {
  const args = process.argv.slice(2);
  const o = { folder: null, frames: 1500, maxSurfels: null, every: 100, json: false };
  for (let i = 0; i < args.length; i++) {
    const a = args[i];
    const int = () => {
      const v = Number(args[++i]);
      if (!Number.isInteger(v) || v <= 0) usage(`${a} needs a positive integer`);
      return v;
    };
    if (a === '--frames') o.frames = int();
    else if (a === '--max-surfels') o.maxSurfels = int();
    else if (a === '--every') o.every = int();
    else if (a === '--json') o.json = true;
    else if (a.startsWith('-')) usage(`unknown option ${a}`);
    else o.folder = a;
  }
  const folder = path.resolve(o.folder ?? path.join(ROOT, '../shared/data/icl_office_kt0'));
  if (!existsSync(path.join(PKG, 'surfel_slam.js'))) usage(`${PKG} has no built package; run scripts/build.sh --no-threads`);
  if (!existsSync(folder)) usage(`${folder} does not exist`);
  const pkg = await loadPackage();
  const r = await longRun(pkg, folder, { frames: o.frames, maxSurfels: o.maxSurfels, every: o.every, log: o.json ? null : console.log });
  if (o.json) {
    console.log(JSON.stringify(r));
    return;
  }
  const mib = (b) => `${(b / 2 ** 20).toFixed(1)} MiB`;
  const at = (n) => r.samples.find((s) => s.frame >= n) ?? r.samples.at(-1);
  console.log(
    `${path.basename(folder)}: ${r.frames} frames (${r.sequenceFrames} looped forwards/backwards), ` +
      `tracked ${r.counts.tracked}, lost ${r.counts.lost}, recovered ${r.counts.recovered}, adds skipped by the budget ${r.skipped}`,
  );
  console.log(
    `  wasm memory at frame 100: ${mib(at(100).memory)} (${at(100).surfels} surfels); at frame ${r.frames}: ${mib(r.finalMemory)} ` +
      `(${r.samples.at(-1).surfels} surfels); the map's arrays last grew at frame ${r.stoppedGrowingAt} (${r.maxSurfelsSeen} slots)`,
  );
  const after = r.samples.filter((s) => s.frame >= r.stoppedGrowingAt);
  if (after.length) {
    console.log(`  memory from frame ${after[0].frame} on: ${mib(after[0].memory)} -> ${mib(r.finalMemory)}`);
  }
  console.log(`  ${r.msPerFrame.toFixed(0)} ms/frame (file reads included); map finite: ${r.finiteMap}; non-finite poses: ${r.nonFinitePoses}`);
  if (r.ate) console.log(`  ATE over the whole looped run: ${(r.ate.rmse * 100).toFixed(2)} cm rmse, ${(r.ate.max * 100).toFixed(2)} cm max (${r.ate.pairs} poses)`);
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  await main();
}
