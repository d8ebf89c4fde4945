#!/usr/bin/env node
// Session save and load times in the page (issue #36), measured on a real
// sequence in headless Chromium: the folder opened, played to --frames,
// paused or played to its end (the page keeps the session in IndexedDB then), "Save session"
// clicked (the download's size), the page reloaded and the file opened with
// "Open session". Prints one JSON line per run. A measurement, not a test:
// 7-Scenes data is not shipped and not run in CI.
//
//   node scripts/page-session-times.mjs [folder] [--frames 250] [--runs 1] [--threads 0]
// (folder default ../shared/data/7scenes_redkitchen_even)
// Needs www/pkg built (scripts/build.sh) and Debian's chromium.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { REPO, startBrowser, openPage, waitForStatus, getStatus, missingPrerequisite } from '../tests/browser/helpers.mjs';

const args = process.argv.slice(2);
const option = (name, fallback) => (args.includes(name) ? args[args.indexOf(name) + 1] : fallback);
const positional = args.filter((a, i) => !a.startsWith('--') && !(i > 0 && args[i - 1].startsWith('--')));
const folder = path.resolve(positional[0] ?? path.join(REPO, '../shared/data/7scenes_redkitchen_even'));
const frames = Number(option('--frames', '250'));
const runs = Number(option('--runs', '1'));
const query = new URLSearchParams({ sample: '0' });
if (option('--threads') === '0') query.set('threads', '0');

const missing = missingPrerequisite() ?? (fs.existsSync(folder) ? null : `no sequence folder ${folder}`);
if (missing) {
  console.error(`page-session-times: ${missing}`);
  process.exit(1);
}
const log = (m) => console.error(m);
const mb = (bytes) => Number((bytes / 1e6).toFixed(2));

async function measure(env, dir) {
  const { page } = await openPage(env, `/?${query}`);
  let s = await waitForStatus(page, (x) => x.ready, { timeoutMs: 120_000 });
  await page.locator('#folder-input').setInputFiles(folder);
  // Poll often so that Pause lands close to the frame count asked for.
  s = await waitForStatus(page, (x) => x.framesProcessed >= frames || x.done, { timeoutMs: 3_600_000, intervalMs: 100, log });
  // At the end the page stops by itself (and the button would replay): Pause only before it.
  if (!s.done && frames < s.frameCount) await page.locator('#play-button').click(); // Pause
  else s = await waitForStatus(page, (x) => x.done, { timeoutMs: 3_600_000, log });
  s = await waitForStatus(page, (x) => !x.playing, { timeoutMs: 120_000 });
  // The pause's auto-save: Slam.save in the worker, then the IndexedDB write.
  s = await waitForStatus(page, (x) => x.sessionStoreMs !== null, { timeoutMs: 300_000 });
  const kept = { frames: s.framesProcessed, surfels: s.surfels, keepSaveMs: s.sessionKeepSaveMs, storeMs: s.sessionStoreMs };

  const [download] = await Promise.all([page.waitForEvent('download', { timeout: 300_000 }), page.locator('#save-session-button').click()]);
  const file = path.join(dir, download.suggestedFilename());
  await download.saveAs(file);
  s = await waitForStatus(page, (x) => x.sessionSaveMs !== null, { timeoutMs: 60_000 });
  const saveMs = s.sessionSaveMs;

  await page.goto(new URL(`/?${query}`, env.server.url).href);
  s = await waitForStatus(page, (x) => x.ready, { timeoutMs: 120_000 });
  await page.locator('#session-input').setInputFiles(file);
  s = await waitForStatus(page, (x) => x.errors.length > 0 || x.sessionOpenMs !== null, { timeoutMs: 300_000 });
  if (s.errors.length) throw new Error(`the session did not open: ${s.errors.join('; ')}`);
  const opened = { frames: s.framesProcessed, surfels: s.surfels };
  await page.close();
  return {
    sequence: path.basename(folder),
    module: s.module,
    threads: s.threads,
    frames: kept.frames,
    surfels: kept.surfels,
    fileMB: mb(fs.statSync(file).size),
    saveMs,
    openMs: s.sessionOpenMs,
    pauseAutoSaveMs: kept.keepSaveMs,
    indexedDbStoreMs: kept.storeMs,
    openedMatches: opened.frames === kept.frames && opened.surfels === kept.surfels,
  };
}

const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-session-times-'));
try {
  // A fresh browser profile each run: with a session already kept in IndexedDB the page
  // offers it back and skips the auto-save on pause.
  for (let run = 0; run < runs; run++) {
    const env = await startBrowser();
    try {
      console.log(JSON.stringify(await measure(env, dir)));
    } finally {
      await env.close();
    }
  }
} finally {
  fs.rmSync(dir, { recursive: true, force: true });
}
