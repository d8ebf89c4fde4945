// 7-Scenes ground truth through parseSequence: a small 7-Scenes-layout folder
// built from the bundled clip (frame-NNNNNN.color.png / .depth.png /
// .pose.txt, poses from the clip's ground truth). detectLayout lists the pose
// files as index files; parseSequence turns their texts into the ground truth
// (checked against the poses written), ready for ateTum. Also: a half-copied
// folder (an image missing) keeps its other frames; none left is an Error.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { CLIP, listTree, makeSevenScenes, tempDir } from './datasets.mjs';

const skip = fs.existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;
const FRAMES = 10;

test('parseSequence returns 7-Scenes ground truth from the pose files', { skip, timeout: 120_000 }, async (t) => {
  const m = await loadPackage();
  const tmp = tempDir('surfel-slam-7scenes-');
  try {
    const { dir, poses } = makeSevenScenes(CLIP, FRAMES, tmp);
    const names = listTree(dir);
    const layout = m.detectLayout(names);
    assert.equal(layout.kind, '7-scenes');
    assert.equal(layout.indexFiles.length, FRAMES);
    assert.ok(layout.indexFiles.every((f) => f.endsWith('.pose.txt')));
    const texts = {};
    for (const f of layout.indexFiles) texts[f] = fs.readFileSync(path.join(dir, f), 'utf8');
    const seq = m.parseSequence(names, texts, 'seven_scenes_teddy');
    assert.equal(seq.preset, '7-scenes');
    assert.equal(seq.frames.length, FRAMES);
    assert.equal(seq.groundTruth.length, FRAMES);
    for (let i = 0; i < FRAMES; i++) {
      const row = Array.from(seq.groundTruth[i]);
      const want = poses[i];
      assert.equal(row[0], i, 'timestamps are frame numbers');
      for (let k = 1; k <= 3; k++) assert.ok(Math.abs(row[k] - want[k]) < 1e-9, `frame ${i} translation`);
      // Same rotation: q and -q alike.
      const dot = row[4] * want[4] + row[5] * want[5] + row[6] * want[6] + row[7] * want[7];
      const norm = Math.hypot(want[4], want[5], want[6], want[7]);
      assert.ok(Math.abs(Math.abs(dot) / norm - 1) < 1e-9, `frame ${i} rotation`);
      assert.equal(seq.frames[i].missing, null);
    }
    assert.ok(seq.groundTruthTum.split('\n').filter((l) => l && !l.startsWith('#')).length === FRAMES);
    assert.ok(m.ateTum(seq.groundTruthTum, seq.groundTruthTum).rmse < 1e-9);
    // Pose texts not given: the frames, without ground truth (as before).
    assert.equal(m.parseSequence(names, {}, 'x').groundTruth.length, 0);

    // The frames track at the 7-Scenes preset and the ATE comes out.
    const slam = new m.Slam(seq.preset);
    try {
      for (const f of seq.frames) {
        slam.pushFrame(new Uint8Array(fs.readFileSync(path.join(dir, f.colour))), new Uint8Array(fs.readFileSync(path.join(dir, f.depth))), f.timestamp);
      }
      const ate = m.ateTum(slam.trajectoryTum(), seq.groundTruthTum);
      t.diagnostic(`7-Scenes from the clip: ${FRAMES} frames, ATE ${(ate.rmse * 100).toFixed(2)} cm over ${ate.pairs} poses (preset fx 585 vs the clip's 535)`);
      assert.equal(ate.pairs, FRAMES);
      assert.ok(ate.rmse < 0.05, `ATE ${ate.rmse} m`);
    } finally {
      slam.free();
    }

    // Half-copied: frame 3's colour image absent.
    const half = names.filter((n) => n !== 'seq-01/frame-000003.color.png');
    const halfSeq = m.parseSequence(half, texts, 'x');
    assert.equal(halfSeq.frames.length, FRAMES);
    assert.match(halfSeq.frames[3].missing, /seq-01\/frame-000003\.color\.png is missing/);
    assert.equal(halfSeq.frames[2].missing, null);
    // No frame left with both images: an Error naming a missing file.
    const noColour = names.filter((n) => !n.endsWith('.color.png') || n.endsWith('000000.color.png'));
    const onlyDepth = noColour.filter((n) => n !== 'seq-01/frame-000000.depth.png');
    assert.throws(() => m.parseSequence(onlyDepth, texts, 'x'), /none of the \d+ frames listed can be read: seq-01\/frame-0000\d\d\.(color|depth)\.png is missing/);
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('a half-copied TUM listing keeps its readable frames', { skip }, async () => {
  const m = await loadPackage();
  const names = ['rgb.txt', 'depth.txt', 'rgb/1.png', 'depth/1.png', 'depth/2.png'];
  const texts = { 'rgb.txt': '1 rgb/1.png\n2 rgb/2.png\n', 'depth.txt': '1 depth/1.png\n2 depth/2.png\n' };
  const seq = m.parseSequence(names, texts, 'x');
  assert.equal(seq.frames.length, 2);
  assert.equal(seq.frames[0].missing, null);
  assert.equal(seq.frames[1].missing, 'rgb/2.png is missing (listed in rgb.txt)');
  assert.throws(() => m.parseSequence(['rgb.txt', 'depth.txt'], texts, 'x'), /none of the 2 frames listed can be read: rgb\/1\.png is missing \(listed in rgb\.txt\)/);
});
