// The page plays the bundled sample by itself in headless Chromium, with the
// threaded wasm module, keeps tracking, draws a non-blank map, and makes no
// request outside its own origin. The network is cut for it: every request
// that would leave the origin is aborted (and recorded), so the page is shown
// to work offline, not only to stay quiet.
import { test } from 'node:test';
import fs from 'node:fs';
import path from 'node:path';
import assert from 'node:assert/strict';
import {
  startBrowser,
  openPage,
  waitForStatus,
  foreignRequests,
  canvasPng,
  decodePng,
  imageStats,
  saveScreenshot,
  skipUnlessReady,
  WWW,
} from './helpers.mjs';

const MIN_FRAMES = 40; // of the sample's 44
const MAX_LOST = 2;

test('bundled sample plays with the threaded module and draws the map', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  const blocked = [];
  await env.context.route('**/*', (route) => {
    const url = route.request().url();
    if (url.startsWith('blob:') || url.startsWith('data:') || new URL(url).origin === env.origin) return route.continue();
    blocked.push(url);
    return route.abort('internetdisconnected');
  });
  try {
    const { page, requests, consoleErrors } = await openPage(env, '/');
    // The new options: the preset's tracker is the default, and the flow overlay draws tracks.
    assert.equal(await page.inputValue('#tracker'), '');
    await page.check('#show-flow');
    const started = Date.now();
    const status = await waitForStatus(page, (s) => s.done || s.framesProcessed >= 44, {
      timeoutMs: 240_000,
      log: (m) => t.diagnostic(m),
    });
    const seconds = (Date.now() - started) / 1000;
    t.diagnostic(
      `sample: ${status.framesProcessed} frames in ${seconds.toFixed(1)} s (page load included); ` +
        `fps ${status.fpsAverage} average, ${status.fps} recent, ${status.msPerFrame} ms/frame in wasm; ` +
        `module ${status.module}, ${status.threads} threads; surfels ${status.surfels}; ` +
        `lost ${status.framesLost}; ATE ${status.ate === null ? '-' : (status.ate * 100).toFixed(1) + ' cm'}`,
    );

    // Let the renderer draw the final state, then look at the page.
    await page.waitForTimeout(500);
    saveScreenshot('sample-page.png', await page.screenshot());
    const png = await canvasPng(page);
    const file = saveScreenshot('sample-canvas.png', png);
    const pixels = imageStats(decodePng(png));
    const depthView = imageStats(decodePng(await canvasPng(page, '#depth-view')));
    t.diagnostic(
      `canvas ${file}: luminance variance ${pixels.variance.toFixed(1)}, ` +
        `${(pixels.nonBackground * 100).toFixed(1)} % non-background, ${pixels.distinctColours} colours`,
    );

    assert.equal(status.error, null, `the page reported an error: ${status.error}`);
    assert.equal(status.ready, true, 'module ready');
    assert.equal(status.crossOriginIsolated, true, 'page is cross-origin isolated');
    assert.equal(status.module, 'threads', 'the threaded module runs');
    assert.ok(status.threads > 1, `more than one thread (got ${status.threads})`);
    assert.ok(status.framesProcessed >= MIN_FRAMES, `frames processed ${status.framesProcessed} >= ${MIN_FRAMES}`);
    assert.ok(status.framesLost <= MAX_LOST, `tracking held: ${status.framesLost} lost frames`);
    assert.ok(status.surfels > 10_000, `surfels ${status.surfels} > 10000`);
    // The module reports its memory: at least its maps' arrays (a surfel is ~40 bytes).
    assert.ok(status.wasmMemoryMiB > (status.surfels * 40) / 2 ** 20, `wasm memory ${status.wasmMemoryMiB} MiB for ${status.surfels} surfels`);
    assert.ok(status.flowTracks > 20, `flow overlay drew ${status.flowTracks} tracks`);
    assert.ok(Number.isFinite(status.ate) && status.ate < 0.1, `ATE so far ${status.ate} m < 0.1 m`);
    assert.ok(pixels.variance > 100, `canvas is not blank (luminance variance ${pixels.variance.toFixed(1)})`);
    // The depth view (wasm's thumbnail of the last frame, colour-mapped) shows a scene, not a flat fill.
    assert.ok(depthView.variance > 100 && depthView.distinctColours > 50, `depth view drawn: ${JSON.stringify(depthView)}`);
    assert.ok(pixels.nonBackground > 0.05, `canvas shows the map (${(pixels.nonBackground * 100).toFixed(1)} % non-background)`);

    const foreign = foreignRequests(requests, env.origin);
    assert.deepEqual(foreign, [], `requests outside ${env.origin}: ${foreign.join(', ')}`);
    assert.deepEqual(blocked, [], `requests the cut network refused: ${blocked.join(', ')}`);
    assert.ok(requests.some((u) => u.endsWith('.wasm')), 'the wasm module was requested (request log works)');
    assert.deepEqual(consoleErrors, [], 'no console errors');
    // The cut is real: a request elsewhere is refused and recorded.
    const outcome = await page.evaluate(() => fetch('https://cdn.example.com/lib.js').then(() => 'fetched', () => 'refused'));
    assert.equal(outcome, 'refused');
    assert.deepEqual(blocked, ['https://cdn.example.com/lib.js']);
  } finally {
    await env.close();
  }
});

test('the blank-canvas check does fail on a blank canvas', () => {
  // Guard against a vacuous check: a uniform image has zero variance.
  const width = 64, height = 48, channels = 4;
  const data = Buffer.alloc(width * height * channels);
  for (let i = 0; i < data.length; i += 4) data.set([18, 20, 26, 255], i);
  const s = imageStats({ width, height, channels, data });
  assert.ok(s.variance <= 100 && s.nonBackground <= 0.05);
});

test('the sample files are read ahead in batches, not one frame at a time', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const manifest = JSON.parse(fs.readFileSync(path.join(WWW, 'sample/manifest.json'), 'utf8'));
  const depths = manifest.files.map((f) => f.path).filter((p) => p.includes('/depth/')).sort();
  const far = depths[20]; // the 21st frame's depth: one batch ahead of the first frames
  const env = await startBrowser();
  try {
    const { page, requests } = await openPage(env, '/');
    const status = await waitForStatus(page, (s) => s.framesProcessed >= 1, { intervalMs: 50, timeoutMs: 60_000 });
    const seen = requests.some((u) => u.endsWith(far));
    t.diagnostic(`after ${status.framesProcessed} frame(s): ${far} ${seen ? 'already requested' : 'not requested'}`);
    assert.ok(status.framesProcessed >= 1 && status.framesProcessed < 17, `checked early: ${status.framesProcessed} frames`);
    assert.ok(seen, `${far} is read before frame 17 starts`);
  } finally {
    await env.close();
  }
});
