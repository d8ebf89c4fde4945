// Shared helpers for the browser tests: server + headless Chromium, status
// polling, same-origin request log, a tiny PNG decoder/encoder (node:zlib).
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';
import { startServer } from '../../www/serve.mjs';

export { decodePng } from '../node/png.mjs';

export const REPO = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
export const SHARED_DATA = path.resolve(REPO, '../shared/data');
export const SCREENSHOTS = path.join(REPO, 'target', 'browser-screenshots');
export const CHROMIUM = process.env.CHROMIUM_PATH || '/usr/bin/chromium';
// The directory served (default www/); override to test another build of the page.
export const WWW = process.env.SURFEL_SLAM_WWW ? path.resolve(process.env.SURFEL_SLAM_WWW) : path.join(REPO, 'www');

export const CHROMIUM_ARGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--enable-unsafe-swiftshader',
];

/**
 * Skips the test (returns true) when Chromium or the built module is missing;
 * under CI (env CI set) that is a failure instead, so CI cannot pass vacuously.
 */
export function skipUnlessReady(t) {
  const missing = missingPrerequisite();
  if (!missing) return false;
  if (process.env.CI) throw new Error(`browser test cannot run: ${missing}`);
  t.skip(missing);
  return true;
}

/** Why the browser tests cannot run here, or null. */
export function missingPrerequisite() {
  if (!fs.existsSync(CHROMIUM)) return `no Chromium at ${CHROMIUM} (set CHROMIUM_PATH)`;
  if (!fs.existsSync(path.join(WWW, 'pkg/surfel_slam.js'))) return `${WWW}/pkg/ is not built: run \`bash scripts/build.sh\``;
  return null;
}

/**
 * Starts the server on a free port and a fresh headless Chromium.
 * `close()` shuts both down and removes the profile directory.
 */
export async function startBrowser() {
  const server = await startServer({ port: 0, root: WWW });
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-chromium-'));
  let context;
  try {
    context = await chromium.launchPersistentContext(profile, {
      executablePath: CHROMIUM,
      headless: true,
      args: CHROMIUM_ARGS,
      viewport: { width: 1280, height: 800 },
    });
  } catch (e) {
    await server.close();
    fs.rmSync(profile, { recursive: true, force: true });
    throw e;
  }
  return {
    server,
    context,
    origin: new URL(server.url).origin,
    async close() {
      await context.close().catch(() => {});
      await server.close();
      fs.rmSync(profile, { recursive: true, force: true });
    },
  };
}

/**
 * Opens `url` in a new page and records every request it (and its workers)
 * make, plus console errors and page errors.
 */
export async function openPage(env, pathAndQuery = '/') {
  const page = await env.context.newPage();
  const requests = [];
  const consoleErrors = [];
  page.on('request', (r) => requests.push(r.url()));
  // Requests from dedicated workers (wasm, thread pool) go through the context.
  env.context.on('request', (r) => requests.push(r.url()));
  page.on('console', (m) => {
    if (m.type() === 'error') consoleErrors.push(m.text());
  });
  page.on('pageerror', (e) => consoleErrors.push(`pageerror: ${e.message}`));
  await page.goto(new URL(pathAndQuery, env.server.url).href);
  return { page, requests, consoleErrors };
}

/**
 * A page of the server's origin showing only `body` (HTML), for tests of
 * one module of www/ on its own: `await import('/renderer.js')` resolves.
 * Console errors and page errors are collected in `errors`.
 */
export async function openModulePage(env, body = '') {
  const page = await env.context.newPage();
  // The bare document has no icon link, so Chromium asks for /favicon.ico.
  await page.route('**/favicon.ico', (route) => route.fulfill({ status: 204 }));
  const errors = [];
  page.on('pageerror', (e) => errors.push(`pageerror: ${e.message}`));
  page.on('console', (m) => {
    if (m.type() === 'error') errors.push(m.text());
  });
  await page.goto(new URL('/protocol.js', env.server.url).href);
  await page.setContent(`<!doctype html><body>${body}</body>`);
  return { page, errors };
}

/** Requests that left the page's own origin (blob:/data: are local). */
export function foreignRequests(requests, origin) {
  return [...new Set(requests)].filter((u) => {
    if (u.startsWith('blob:') || u.startsWith('data:')) return false;
    try {
      return new URL(u).origin !== origin;
    } catch {
      return true;
    }
  });
}

export const getStatus = (page) => page.evaluate(() => JSON.parse(JSON.stringify(window.surfelSlamStatus ?? null)));

