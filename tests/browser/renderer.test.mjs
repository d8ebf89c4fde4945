// The WebGL renderer on its own, in headless Chromium: two surfels uploaded
// as the worker uploads them, drawn, and the canvas read back.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { startBrowser, skipUnlessReady } from './helpers.mjs';

/** Red and green pixel counts after drawing a red surfel (confidence 10)
 * and a green one with `confidence`, side by side in front of the default view. */
async function drawnColours(page, confidence) {
  return page.evaluate(async (greenConfidence) => {
    const { Renderer } = await import('/renderer.js');
    const canvas = document.createElement('canvas');
    canvas.style.width = '96px';
    canvas.style.height = '96px';
    document.body.append(canvas);
    const renderer = new Renderer(canvas);
    renderer.updateSurfels({
      count: 2,
      start: 0,
      end: 2,
      positions: new Float32Array([-0.3, 0, 1, 0.3, 0, 1]),
      normals: new Float32Array([0, 0, -1, 0, 0, -1]),
      colours: new Uint8Array([255, 0, 0, 255, 0, 255, 0, 255]),
      radii: new Float32Array([0.1, 0.1]),
      confidences: new Float32Array([10, greenConfidence]),
    });
    renderer.resize();
    renderer.flushUploads();
    renderer.draw();
    const gl = renderer.gl;
    const { width, height } = canvas;
    const pixels = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    canvas.remove();
    let red = 0;
    let green = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      const [r, g] = [pixels[i], pixels[i + 1]];
      if (r > 150 && g < 80) red++;
      if (g > 150 && r < 80) green++;
    }
    return { red, green };
  }, confidence);
}

test('surfels absorbed into others (negative confidence) are not drawn', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    // Any page of the server's origin, so that the module imports resolve.
    const page = await env.context.newPage();
    // The bare documents have no icon link, so Chromium asks for /favicon.ico.
    await page.route('**/favicon.ico', (route) => route.fulfill({ status: 204 }));
    await page.goto(new URL('/renderer.js', env.server.url).href);
    await page.setContent('<!doctype html><body></body>');
    const consoleErrors = [];
    page.on('console', (m) => {
      if (m.type() === 'error') consoleErrors.push(m.text());
    });
    page.on('pageerror', (e) => consoleErrors.push(`pageerror: ${e.message}`));
    const kept = await drawnColours(page, 7);
    assert.ok(kept.red > 0 && kept.green > 0, `both surfels drawn: ${JSON.stringify(kept)}`);
    const absorbed = await drawnColours(page, -1);
    assert.ok(absorbed.red > 0, `the kept surfel is drawn: ${JSON.stringify(absorbed)}`);
    assert.equal(absorbed.green, 0, `the absorbed surfel is hidden: ${JSON.stringify(absorbed)}`);
    assert.deepEqual(consoleErrors, []);
  } finally {
    await env.close();
  }
});
