#!/usr/bin/env node
// Plays the bundled sample in headless Chromium (threaded module, flow
// overlay off) and prints the page's own speed figures from
// window.surfelSlamStatus: fps and median ms per stage in wasm.
//
//   node scripts/page-fps.mjs [--threads 0] [--colour wasm]
// (--colour wasm: colour decoded in wasm, not by the browser, for comparisons)
// Needs www/pkg built (scripts/build.sh) and Debian's chromium.
import { startBrowser, openPage, waitForStatus } from '../tests/browser/helpers.mjs';

const option = (name) => (process.argv.includes(name) ? process.argv[process.argv.indexOf(name) + 1] : undefined);
const query = new URLSearchParams();
if (option('--threads') === '0') query.set('threads', '0');
if (option('--colour') === 'wasm') query.set('colour', 'wasm');
const env = await startBrowser();
try {
  const { page } = await openPage(env, query.size ? `/?${query}` : '/');
  const s = await waitForStatus(page, (st) => st.done || st.framesProcessed >= 44, { timeoutMs: 240_000 });
  console.log(
    `sample: ${s.framesProcessed} frames, module ${s.module} (${s.threads} threads), ` +
      `fps ${s.fpsAverage} average / ${s.fps} recent, lost ${s.framesLost}, surfels ${s.surfels}, ` +
      `colour decoded by ${s.colourDecoder} (${s.framesColourDecodedInBrowser} frames in the browser)`,
  );
  console.log(`median ms in wasm: ${JSON.stringify(s.stageMedianMs)}`);
  console.log(`median ms in the worker: ${JSON.stringify(s.workerMedianMs)}`);
} finally {
  await env.close?.();
  await env.browser?.close?.();
}