/** Polls window.surfelSlamStatus until `predicate(status)` or the timeout; returns the last status. */
export async function waitForStatus(page, predicate, { timeoutMs = 240_000, intervalMs = 500, log = null } = {}) {
  const start = Date.now();
  let status = null;
  let lastLog = 0;
  for (;;) {
    status = await getStatus(page);
    if (status && predicate(status)) return status;
    if (status?.error && /wasm module|worker failed|WebGL/.test(status.error)) return status; // fatal
    if (Date.now() - start > timeoutMs) return status;
    if (log && Date.now() - lastLog > 10_000) {
      lastLog = Date.now();
      log(`  ... ${Math.round((Date.now() - start) / 1000)} s: frames ${status?.framesProcessed ?? '-'}, surfels ${status?.surfels ?? '-'}`);
    }
    await new Promise((r) => setTimeout(r, intervalMs));
  }
}

// ---- PNG ------------------------------------------------------------------------------

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = CRC_TABLE[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}


/** Encodes an 8-bit greyscale PNG. */
export function encodeGreyPng(width, height, grey) {
  const chunk = (type, data) => {
    const len = Buffer.alloc(4);
    len.writeUInt32BE(data.length);
    const body = Buffer.concat([Buffer.from(type, 'latin1'), data]);
    const crc = Buffer.alloc(4);
    crc.writeUInt32BE(crc32(body));
    return Buffer.concat([len, body, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr[8] = 8; // bit depth
  ihdr[9] = 0; // greyscale
  const raw = Buffer.alloc((width + 1) * height);
  for (let y = 0; y < height; y++) grey.copy(raw, y * (width + 1) + 1, y * width, (y + 1) * width);
  return Buffer.concat([
    Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]),
    chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw)),
    chunk('IEND', Buffer.alloc(0)),
  ]);
}

/**
 * Luminance statistics of a decoded image: variance, and the fraction of
 * pixels that differ clearly from the most common colour (the background).
 */
export function imageStats({ width, height, channels, data }) {
  const n = width * height;
  let sum = 0, sum2 = 0;
  const counts = new Map();
  const lum = new Float32Array(n);
  for (let i = 0; i < n; i++) {
    const p = i * channels;
    const r = data[p], g = channels >= 3 ? data[p + 1] : r, b = channels >= 3 ? data[p + 2] : r;
    const l = 0.299 * r + 0.587 * g + 0.114 * b;
    lum[i] = l;
    sum += l;
    sum2 += l * l;
    const key = (r << 16) | (g << 8) | b;
    counts.set(key, (counts.get(key) ?? 0) + 1);
  }
  const mean = sum / n;
  const variance = sum2 / n - mean * mean;
  let bgKey = 0, bgCount = -1;
  for (const [k, c] of counts) if (c > bgCount) [bgKey, bgCount] = [k, c];
  const bg = 0.299 * (bgKey >> 16) + 0.587 * ((bgKey >> 8) & 255) + 0.114 * (bgKey & 255);
  let differing = 0;
  for (let i = 0; i < n; i++) if (Math.abs(lum[i] - bg) > 12) differing++;
  return { mean, variance, distinctColours: counts.size, nonBackground: differing / n };
}

/** The WebGL canvas's own pixels (no overlays), as a PNG buffer. */
export async function canvasPng(page, selector = '#map-canvas') {
  const dataUrl = await page.evaluate((sel) => document.querySelector(sel).toDataURL('image/png'), selector);
  return Buffer.from(dataUrl.slice(dataUrl.indexOf(',') + 1), 'base64');
}

export function saveScreenshot(name, png) {
  fs.mkdirSync(SCREENSHOTS, { recursive: true });
  const file = path.join(SCREENSHOTS, name);
  fs.writeFileSync(file, png);
  return file;
}

/** Copies a TUM-layout clip of `frames` frames (index files trimmed) into a new temp folder. */
export function makeTumClip(srcDir, frames, folderName) {
  const parent = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-seq-'));
  const dst = path.join(parent, folderName);
  fs.mkdirSync(path.join(dst, 'rgb'), { recursive: true });
  fs.mkdirSync(path.join(dst, 'depth'), { recursive: true });
  const list = (file) => {
    const lines = fs.readFileSync(path.join(srcDir, file), 'utf8').split('\n');
    return { header: lines.filter((l) => l.startsWith('#')), rows: lines.filter((l) => l.trim() && !l.startsWith('#')) };
  };
  const out = { dir: dst, parent, colour: [], depth: [] };
  for (const [file, key] of [['rgb.txt', 'colour'], ['depth.txt', 'depth']]) {
    const { header, rows } = list(file);
    const kept = rows.slice(0, frames);
    fs.writeFileSync(path.join(dst, file), [...header, ...kept, ''].join('\n'));
    for (const row of kept) {
      const rel = row.split(/\s+/)[1];
      fs.copyFileSync(path.join(srcDir, rel), path.join(dst, rel));
      out[key].push(rel);
    }
  }
  return out;
}
