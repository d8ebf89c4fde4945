// Where the page shows a problem (issue 34, item 1): one box over the map,
// in the viewport whatever the panel's scroll, newest message first; a new
// run or a successful Apply clears what no longer applies; a failed open
// says so on the sequence line. The cases a new user hit, in their order:
// a run with a skipped frame, Apply with fx = 0, a folder that is no
// dataset, a truncated archive, then a good Apply; then the camera-settings
// warning of a wrong preset (item 2). A screenshot of each
// state goes to target/browser-screenshots/messages-*.png.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { startBrowser, openPage, waitForStatus, saveScreenshot, skipUnlessReady } from './helpers.mjs';
import { CLIP, tempDir, tumSubset, writeArchive } from '../node/datasets.mjs';

/** The newest message's box: in the viewport and on top (not covered), and its text. */
async function newestOnScreen(page) {
  return page.evaluate(() => {
    const li = document.querySelector('#message-text li');
    if (!li || document.getElementById('message').hidden) return { visible: false, text: null };
    const r = li.getBoundingClientRect();
    const inViewport = r.top >= 0 && r.left >= 0 && r.bottom <= innerHeight && r.right <= innerWidth && r.height > 0;
    const hit = document.elementFromPoint(r.left + Math.min(20, r.width / 2), r.top + r.height / 2);
    return { visible: inViewport && !!hit && document.getElementById('message').contains(hit), text: li.textContent };
  });
}

const shownText = (page) => page.evaluate(() => (document.getElementById('message').hidden ? '' : document.getElementById('message-text').textContent));

