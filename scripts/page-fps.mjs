#!/usr/bin/env node
// Plays the bundled sample, or a sequence folder, in headless Chromium
// (threaded module, flow overlay off) and prints the page's own speed
// figures from window.surfelSlamStatus: fps over every `--every` frames as
// the run goes (the frames processed in the window over its wall time),
// then the median ms per stage in wasm, the splats the map view drew and
// the module's memory (its linear memory, which only grows: the peak).
//
//   node scripts/page-fps.mjs [--folder DIR] [--frames N] [--every N]
//                             [--threads 0] [--colour wasm] [--splats N]
// --folder: a TUM, ICL-NUIM or 7-Scenes folder, given to the page's folder
//   input as a user would (default: the bundled sample, played at load);
// --frames: stop after N frames (default: all); --every: window, frames
//   (default 50); --splats: the map view's splat budget while playing
//   (0: the whole map every draw; default: the page's); --colour wasm:
//   colour decoded in wasm, not by the browser, for comparisons.
// Needs www/pkg built (scripts/build.sh) and Debian's chromium.
import { startBrowser, openPage, waitForStatus } from '../tests/browser/helpers.mjs';

const option = (name) => (process.argv.includes(name) ? process.argv[process.argv.indexOf(name) + 1] : undefined);
const query = new URLSearchParams();
if (option('--threads') === '0') query.set('threads', '0');
if (option('--colour') === 'wasm') query.set('colour', 'wasm');
if (option('--splats') !== undefined) query.set('splats', option('--splats'));
const folder = option('--folder');
const limit = Number(option('--frames') ?? Infinity);
const every = Math.max(1, Number(option('--every') ?? 50));
const env = await startBrowser();
try {
  const { page } = await openPage(env, query.size ? `/?${query}` : '/');
  if (folder) {
    // The bundled sample starts at load: let it end, then open the folder.
    const sample = await waitForStatus(page, (st) => st.done && !st.playing, { timeoutMs: 240_000 });
    await page.locator('#folder-input').setInputFiles(folder);
    await waitForStatus(page, (st) => st.sequence !== sample.sequence && st.playing, { timeoutMs: 120_000 });
  }
  const series = [];
  let mark = { frames: 0, at: performance.now() };
  let s;
  for (;;) {
    s = await waitForStatus(
      page,
      (st) => st.done || st.failed || st.framesProcessed >= Math.min(limit, mark.frames + every),
      { timeoutMs: 600_000, intervalMs: 200 },
    );
    const now = performance.now();
    if (s.framesProcessed > mark.frames) {
      const fps = ((s.framesProcessed - mark.frames) * 1000) / (now - mark.at);
      series.push(`${mark.frames}-${s.framesProcessed}: ${fps.toFixed(1)}`);
      console.log(
        `frames ${mark.frames}-${s.framesProcessed}: ${fps.toFixed(1)} fps, ${s.surfels} surfels, ` +
          `${s.splatsDrawn} splats drawn, wasm ${s.msPerFrame} ms/frame`,
      );
      mark = { frames: s.framesProcessed, at: now };
    }
    if (s.done || s.failed || s.framesProcessed >= limit) break;
  }
  console.log(
    `${folder ?? 'sample'}: ${s.framesProcessed} frames, module ${s.module} (${s.threads} threads), ` +
      `fps ${s.fpsAverage} average, lost ${s.framesLost}, surfels ${s.surfels}, wasm memory ${s.wasmMemoryMiB} MiB, ` +
      `colour decoded by ${s.colourDecoder} (${s.framesColourDecodedInBrowser} frames in the browser)`,
  );
  console.log(`fps series (frames: fps): ${series.join(', ')}`);
  console.log(`median ms in wasm: ${JSON.stringify(s.stageMedianMs)}`);
  console.log(`median ms in the worker: ${JSON.stringify(s.workerMedianMs)}`);
} finally {
  await env.close?.();
  await env.browser?.close?.();
}
