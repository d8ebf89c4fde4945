// Datasets as people have them, on the page: an archive picked (.tgz, .zip;
// read in place by the wasm ArchiveReader), a 7-Scenes folder (ground truth
// from its per-frame pose files: ATE and the ground-truth path shown), a
// RealSense recording as Open3D's recorder writes it (the trajectory
// downloaded and scored against the clip's truth; the same truth loaded as
// the user's reference, TUM and CSV: reference-loaded-page.png), a Stray
// Scanner export (256x192 depth only, confidence images; the RMS difference
// from its odometry, named as the CLI names it; a cut-off last odometry row
// said in the message box), and a
// half-copied folder (a missing image skips its frame, by name). All built
// from the bundled clip, so no ../shared is needed.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { SHARED_DATA, startBrowser, openPage, getStatus, waitForStatus, foreignRequests, saveScreenshot, skipUnlessReady } from './helpers.mjs';
import { CLIP, makeRealSense, makeSevenScenes, makeStray, tempDir, tumHalved, tumSubset, writeArchive } from '../node/datasets.mjs';

const FRAMES = 12;

/** Opens the page without the sample, drops the folder `dir` on it and waits
 * until a sequence of kind `kind` has played: { page, consoleErrors, status }. */
async function playDropped(t, env, dir, kind) {
  const { page, consoleErrors } = await openPage(env, '/?sample=0');
  await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
  await page.locator('#folder-input').setInputFiles(dir);
  const status = await waitForStatus(page, (s) => s.sequenceKind === kind && s.done && !s.playing, {
    timeoutMs: 120_000,
    log: (m) => t.diagnostic(m),
  });
  await page.waitForTimeout(300);
  return { page, consoleErrors, status };
}


