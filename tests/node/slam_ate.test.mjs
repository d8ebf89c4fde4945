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
  } finally {
    slam.free();
  }
});
