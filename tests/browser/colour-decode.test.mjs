// The worker decodes colour images with the browser (createImageBitmap and an
// OffscreenCanvas) and only depth in wasm: the pixels are exactly the file's,
// the page says who decoded each frame's colour, and a colour file the
// browser cannot decode (or not exactly: translucent, 16-bit) goes to the
// wasm decoder, which either processes it or names the file in its message.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { REPO, startBrowser, openPage, waitForStatus, decodePng, makeTumClip, skipUnlessReady } from './helpers.mjs';
import { encodePng } from '../node/png.mjs';

const SAMPLE = path.join(REPO, 'www/sample/tum_fr3_teddy_clip');

test('colour is decoded by the browser, exactly; bad colour files are still named', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const clip = makeTumClip(SAMPLE, 6, 'rgbd_dataset_freiburg3_colour_cases');
  const write = (rel, bytes) => fs.writeFileSync(path.join(clip.dir, rel), bytes);
  write(clip.colour[2], Buffer.from('not a PNG, whatever the name says'.repeat(40))); // corrupt
  write(clip.colour[3], encodePng(640, 480, 4, 8, 90)); // translucent RGBA: decoded in wasm
  write(clip.colour[4], encodePng(640, 480, 3, 16, 40000)); // 16-bit RGB: decoded in wasm

  const env = await startBrowser();
  try {
    const { page, consoleErrors } = await openPage(env, '/?sample=0');
    const ready = await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    assert.equal(ready.frameReader, true, 'frames are read and decoded by a worker of their own');

    // The browser's pixels are the file's own (no colour management, no
    // premultiplication): the same as a plain PNG decoder's.
    const sampleColour = fs.readFileSync(path.join(SAMPLE, fs.readdirSync(path.join(SAMPLE, 'rgb')).sort().map((f) => `rgb/${f}`)[0]));
    const reference = decodePng(sampleColour);
    const browser = await page.evaluate(async (bytes) => {
      const { decodeColour } = await import('/colour-decode.js');
      const { width, height, rgba } = await decodeColour(new Uint8Array(bytes).buffer);
      return { width, height, rgba: Array.from(rgba) };
    }, Array.from(sampleColour));
    assert.deepEqual([browser.width, browser.height], [reference.width, reference.height]);
    let differing = 0;
    for (let i = 0, j = 0; i < reference.width * reference.height; i++, j += reference.channels) {
      for (let c = 0; c < 3; c++) if (browser.rgba[4 * i + c] !== reference.data[j + c]) differing++;
      if (browser.rgba[4 * i + 3] !== 255) differing++;
    }
    assert.equal(differing, 0, 'browser-decoded colour equals the PNG decoder');

    // A sequence with a corrupt, a translucent and a 16-bit colour image.
    await page.locator('#folder-input').setInputFiles(clip.dir);
    const status = await waitForStatus(page, (s) => s.done && !s.playing, { timeoutMs: 240_000 });
    t.diagnostic(`errors: ${JSON.stringify(status.errors)}; colour decoded in the browser for ${status.framesColourDecodedInBrowser} frames`);
    const bad = path.basename(clip.colour[2]);
    assert.ok(
      status.errors.some((e) => e.includes(bad) && /colour image could not be decoded/.test(e)),
      `an error names the corrupt colour file ${bad}: ${JSON.stringify(status.errors)}`,
    );
    assert.equal(status.framesFailed, 1, 'only the corrupt frame was skipped');
    assert.equal(status.framesProcessed, 5, 'the translucent and 16-bit colour frames were processed (by wasm)');
    assert.equal(status.framesColourDecodedInBrowser, 3, 'the three ordinary colour images were decoded by the browser');
    assert.equal(status.colourDecoder, 'browser', 'the last frame (ordinary) was decoded by the browser');
    assert.ok(status.surfels > 0, 'the map is built');
    assert.deepEqual(consoleErrors, [], 'no console errors');
  } finally {
    await env.close();
    fs.rmSync(clip.parent, { recursive: true, force: true });
  }
});
