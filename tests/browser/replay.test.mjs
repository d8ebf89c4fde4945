// Playing a sequence again: Reset + Play and Replay after a run longer than
// the map's periodic cleanup and compaction (a reset once left the module's
// spatial index pointing past the new map's end: a panic, then a poisoned
// object for the rest of the session), Pause, settings changes that restart
// and play, and the page's answer to a failure inside the module.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { SHARED_DATA, startBrowser, openPage, waitForStatus, getStatus, saveScreenshot, skipUnlessReady } from './helpers.mjs';

const TEDDY = path.join(SHARED_DATA, 'tum_fr3_teddy');

/** Console messages of every kind from the page and its workers. */
function recordConsole(env) {
  const messages = [];
  env.context.on('console', (m) => messages.push(`${m.type()}: ${m.text()}`));
  return messages;
}

const playText = (page) => page.locator('#play-button').textContent();

/** Waits for a finished run (every frame processed, stopped) and returns its status. */
async function waitForEnd(page, t, frameCount) {
  return waitForStatus(page, (s) => s.done && !s.playing && s.framesProcessed + s.framesFailed >= frameCount, {
    timeoutMs: 600_000,
    log: (m) => t.diagnostic(m),
  });
}

function summary(s) {
  return `${s.framesProcessed} frames, lost ${s.framesLost}, ${s.surfels} surfels, ATE ${(s.ate * 100).toFixed(4)} cm, ${s.fpsAverage} fps`;
}

test('Reset + Play and Replay after 150+ real frames play again with the same ATE', { timeout: 1_500_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  if (!fs.existsSync(TEDDY)) {
    if (process.env.CI === 'true') throw new Error(`${TEDDY} is absent (CI needs ../shared/data beside the checkout)`);
    return t.skip(`${TEDDY} is absent (needs ../shared/data beside the checkout)`);
  }
  const env = await startBrowser();
  const messages = recordConsole(env);
  try {
    const { page, consoleErrors } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    await page.locator('#folder-input').setInputFiles(TEDDY);
    const first = await waitForEnd(page, t, 150);
    t.diagnostic(`first pass: ${summary(first)}`);
    assert.equal(first.error, null, `first pass: ${first.error}`);
    assert.ok(first.frameCount >= 150, `a sequence of 150+ frames (${first.frameCount})`);
    assert.equal(first.framesProcessed, first.frameCount, 'every frame processed');
    assert.ok(Number.isFinite(first.ate) && first.ate < 0.05, `ATE ${first.ate} m`);
    assert.equal(await playText(page), 'Replay');

    // Reset, then Play.
    await page.locator('#reset-button').click();
    let s = await waitForStatus(page, (x) => x.framesProcessed === 0 && !x.playing && !x.done, { timeoutMs: 30_000 });
    assert.equal(s.framesProcessed, 0, 'Reset empties the map');
    assert.equal(await playText(page), 'Play');
    await page.locator('#play-button').click();
    const second = await waitForEnd(page, t, first.frameCount);
    t.diagnostic(`after Reset + Play: ${summary(second)}`);
    assert.equal(second.error, null, `after Reset + Play: ${second.error}`);
    assert.equal(second.framesProcessed, first.frameCount, 'every frame processed again');
    // Same input, same output: the threaded module too (its sums keep their order).
    assert.equal(second.ate, first.ate, 'the same ATE as the first pass');
    assert.equal(second.surfels, first.surfels, 'the same map as the first pass');

    // Replay: one click empties the map and plays from the first frame.
    assert.equal(await playText(page), 'Replay');
    await page.locator('#play-button').click();
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed >= 1 && x.framesProcessed < first.frameCount, { timeoutMs: 60_000 });
    assert.ok(s.playing, 'Replay plays after one click');
    // Pause stops; Play goes on from there.
    s = await waitForStatus(page, (x) => x.framesProcessed >= 20, { timeoutMs: 120_000 });
    await page.locator('#play-button').click();
    s = await waitForStatus(page, (x) => !x.playing, { timeoutMs: 30_000 });
    const paused = s.framesProcessed;
    await page.waitForTimeout(1500);
    s = await getStatus(page);
    assert.equal(s.playing, false, 'Pause stops');
    assert.equal(s.framesProcessed, paused, 'no frame is processed while paused');
    assert.equal(await playText(page), 'Play');
    await page.locator('#play-button').click();
    const third = await waitForEnd(page, t, first.frameCount);
    t.diagnostic(`after Replay (paused at ${paused}): ${summary(third)}`);
    saveScreenshot('replay-teddy-page.png', await page.screenshot());
    assert.equal(third.error, null, `after Replay: ${third.error}`);
    assert.equal(third.framesProcessed, first.frameCount, 'every frame processed a third time');
    assert.equal(third.ate, first.ate, 'the same ATE as the first pass');
    assert.equal(third.surfels, first.surfels, 'the same map as the first pass');

    assert.equal(third.moduleFailures, 0, 'the module never failed');
    assert.deepEqual(third.errors, [], 'no error on the page');
    assert.deepEqual(consoleErrors, [], 'no console errors');
    const deprecated = messages.filter((m) => /deprecated/i.test(m));
    assert.deepEqual(deprecated, [], 'no deprecation warnings (wasm-bindgen init takes an object)');
  } finally {
    await env.close();
  }
});

