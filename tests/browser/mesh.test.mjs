// The page's meshes: after the bundled sample (TUM teddy) has played, the
// "Mesh (GLB)" download is a glTF 2.0 binary with a triangle mesh (vertex
// colours, normals) that the Khronos validator accepts with 0 errors, meshed
// in the worker with progress shown; "Mesh (PLY)" announces faces; and the
// "view mesh" toggle draws the mesh instead of the splats without errors.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import validator from 'gltf-validator';
import {
  startBrowser,
  openPage,
  waitForStatus,
  canvasPng,
  decodePng,
  imageStats,
  saveScreenshot,
  skipUnlessReady,
} from './helpers.mjs';

/** Clicks a download button; the file's bytes and suggested name. */
async function download(page, selector) {
  const [d] = await Promise.all([page.waitForEvent('download', { timeout: 120_000 }), page.locator(selector).click()]);
  return { bytes: fs.readFileSync(await d.path()), name: d.suggestedFilename() };
}

/** The GLB's JSON after checking the header and chunk framing. */
function glbJson(bytes) {
  assert.equal(bytes.subarray(0, 4).toString('latin1'), 'glTF', 'starts with the glTF magic');
  assert.equal(bytes.readUInt32LE(4), 2, 'glTF version 2');
  assert.equal(bytes.readUInt32LE(8), bytes.length, 'header length = file length');
  const jsonLength = bytes.readUInt32LE(12);
  assert.equal(bytes.readUInt32LE(16), 0x4e4f534a, 'first chunk is JSON');
  assert.equal(jsonLength % 4, 0, 'JSON chunk 4-byte aligned');
  const json = JSON.parse(bytes.subarray(20, 20 + jsonLength).toString('utf8'));
  const binAt = 20 + jsonLength;
  assert.equal(bytes.readUInt32LE(binAt + 4), 0x004e4942, 'second chunk is BIN');
  assert.equal(binAt + 8 + bytes.readUInt32LE(binAt), bytes.length, 'BIN chunk ends the file');
  return json;
}

test('mesh downloads and the mesh view after the bundled sample', { timeout: 400_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, consoleErrors } = await openPage(env, '/');
    const played = await waitForStatus(page, (s) => s.done || s.framesProcessed >= 44, { timeoutMs: 240_000 });
    t.diagnostic(`sample: ${played.framesProcessed} frames, ${played.surfels} surfels`);
    await waitForStatus(page, (s) => !s.playing, { timeoutMs: 30_000 });

    // Record every progress text the page shows while meshing.
    await page.evaluate(() => {
      window.meshProgressSeen = [];
      const el = document.getElementById('mesh-progress');
      new MutationObserver(() => el.textContent && window.meshProgressSeen.push(el.textContent)).observe(el, {
        childList: true,
        characterData: true,
        subtree: true,
      });
    });

    const clicked = Date.now();
    const glb = await download(page, '#mesh-glb-button');
    t.diagnostic(`${glb.name}: ${glb.bytes.length} bytes in ${Date.now() - clicked} ms (click to download, meshing in the worker), kept as ${saveScreenshot('mesh-sample.glb', glb.bytes)}`);
    assert.match(glb.name, /_mesh\.glb$/);
    const json = glbJson(glb.bytes);
    const primitive = json.meshes[0].primitives[0];
    assert.equal(primitive.mode ?? 4, 4, 'triangles');
    for (const a of ['POSITION', 'NORMAL', 'COLOR_0']) assert.ok(a in primitive.attributes, `${a} attribute`);
    const vertices = json.accessors[primitive.attributes.POSITION].count;
    const triangles = json.accessors[primitive.indices].count / 3;
    t.diagnostic(`GLB mesh: ${vertices} vertices, ${triangles} triangles`);
    assert.ok(vertices > 1000 && triangles > 1000, `a real mesh: ${vertices} vertices, ${triangles} triangles`);
    const report = await validator.validateBytes(new Uint8Array(glb.bytes), { maxIssues: 100 });
    assert.equal(report.issues.numErrors, 0, JSON.stringify(report.issues.messages.slice(0, 5)));

    const progress = await page.evaluate(() => window.meshProgressSeen);
    t.diagnostic(`progress shown: ${progress.join(', ')}`);
    assert.ok(progress.some((p) => /^meshing \d+ %$/.test(p)), `progress shown while meshing: ${progress}`);
    assert.equal(await page.textContent('#mesh-progress'), '', 'progress cleared when done');

    const ply = await download(page, '#mesh-ply-button');
    const header = ply.bytes.subarray(0, 400).toString('latin1');
    const faces = Number(/element face (\d+)/.exec(header)?.[1]);
    assert.ok(header.startsWith('ply\n') && faces === triangles, `PLY mesh with the GLB's ${triangles} faces: ${faces}`);

    const points = await download(page, '#points-glb-button');
    const pointsJson = glbJson(points.bytes);
    assert.equal(pointsJson.meshes[0].primitives[0].mode, 0, 'points');

    // The mesh view: meshed when switched on, drawn instead of the splats.
    await page.waitForFunction(() => document.getElementById('mesh-progress').textContent === '');
    await page.check('#view-mesh');
    const shown = await waitForStatus(page, (s) => s.meshTriangles !== null, { timeoutMs: 120_000 });
    assert.equal(shown.meshTriangles, triangles, 'the view shows the same mesh as the download');
    await page.waitForTimeout(800);
    const png = await canvasPng(page);
    saveScreenshot('mesh-canvas.png', png);
    saveScreenshot('mesh-page.png', await page.screenshot());
    const pixels = imageStats(decodePng(png));
    t.diagnostic(`mesh view: luminance variance ${pixels.variance.toFixed(1)}, ${(pixels.nonBackground * 100).toFixed(1)} % non-background`);
    assert.ok(pixels.variance > 100 && pixels.nonBackground > 0.05, `mesh view not blank: ${JSON.stringify(pixels)}`);

    const status = await waitForStatus(page, () => true);
    assert.equal(status.error, null, `the page reported an error: ${status.error}`);
    assert.deepEqual(consoleErrors, [], 'no console errors');
  } finally {
    await env.close();
  }
});