test('each problem is shown over the map, newest first, and cleared when it no longer applies', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-messages-');
  const clip = tumSubset(CLIP, 6, path.join(tmp, 'rgbd_dataset_freiburg3_clip'));
  // One frame whose depth image is missing: a "frame N skipped" message from the run.
  const depthRows = fs.readFileSync(path.join(clip, 'depth.txt'), 'utf8').split('\n').filter((l) => l.trim() && !l.startsWith('#'));
  const gone = depthRows[2].split(/\s+/)[1];
  fs.rmSync(path.join(clip, gone));
  const notADataset = path.join(tmp, 'docs');
  fs.mkdirSync(notADataset);
  fs.writeFileSync(path.join(notADataset, 'notes.txt'), 'nothing to see\n');
  fs.writeFileSync(path.join(notADataset, 'README.md'), '# not a dataset\n');
  const archive = writeArchive(clip, 'teddy_truncated', tmp, 'tgz');
  const bytes = fs.readFileSync(archive);
  fs.writeFileSync(archive, bytes.subarray(0, bytes.length >> 1));

  const env = await startBrowser();
  try {
    const { page } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    await page.locator('#folder-input').setInputFiles(clip);
    let status = await waitForStatus(page, (s) => s.done && !s.playing && s.framesFailed === 1, { timeoutMs: 120_000 });
    const skipped = status.errors.find((e) => e.includes(path.basename(gone)));
    assert.ok(skipped, `the missing image is named: ${JSON.stringify(status.errors)}`);
    assert.match(skipped, /^frame 2 skipped/, 'frames numbered from 0, as in the CLI');
    saveScreenshot('messages-1-frame-skipped.png', await page.screenshot());

    // 1. Apply with fx = 0: the panel is scrolled down to the fields; the message is still in view.
    await page.locator('#fx').fill('0');
    await page.locator('#apply-intrinsics').scrollIntoViewIfNeeded();
    await page.locator('#apply-intrinsics').click();
    status = await waitForStatus(page, (s) => /fx/.test(s.shownErrors[0] ?? ''), { timeoutMs: 30_000 });
    let shown = await newestOnScreen(page);
    t.diagnostic(`fx = 0: ${shown.text}`);
    assert.ok(shown.visible, 'the fx = 0 message is in the viewport, not covered');
    assert.match(shown.text, /fx = 0/);
    saveScreenshot('messages-2-fx-zero.png', await page.screenshot());

    // 2. A folder that is no dataset: its message is the first one shown; the sequence line says so.
    await page.locator('#folder-input').setInputFiles(notADataset);
    status = await waitForStatus(page, (s) => /docs/.test(s.shownErrors[0] ?? ''), { timeoutMs: 30_000 });
    shown = await newestOnScreen(page);
    t.diagnostic(`no dataset: ${shown.text}`);
    assert.ok(shown.visible, 'the layout message is in the viewport');
    assert.match(shown.text, /docs.*(layout|dataset)/i);
    let line = await page.locator('#sequence-info').textContent();
    assert.match(line, /could not open docs/, `sequence line: ${line}`);
    assert.match(line, /still loaded: rgbd_dataset_freiburg3_clip/);
    saveScreenshot('messages-3-not-a-dataset.png', await page.screenshot());

    // 3. A truncated archive.
    await page.locator('#archive-input').setInputFiles(archive);
    status = await waitForStatus(page, (s) => /teddy_truncated/.test(s.shownErrors[0] ?? ''), { timeoutMs: 60_000 });
    shown = await newestOnScreen(page);
    t.diagnostic(`truncated archive: ${shown.text}`);
    assert.ok(shown.visible, 'the archive message is in the viewport');
    line = await page.locator('#sequence-info').textContent();
    assert.match(line, /could not open teddy_truncated/, `sequence line: ${line}`);
    assert.equal(status.sequence, 'rgbd_dataset_freiburg3_clip', 'the loaded sequence stays');
    saveScreenshot('messages-4-truncated-archive.png', await page.screenshot());

    // 4. A good Apply: a new run; the stale fx = 0 message (and the others) are gone.
    await page.locator('#fx').fill('535.4');
    await page.locator('#apply-intrinsics').click();
    // (The old run was done too: wait for the new one, which cleared the board.)
    status = await waitForStatus(page, (s) => !s.shownErrors.some((e) => /fx = 0/.test(e)) && s.done && !s.playing && s.framesProcessed + s.framesFailed === 6, { timeoutMs: 120_000 });
    const after = await shownText(page);
    t.diagnostic(`after a good Apply: ${JSON.stringify(status.shownErrors)}`);
    assert.doesNotMatch(after, /fx = 0/, 'the stale fx = 0 message is gone');
    assert.doesNotMatch(after, /docs|teddy_truncated/, 'the failed opens are gone');
    // The new run's own problem (the same missing image) is shown again, alone.
    assert.deepEqual(status.shownErrors.length, 1, JSON.stringify(status.shownErrors));
    assert.match(status.shownErrors[0], new RegExp(path.basename(gone).replace('.', '\\.')));
    saveScreenshot('messages-5-good-apply.png', await page.screenshot());

    // 5. The 7-Scenes preset on this TUM folder (issue 34, item 2): warnings
    // naming the preset and the depth scale, shown like the errors; the
    // right preset has none.
    await page.locator('#preset').selectOption('7-scenes');
    status = await waitForStatus(page, (s) => s.warnings.some((w) => /depth scale 1000 units\/m looks wrong/.test(w)), { timeoutMs: 60_000 });
    t.diagnostic(`7-scenes preset: ${JSON.stringify(status.warnings)}`);
    assert.ok(status.warnings.some((w) => /preset 7-scenes does not match/.test(w)), JSON.stringify(status.warnings));
    shown = await newestOnScreen(page);
    assert.ok(shown.visible, 'the warning is in the viewport');
    saveScreenshot('messages-6-wrong-preset-warning.png', await page.screenshot());
    await page.locator('#preset').selectOption('tum-fr3');
    status = await waitForStatus(page, (s) => s.warnings.length === 0 && s.done && !s.playing && s.framesProcessed + s.framesFailed === 6, { timeoutMs: 120_000 });
    assert.deepEqual(status.warnings, [], 'the right preset: no warning');
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});
