// The statistics panel and the plots show relocalisation and loop closure:
// frame reports as the module gives them (a frame relocalised from a
// keyframe, a loop closure count, the loop stage's time) fed to stats.js and
// plots.js in headless Chromium; the table's text and the verdict strip's
// pixels read back.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { startBrowser, skipUnlessReady, openModulePage } from './helpers.mjs';

test('relocalised frames, loop closures and the loop stage time reach the panel and the verdict strip', { timeout: 120_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env, '<table id="stats"></table><canvas id="error" style="width:200px;height:80px"></canvas>');
    const r = await page.evaluate(async () => {
      const { Stats } = await import('/stats.js');
      const { Plots, VERDICT_COLOURS } = await import('/plots.js');
      const table = document.getElementById('stats');
      const stats = new Stats(table);
      const plots = new Plots({ error: document.getElementById('error') });
      const verdicts = ['tracked', 'tracked', 'lost', 'lost', 'recovered', 'held', 'tracked', 'restarted'];
      const rows = () => Object.fromEntries([...table.rows].map((tr) => [tr.cells[0].textContent.trim(), tr.cells[1].textContent]));
      let withoutLoop = null;
      verdicts.forEach((verdict, index) => {
        const relocalisedFrom = index === 4 ? 1 : null;
        const loop = index >= 6; // a module with the loop stage from frame 6 on
        const timings = { decode: 1, preprocess: 1, track: 2, fuse: 3, predict: 1, total: 8, ...(loop ? { loop: 4 } : {}) };
        const loopDecision = index === 6 ? 'local refused: free-space (frame 6)' : null;
        const cameraFixedShare = index === 5 || index === 6 ? 0.125 : 0; // a hand in view on frames 5 and 6
        const result = { verdict, relocalisedFrom, timings, surfels: 100, cameraFixedShare, ...(loop ? { loopClosures: index === 7 ? 1 : 0, globalLoopClosures: index === 7 ? 1 : 0, loopDecision } : {}) };
        stats.onFrame({ index, frameCount: verdicts.length, result, surfels: { count: 100, start: 0, end: 0 }, timing: { wall: 9 } });
        plots.add(index, timings, 100, 0.01, { verdict, relocalised: relocalisedFrom !== null, loopClosed: index === 7 });
        if (index === 5) withoutLoop = rows();
      });
      plots.draw();
      const canvas = document.getElementById('error');
      const ctx = canvas.getContext('2d');
      const hex = (c) => [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16));
      const seen = {};
      const data = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
      for (const [name, colour] of Object.entries(VERDICT_COLOURS)) {
        const [r, g, b] = hex(colour);
        let n = 0;
        for (let i = 0; i < data.length; i += 4) if (Math.abs(data[i] - r) < 3 && Math.abs(data[i + 1] - g) < 3 && Math.abs(data[i + 2] - b) < 3) n++;
        seen[name] = n;
      }
      return { rows: rows(), withoutLoop, seen, marks: plots.marks, strip: Array.from(plots.verdicts.subarray(0, verdicts.length)) };
    });
    assert.equal(r.rows['relocalised'], '1 (last: frame 4, placed by the keyframe of frame 1)');
    assert.equal(r.rows['loop closures'], '1 (1 global)');
    assert.equal(r.rows['last loop decision'], 'local refused: free-space (frame 6)', 'the last decision stays when a frame checks nothing');
    assert.equal(r.withoutLoop['last loop decision'], undefined, 'no decision row before the module reports loop closure');
    // The window's mean: 4 ms on the last two of its eight frames.
    assert.equal(r.rows['loop'], '1.0', 'the loop stage time once reported');
    assert.equal(r.withoutLoop['loop closures'], '–', 'no count before the module reports one');
    assert.equal(r.withoutLoop['loop'], undefined, 'no loop stage row before the module reports one');
    assert.equal(r.rows['tracked / held / lost / recovered / restarted'], '3 / 1 / 2 / 1 / 1');
    assert.equal(r.withoutLoop['masked as carried with the camera'], '1 frame (this one: 12.5 % of the image)');
    assert.equal(r.rows['masked as carried with the camera'], '2 frames (this one: 0.0 % of the image)', 'the count stays when the mask ends');
    assert.deepEqual(r.marks, [
      { frame: 4, kind: 'relocalised' },
      { frame: 7, kind: 'loop' },
    ]);
    // tracked 1, held 3, relocalised 5, restarted 6, lost 7 (VERDICT_CODES order + 1).
    assert.deepEqual(r.strip, [1, 1, 7, 7, 5, 3, 1, 6]);
    for (const name of ['tracked', 'held', 'lost', 'relocalised', 'restarted']) assert.ok(r.seen[name] > 0, `${name} drawn in the strip: ${JSON.stringify(r.seen)}`);
    assert.equal(r.seen.recovered, 0, 'the relocalised frame is shown as relocalised, not only recovered');
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
  }
});