test('an archive picked plays like the folder', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-archive-');
  const folder = tumSubset(CLIP, FRAMES, path.join(tmp, 'clip'));
  const env = await startBrowser();
  try {
    const { page, requests, consoleErrors } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    for (const ext of ['tgz', 'zip']) {
      const archive = writeArchive(folder, 'rgbd_dataset_freiburg3_clip', tmp, ext);
      await page.locator('#archive-input').setInputFiles(archive);
      const status = await waitForStatus(
        page,
        (s) => s.sequence === 'rgbd_dataset_freiburg3_clip' && s.done && !s.playing && s.framesProcessed + s.framesFailed >= FRAMES,
        { timeoutMs: 120_000, log: (m) => t.diagnostic(m) },
      );
      t.diagnostic(
        `${ext}: ${status.framesProcessed}/${status.frameCount} frames, ${status.surfels} surfels, ` +
          `ATE ${status.ate === null ? '-' : (status.ate * 100).toFixed(2) + ' cm'}, errors ${JSON.stringify(status.errors)}`,
      );
      assert.equal(status.error, null, `${ext}: ${status.error}`);
      assert.equal(status.sequenceKind, 'tum');
      assert.equal(status.frameCount, FRAMES);
      assert.equal(status.framesProcessed, FRAMES);
      assert.ok(Number.isFinite(status.ate) && status.ate < 0.03, `${ext}: ATE ${status.ate}`);
      if (ext === 'tgz') saveScreenshot('archive-tgz-page.png', await page.screenshot());
    }
    // A damaged archive: a message naming it; the previous sequence stays loaded.
    const bytes = fs.readFileSync(path.join(tmp, 'rgbd_dataset_freiburg3_clip.tgz'));
    const broken = path.join(tmp, 'broken.tgz');
    fs.writeFileSync(broken, bytes.subarray(0, bytes.length >> 1));
    await page.locator('#archive-input').setInputFiles(broken);
    const status = await waitForStatus(page, (s) => /broken\.tgz/.test(s.error ?? ''), { timeoutMs: 60_000 });
    t.diagnostic(`truncated archive: ${status.error}`);
    assert.match(status.error ?? '', /broken\.tgz.*(corrupt|truncated)/);
    assert.equal(status.sequence, 'rgbd_dataset_freiburg3_clip', 'the previous sequence stays loaded');
    assert.deepEqual(foreignRequests(requests, env.origin), []);
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('the whole teddy sequence plays from a .tgz picked', { timeout: 600_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const teddy = path.join(SHARED_DATA, 'tum_fr3_teddy');
  if (!fs.existsSync(teddy)) {
    if (process.env.CI === 'true') throw new Error(`${teddy} is required when CI=true`);
    return t.skip(`${teddy} is absent (needs ../shared/data beside the checkout)`);
  }
  const tmp = tempDir('surfel-slam-page-teddy-');
  const archive = writeArchive(teddy, 'rgbd_dataset_freiburg3_teddy', tmp, 'tgz');
  const env = await startBrowser();
  try {
    const { page } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    const t0 = Date.now();
    await page.locator('#archive-input').setInputFiles(archive);
    await waitForStatus(page, (s) => s.sequence === 'rgbd_dataset_freiburg3_teddy' && s.framesProcessed >= 1, { timeoutMs: 120_000 });
    const firstFrameS = (Date.now() - t0) / 1000;
    const status = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 500_000, log: (m) => t.diagnostic(m) });
    t.diagnostic(
      `teddy.tgz (${(fs.statSync(archive).size / 2 ** 20).toFixed(0)} MB) on the page: first frame after ${firstFrameS.toFixed(1)} s, ` +
        `${status.framesProcessed}/${status.frameCount} frames at ${status.fpsAverage} fps, ATE ${(status.ate * 100).toFixed(3)} cm, module ${status.module}`,
    );
    assert.equal(status.error, null, status.error);
    assert.equal(status.framesProcessed, status.frameCount);
    assert.ok(status.frameCount > 150);
    // The CLI gives 0.71 cm on the folder and on the archive.
    assert.ok(status.ate < 0.01, `ATE ${status.ate} m`);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('a 7-Scenes folder shows its ground truth and ATE', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-7scenes-');
  const { dir } = makeSevenScenes(CLIP, FRAMES, tmp);
  const env = await startBrowser();
  try {
    const { page, status } = await playDropped(t, env, dir, '7-scenes');
    saveScreenshot('seven-scenes-page.png', await page.screenshot());
    const info = await page.locator('#sequence-info').textContent();
    t.diagnostic(`${info}; ATE ${status.ate === null ? '-' : (status.ate * 100).toFixed(2) + ' cm'}`);
    assert.equal(status.error, null, status.error);
    assert.equal(status.framesProcessed, FRAMES);
    assert.match(info, new RegExp(`ground truth ${FRAMES} poses`));
    assert.ok(Number.isFinite(status.ate) && status.ate < 0.05, `ATE ${status.ate}`);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('a RealSense folder plays with the intrinsics of its JSON and file numbers as timestamps', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-realsense-');
  const { dir, truthTum } = makeRealSense(CLIP, FRAMES, tmp);
  const env = await startBrowser();
  try {
    const { page, consoleErrors, status } = await playDropped(t, env, dir, 'realsense');
    saveScreenshot('realsense-page.png', await page.screenshot());
    const info = await page.locator('#sequence-info').textContent();
    assert.equal(status.error, null, status.error);
    assert.equal(status.framesProcessed, FRAMES);
    assert.equal(status.framesFailed, 0);
    assert.equal(status.framesLost, 0);
    assert.match(info, /realsense-d400/);
    // The intrinsics shown are the JSON's (column-major), not the preset's;
    // depth in the D400's millimetres.
    const shown = await page.evaluate(() => ['fx', 'fy', 'cx', 'cy', 'depth-scale'].map((id) => Number(document.getElementById(id).value)));
    assert.deepEqual(shown, [535.4, 539.2, 320.1, 247.6, 1000]);
    // No ground truth in the layout: the downloaded trajectory, stamped with
    // file numbers, scored here against the clip's truth stamped alike.
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#trajectory-button').click()]);
    const trajectory = fs.readFileSync(await download.path(), 'utf8');
    const ate = await page.evaluate(
      async ([estimate, truth]) => {
        const m = await import('./pkg/surfel_slam.js');
        await m.default();
        const a = m.ateTum(estimate, truth);
        return { rmse: a.rmse, pairs: a.pairs };
      },
      [trajectory, truthTum],
    );
    t.diagnostic(`${info}; ${status.framesProcessed} frames, ATE ${(ate.rmse * 100).toFixed(3)} cm against the clip's truth`);
    assert.equal(ate.pairs, FRAMES, 'one pose a file number');
    assert.ok(ate.rmse < 0.01, `ATE ${ate.rmse} m`);
    // No reference of its own: none named (not "ground truth"), the drift plot says so in its width.
    assert.equal(status.reference, null);
    assert.ok(!(await page.locator('#show-gt-label').isVisible()), 'no reference checkbox without a reference');
    assert.equal(status.driftPlotTitle?.fits, true, JSON.stringify(status.driftPlotTitle));
    assert.match(status.driftPlotTitle.text, /no reference/);
    // "Reference…": the same truth as the user's own file, TUM by timestamp, then CSV by frame number.
    const tumFile = path.join(tmp, 'tracker.txt');
    fs.writeFileSync(tumFile, `# t tx ty tz qx qy qz qw\n${truthTum}`);
    await page.locator('#reference-input').setInputFiles(tumFile);
    const scored = await waitForStatus(page, (s) => s.userReference?.name === 'tracker.txt' && Number.isFinite(s.ate), { timeoutMs: 30_000 });
    await page.waitForTimeout(400); // the plot's redraw
    saveScreenshot('reference-loaded-page.png', await page.screenshot());
    const table = await page.locator('#stats').textContent();
    const line = await page.locator('#sequence-info').textContent();
    const title = (await getStatus(page)).driftPlotTitle;
    t.diagnostic(`your reference: ATE ${(scored.ate * 100).toFixed(3)} cm, drift ${scored.positionErrorCm} cm; ${line}; plot: ${title.text}`);
    assert.equal(scored.reference, 'your reference');
    assert.equal(await page.locator('#reference-name').textContent(), 'your reference');
    assert.ok(await page.locator('#show-gt-label').isVisible());
    assert.ok(Math.abs(scored.ate - ate.rmse) < 1e-6, `the page's ATE ${scored.ate} is the truth's ${ate.rmse}`);
    assert.match(table, /ATE rmse against your reference\s*[\d.]+ cm \(12 poses\)/);
    assert.match(line, /your reference tracker\.txt: 12 poses, 12 of 12 frames matched by timestamp/);
    assert.ok(Number.isFinite(scored.positionErrorCm) && scored.positionErrorCm < 2, `drift from it over the frames run: ${scored.positionErrorCm} cm`);
    assert.ok(title.fits && /drift/.test(title.text) && /cm/.test(title.text), JSON.stringify(title));
    const csvFile = path.join(tmp, 'tracker.csv');
    const rows = truthTum.trim().split('\n').map((l) => l.trim().split(/\s+/).join(', '));
    // Its last row cut off (the tracker stopped mid-write): skipped, said by file and line.
    fs.writeFileSync(csvFile, ['frame, x, y, z, qx, qy, qz, qw', ...rows, `${rows.length}, 0.1`].join('\n'));
    await page.locator('#reference-input').setInputFiles(csvFile);
    const byFrame = await waitForStatus(page, (s) => s.userReference?.name === 'tracker.csv', { timeoutMs: 30_000 });
    assert.ok(Math.abs(byFrame.ate - ate.rmse) < 1e-6, `by frame number: ${byFrame.ate}`);
    assert.equal(byFrame.userReference.key, 'frame');
    assert.ok(byFrame.shownErrors.some((m) => new RegExp(`^tracker\\.csv, line ${rows.length + 2}: the last line is cut off`).test(m)), JSON.stringify(byFrame.shownErrors));
    // A file that matches no frame is refused, by name; the reference stays.
    const far = path.join(tmp, 'elsewhere.txt');
    fs.writeFileSync(far, '1000 0 0 0 0 0 0 1\n1001 0 0 0 0 0 0 1\n');
    await page.locator('#reference-input').setInputFiles(far);
    const refused = await waitForStatus(page, (s) => /elsewhere\.txt/.test(s.error ?? ''), { timeoutMs: 30_000 });
    assert.match(refused.error, /none of its 2 poses falls on a frame/);
    assert.equal(refused.userReference.name, 'tracker.csv');
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test("a TUM folder resized to 320x240 plays with its preset's calibration scaled to it", { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-tum-half-');
  const dir = tumHalved(CLIP, FRAMES, path.join(tmp, 'rgbd_dataset_freiburg3_half'));
  const env = await startBrowser();
  try {
    const { page, consoleErrors, status } = await playDropped(t, env, dir, 'tum');
    saveScreenshot('tum-half-page.png', await page.screenshot());
    t.diagnostic(`${status.framesProcessed} frames at 320x240, ATE ${(status.ate * 100).toFixed(3)} cm, errors ${JSON.stringify(status.errors)}`);
    assert.equal(status.error, null, status.error);
    // Before, the page built the run at the preset's 640x480 and refused every frame.
    assert.equal(status.framesProcessed, FRAMES);
    assert.equal(status.framesFailed, 0);
    assert.equal(status.framesLost, 0);
    assert.deepEqual(status.errors, []);
    // Freiburg 3's 535.4, 539.2, 320.1, 247.6 halved, pixel centres kept.
    const shown = await page.evaluate(() => ['fx', 'fy', 'cx', 'cy', 'depth-scale'].map((id) => Number(document.getElementById(id).value)));
    assert.deepEqual(shown, [267.7, 269.6, 159.8, 123.55, 5000]);
    assert.ok(Number.isFinite(status.ate) && status.ate < 0.02, `ATE ${status.ate} m`);
    // Another preset chosen in the panel comes at the frames' size too
    // (Freiburg 1's 517.3, 516.5, 318.6, 255.3 halved), and the sequence
    // plays again with it; before, the panel showed its 640x480 values.
    await page.locator('#preset').selectOption('tum-fr1');
    const fr1 = await page.evaluate(() => ['fx', 'fy', 'cx', 'cy'].map((id) => Number(document.getElementById(id).value)));
    assert.deepEqual(fr1, [258.65, 258.25, 159.05, 127.4]);
    await waitForStatus(page, (s) => s.playing || s.framesProcessed < FRAMES, { timeoutMs: 60_000 });
    const again = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 120_000 });
    assert.equal(again.framesProcessed, FRAMES);
    assert.equal(again.framesFailed, 0);
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('an 848x480 RealSense folder plays, and plays again after a settings change at its own size', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-realsense-848-');
  const { dir } = makeRealSense(CLIP, FRAMES, tmp, 'realsense_848', 848);
  const env = await startBrowser();
  try {
    const { page, consoleErrors, status } = await playDropped(t, env, dir, 'realsense');
    assert.equal(status.error, null, status.error);
    assert.equal(status.framesProcessed, FRAMES);
    assert.equal(status.framesFailed, 0);
    // The input thumbnails keep the frames' 16:9, not the 4:3 of 640x480.
    const box = await page.locator('#colour-view').boundingBox();
    assert.ok(Math.abs(box.width / box.height - 848 / 480) < 0.05, `colour view ${box.width}x${box.height}`);
    saveScreenshot('realsense-848-page.png', await page.screenshot());
    // A settings change rebuilds the run from the panel: at the folder's
    // 848x480, not the preset's default size, or every frame is refused.
    await page.locator('#loop-closure').uncheck();
    await waitForStatus(page, (s) => s.playing || s.framesProcessed < FRAMES, { timeoutMs: 60_000 });
    const again = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 120_000, log: (m) => t.diagnostic(m) });
    t.diagnostic(`after the change: ${again.framesProcessed} processed, ${again.framesFailed} failed, ${again.framesLost} lost, errors ${JSON.stringify(again.errors)}`);
    assert.equal(again.framesFailed, 0, JSON.stringify(again.errors));
    assert.equal(again.framesProcessed, FRAMES);
    assert.equal(again.framesLost, 0);
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('a Stray Scanner folder plays on depth alone, its low-confidence depth dropped, beside its odometry', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-stray-');
  const { dir } = makeStray(CLIP, FRAMES, tmp);
  // The app stopped while writing the next frame's odometry row: cut off, its line said, the complete frames all play.
  const odometryCsv = path.join(dir, 'odometry.csv');
  const cutLine = fs.readFileSync(odometryCsv, 'utf8').trimEnd().split('\n').length + 1;
  fs.appendFileSync(odometryCsv, `9999.5, ${FRAMES}, 0.1, 0.2`);
  const env = await startBrowser();
  try {
    const { page, consoleErrors, status } = await playDropped(t, env, dir, 'stray-scanner');
    saveScreenshot('stray-scanner-page.png', await page.screenshot());
    const info = await page.locator('#sequence-info').textContent();
    t.diagnostic(`${info}; ${status.framesProcessed} frames, ${status.framesLost} lost, ${status.surfels} surfels, errors ${JSON.stringify(status.errors)}, shown ${JSON.stringify(status.shownErrors)}`);
    assert.equal(status.error, null, status.error);
    const cutOff = status.shownErrors.filter((m) => /odometry\.csv/.test(m));
    assert.equal(cutOff.length, 1, JSON.stringify(status.shownErrors));
    assert.match(cutOff[0], new RegExp(`^stray_teddy/odometry\\.csv, line ${cutLine}: the last line is cut off`));
    assert.equal(status.framesProcessed, FRAMES);
    assert.equal(status.framesFailed, 0);
    assert.equal(status.framesLost, 0);
    assert.match(info, /stray-lidar/);
    // Its odometry (here the clip's ground truth) is drawn as the reference, named as the device's.
    assert.match(info, new RegExp(`no ground truth, the device's odometry ${FRAMES} poses`));
    assert.equal(status.reference, "device's odometry");
    assert.equal(await page.locator('#reference-name').textContent(), "device's odometry");
    assert.ok(Number.isFinite(status.positionErrorCm) && status.positionErrorCm < 2, `${status.positionErrorCm} cm from the odometry`);
    // The overall figure, named as the CLI's summary names it.
    const table = await page.locator('#stats').textContent();
    t.diagnostic(`stats: ${table.match(/difference from the device's odometry[^a-z]*/)?.[0]}; plot: ${status.driftPlotTitle?.text}`);
    assert.ok(Number.isFinite(status.ate) && status.ate < 0.02, `RMS from the odometry ${status.ate} m`);
    assert.match(table, /difference from the device's odometry\s*[\d.]+ cm RMS \(12 poses; odometry, not ground truth\)/);
    assert.equal(status.driftPlotTitle?.fits, true, JSON.stringify(status.driftPlotTitle));
    // The native reading of the same folder, surfel for surfel: the same
    // decode (confidence 0 dropped, grey colour) and the same pipeline.
    const fresh = tempDir('surfel-slam-page-stray-copy-');
    const copy = makeStray(CLIP, FRAMES, fresh);
    const noConfidence = makeStray(CLIP, FRAMES, fresh, 'stray_all_confident', 0);
    const counts = await page.evaluate(async (folders) => {
      const m = await import('./pkg/surfel_slam.js');
      await m.default();
      const run = ({ name, names, texts, bytes }) => {
        // As the page's worker reads a folder: the layout's own calibration over the preset.
        const seq = m.parseSequence(names, texts, name);
        const preset = typeof seq.preset === 'string' ? seq.preset : seq.preset.name;
        const slam = new m.Slam({ ...seq.intrinsics, preset });
        for (const f of seq.frames) {
          const [depth, confidence] = [new Uint8Array(bytes[f.depth]), new Uint8Array(bytes[f.confidence])];
          slam.pushFiles(null, depth, confidence, [null, f.depth, f.confidence], f.timestamp);
        }
        const n = slam.liveSurfels;
        slam.free();
        return n;
      };
      return folders.map(run);
    }, [folderFiles(copy.dir), folderFiles(noConfidence.dir)]);
    t.diagnostic(`surfels in wasm: ${counts[0]} with a low-confidence band, ${counts[1]} without`);
    assert.equal(counts[0], status.surfels, 'the page pushes the files as read');
    assert.ok(counts[0] < counts[1], 'depth of confidence 0 is not mapped');
    fs.rmSync(fresh, { recursive: true, force: true });
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

/** A folder as plain data for page.evaluate: its name, file names, the text of its .csv files and every file's bytes. */
function folderFiles(dir) {
  const name = path.basename(dir);
  const names = [];
  const texts = {};
  const bytes = {};
  const walk = (rel) => {
    for (const entry of fs.readdirSync(path.join(dir, rel), { withFileTypes: true })) {
      const sub = rel ? `${rel}/${entry.name}` : entry.name;
      if (entry.isDirectory()) walk(sub);
      else {
        const key = `${name}/${sub}`;
        names.push(key);
        const data = fs.readFileSync(path.join(dir, sub));
        if (sub.endsWith('.csv')) texts[key] = data.toString('utf8');
        else bytes[key] = Array.from(data);
      }
    }
  };
  walk('');
  return { name, names, texts, bytes };
}

test('a half-copied folder skips the frames whose images are missing', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-half-');
  const dir = tumSubset(CLIP, FRAMES, path.join(tmp, 'rgbd_dataset_freiburg3_half'));
  const colours = fs
    .readFileSync(path.join(dir, 'rgb.txt'), 'utf8')
    .split('\n')
    .filter((l) => l.trim() && !l.startsWith('#'))
    .map((l) => l.split(/\s+/)[1]);
  const gone = [colours[3], colours[10]];
  for (const c of gone) fs.rmSync(path.join(dir, c));
  const env = await startBrowser();
  try {
    const { page } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    await page.locator('#folder-input').setInputFiles(dir);
    const status = await waitForStatus(page, (s) => s.sequence === 'rgbd_dataset_freiburg3_half' && s.done && !s.playing, {
      timeoutMs: 120_000,
    });
    t.diagnostic(`half-copied: ${status.framesProcessed} processed, ${status.framesFailed} skipped: ${JSON.stringify(status.errors)}`);
    assert.equal(status.frameCount, FRAMES);
    assert.equal(status.framesFailed, gone.length);
    assert.equal(status.framesProcessed, FRAMES - gone.length);
    for (const c of gone) {
      assert.ok(
        status.errors.some((e) => e.includes(c) && e.includes('is missing (listed in rgbd_dataset_freiburg3_half/rgb.txt)')),
        `names ${c}`,
      );
    }
    assert.ok(Number.isFinite(status.ate), 'ATE over the frames that ran');
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});
