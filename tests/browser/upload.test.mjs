// Folder upload through the file input, and the error cases: a sequence with
// an 8-bit depth PNG and a corrupt colour PNG, then a folder that is no
// dataset at all. The page must say what is wrong (naming the file), keep the
// map, and stay alive. Then switching sequences mid-play (issue 84): the old
// map leaves the view at once (screenshot switch-after-page.png), a refused
// folder lets the sample play on, and a run whose every frame is refused
// says so over the map (nothing-tracked-page.png).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {
  REPO,
  SHARED_DATA,
  startBrowser,
  openPage,
  waitForStatus,
  foreignRequests,
  encodeGreyPng,
  makeTumClip,
  saveScreenshot,
  skipUnlessReady,
  canvasPng,
  decodePng,
  getStatus,
  imageStats,
} from './helpers.mjs';
import { tumHalved } from '../node/datasets.mjs';

const ICL = path.join(SHARED_DATA, 'icl_office_kt0');
const ICL_FRAMES = 15;

/** An ICL-NUIM folder with the first `n` frames (index files trimmed, images copied). */
function makeIclClip(n) {
  const parent = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-icl-'));
  const dir = path.join(parent, 'icl_office_kt0_first15');
  fs.mkdirSync(path.join(dir, 'rgb'), { recursive: true });
  fs.mkdirSync(path.join(dir, 'depth'), { recursive: true });
  const assoc = fs.readFileSync(path.join(ICL, 'associations.txt'), 'utf8').split('\n').filter((l) => l.trim());
  const kept = assoc.slice(0, n);
  fs.writeFileSync(path.join(dir, 'associations.txt'), kept.join('\n') + '\n');
  const numbers = new Set(kept.map((l) => l.split(/\s+/)[0]));
  const gt = fs.readFileSync(path.join(ICL, 'traj0.gt.freiburg'), 'utf8').split('\n');
  fs.writeFileSync(path.join(dir, 'traj0.gt.freiburg'), gt.filter((l) => numbers.has(l.split(/\s+/)[0])).join('\n') + '\n');
  for (const line of kept) {
    const [, depth, , rgb] = line.split(/\s+/);
    fs.copyFileSync(path.join(ICL, depth), path.join(dir, depth));
    fs.copyFileSync(path.join(ICL, rgb), path.join(dir, rgb));
  }
  return { parent, dir };
}

const chooseFolder = (page, dir) => page.locator('#folder-input').setInputFiles(dir);

/** Mean row of the near-white pixels and of all non-background pixels of a decoded image. */
function brightAboveRest({ width, height, channels, data }) {
  const bg = [data[0], data[1], data[2]];
  let bright = 0, brightCount = 0, all = 0, allCount = 0;
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const p = (y * width + x) * channels;
      const [r, g, b] = [data[p], data[p + 1], data[p + 2]];
      if (Math.abs(r - bg[0]) + Math.abs(g - bg[1]) + Math.abs(b - bg[2]) < 12) continue;
      all += y;
      allCount++;
      if (0.299 * r + 0.587 * g + 0.114 * b > 225) {
        bright += y;
        brightCount++;
      }
    }
  }
  return { bright: bright / Math.max(1, brightCount), all: all / Math.max(1, allCount), brightCount };
}

test('a folder uploaded through the file input is tracked and fused', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  if (!fs.existsSync(ICL)) return t.skip(`${ICL} is absent (needs ../shared/data beside the checkout)`);
  const clip = makeIclClip(ICL_FRAMES);
  const env = await startBrowser();
  try {
    const { page, requests } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    await chooseFolder(page, clip.dir);
    const status = await waitForStatus(page, (s) => s.done || s.framesProcessed >= ICL_FRAMES, {
      timeoutMs: 240_000,
      log: (m) => t.diagnostic(m),
    });
    t.diagnostic(
      `ICL-NUIM upload: ${status.framesProcessed} frames, ${status.surfels} surfels, lost ${status.framesLost}, ` +
        `fps ${status.fpsAverage}, ATE ${status.ate === null ? '-' : (status.ate * 100).toFixed(1) + ' cm'}`,
    );
    // Upright: seen from behind the first camera, the ceiling's lights (the
    // brightest surfels) are above the rest of the map, as in the colour image.
    await page.locator('#view-button').click();
    await page.waitForTimeout(800);
    saveScreenshot('upload-icl-page.png', await page.screenshot());
    const upright = brightAboveRest(decodePng(await canvasPng(page)));
    t.diagnostic(`ICL-NUIM view: bright pixels at mean y ${upright.bright.toFixed(0)}, the map at ${upright.all.toFixed(0)} (${upright.brightCount} bright)`);
    assert.equal(status.displayFlipY, true, 'negative fy: the map is shown mirrored in y');
    assert.ok(upright.brightCount > 200 && upright.bright < upright.all - 10, `ceiling lights above the map's middle: ${JSON.stringify(upright)}`);
    assert.equal(status.error, null, `the page reported an error: ${status.error}`);
    assert.equal(status.sequenceKind, 'icl-nuim');
    assert.equal(status.frameCount, ICL_FRAMES);
    assert.ok(status.framesProcessed >= ICL_FRAMES, `frames processed ${status.framesProcessed}`);
    assert.ok(status.framesLost <= 1, `lost ${status.framesLost}`);
    assert.ok(status.surfels > 10_000, `surfels ${status.surfels}`);
    assert.ok(Number.isFinite(status.ate), 'ATE computed from the folder ground truth');
    const info = await page.locator('#sequence-info').textContent();
    assert.match(info, /icl_office_kt0_first15/);
    const foreign = foreignRequests(requests, env.origin);
    assert.deepEqual(foreign, [], `requests outside ${env.origin}: ${foreign.join(', ')}`);
  } finally {
    await env.close();
    fs.rmSync(clip.parent, { recursive: true, force: true });
  }
});

