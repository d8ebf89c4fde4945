#!/usr/bin/env node
// The wasm module alone in a headless Chromium worker: the bundled sample's
// frames are fetched first, then pushed back to back (pushFrame, both PNGs
// decoded in wasm), and the median ms per stage is printed per run. No page,
// no rendering, no file reads during the run: what the module costs in
// Chromium, to set beside the page's own figures (scripts/page-fps.mjs).
//
//   node scripts/chromium-bench.mjs [--threads N] [--runs R] [--pkg DIR]
// --threads 0: the single-threaded SIMD module; N >= 1: the threaded module
// with a pool of N (default 2). --pkg: a copy of www/pkg to measure instead
// (to alternate two builds side by side). Needs www/pkg built (scripts/build.sh).
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const option = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i >= 0 ? Number(process.argv[i + 1]) : fallback;
};
const threads = option('--threads', 2);
const runs = option('--runs', 3);
const www = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../www');
const pkgAt = process.argv.indexOf('--pkg');
const pkg = pkgAt >= 0 ? path.resolve(process.argv[pkgAt + 1]) : path.join(www, 'pkg');

// The bench's own page beside copies of the built module and the sample
// (the server serves nothing from outside its root, symlinks included).
const root = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-bench-'));
fs.cpSync(pkg, path.join(root, 'pkg'), { recursive: true });
fs.cpSync(path.join(www, 'sample'), path.join(root, 'sample'), { recursive: true });
fs.writeFileSync(path.join(root, 'index.html'), `<!doctype html><meta charset="utf-8"><script type="module">
const worker = new Worker('bench-worker.js', { type: 'module' });
let resolve;
worker.onmessage = ({ data }) => (data === 'ready' ? (window.benchReady = true) : resolve(data));
worker.onerror = (e) => (window.benchReady = \`worker failed: \${e.message}\`);
window.runBench = () => new Promise((r) => { resolve = r; worker.postMessage('run'); });
</script>`);
const moduleUrl = threads > 0 ? './pkg/threads/surfel_slam.js' : './pkg/surfel_slam.js';
fs.writeFileSync(path.join(root, 'bench-worker.js'), `
const m = await import('${moduleUrl}');
await m.default();
if (${threads} > 0) await m.initThreadPool(${threads});
const manifest = await (await fetch('sample/manifest.json')).json();
const dir = 'sample/' + manifest.name + '/';
const names = manifest.files.map((f) => f.path.slice(manifest.name.length + 1)).sort();
const layout = m.detectLayout(names);
const texts = {};
for (const f of layout.indexFiles) texts[f] = await (await fetch(dir + f)).text();
const sequence = m.parseSequence(names, texts, manifest.name);
const bytes = [];
for (const f of sequence.frames) {
  const read = async (p) => new Uint8Array(await (await fetch(dir + p)).arrayBuffer());
  bytes.push([await read(f.colour), await read(f.depth), f.timestamp]);
}
const median = (v) => [...v].sort((a, b) => a - b)[v.length >> 1];
self.onmessage = () => {
  const slam = new m.Slam({ preset: sequence.preset });
  const stages = { decode: [], preprocess: [], track: [], fuse: [], predict: [], total: [] };
  for (const [colour, depth, t] of bytes) {
    const r = slam.pushFrame(colour, depth, t);
    for (const k of Object.keys(stages)) stages[k].push(r.timings[k]);
  }
  slam.free();
  self.postMessage(Object.fromEntries(Object.entries(stages).map(([k, v]) => [k, Number(median(v).toFixed(2))])));
};
self.postMessage('ready');
`);

process.env.SURFEL_SLAM_WWW = root;
const { startBrowser, openPage } = await import('../tests/browser/helpers.mjs');
const env = await startBrowser();
try {
  const { page } = await openPage(env, '/');
  const ready = await (await page.waitForFunction(() => window.benchReady, null, { timeout: 120_000 })).jsonValue();
  if (ready !== true) throw new Error(ready);
  console.log(`module ${threads > 0 ? `threads (pool of ${threads})` : 'simd (1 thread)'}, median ms per stage:`);
  for (let i = 0; i < runs; i++) console.log(JSON.stringify(await page.evaluate(() => window.runBench())));
} finally {
  await env.close();
  fs.rmSync(root, { recursive: true, force: true });
}
