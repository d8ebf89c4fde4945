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

/** Draws a 20 x 20 grid of red surfels (2 cm apart, 1 cm radius, 1.5 m in
 * front of the default view) with the renderer playing (`throttle`) or
 * not, under a splat budget; returns the splats drawn, the red pixels and
 * their bounding box. */
async function drawnGrid(page, { budget, playing }) {
  return page.evaluate(
    async ({ budget, playing }) => {
      const { Renderer } = await import('/renderer.js');
      const canvas = document.createElement('canvas');
      canvas.style.width = '128px';
      canvas.style.height = '128px';
      document.body.append(canvas);
      const renderer = new Renderer(canvas);
      const n = 400;
      const positions = new Float32Array(3 * n);
      for (let i = 0; i < n; i++) positions.set([((i % 20) - 9.5) * 0.02, (Math.floor(i / 20) - 9.5) * 0.02, 1.5], 3 * i);
      renderer.updateSurfels({
        count: n,
        start: 0,
        end: n,
        positions,
        normals: new Float32Array(3 * n).map((_, j) => (j % 3 === 2 ? -1 : 0)),
        colours: new Uint8Array(4 * n).map((_, j) => (j % 4 === 1 || j % 4 === 2 ? 0 : 255)),
        radii: new Float32Array(n).fill(0.01),
        confidences: new Float32Array(n).fill(10),
      });
      renderer.splatBudget = budget;
      renderer.throttle = playing;
      renderer.resize();
      renderer.flushUploads();
      renderer.draw();
      const gl = renderer.gl;
      const { width, height } = canvas;
      const pixels = new Uint8Array(width * height * 4);
      gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
      canvas.remove();
      let red = 0;
      const box = { minX: width, maxX: -1, minY: height, maxY: -1 };
      for (let i = 0; i < pixels.length; i += 4) {
        if (pixels[i] > 150 && pixels[i + 1] < 80) {
          red++;
          const x = (i / 4) % width;
          const y = Math.floor(i / 4 / width);
          box.minX = Math.min(box.minX, x);
          box.maxX = Math.max(box.maxX, x);
          box.minY = Math.min(box.minY, y);
          box.maxY = Math.max(box.maxY, y);
        }
      }
      return { splats: renderer.splatsDrawn, red, box };
    },
    { budget, playing },
  );
}

test('while SLAM runs the map is drawn within the splat budget, covering the same surfaces', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const page = await env.context.newPage();
    await page.route('**/favicon.ico', (route) => route.fulfill({ status: 204 }));
    await page.goto(new URL('/renderer.js', env.server.url).href);
    await page.setContent('<!doctype html><body></body>');
    const whole = await drawnGrid(page, { budget: 100, playing: false });
    const bounded = await drawnGrid(page, { budget: 100, playing: true });
    const unbounded = await drawnGrid(page, { budget: 0, playing: true });
    t.diagnostic(`whole ${JSON.stringify(whole)}; bounded ${JSON.stringify(bounded)}; no budget ${JSON.stringify(unbounded)}`);
    assert.equal(whole.splats, 400, 'idle: the whole map');
    assert.equal(unbounded.splats, 400, 'budget 0: the whole map');
    assert.equal(bounded.splats, 100, 'playing: every 4th surfel');
    assert.ok(whole.red > 0);
    // Every 4th surfel at twice the radius covers the same patch.
    assert.ok(bounded.red > 0.6 * whole.red && bounded.red < 1.6 * whole.red, `${bounded.red} vs ${whole.red} red pixels`);
    for (const k of ['minX', 'maxX', 'minY', 'maxY']) {
      assert.ok(Math.abs(bounded.box[k] - whole.box[k]) <= 4, `${k}: ${bounded.box[k]} vs ${whole.box[k]}`);
    }
  } finally {
    await env.close();
  }
});
