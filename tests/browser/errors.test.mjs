// The page on the bad inputs not covered by upload.test.mjs (which does the
// 8-bit depth, corrupt colour and not-a-dataset cases): truncated depth, RGB
// depth, colour/depth size mismatch, a frame of another size, every frame
// missing a file listed in an index, a malformed ground-truth line, an empty folder,
// absurd intrinsics and a zero depth scale. Each must be shown on the page
// naming the file or setting; the map and the page survive.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { REPO, startBrowser, openPage, waitForStatus, foreignRequests, makeTumClip, skipUnlessReady } from './helpers.mjs';
import { encodePng } from '../node/png.mjs';

const SAMPLE = path.join(REPO, 'www/sample/tum_fr3_teddy_clip');
const chooseFolder = (page, dir) => page.locator('#folder-input').setInputFiles(dir);
const base = (p) => path.basename(p);

test('every bad input gets a message naming the file or setting; the page survives', { timeout: 400_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const clip = makeTumClip(SAMPLE, 6, 'rgbd_dataset_freiburg3_damaged');
  const write = (rel, bytes) => fs.writeFileSync(path.join(clip.dir, rel), bytes);
  const truncated = fs.readFileSync(path.join(clip.dir, clip.depth[1]));
  write(clip.depth[1], truncated.subarray(0, truncated.length >> 1));
  write(clip.depth[2], fs.readFileSync(path.join(clip.dir, clip.colour[2]))); // RGB "depth"
  write(clip.colour[3], encodePng(320, 240, 3, 8, 90)); // colour 320x240, depth 640x480
  write(clip.colour[4], encodePng(320, 240, 3, 8, 90)); // both 320x240
  write(clip.depth[4], encodePng(320, 240, 1, 16, 5000));

  const missing = makeTumClip(SAMPLE, 3, 'rgbd_dataset_freiburg3_half_copied');
  // Every depth image gone: no frame can run (one gone only skips its frame: datasets.test.mjs).
  for (const d of missing.depth) fs.rmSync(path.join(missing.dir, d));
  const badGt = makeTumClip(SAMPLE, 3, 'rgbd_dataset_freiburg3_bad_gt');
  const gtLines = fs.readFileSync(path.join(SAMPLE, 'groundtruth.txt'), 'utf8').split('\n');
  gtLines.splice(6, 0, '1341841873.5 1.0 2.0 oops 0 0 0 1');
  fs.writeFileSync(path.join(badGt.dir, 'groundtruth.txt'), gtLines.join('\n'));
  const empty = fs.mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-empty-'));

  const answers = [];
  const env = await startBrowser();
  try {
    const { page, requests } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });

    // Bad frames inside a good sequence.
    await chooseFolder(page, clip.dir);
    let status = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 240_000 });
    const frameCases = [
      ['truncated depth PNG', clip.depth[1], /depth image could not be decoded/],
      ['RGB depth PNG', clip.depth[2], /16-bit single-channel PNG, found Rgb8/],
      ['colour/depth size mismatch', clip.colour[3], /colour is 320x240 but depth is 640x480/],
      ["frame size differs from the sequence's", clip.depth[4], /frame is 320x240 but the sequence is 640x480/],
    ];
    for (const [name, file, pattern] of frameCases) {
      const message = status.errors.find((e) => e.includes(base(file)) && pattern.test(e));
      answers.push(`| ${name} | ${message ?? JSON.stringify(status.errors)} |`);
      assert.ok(message, `${name}: a message names ${base(file)} and matches ${pattern}: ${JSON.stringify(status.errors)}`);
    }
    assert.equal(status.framesFailed, 4, 'the four bad frames were skipped');
    assert.equal(status.framesProcessed, 2, 'the two good frames were processed');
    assert.ok(status.surfels > 0, 'the map is kept');
    const surfels = status.surfels;
    const shown = await page.locator('#message-text').textContent();
    assert.match(shown, /320x240/, 'the latest errors are shown on the page');

    // Bad folders: the message names the problem; the loaded sequence and its map stay.
    const folderCases = [
      ['every frame misses a file listed in an index', missing.dir, new RegExp(`none of the 3 frames listed can be read: .*${base(missing.depth[0]).replace('.', '\\.')} is missing \\(listed in .*depth\\.txt\\)`)],
      ['malformed ground-truth line', badGt.dir, /groundtruth\.txt, line 7: .*oops/],
      ['empty folder', empty, /empty/],
    ];
    for (const [name, dir, pattern] of folderCases) {
      const before = status.errors.length;
      await chooseFolder(page, dir);
      status = await waitForStatus(page, (s) => s.errors.length > before, { timeoutMs: 30_000 });
      const message = status.errors.at(-1) ?? '';
      answers.push(`| ${name} | ${message} |`);
      assert.match(message, pattern, name);
      assert.equal(status.surfels, surfels, `${name}: the map is kept`);
      assert.equal(status.sequence, 'rgbd_dataset_freiburg3_damaged', `${name}: the sequence stays loaded`);
    }

    // Bad camera settings through the intrinsics form: refused, old camera
    // kept. (NaN cannot be typed: the fields are number inputs, and an empty
    // one falls back to the preset's value.)
    const goodFields = { fx: '535.4', fy: '539.2', cx: '320.1', cy: '247.6', 'depth-scale': '5000' };
    const settingCases = [
      ['absurd intrinsics (fx 0.5354)', { fx: '0.5354' }, /fx = 0\.5354 px is not a plausible focal length/],
      ['absurd principal point (cy 1e9)', { cy: '1000000000' }, /cy = 1000000000 px puts the principal point far outside/],
      ['depth scale 0', { 'depth-scale': '0' }, /depth scale must be a positive number/],
    ];
    for (const [name, fields, pattern] of settingCases) {
      for (const [id, value] of Object.entries({ ...goodFields, ...fields })) await page.locator(`#${id}`).fill(value);
      const before = status.errors.length;
      await page.locator('#apply-intrinsics').click();
      status = await waitForStatus(page, (s) => s.errors.length > before, { timeoutMs: 30_000 });
      const message = status.errors.at(-1) ?? '';
      answers.push(`| ${name} | ${message} |`);
      assert.match(message, pattern, name);
      assert.equal(status.surfels, surfels, `${name}: the map is kept`);
    }
    t.diagnostic(`page answers:\n${answers.join('\n')}`);

    const foreign = foreignRequests(requests, env.origin);
    assert.deepEqual(foreign, [], `requests outside ${env.origin}: ${foreign.join(', ')}`);
    // Still alive: the bundled sample runs, and the stats show verdict counts.
    await page.locator('#sample-button').click();
    status = await waitForStatus(page, (s) => s.sequence === 'tum_fr3_teddy_clip' && s.framesProcessed >= 2, { timeoutMs: 120_000 });
    assert.ok(status.framesProcessed >= 2, 'a new sequence runs after the errors');
    assert.equal(typeof status.framesRecovered, 'number');
    assert.match(await page.locator('#stats').textContent(), /tracked \/ held \/ lost \/ recovered/);
  } finally {
    await env.close();
    for (const d of [clip.parent, missing.parent, badGt.parent, empty]) fs.rmSync(d, { recursive: true, force: true });
  }
});
