// The threaded module (wasm-bindgen-rayon, the page's build when it is
// cross-origin isolated) gives native's poses bit for bit (issue #37).
//
// `cargo test --test wasm_parity_native` (scripts/test-wasm.sh step 1) plays
// the window sequence natively (80 noisy synthetic frames out and back past
// a 10-frame active window, see tests/wasm_common) and writes its frames, JS
// config and per-frame report poses to target/wasm-parity/. Here a worker
// in headless Chromium plays the same frames through the threaded module on
// a pool of 4 threads and the poses must be the same bits. The reference is
// used only when it was written for the current sources (the same
// fingerprint as tests/wasm_common); when it is missing or stale the test
// skips with a message, and under CI fails.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromium } from 'playwright-core';
import { startServer } from '../../www/serve.mjs';
import { CHROMIUM, CHROMIUM_ARGS, REPO, WWW, skipUnlessReady } from './helpers.mjs';

const PARITY = path.join(REPO, 'target', 'wasm-parity');
const THREADS = 4;

/** Relative paths ('/' separated) of the files under `dir`. */
function listRecursive(dir, rel = '') {
  const out = [];
  for (const entry of fs.readdirSync(path.join(dir, rel), { withFileTypes: true })) {
    const child = rel ? `${rel}/${entry.name}` : entry.name;
    if (entry.isDirectory()) out.push(...listRecursive(dir, child));
    else out.push(child);
  }
  return out;
}

/** tests/wasm_common's `fingerprint` of the sources (FNV-1a, path order; the files `is_fingerprinted` names). */
function sourceFingerprint() {
  const names = ['Cargo.toml', 'Cargo.lock']
    .concat(listRecursive(REPO, 'src').filter((n) => n.endsWith('.rs')))
    .concat(listRecursive(REPO, 'tests/wasm_common').filter((n) => n.endsWith('.rs')))
    .concat(['tests/common/revisit.rs'])
    .sort();
  const mask = (1n << 64n) - 1n;
  let h = 0xcbf29ce484222325n;
  const eat = (bytes) => {
    for (const b of bytes) h = ((h ^ BigInt(b)) * 0x100000001b3n) & mask;
  };
  for (const name of names) {
    eat(Buffer.from(name));
    eat([0]);
    eat(fs.readFileSync(path.join(REPO, name)));
    eat([0xff]);
  }
  return `${h.toString(16).padStart(16, '0')} (${names.length} files)`;
}

/** The 64 bits of a number, as 16 hexadecimal digits. */
function bitsOf(x) {
  const view = new DataView(new ArrayBuffer(8));
  view.setFloat64(0, x);
  return view.getBigUint64(0).toString(16).padStart(16, '0');
}

/** The native reference for the current sources, or why there is none. */
function readReference() {
  const configFile = path.join(PARITY, 'window-config.json');
  const posesFile = path.join(PARITY, 'window-online.bits');
  if (!fs.existsSync(configFile) || !fs.existsSync(posesFile)) return { why: 'no native reference in target/wasm-parity' };
  const sources = sourceFingerprint();
  const input = JSON.parse(fs.readFileSync(configFile, 'utf8'));
  const [header, ...lines] = fs.readFileSync(posesFile, 'utf8').trimEnd().split('\n');
  if (input.sources !== sources || header !== `# surfel-slam native reference, sources ${sources}`) {
    return { why: `stale native reference (written for other sources than ${sources})` };
  }
  return { input, poses: lines.map((l) => l.split(' ')) };
}

test('threaded module: the window sequence gives native poses bit for bit', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const moduleFile = path.join(WWW, 'pkg', 'threads', 'surfel_slam.js');
  const moduleRel = path.relative(REPO, moduleFile);
  const missing = !fs.existsSync(moduleFile)
    ? `${moduleFile} is not built: run \`bash scripts/build.sh\``
    : moduleRel.startsWith('..')
      ? `${WWW} is outside the repository`
      : null;
  const reference = missing ? { why: missing } : readReference();
  if (reference.why) {
    const why = `${reference.why}; run \`cargo test --test wasm_parity_native\` then \`bash scripts/build.sh\``;
    if (process.env.CI) throw new Error(why);
    t.skip(why);
    return;
  }
  const { input, poses: expected } = reference;

  // The repository is served (cross-origin isolated) so that the worker,
  // the built module and the frames share one origin.
  const server = await startServer({ port: 0, root: REPO });
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-chromium-'));
  let context;
  try {
    context = await chromium.launchPersistentContext(profile, { executablePath: CHROMIUM, headless: true, args: CHROMIUM_ARGS });
    const page = await context.newPage();
    await page.goto(new URL('tests/browser/threaded-parity.html', server.url).href);
    assert.equal(await page.evaluate(() => self.crossOriginIsolated), true, 'the page is cross-origin isolated');
    const result = await page.evaluate(
      (message) =>
        new Promise((resolve) => {
          const worker = new Worker('./threaded-parity-worker.mjs', { type: 'module' });
          worker.onmessage = ({ data }) => resolve(data);
          worker.onerror = (e) => resolve({ ok: false, error: e.message || 'worker failed to start' });
          worker.postMessage(message);
        }),
      {
        modulePath: `/${moduleRel.split(path.sep).join('/')}`,
        framesPath: '/target/wasm-parity/window-frames.bin',
        input,
        threads: THREADS,
      },
    );
    assert.ok(result.ok, result.error);
    assert.equal(result.threads, THREADS, 'the module runs a pool of that many threads');
    assert.equal(result.poses.length, expected.length, 'one pose per frame');
    // DAffine3's columns in the 4x4 column-major report matrix.
    const affine = [0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14];
    result.poses.forEach(({ timestamp, pose }, i) => {
      const bits = [timestamp, ...affine.map((k) => pose[k])].map(bitsOf);
      assert.deepEqual(bits, expected[i], `frame ${i}: the threaded module's pose is not native's`);
    });
  } finally {
    await context?.close().catch(() => {});
    await server.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
});