test('bad frames and bad folders give a clear message and keep the map', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  // The bundled sample is part of the repo, so this test never needs ../shared.
  const clip = makeTumClip(path.join(REPO, 'www/sample/tum_fr3_teddy_clip'), 6, 'rgbd_dataset_freiburg3_broken');
  const badDepth = clip.depth[1]; // second frame: 8-bit depth
  fs.writeFileSync(path.join(clip.dir, badDepth), encodeGreyPng(640, 480, Buffer.alloc(640 * 480, 77)));
  const badColour = clip.colour[3]; // fourth frame: garbage bytes
  fs.writeFileSync(path.join(clip.dir, badColour), Buffer.from('this is not a PNG file at all'.repeat(50)));
  const notADataset = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-junk-'));
  fs.mkdirSync(path.join(notADataset, 'holiday_photos'));
  fs.writeFileSync(path.join(notADataset, 'holiday_photos', 'notes.txt'), 'nothing to see\n');
  fs.writeFileSync(path.join(notADataset, 'holiday_photos', 'beach.jpg'), 'not really a jpeg');

  const env = await startBrowser();
  try {
    const { page, requests } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    await chooseFolder(page, clip.dir);
    let status = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 240_000 });
    t.diagnostic(`errors: ${JSON.stringify(status.errors)}`);
    const message = await page.locator('#message-text').textContent();
    saveScreenshot('error-page.png', await page.screenshot());

    assert.ok(status.error, 'status.error is set');
    const depthName = path.basename(badDepth);
    const colourName = path.basename(badColour);
    assert.ok(
      status.errors.some((e) => e.includes(depthName)),
      `an error names the 8-bit depth file ${depthName}: ${JSON.stringify(status.errors)}`,
    );
    assert.ok(
      status.errors.some((e) => e.includes(colourName)),
      `an error names the corrupt colour file ${colourName}: ${JSON.stringify(status.errors)}`,
    );
    assert.ok(await page.locator('#message').isVisible(), 'the message is shown on the page');
    assert.ok(message.includes(colourName) || message.includes(depthName), `page message names the file: ${message}`);
    assert.equal(status.framesFailed, 2, 'exactly the two bad frames were skipped');
    assert.equal(status.framesProcessed, 4, 'the four good frames were processed');
    assert.ok(status.surfels > 0, `the map is kept (${status.surfels} surfels)`);
    const surfelsBefore = status.surfels;

    // A folder that is no dataset: message, map kept, page alive.
    await chooseFolder(page, path.join(notADataset, 'holiday_photos'));
    status = await waitForStatus(page, (s) => /unrecognised|holiday_photos/i.test(s.error ?? ''), { timeoutMs: 30_000 });
    t.diagnostic(`unrecognised folder: ${status.error}`);
    assert.match(status.error ?? '', /holiday_photos/);
    assert.match(status.error ?? '', /unrecognised/i);
    assert.equal(status.surfels, surfelsBefore, 'the map is kept');
    assert.equal(status.sequence, 'rgbd_dataset_freiburg3_broken', 'the previous sequence stays loaded');

    const foreign = foreignRequests(requests, env.origin);
    assert.deepEqual(foreign, [], `requests outside ${env.origin}: ${foreign.join(', ')}`);
    // The page is alive: the bundled sample can still be started.
    await page.locator('#sample-button').click();
    status = await waitForStatus(page, (s) => s.sequence === 'tum_fr3_teddy_clip' && s.framesProcessed >= 1, { timeoutMs: 60_000 });
    assert.ok(status.framesProcessed >= 1, 'a new sequence runs after the errors');
  } finally {
    await env.close();
    fs.rmSync(clip.parent, { recursive: true, force: true });
    fs.rmSync(notADataset, { recursive: true, force: true });
  }
});

