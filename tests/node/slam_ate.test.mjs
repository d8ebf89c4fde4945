// Slam.ate(groundTruthTum): the ATE of the trajectory so far against the
// ground truth, without the TUM text round trip of
// ateTum(slam.trajectoryTum(), ...). On the bundled teddy clip (always
// present): the error against the real ground truth is small, equals the
// text round trip's to its printed digits, and bad input throws by name.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG, ROOT } from './long_run.mjs';

const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');
const FRAMES = 12;
const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;

const rows = (file) =>
  readFileSync(path.join(CLIP, file), 'utf8')
    .split('\n')
    .filter((l) => l.trim() && !l.startsWith('#'))
    .map((l) => l.split(/\s+/));

test('Slam.ate scores the trajectory against the ground truth', { skip, timeout: 300_000 }, async () => {
  const m = await loadPackage();
  const gt = readFileSync(path.join(CLIP, 'groundtruth.txt'), 'utf8');
  const [rgb, depth] = [rows('rgb.txt'), rows('depth.txt')];
  const slam = new m.Slam({ preset: 'tum-fr3' });
  try {
    assert.throws(() => slam.ate(gt), /pose/i, 'no trajectory yet');
    for (let i = 0; i < FRAMES; i++) {
      const colour = new Uint8Array(readFileSync(path.join(CLIP, rgb[i][1])));
      const d = new Uint8Array(readFileSync(path.join(CLIP, depth[i][1])));
      slam.pushFrame(colour, d, Number(rgb[i][0]));
    }
    const direct = slam.ate(gt);
    const viaText = m.ateTum(slam.trajectoryTum(), gt);
    // The clip keeps every third ground-truth row: most frames have one within 0.02 s.
    assert.ok(direct.pairs >= FRAMES / 2, `${direct.pairs} pairs`);
    assert.equal(direct.pairs, viaText.pairs);
    // The text holds 9 decimals (metres, unit quaternion): the same error to well below a micrometre.
    for (const k of ['rmse', 'mean', 'median', 'max']) {
      assert.ok(Math.abs(direct[k] - viaText[k]) < 1e-7, `${k}: ${direct[k]} vs ${viaText[k]}`);
    }
    assert.ok(direct.rmse > 0 && direct.rmse < 0.02, `ATE ${direct.rmse} m on ${FRAMES} teddy frames`);
    assert.ok(direct.max >= direct.rmse && direct.rmse >= direct.mean * 0.999);

    // A tight maxDt matches fewer poses; bad arguments throw by name.
    assert.ok(slam.ate(gt, 0.005).pairs < direct.pairs);
    assert.throws(() => slam.ate(gt, -1), /maxDt must be a non-negative number/);
    assert.throws(() => slam.ate('1 2 3\n'), /ground truth/);

    // parseReference (the page's "reference...", the CLI's run --reference): the
    // ground truth brought as TUM text, and as a frame-number CSV of each
    // frame's nearest truth pose (a cut-off last row: one warning), scores
    // as the ground truth does.
    const tumRef = m.parseReference(gt, 'groundtruth.txt');
    assert.equal(tumRef.key, 'timestamp');
    assert.deepEqual(tumRef.warnings, []);
    assert.ok(Math.abs(slam.ate(tumRef.tum).rmse - direct.rmse) < 1e-7);
    const truth = rows('groundtruth.txt').map((r) => r.map(Number));
    const stamps = rgb.slice(0, FRAMES).map((r) => Number(r[0]));
    let csv = 'frame, x, y, z, qx, qy, qz, qw\n';
    stamps.forEach((t, i) => {
      const near = truth.reduce((a, b) => (Math.abs(b[0] - t) < Math.abs(a[0] - t) ? b : a));
      if (Math.abs(near[0] - t) <= 0.02) csv += `${i}, ${near.slice(1).join(', ')}\n`;
    });
    const frameRef = m.parseReference(`${csv}${FRAMES}, 0.1, 0.2`, 'ref.csv', stamps);
    assert.equal(frameRef.key, 'frame');
    assert.equal(frameRef.warnings.length, 1);
    assert.match(frameRef.warnings[0], /^ref\.csv, line \d+: the last line is cut off/);
    assert.equal(frameRef.poses.length, direct.pairs);
    const byFrame = slam.ate(frameRef.tum);
    assert.equal(byFrame.pairs, direct.pairs);
    assert.ok(Math.abs(byFrame.rmse - direct.rmse) < 1e-7, `${byFrame.rmse} vs ${direct.rmse}`);
    assert.throws(() => m.parseReference('x, y\n1, 2\n', 'bad.csv'), /bad\.csv, line 1: .*frame/);
  } finally {
    slam.free();
  }
});