/** The number of vertices a PLY download declares, and its size. */
async function downloadPly(page) {
  const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#ply-button').click()]);
  const bytes = fs.readFileSync(await download.path());
  const header = bytes.subarray(0, Math.min(bytes.length, 1024)).toString('latin1');
  const vertices = Number(/element vertex (\d+)/.exec(header)?.[1] ?? NaN);
  return { vertices, bytes: bytes.length, name: download.suggestedFilename() };
}

async function downloadTrajectory(page) {
  const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#trajectory-button').click()]);
  const text = fs.readFileSync(await download.path(), 'utf8');
  return text.split('\n').filter((l) => l.trim() && !l.startsWith('#'));
}

test('a module failure stops playback, keeps the downloads, and the next Play runs on a fresh module', { timeout: 600_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    // The bundled sample plays by itself; testHooks=1 lets the test break the module.
    const { page, consoleErrors } = await openPage(env, '/?testHooks=1');
    let s = await waitForStatus(page, (x) => x.framesProcessed >= 12, { timeoutMs: 120_000 });
    // At 1280x800 the downloads are in view and the sections below the fold are named.
    for (const id of ['#ply-button', '#trajectory-button', '#play-button']) {
      const box = await page.locator(id).boundingBox();
      assert.ok(box && box.y + box.height <= 800, `${id} is above the fold: ${JSON.stringify(box)}`);
    }
    assert.ok(await page.locator('#more-below').isVisible(), 'a hint names the sections below the fold');
    assert.match(await page.locator('#more-below').textContent(), /View/);
    // What a panic leaves behind: the Slam object unusable at the next call.
    await page.evaluate(() => window.surfelSlamTest.breakModule());
    s = await waitForStatus(page, (x) => x.failed, { timeoutMs: 60_000 });
    const failedAt = s.framesProcessed;
    t.diagnostic(`failed after ${failedAt} frames: ${s.error}`);
    assert.equal(s.failed, true);
    assert.equal(s.moduleFailures, 1);
    assert.equal(s.playing, false, 'playback stopped');
    assert.match(s.error ?? '', /module failed/);
    assert.ok(await page.locator('#message').isVisible(), 'the failure is shown');
    assert.equal(await playText(page), 'Play');
    await page.waitForTimeout(1000);
    assert.equal((await getStatus(page)).framesProcessed, failedAt, 'nothing runs after the failure');

    // The downloads still give the map and trajectory up to the failure.
    const ply = await downloadPly(page);
    t.diagnostic(`PLY after the failure: ${ply.vertices} vertices, ${ply.bytes} bytes`);
    assert.ok(ply.vertices > 10_000 && ply.vertices <= s.surfelSlots, `PLY of the map so far: ${ply.vertices} vertices (${s.surfelSlots} slots)`);
    assert.equal(ply.bytes - ply.vertices * 35 > 0 && ply.bytes - ply.vertices * 35 < 1024, true, 'PLY size = header + 35 bytes a vertex');
    const poses = await downloadTrajectory(page);
    assert.equal(poses.length, failedAt, 'one trajectory line per frame processed');
    for (const line of poses) assert.equal(line.split(' ').length, 8, `TUM line: ${line}`);

    // Play: a fresh module and Slam, from the first frame, to the end.
    await page.locator('#play-button').click();
    s = await waitForStatus(page, (x) => !x.failed && x.done && !x.playing, { timeoutMs: 240_000, log: (m) => t.diagnostic(m) });
    t.diagnostic(`after the rebuild: ${summary(s)}`);
    assert.equal(s.failed, false);
    assert.equal(s.framesProcessed, s.frameCount, 'the whole sample ran on the new module');
    assert.equal(s.framesLost, 0);
    assert.ok(Number.isFinite(s.ate) && s.ate < 0.05, `ATE ${s.ate} m`);
    assert.equal(s.errors.length, 1, `only the failure was reported: ${JSON.stringify(s.errors)}`);
    const fresh = await downloadPly(page);
    // Not compared with the PLY at the failure: early maps hold many young
    // surfels that later cleanups remove, so 16 frames can outnumber 44.
    assert.ok(fresh.vertices > 0, `PLY of the new, whole map: ${fresh.vertices} vertices`);
    assert.equal(s.surfels, fresh.vertices, 'the surfel count shown is what the map holds (the PLY)');
    assert.match(await page.locator('#stats').textContent(), new RegExp(fresh.vertices.toLocaleString('en-US')));
    assert.equal((await downloadTrajectory(page)).length, s.frameCount);

    // A settings change restarts the sequence and plays it; Pause stops it.
    await page.locator('#half-resolution').check();
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed >= 3 && !x.done, { timeoutMs: 60_000 });
    assert.ok(s.playing, 'half resolution restarts and plays');
    s = await waitForEnd(page, t, s.frameCount);
    t.diagnostic(`half resolution: ${summary(s)}`);
    assert.ok(Number.isFinite(s.ate) && s.ate < 0.05, `half-resolution ATE ${s.ate} m`);
    await page.locator('#tracker').selectOption('joint');
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed >= 2, { timeoutMs: 60_000 });
    assert.ok(s.playing, 'a tracker change restarts and plays');
    await page.locator('#noise').selectOption('kinect-v1');
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed >= 2, { timeoutMs: 60_000 });
    assert.ok(s.playing, 'a noise model change restarts and plays');
    await page.locator('#loop-closure').uncheck();
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed >= 2, { timeoutMs: 60_000 });
    assert.ok(s.playing, 'loop closure off restarts and plays');
    await page.locator('#play-button').click();
    s = await waitForStatus(page, (x) => !x.playing, { timeoutMs: 30_000 });
    assert.equal(s.playing, false, 'Pause stops');
    assert.equal(s.errors.length, 1, `no new error: ${JSON.stringify(s.errors)}`);
    assert.deepEqual(consoleErrors, [], 'no console errors');
  } finally {
    await env.close();
  }
});

