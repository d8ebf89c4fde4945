// Sessions in the page (issue #36): the bundled sample played part way and
// saved ("Save session" downloads <sequence>.slam), the page reloaded, the
// file opened ("Open session") -> the frame and surfel counts and the camera
// path are the saved ones; a truncated copy, a damaged one, one of a newer
// format, files that are no session and a sequence of another camera are
// refused with their kind in the message box and the loaded map stays; the
// sample opened again then continues the session to its last frame, as
// Replay of it uninterrupted. Then the last session offered back after a
// reload (IndexedDB), and the sample localised in a session.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { REPO, startBrowser, openPage, waitForStatus, getStatus, skipUnlessReady, makeTumClip } from './helpers.mjs';
import { zipBytes } from '../node/datasets.mjs';

const SAVE_AFTER = 15; // frames of the 44-frame sample before saving

async function downloadTrajectory(page) {
  const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#trajectory-button').click()]);
  return fs.readFileSync(await download.path(), 'utf8').split('\n').filter((l) => l.trim() && !l.startsWith('#'));
}

/** The first entry of a zip file (the session's manifest.json): name and inflated bytes. */
function firstZipEntry(zip) {
  const method = zip.readUInt16LE(8);
  const size = zip.readUInt32LE(18);
  const nameLength = zip.readUInt16LE(26);
  const start = 30 + nameLength + zip.readUInt16LE(28);
  const data = zip.subarray(start, start + size);
  return { name: zip.subarray(30, 30 + nameLength).toString('utf8'), bytes: method === 8 ? zlib.inflateRawSync(data) : data };
}

/** Chooses `file` in the Open session input and waits for the page's answer (opened or refused). */
async function openSession(page, file) {
  const before = await getStatus(page);
  await page.locator('#session-input').setInputFiles(file);
  return waitForStatus(page, (s) => s.errors.length > before.errors.length || (s.session && s.sessionOpenMs !== before.sessionOpenMs), {
    timeoutMs: 60_000,
  });
}

