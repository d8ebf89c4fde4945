// Every bad input of issue 7 through the wasm API (the built npm package),
// the way the page and Node users call it: each throws an Error whose
// message names the problem (and the file, where the API is given file
// names), and the same Slam keeps accepting good frames afterwards.
// Frames come from the bundled sample clip (in the repo, always present).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG, ROOT } from './long_run.mjs';
import { encodePng } from './png.mjs';

const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');

function rows(file) {
  return readFileSync(path.join(CLIP, file), 'utf8')
    .split('\n')
    .filter((l) => l.trim() && !l.startsWith('#'));
}

const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;

test('bad frames and settings throw a clear Error; the Slam keeps working', { skip, timeout: 300_000 }, async (t) => {
  const m = await loadPackage();
  const frame = (i) => {
    const c = rows('rgb.txt')[i].split(/\s+/)[1];
    const d = rows('depth.txt')[i].split(/\s+/)[1];
    return [new Uint8Array(readFileSync(path.join(CLIP, c))), new Uint8Array(readFileSync(path.join(CLIP, d)))];
  };
  const answers = [];
  const expectThrow = (name, fn, pattern) => {
    let message = null;
    try {
      fn();
    } catch (e) {
      message = e.message;
    }
    answers.push(`| ${name} | ${message} |`);
    assert.ok(message !== null, `${name}: did not throw`);
    assert.match(message, pattern, name);
  };

  // Settings.
  expectThrow('non-finite intrinsics (fx NaN)', () => new m.Slam({ preset: 'tum-fr3', fx: NaN }), /config\.fx must be a finite number/);
  expectThrow('absurd intrinsics (fx 0.5354)', () => new m.Slam({ preset: 'tum-fr3', fx: 0.5354 }), /fx = 0\.5354 px is not a plausible focal length/);
  expectThrow('absurd principal point (cy 1e9)', () => new m.Slam({ preset: 'tum-fr3', cy: 1e9 }), /cy = .* outside the 640x480 image/);
  expectThrow('depth scale 0', () => new m.Slam({ preset: 'tum-fr3', depthScale: 0 }), /depth scale must be a positive number/);

  const slam = new m.Slam({ preset: 'tum-fr3' });
  try {
    let i = 0;
    const good = () => {
      const [c, d] = frame(i);
      const r = slam.pushFrame(c, d, i++);
      assert.ok(['initialised', 'tracked', 'held'].includes(r.verdict), `good frame after an error: ${r.verdict}`);
      return r;
    };
    good();
    const [colour, depth] = frame(1);
    const bad = [
      ['corrupt colour PNG', () => slam.pushFrame(new TextEncoder().encode('not a PNG at all'.repeat(9)), depth, 50), /colour image could not be decoded/],
      ['truncated depth PNG', () => slam.pushFrame(colour, depth.subarray(0, depth.length >> 1), 50), /depth image could not be decoded/],
      ['8-bit depth PNG', () => slam.pushFrame(colour, encodePng(640, 480, 1, 8, 77), 50), /depth image must be a 16-bit single-channel PNG, found L8/],
      ['RGB depth PNG', () => slam.pushFrame(colour, colour, 50), /depth image must be a 16-bit single-channel PNG, found Rgb8/],
      ['colour/depth size mismatch', () => slam.pushFrame(encodePng(320, 240, 3, 8, 9), depth, 50), /colour is 320x240 but depth is 640x480/],
      [
        'frame size differs from the sequence\'s',
        () => slam.pushFrame(encodePng(320, 240, 3, 8, 9), encodePng(320, 240, 1, 16, 5000), 50),
        /frame is 320x240 but the sequence is 640x480/,
      ],
      ['raw frame of the wrong size', () => slam.pushRaw(320, 240, new Uint8Array(320 * 240 * 4), new Uint16Array(320 * 240), 50), /frame is 320x240/],
      ['forged PNG size (16384x16384)', () => slam.pushFrame(colour, encodePng(4, 4, 1, 16, 0, [16384, 16384]), 50), /image size 16384x16384 is not supported/],
      ['non-finite timestamp', () => slam.pushFrame(colour, depth, NaN), /timestamp must be a finite number/],
    ];
    for (const [name, fn, pattern] of bad) {
      const before = slam.surfelCount;
      expectThrow(name, fn, pattern);
      assert.equal(slam.surfelCount, before, `${name}: the map changed`);
      good();
    }
    assert.equal(good().counts.lost, 0);
    // A frame without depth: lost, not fused; the next one is re-acquired.
    const before = slam.surfelCount;
    const [c, d] = frame(i);
    const blank = slam.pushFrame(c, encodePng(640, 480, 1, 16, 0), i++);
    assert.equal(blank.verdict, 'lost');
    assert.equal(blank.lostReason, 'too-few-inliers');
    assert.equal(slam.surfelCount, before, 'a lost frame was fused');
    const back = slam.pushFrame(c, d, i++);
    assert.equal(back.verdict, 'recovered');
    assert.deepEqual(back.counts, { tracked: i - 2, lost: 1, recovered: 1, held: 0, restarted: 0, lostStreak: 0 });
    assert.ok(slam.positions().every(Number.isFinite));
  } finally {
    slam.free();
  }

  // Folders (file names and index texts, as the page reads them).
  const names = ['teddy/rgb.txt', 'teddy/depth.txt', 'teddy/groundtruth.txt'];
  const rgbRows = rows('rgb.txt').slice(0, 3);
  const depthRows = rows('depth.txt').slice(0, 3);
  for (const r of [...rgbRows, ...depthRows]) names.push(`teddy/${r.split(/\s+/)[1]}`);
  const texts = {
    'teddy/rgb.txt': rgbRows.join('\n'),
    'teddy/depth.txt': depthRows.join('\n'),
    'teddy/groundtruth.txt': rows('groundtruth.txt').slice(0, 20).join('\n'),
  };
  assert.equal(m.parseSequence(names, texts, 'teddy').frames.length, 3, 'the good listing parses');
  expectThrow('empty folder', () => m.detectLayout([]), /the folder is empty/);
  expectThrow('folder in no known layout', () => m.detectLayout(['holiday_photos/beach.jpg', 'holiday_photos/notes.txt']), /unrecognised dataset layout.*holiday_photos\/beach\.jpg/);
  const missing = names.filter((n) => n !== `teddy/${depthRows[1].split(/\s+/)[1]}`);
  // A file listed but missing skips its frame (half-copied datasets); no frame left is an error.
  const halfCopied = m.parseSequence(missing, texts, 'teddy');
  assert.match(halfCopied.frames[1].missing, /teddy\/depth\/\S+\.png is missing \(listed in teddy\/depth\.txt\)/);
  assert.equal(halfCopied.frames[0].missing, null);
  const noDepth = names.filter((n) => !n.startsWith('teddy/depth/'));
  expectThrow('every frame misses a file listed in an index', () => m.parseSequence(noDepth, texts, 'teddy'), /none of the 3 frames listed can be read: teddy\/depth\/\S+\.png is missing \(listed in teddy\/depth\.txt\)/);
  const oops = '\n1341841873.5 1.0 2.0 oops 0 0 0 1';
  const lastGt = rows('groundtruth.txt')[20];
  const badGt = { ...texts, 'teddy/groundtruth.txt': `${texts['teddy/groundtruth.txt']}${oops}\n${lastGt}` };
  expectThrow('malformed ground-truth line', () => m.parseSequence(names, badGt, 'teddy'), /groundtruth\.txt, line 21: .*oops/);
  // The same line last is a recording cut short: skipped, with a warning naming it.
  const cutGt = m.parseSequence(names, { ...texts, 'teddy/groundtruth.txt': texts['teddy/groundtruth.txt'] + oops }, 'teddy');
  assert.equal(cutGt.groundTruth.length, 20);
  assert.deepEqual(cutGt.warnings.map((w) => w.replace(/:.*/, '')), ['teddy/groundtruth.txt, line 21']);
  t.diagnostic(`wasm API answers:\n${answers.join('\n')}`);
});