test('a sequence opened while the sample plays replaces its map at once; a refused folder lets it play on; a run that maps nothing says so', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-switch-'));
  // At half size: its first frames hold far fewer surfels than the sample's map when it is opened.
  const small = tumHalved(path.join(REPO, 'www/sample/tum_fr3_teddy_clip'), 6, path.join(tmp, 'rgbd_dataset_freiburg3_small'));
  const notADataset = path.join(tmp, 'holiday_photos');
  fs.mkdirSync(notADataset);
  fs.writeFileSync(path.join(notADataset, 'notes.txt'), 'nothing to see\n');
  // Every depth image 8-bit: every frame refused.
  const broken = makeTumClip(path.join(REPO, 'www/sample/tum_fr3_teddy_clip'), 3, 'rgbd_dataset_freiburg3_all_refused');
  for (const d of broken.depth) fs.writeFileSync(path.join(broken.dir, d), encodeGreyPng(640, 480, Buffer.alloc(640 * 480, 77)));
  const env = await startBrowser();
  try {
    const { page } = await openPage(env, '/');
    let s = await waitForStatus(page, (x) => x.sequence === 'tum_fr3_teddy_clip' && x.framesProcessed >= 12 && x.playing, { timeoutMs: 180_000, log: (m) => t.diagnostic(m) });
    // A folder that is no dataset, mid-run: said, and the sample plays on.
    await chooseFolder(page, notADataset);
    s = await waitForStatus(page, (x) => /holiday_photos/.test(x.error ?? ''), { timeoutMs: 30_000 });
    const at = s.framesProcessed;
    assert.match(s.error, /tum_fr3_teddy_clip plays on/, s.error);
    s = await waitForStatus(page, (x) => x.playing && x.framesProcessed > at + 2, { timeoutMs: 60_000 });
    assert.ok(s.framesProcessed > at + 2, `the sample went on after the refusal: ${at} -> ${s.framesProcessed} frames`);

    // The next folder, while the sample plays with its map drawn.
    s = await waitForStatus(page, (x) => x.surfels > 200_000 || x.done, { timeoutMs: 120_000 });
    const old = { splatsDrawn: s.splatsDrawn, surfels: s.surfels };
    await chooseFolder(page, small);
    const opened = await waitForStatus(page, (x) => x.sequence === 'rgbd_dataset_freiburg3_small', { timeoutMs: 60_000, intervalMs: 20 });
    // The canvas as the new sequence opens: empty (unless its first frame was drawn in the meantime).
    const openedCanvas = await canvasPng(page);
    const stillEmpty = (await getStatus(page)).framesProcessed === 0;
    saveScreenshot('switch-opened-canvas.png', openedCanvas);
    const openedPixels = imageStats(decodePng(openedCanvas));
    const first = await waitForStatus(page, (x) => x.framesProcessed >= 1 && x.sequence === 'rgbd_dataset_freiburg3_small', { timeoutMs: 60_000, intervalMs: 20 });
    saveScreenshot('switch-after-page.png', await page.screenshot());
    await page.waitForTimeout(300); // the first frame's draw (throttled to one in 100 ms)
    const drawn = await waitForStatus(page, (x) => x.framesProcessed >= 1, { timeoutMs: 5_000 });
    t.diagnostic(
      `sample's map ${old.surfels} surfels (${old.splatsDrawn} splats); on opening: ${opened.splatsDrawn} splats for ${opened.surfelSlots} surfels; ` +
        `first frame: ${first.splatsDrawn} splats for ${first.surfelSlots} surfels; later: ${drawn.splatsDrawn} for ${drawn.surfelSlots}`,
    );
    assert.ok(old.splatsDrawn > 2 * first.surfelSlots, `the sample's map was drawn (${old.splatsDrawn} splats), more than the new one's first frame has`);
    for (const x of [opened, first]) {
      assert.ok(x.splatsDrawn <= x.surfelSlots, `splats drawn ${x.splatsDrawn} <= the new map's ${x.surfelSlots} surfels (frame ${x.frameIndex})`);
    }
    assert.ok(drawn.splatsDrawn < old.splatsDrawn / 2, `later, the new map is drawn, not the old: ${drawn.splatsDrawn} splats`);
    t.diagnostic(`canvas on opening: ${(openedPixels.nonBackground * 100).toFixed(1)} % non-background${stillEmpty ? '' : ' (a new frame was in already)'}`);
    if (stillEmpty) assert.ok(openedPixels.nonBackground < 0.02, `the old map is off the canvas: ${(openedPixels.nonBackground * 100).toFixed(1)} % non-background`);

    // A whole run in which every frame is refused: said over the map.
    await chooseFolder(page, broken.dir);
    s = await waitForStatus(page, (x) => x.sequence === 'rgbd_dataset_freiburg3_all_refused' && x.done && !x.playing, { timeoutMs: 60_000 });
    const notice = await page.locator('#map-notice');
    saveScreenshot('nothing-tracked-page.png', await page.screenshot());
    t.diagnostic(`all refused: ${s.mapNotice}`);
    assert.equal(s.framesFailed, 3);
    assert.match(s.mapNotice ?? '', /^Nothing could be tracked: all 3 frames of rgbd_dataset_freiburg3_all_refused were skipped/);
    assert.ok(await notice.isVisible(), 'the notice is shown over the map');
    // A run with a map has none.
    await page.locator('#sample-button').click();
    s = await waitForStatus(page, (x) => x.sequence === 'tum_fr3_teddy_clip' && x.framesProcessed >= 1, { timeoutMs: 60_000 });
    assert.equal(s.mapNotice, null);
    assert.ok(!(await notice.isVisible()), 'the notice went with the run');
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
    fs.rmSync(broken.parent, { recursive: true, force: true });
  }
});