test('Save session, reload, Open session restores the map; bad files are refused by kind; the sample then continues', { timeout: 600_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-session-'));
  try {
    // The bundled sample plays by itself: pause it part way.
    let { page, consoleErrors } = await openPage(env, '/');
    let s = await waitForStatus(page, (x) => x.framesProcessed >= SAVE_AFTER, { timeoutMs: 180_000 });
    assert.ok(s.framesProcessed >= SAVE_AFTER, `sample played: ${s.framesProcessed} frames (${s.error})`);
    await page.locator('#play-button').click(); // Pause
    s = await waitForStatus(page, (x) => !x.playing, { timeoutMs: 60_000 });
    await page.waitForTimeout(300); // the frame under way when Pause arrived
    s = await getStatus(page);
    assert.ok(!s.done, 'paused before the end of the sample');
    const saved = { frames: s.framesProcessed, surfels: s.surfels };
    const savedPath = await downloadTrajectory(page);
    assert.equal(savedPath.length, saved.frames, 'one pose a frame');

    assert.equal(await page.locator('#save-session-button').isDisabled(), false, 'Save session is enabled with a map');
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#save-session-button').click()]);
    assert.equal(download.suggestedFilename(), 'tum_fr3_teddy_clip.slam');
    const sessionFile = path.join(dir, download.suggestedFilename());
    fs.copyFileSync(await download.path(), sessionFile);
    const bytes = fs.readFileSync(sessionFile);
    assert.equal(bytes.subarray(0, 2).toString('latin1'), 'PK', 'the session is a zip');
    s = await getStatus(page);
    t.diagnostic(`saved after ${saved.frames} frames: ${saved.surfels} surfels, ${bytes.length} bytes, Slam.save ${s.sessionSaveMs} ms`);

    // A reload (no sample this time): nothing mapped, Save session disabled.
    await page.goto(new URL('/?sample=0', env.server.url).href);
    s = await waitForStatus(page, (x) => x.ready, { timeoutMs: 60_000 });
    assert.equal(s.surfels, 0);
    assert.equal(await page.locator('#save-session-button').isDisabled(), true, 'Save session is disabled with no map');

    s = await openSession(page, sessionFile);
    t.diagnostic(`opened: ${s.framesProcessed} frames, ${s.surfels} surfels, Slam.load ${s.sessionOpenMs} ms (${s.module} module)`);
    assert.deepEqual(s.errors, [], 'the saved session opens');
    assert.equal(s.framesProcessed, saved.frames, 'frame count restored');
    assert.equal(s.surfels, saved.surfels, 'surfel count restored');
    assert.equal(s.session?.name, 'tum_fr3_teddy_clip.slam');
    assert.deepEqual(await downloadTrajectory(page), savedPath, 'the camera path restored (TUM text, line for line)');
    assert.match(await page.locator('#stats').textContent(), new RegExp(saved.surfels.toLocaleString('en-US')));
    assert.equal(await page.locator('#save-session-button').isDisabled(), false, 'an opened session can be saved again');

    // Bad files: refused by kind, the opened map stays.
    const truncated = path.join(dir, 'truncated.slam');
    fs.writeFileSync(truncated, bytes.subarray(0, Math.floor(bytes.length / 2)));
    const notSession = path.join(dir, 'notes.slam');
    fs.writeFileSync(notSession, 'these are notes, not a session\n'.repeat(40));
    const sampleZip = path.join(dir, 'pictures.zip');
    // A zip, but not a session: the session file's own bytes with the manifest's name changed.
    fs.writeFileSync(sampleZip, Buffer.from(bytes.toString('latin1').replaceAll('manifest.json', 'manifest.jsoX'), 'latin1'));
    const corrupt = path.join(dir, 'corrupt.slam');
    const damaged = Buffer.from(bytes);
    damaged[Math.floor(damaged.length / 3)] ^= 0xff;
    fs.writeFileSync(corrupt, damaged);
    // A session of a newer format: the saved manifest with a higher version.
    const manifestEntry = firstZipEntry(bytes);
    assert.equal(manifestEntry.name, 'manifest.json');
    const manifest = JSON.parse(manifestEntry.bytes.toString('utf8'));
    const future = path.join(dir, 'future.slam');
    fs.writeFileSync(future, zipBytes([['manifest.json', Buffer.from(JSON.stringify({ ...manifest, version: manifest.version + 1 }))]]));
    for (const [file, kind] of [
      [truncated, 'truncated'],
      [corrupt, 'corrupt'],
      [future, 'future-version'],
      [notSession, 'not-a-session'],
      [sampleZip, 'not-a-session'],
    ]) {
      s = await openSession(page, file);
      const shown = s.shownErrors[0] ?? '';
      t.diagnostic(`${path.basename(file)}: ${shown}`);
      assert.match(shown, new RegExp(`${path.basename(file)}: ${kind}:`), `the message names the kind (${kind})`);
      assert.ok(await page.locator('#message').isVisible(), 'the message box is shown');
      const box = await page.locator('#message').boundingBox();
      assert.ok(box && box.y >= 0 && box.y < 800, `the message is in view: ${JSON.stringify(box)}`);
      assert.equal(s.framesProcessed, saved.frames, `${kind}: frames unchanged`);
      assert.equal(s.surfels, saved.surfels, `${kind}: surfels unchanged`);
    }
    // A sequence of another camera (the sample's images under a fr1 name: the TUM fr1 camera)
    // cannot go on in the session: refused by kind, the session's map stays.
    const fr1 = makeTumClip(path.join(REPO, 'www/sample/tum_fr3_teddy_clip'), 3, 'rgbd_dataset_freiburg1_teddy');
    try {
      const before = (await getStatus(page)).errors.length;
      await page.locator('#folder-input').setInputFiles(fr1.dir);
      s = await waitForStatus(page, (x) => x.errors.length > before, { timeoutMs: 60_000 });
    } finally {
      fs.rmSync(fr1.parent, { recursive: true, force: true });
    }
    t.diagnostic(`fr1 folder: ${s.shownErrors[0]}`);
    assert.match(s.shownErrors[0] ?? '', /rgbd_dataset_freiburg1_teddy: the opened session does not fit this sequence: camera-mismatch: /);
    assert.equal(s.framesProcessed, saved.frames, 'camera-mismatch: frames unchanged');
    assert.equal(s.surfels, saved.surfels, 'camera-mismatch: surfels unchanged');
    assert.deepEqual(await downloadTrajectory(page), savedPath, 'the path is still the session\'s');

    // The sample opened now continues the session at its next frame, to the end.
    await page.locator('#sample-button').click();
    s = await waitForStatus(page, (x) => x.done && !x.playing, { timeoutMs: 240_000 });
    t.diagnostic(`continued: ${s.framesProcessed} frames, ${s.surfels} surfels, ATE ${s.ate} m, errors ${JSON.stringify(s.errors)}`);
    assert.equal(s.framesProcessed, s.frameCount, 'the saved frames and the rest of the sample, each once');
    assert.equal(s.framesLost, 0);
    assert.ok(Number.isFinite(s.ate) && s.ate < 0.05, `ATE after continuing ${s.ate} m`);
    const fullPath = await downloadTrajectory(page);
    assert.equal(fullPath.length, s.frameCount);
    assert.deepEqual(fullPath.slice(0, saved.frames), savedPath, 'the saved poses stay as they were');

    // Replay: the same sample uninterrupted, in the same settings: the continued run is that run.
    const continued = { surfels: s.surfels, ate: s.ate };
    await page.locator('#play-button').click(); // Replay
    s = await waitForStatus(page, (x) => x.playing, { timeoutMs: 30_000 });
    s = await waitForStatus(page, (x) => x.done && !x.playing, { timeoutMs: 240_000 });
    const uninterrupted = await downloadTrajectory(page);
    assert.equal(uninterrupted.length, fullPath.length);
    let largest = 0;
    for (let i = 0; i < fullPath.length; i++) {
      const [a, b] = [fullPath[i], uninterrupted[i]].map((l) => l.split(' ').map(Number));
      assert.equal(a[0], b[0], `timestamps of line ${i}`);
      largest = Math.max(largest, Math.hypot(a[1] - b[1], a[2] - b[2], a[3] - b[3]));
    }
    t.diagnostic(
      `uninterrupted: ${s.surfels} surfels, ATE ${s.ate} m; continued vs uninterrupted: largest position difference ${largest} m, ` +
        `trajectory text ${fullPath.join('\n') === uninterrupted.join('\n') ? 'identical' : 'differs'} (${s.module} module)`,
    );
    // The single-threaded module is exact; the threaded one sums in parallel (docs/js-api.md: reset, to rounding).
    assert.ok(largest < 1e-4, `continued poses within 0.1 mm of the uninterrupted run's: ${largest} m`);
    if (s.module === 'simd') {
      assert.deepEqual(fullPath, uninterrupted, 'single-threaded: the same TUM text');
      assert.equal(continued.surfels, s.surfels, 'single-threaded: the same map size');
    }
    assert.deepEqual(consoleErrors, []);
  } finally {
    await env.close();
    fs.rmSync(dir, { recursive: true, force: true });
  }
});

