// The WebGL renderer on its own, in headless Chromium: surfels uploaded as
// the worker uploads them, drawn, and the canvas read back.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { startBrowser, skipUnlessReady, openModulePage } from './helpers.mjs';

/**
 * Draws `surfels` ({positions: [x, y, z, ...], colours: [r, g, b, a, ...],
 * radii, confidences}; normals face the camera) on a `size`-pixel square
 * canvas in front of the default view, with the renderer playing
 * (`playing`, drawing within `budget` splats) or not. Returns the splats
 * drawn, the red and green pixel counts and the red pixels' bounding box.
 */
async function draw(page, surfels, { size = 96, budget = 0, playing = false } = {}) {
  return page.evaluate(
    async ({ surfels, size, budget, playing }) => {
      const { Renderer } = await import('/renderer.js');
      const canvas = document.createElement('canvas');
      canvas.style.width = `${size}px`;
      canvas.style.height = `${size}px`;
      document.body.append(canvas);
      const renderer = new Renderer(canvas);
      const n = surfels.radii.length;
      renderer.updateSurfels({
        count: n,
        start: 0,
        end: n,
        positions: new Float32Array(surfels.positions),
        normals: new Float32Array(3 * n).map((_, j) => (j % 3 === 2 ? -1 : 0)),
        colours: new Uint8Array(surfels.colours),
        radii: new Float32Array(surfels.radii),
        confidences: new Float32Array(surfels.confidences),
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
      const out = { splats: renderer.splatsDrawn, red: 0, green: 0, box: { minX: width, maxX: -1, minY: height, maxY: -1 } };
      for (let i = 0; i < pixels.length; i += 4) {
        const [r, g] = [pixels[i], pixels[i + 1]];
        if (g > 150 && r < 80) out.green++;
        if (r > 150 && g < 80) {
          out.red++;
          const [x, y] = [(i / 4) % width, Math.floor(i / 4 / width)];
          out.box = {
            minX: Math.min(out.box.minX, x),
            maxX: Math.max(out.box.maxX, x),
            minY: Math.min(out.box.minY, y),
            maxY: Math.max(out.box.maxY, y),
          };
        }
      }
      return out;
    },
    { surfels, size, budget, playing },
  );
}

/** A red surfel (confidence 10) and a green one with `confidence`, side by side. */
const redAndGreen = (confidence) => ({
  positions: [-0.3, 0, 1, 0.3, 0, 1],
  colours: [255, 0, 0, 255, 0, 255, 0, 255],
  radii: [0.1, 0.1],
  confidences: [10, confidence],
});

/** A 20 x 20 grid of red surfels 2 cm apart (1 cm radius), row by row, 1.5 m away. */
function redGrid() {
  const positions = [];
  for (let i = 0; i < 400; i++) positions.push(((i % 20) - 9.5) * 0.02, (Math.floor(i / 20) - 9.5) * 0.02, 1.5);
  return {
    positions,
    colours: Array.from({ length: 400 }, () => [255, 0, 0, 255]).flat(),
    radii: new Array(400).fill(0.01),
    confidences: new Array(400).fill(10),
  };
}

test('surfels absorbed into others (negative confidence) are not drawn', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env);
    const kept = await draw(page, redAndGreen(7));
    assert.ok(kept.red > 0 && kept.green > 0, `both surfels drawn: ${JSON.stringify(kept)}`);
    const absorbed = await draw(page, redAndGreen(-1));
    assert.ok(absorbed.red > 0, `the kept surfel is drawn: ${JSON.stringify(absorbed)}`);
    assert.equal(absorbed.green, 0, `the absorbed surfel is hidden: ${JSON.stringify(absorbed)}`);
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
  }
});