test('a worker stuck inside the module is replaced; the downloads keep the map so far', { timeout: 600_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    // stallMs: how long the page waits for a frame before it gives the worker up (30 s by default).
    const { page, consoleErrors } = await openPage(env, '/?testHooks=1&stallMs=4000');
    let s = await waitForStatus(page, (x) => x.framesProcessed >= 10, { timeoutMs: 120_000 });
    // What a panic on one of the module's threads leaves: the worker waits for it for ever.
    await page.evaluate(() => window.surfelSlamTest.hangModule());
    s = await waitForStatus(page, (x) => x.failed, { timeoutMs: 60_000 });
    const stuckAt = s.framesProcessed;
    t.diagnostic(`worker replaced after ${stuckAt} frames: ${s.error}`);
    assert.equal(s.playing, false, 'playback stopped');
    assert.match(s.error ?? '', /stopped answering/);
    const ply = await downloadPly(page);
    assert.ok(ply.vertices > 10_000, `PLY of the map so far from the page's copy: ${ply.vertices} vertices`);
    assert.equal((await downloadTrajectory(page)).length, stuckAt, 'one trajectory line per frame processed');

    // Play opens the sequence again in the new worker and plays it to the end.
    await waitForStatus(page, (x) => x.ready, { timeoutMs: 60_000 });
    await page.locator('#play-button').click();
    s = await waitForStatus(page, (x) => !x.failed && x.done && !x.playing, { timeoutMs: 240_000, log: (m) => t.diagnostic(m) });
    t.diagnostic(`in the new worker: ${summary(s)}`);
    assert.equal(s.framesProcessed, s.frameCount, 'the whole sample ran in the new worker');
    assert.ok(Number.isFinite(s.ate) && s.ate < 0.05, `ATE ${s.ate} m`);
    assert.equal(s.moduleFailures, 1);
    assert.deepEqual(consoleErrors, [], 'no console errors');
  } finally {
    await env.close();
  }
});