test('after a reload the page offers the session kept at the last pause, and restores it', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, consoleErrors } = await openPage(env, '/');
    let s = await waitForStatus(page, (x) => x.framesProcessed >= 8, { timeoutMs: 180_000 });
    assert.equal(s.lastSessionOffered, null, 'a fresh browser has no session to offer');
    await page.locator('#play-button').click(); // Pause: the session is kept in IndexedDB
    s = await waitForStatus(page, (x) => !x.playing && x.lastSessionStored, { timeoutMs: 60_000 });
    assert.ok(s.lastSessionStored, 'kept at the pause');
    const kept = { frames: s.framesProcessed, surfels: s.surfels };
    t.diagnostic(`kept at the pause: ${kept.frames} frames, ${kept.surfels} surfels, ${s.lastSessionStored.bytes} bytes`);

    // The accidental reload: the sample plays again by itself; the message box offers the session back.
    await page.reload();
    s = await waitForStatus(page, (x) => x.framesProcessed >= 2 && x.lastSessionOffered, { timeoutMs: 120_000 });
    assert.equal(s.lastSessionOffered, 'tum_fr3_teddy_clip.slam');
    const restore = page.locator('#message-text button', { hasText: 'Restore last session' });
    assert.ok(await restore.isVisible(), 'the offer is in the message box, in view');
    await restore.click();
    s = await waitForStatus(page, (x) => x.session && !x.playing, { timeoutMs: 60_000 });
    t.diagnostic(`restored: ${s.framesProcessed} frames, ${s.surfels} surfels, Slam.load ${s.sessionOpenMs} ms`);
    assert.equal(s.framesProcessed, kept.frames, 'frame count restored');
    assert.equal(s.surfels, kept.surfels, 'surfel count restored');
    assert.equal(s.lastSessionOffered, null, 'offered once');
    assert.equal(await restore.count(), 0, 'the offer is gone');
    assert.deepEqual(consoleErrors, []);
  } finally {
    await env.close();
  }
});