test('while SLAM runs the map is drawn within the splat budget, covering the same surfaces', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env);
    const grid = redGrid();
    const whole = await draw(page, grid, { size: 128, budget: 100, playing: false });
    const bounded = await draw(page, grid, { size: 128, budget: 100, playing: true });
    const unbounded = await draw(page, grid, { size: 128, budget: 0, playing: true });
    t.diagnostic(`whole ${JSON.stringify(whole)}; bounded ${JSON.stringify(bounded)}; no budget ${JSON.stringify(unbounded)}`);
    assert.equal(whole.splats, 400, 'idle: the whole map');
    assert.equal(unbounded.splats, 400, 'budget 0: the whole map');
    assert.equal(bounded.splats, 100, 'playing: every 4th surfel');
    assert.ok(whole.red > 0);
    // Every 4th surfel at twice the radius covers the same patch (the
    // first 100 surfels alone would cover its bottom quarter only).
    assert.ok(bounded.red > 0.6 * whole.red && bounded.red < 1.6 * whole.red, `${bounded.red} vs ${whole.red} red pixels`);
    for (const k of ['minX', 'maxX', 'minY', 'maxY']) {
      assert.ok(Math.abs(bounded.box[k] - whole.box[k]) <= 4, `${k}: ${bounded.box[k]} vs ${whole.box[k]}`);
    }
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
  }
});

/** Red pixels of the renderer's canvas: their count and bounding box as fractions of the canvas. */
async function redExtent(page) {
  return page.evaluate(() => {
    const { gl, canvas } = window.testRenderer;
    const { width, height } = canvas;
    const pixels = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    let red = 0, minX = width, maxX = -1, minY = height, maxY = -1;
    for (let i = 0; i < pixels.length; i += 4) {
      if (!(pixels[i] > 150 && pixels[i + 1] < 80)) continue;
      red++;
      const [x, y] = [(i / 4) % width, Math.floor(i / 4 / width)];
      [minX, maxX, minY, maxY] = [Math.min(minX, x), Math.max(maxX, x), Math.min(minY, y), Math.max(maxY, y)];
    }
    return { red, width: red ? (maxX - minX + 1) / width : 0, height: red ? (maxY - minY + 1) / height : 0 };
  });
}

test('Fit map fills the view with the map, stray surfels far off left out; clear() empties the view at once', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env);
    await page.evaluate(async () => {
      const { Renderer } = await import('/renderer.js');
      const canvas = document.createElement('canvas');
      canvas.style.width = '240px';
      canvas.style.height = '160px';
      document.body.append(canvas);
      const renderer = new Renderer(canvas);
      // A 1 m x 0.5 m red wall 2 m in front of the first camera (5 mm apart), and 20 stray surfels 40 m off.
      const wall = [];
      for (let i = 0; i < 200; i++) for (let j = 0; j < 100; j++) wall.push(-0.5 + i * 0.005, -0.25 + j * 0.005, 2);
      for (let k = 0; k < 20; k++) wall.push(40, -30, 45);
      const n = wall.length / 3;
      renderer.updateSurfels({
        count: n, start: 0, end: n,
        positions: new Float32Array(wall),
        normals: new Float32Array(3 * n).map((_, j) => (j % 3 === 2 ? -1 : 0)),
        colours: new Uint8Array(4 * n).map((_, j) => (j % 4 === 0 || j % 4 === 3 ? 255 : 0)),
        radii: new Float32Array(n).fill(0.004),
        confidences: new Float32Array(n).fill(10),
      });
      renderer.setCameraPose(new Float64Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]));
      renderer.resize();
      renderer.flushUploads();
      window.testRenderer = renderer;
    });
    const draw = () => page.evaluate(() => window.testRenderer.draw());
    await draw();
    const before = await redExtent(page);
    await page.evaluate(() => window.testRenderer.fitView());
    await draw();
    const fitted = await redExtent(page);
    t.diagnostic(`wall before Fit map: ${JSON.stringify(before)}; after: ${JSON.stringify(fitted)}`);
    // The wall's 2:1 in a 3:2 view: its width fills the view's.
    assert.ok(fitted.width > 0.85, `the map fills the view's width: ${fitted.width.toFixed(2)}`);
    assert.ok(fitted.height > 0.35 && fitted.height < 1, `and keeps its shape: height ${fitted.height.toFixed(2)}`);

    // A new sequence: the old map goes from the view at once, even while a
    // slow GPU (4 x 5 s) would hold the next throttled draw back.
    const cleared = await page.evaluate(() => {
      const r = window.testRenderer;
      r.throttle = true;
      r.gpuMs = 5000;
      r.lastDrawAt = performance.now();
      r.clear();
      return { splatsDrawn: r.splatsDrawn, count: r.count };
    });
    const after = await redExtent(page);
    assert.deepEqual(cleared, { splatsDrawn: 0, count: 0 });
    assert.equal(after.red, 0, 'nothing of the old map is left on the canvas');
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
  }
});