test('with "localise", the sample opened after a session is placed in its map without changing it', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-session-'));
  try {
    const { page, consoleErrors } = await openPage(env, '/');
    let s = await waitForStatus(page, (x) => x.framesProcessed >= SAVE_AFTER, { timeoutMs: 180_000 });
    await page.locator('#play-button').click(); // Pause
    await waitForStatus(page, (x) => !x.playing, { timeoutMs: 60_000 });
    await page.waitForTimeout(300);
    s = await getStatus(page);
    const saved = { frames: s.framesProcessed, surfels: s.surfels };
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#save-session-button').click()]);
    const sessionFile = path.join(dir, download.suggestedFilename());
    fs.copyFileSync(await download.path(), sessionFile);

    await page.goto(new URL('/?sample=0', env.server.url).href);
    await waitForStatus(page, (x) => x.ready, { timeoutMs: 60_000 });
    await page.locator('#session-localise').check();
    s = await openSession(page, sessionFile);
    assert.equal(s.session?.localising, true, 'opened for localisation');
    assert.equal(s.surfels, saved.surfels);

    // The whole sample, from its first frame, placed in the map of its first frames.
    await page.locator('#sample-button').click();
    s = await waitForStatus(page, (x) => x.done && !x.playing, { timeoutMs: 240_000 });
    const localised = s.framesProcessed - saved.frames;
    t.diagnostic(
      `localised ${localised} frames in a map of ${saved.frames}: ${s.framesUnplaced} unplaced, ATE of the placed ${s.ate} m, ` +
        `surfels ${s.surfels} (saved ${saved.surfels}), errors ${JSON.stringify(s.errors)}`,
    );
    assert.equal(localised, s.frameCount, 'every frame of the sample localised, from its first');
    assert.equal(s.surfels, saved.surfels, 'localising does not change the map');
    assert.ok(s.framesUnplaced < s.frameCount / 2, `most frames placed (${s.framesUnplaced} of ${s.frameCount} unplaced)`);
    assert.ok(Number.isFinite(s.ate) && s.ate < 0.05, `ATE of the placed frames ${s.ate} m`);
    assert.deepEqual(consoleErrors, []);
  } finally {
    await env.close();
    fs.rmSync(dir, { recursive: true, force: true });
  }
});

test('a session of another camera than the open sequence\'s closes that sequence and keeps its own camera', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-session-'));
  const fr1 = makeTumClip(path.join(REPO, 'www/sample/tum_fr3_teddy_clip'), 4, 'rgbd_dataset_freiburg1_teddy');
  try {
    // A session of the fr1 camera: the sample's first frames under a fr1 name.
    const { page, consoleErrors } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (x) => x.ready, { timeoutMs: 60_000 });
    await page.locator('#folder-input').setInputFiles(fr1.dir);
    let s = await waitForStatus(page, (x) => x.done && !x.playing && x.framesProcessed === 4, { timeoutMs: 120_000 });
    const saved = { frames: s.framesProcessed, surfels: s.surfels };
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#save-session-button').click()]);
    const sessionFile = path.join(dir, download.suggestedFilename());
    fs.copyFileSync(await download.path(), sessionFile);

    // The sample (fr3) playing: the fr1 session replaces it, with its camera.
    await page.locator('#sample-button').click();
    await waitForStatus(page, (x) => x.sequence === 'tum_fr3_teddy_clip' && x.framesProcessed >= 2, { timeoutMs: 120_000 });
    s = await openSession(page, sessionFile);
    t.diagnostic(`fr1 session over the fr3 sample: sequence ${s.sequence}, ${s.framesProcessed} frames, ${s.surfels} surfels, ${JSON.stringify(s.errors)}`);
    assert.equal(s.session?.name, 'rgbd_dataset_freiburg1_teddy.slam');
    assert.equal(s.sequence, null, 'the fr3 sequence is closed');
    assert.equal(s.framesProcessed, saved.frames);
    assert.equal(s.surfels, saved.surfels);
    assert.equal(await page.locator('#play-button').isDisabled(), true, 'nothing to play until a sequence of its camera is opened');
    assert.match(await page.locator('#sequence-info').textContent(), /open or drop a sequence of its camera/);
    assert.deepEqual(consoleErrors, []);
  } finally {
    await env.close();
    fs.rmSync(dir, { recursive: true, force: true });
    fs.rmSync(fr1.parent, { recursive: true, force: true });
  }
});
