// The RealSense (Open3D recorder) and Stray Scanner layouts through the npm
// package's detectLayout / parseSequence, from file listings and the index
// texts alone: the kinds and presets, the intrinsics (column-major JSON; a
// camera matrix at 1920x1440 scaled to the 256x192 depth), the frames'
// timestamps, confidence and missing colour, the device's odometry (not
// ground truth), and the errors that name a malformed file; and both played
// end to end from folders written from the bundled clip, as a Node user
// would read them, against the clip's ground truth.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { openSequence } from './sequence.mjs';

const skip = fs.existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;
const num = (i) => String(i).padStart(6, '0');

test('a RealSense recording: the file intrinsics, column-major, and file numbers as timestamps', { skip }, async () => {
  const m = await loadPackage();
  const names = ['rs/camera_intrinsic.json', 'rs/realsense.bag', 'rs/scene/integrated.ply'];
  for (const i of [0, 1, 2]) names.push(`rs/color/${num(i)}.jpg`, `rs/depth/${num(i)}.png`);
  const layout = m.detectLayout(names);
  assert.equal(layout.kind, 'realsense');
  assert.deepEqual(layout.indexFiles, ['rs/camera_intrinsic.json']);
  const json = JSON.stringify({ width: 848, height: 480, intrinsic_matrix: [421.0, 0, 0, 0, 420.5, 0, 423.9, 241.2, 1] });
  const seq = m.parseSequence(names, { 'rs/camera_intrinsic.json': json }, 'rs');
  assert.equal(seq.preset, 'realsense-d400');
  const k = seq.intrinsics;
  assert.deepEqual([k.fx, k.fy, k.cx, k.cy, k.width, k.height].map((v) => Math.round(v * 10) / 10), [421, 420.5, 423.9, 241.2, 848, 480]);
  assert.deepEqual(seq.frames.map((f) => f.timestamp), [0, 1, 2]);
  assert.equal(seq.frames[1].colour, 'rs/color/000001.jpg');
  assert.equal(seq.groundTruth.length, 0);
  // A row-major matrix (fx, 0, cx in the first row) is refused, naming the file.
  const rowMajor = JSON.stringify({ width: 848, height: 480, intrinsic_matrix: [421.0, 0, 423.9, 0, 420.5, 241.2, 0, 0, 1] });
  assert.throws(() => m.parseSequence(names, { 'rs/camera_intrinsic.json': rowMajor }, 'rs'), /camera_intrinsic\.json/);
});

test('a Stray Scanner export: scaled intrinsics, confidence, depth only, odometry as a reference', { skip }, async () => {
  const m = await loadPackage();
  const frames = 4;
  const names = ['s/camera_matrix.csv', 's/odometry.csv', 's/rgb.mp4', 's/imu.csv'];
  for (let i = 0; i < frames; i++) names.push(`s/depth/${num(i)}.png`, `s/confidence/${num(i)}.png`);
  const layout = m.detectLayout(names);
  assert.equal(layout.kind, 'stray-scanner');
  const matrix = '1440.0, 0.0, 960.0\n0.0, 1440.0, 720.0\n0.0, 0.0, 1.0942\n';
  // 15 columns, the distortion centre empty; one row fewer than frames.
  let odometry = 'timestamp, frame, x, y, z, qx, qy, qz, qw, fx, fy, cx, cy, distortion_center_x, distortion_center_y\n';
  for (let i = 0; i < frames - 1; i++) odometry += `${10 + i / 60}, ${i}, ${0.01 * i}, 0, 0, 0, 0, 0, 1, 1440, 1440, 960, 720, ,\n`;
  const texts = { 's/camera_matrix.csv': matrix, 's/odometry.csv': odometry };
  const seq = m.parseSequence(names, texts, 's');
  assert.equal(seq.preset, 'stray-lidar');
  const k = seq.intrinsics;
  const scale = 256 / 1920;
  assert.ok(Math.abs(k.fx - 1440 * scale) < 1e-3 && Math.abs(k.cx - 960 * scale) < 1e-3, JSON.stringify(k));
  assert.deepEqual([k.width, k.height], [256, 192]);
  assert.equal(seq.frames.length, frames);
  assert.ok(seq.frames.every((f) => f.colour === null), 'depth only: no rgb/ folder');
  assert.equal(seq.frames[2].confidence, 's/confidence/000002.png');
  // The frame past the last odometry row continues at the rows' interval.
  const last = seq.frames[frames - 1].timestamp;
  assert.ok(Math.abs(last - (10 + (frames - 1) / 60)) < 1e-6, `${last}`);
  // Odometry is the device's, not ground truth.
  assert.equal(seq.groundTruth.length, 0);
  assert.equal(seq.odometry.length, frames - 1);
  // A missing column is refused, naming the file and the line ...
  const header = 'timestamp, frame, x, y, z, qx, qy, qz, qw\n';
  const short = `${header}10, 0, 0, 0, 0, 0, 0, 1\n10.1, 1, 0, 0, 0, 0, 0, 0, 1\n`;
  assert.throws(() => m.parseSequence(names, { ...texts, 's/odometry.csv': short }, 's'), /odometry\.csv, line 2: /);
  // ... but on the last row it is a recording cut short: skipped, one warning naming both.
  const cut = `${header}10, 0, 0, 0, 0, 0, 0, 0, 1\n10.1, 1, 0, 0, 0, 0`;
  const cutSeq = m.parseSequence(names, { ...texts, 's/odometry.csv': cut }, 's');
  assert.equal(cutSeq.odometry.length, 1);
  assert.equal(cutSeq.frames.length, frames);
  assert.equal(cutSeq.warnings.length, 1, JSON.stringify(cutSeq.warnings));
  assert.match(cutSeq.warnings[0], /^s\/odometry\.csv, line 3: the last line is cut off/);
  assert.deepEqual(seq.warnings, []);
});

test('pushFiles: a Stray frame pushed as its files, depth only with confidence; bad files named, nothing changed', { skip }, async () => {
  const m = await loadPackage();
  const { makeStray, tempDir, CLIP, encodeGrey8Png } = await import('./datasets.mjs');
  const tmp = tempDir('surfel-slam-node-stray-');
  try {
    const { dir } = makeStray(CLIP, 2, tmp);
    const names = [];
    for (const sub of ['depth', 'confidence']) for (const f of fs.readdirSync(path.join(dir, sub))) names.push(`stray_teddy/${sub}/${f}`);
    names.push('stray_teddy/camera_matrix.csv', 'stray_teddy/odometry.csv');
    const text = (f) => fs.readFileSync(path.join(dir, f), 'utf8');
    const seq = m.parseSequence(names, { 'stray_teddy/camera_matrix.csv': text('camera_matrix.csv'), 'stray_teddy/odometry.csv': text('odometry.csv') }, 'stray_teddy');
    const slam = new m.Slam({ ...seq.intrinsics, preset: seq.preset });
    const bytes = (p) => new Uint8Array(fs.readFileSync(path.join(tmp, p)));
    const [f0, f1] = seq.frames;
    const first = slam.pushFiles(null, bytes(f0.depth), bytes(f0.confidence), [null, f0.depth, f0.confidence], f0.timestamp);
    assert.equal(first.verdict, 'initialised');
    const surfels = slam.liveSurfels;
    assert.ok(surfels > 10000, `${surfels}`);
    // A confidence image of another size, a depth image of another size: refused by name, the map kept.
    const smallConfidence = encodeGrey8Png(128, 96, new Uint8Array(128 * 96).fill(2));
    assert.throws(() => slam.pushFiles(null, bytes(f1.depth), smallConfidence, [null, f1.depth, 'c/small.png'], f1.timestamp), /c\/small\.png/);
    const tumDepth = new Uint8Array(fs.readFileSync(path.join(CLIP, fs.readFileSync(path.join(CLIP, 'depth.txt'), 'utf8').split('\n').find((l) => l && !l.startsWith('#')).split(/\s+/)[1])));
    assert.throws(() => slam.pushFiles(null, tumDepth, null, [null, 'd/640x480.png', null], f1.timestamp), /d\/640x480\.png.*640.*480/);
    assert.throws(() => slam.pushFiles(null, new Uint8Array([1, 2, 3]), null, [null, 'd/garbage.png', null], f1.timestamp), /d\/garbage\.png/);
    assert.equal(slam.liveSurfels, surfels, 'nothing changed');
    const second = slam.pushFiles(null, bytes(f1.depth), bytes(f1.confidence), [null, f1.depth, f1.confidence], f1.timestamp);
    assert.equal(second.verdict, 'tracked');
    slam.free();
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

/**
 * Plays the sequence folder `dir` through the package as a Node user would:
 * listed, detected, parsed with its index texts, each frame pushed as its
 * files (colour, depth, confidence; null where the layout has none).
 * Returns { seq, trajectoryTum, verdicts }.
 */
async function playFolder(m, dir) {
  const { sequence: seq } = await openSequence(m, dir);
  const slam = new m.Slam({ ...seq.intrinsics, preset: seq.preset });
  const bytes = (f) => (f === null ? null : new Uint8Array(fs.readFileSync(path.join(dir, f))));
  const verdicts = seq.frames.map(
    (f) => slam.pushFiles(bytes(f.colour), bytes(f.depth), bytes(f.confidence), [f.colour, f.depth, f.confidence], f.timestamp).verdict,
  );
  const trajectoryTum = slam.trajectoryTum();
  slam.free();
  return { seq, trajectoryTum, verdicts };
}

test('RealSense and Stray Scanner folders play end to end, with default settings, against the truth', { skip }, async (t) => {
  const m = await loadPackage();
  const { makeRealSense, makeStray, tempDir, CLIP } = await import('./datasets.mjs');
  const tmp = tempDir('surfel-slam-node-sensors-');
  try {
    const frames = 24;
    const realsense = makeRealSense(CLIP, frames, tmp);
    const rs = await playFolder(m, realsense.dir);
    assert.equal(rs.seq.preset, 'realsense-d400');
    assert.deepEqual(rs.seq.frames.map((f) => f.timestamp), [...Array(frames).keys()], 'file numbers as timestamps');
    assert.deepEqual(rs.verdicts.slice(1), Array(frames - 1).fill('tracked'));
    const rsAte = m.ateTum(rs.trajectoryTum, realsense.truthTum);
    t.diagnostic(`RealSense layout: ${frames} frames, ATE ${(rsAte.rmse * 100).toFixed(3)} cm against the clip's truth`);
    assert.equal(rsAte.pairs, frames);
    assert.ok(rsAte.rmse < 0.01, `ATE ${rsAte.rmse} m`);

    const stray = makeStray(CLIP, frames, tmp);
    const st = await playFolder(m, stray.dir);
    assert.equal(st.seq.preset, 'stray-lidar');
    assert.ok(st.seq.frames.every((f) => f.colour === null), 'depth only');
    assert.deepEqual(st.verdicts.slice(1), Array(frames - 1).fill('tracked'));
    // The export's odometry is the clip's truth; for a real scan it is the device's.
    const stAte = m.ateTum(st.trajectoryTum, st.seq.odometryTum);
    t.diagnostic(`Stray layout: ${frames} frames, depth only at 256x192, ${(stAte.rmse * 100).toFixed(3)} cm from the odometry`);
    assert.equal(stAte.pairs, frames);
    assert.ok(stAte.rmse < 0.02, `${stAte.rmse} m from the odometry`);
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test("presetForDepthImage: a preset's calibration at the size of a layout's frames", { skip }, async () => {
  const m = await loadPackage();
  const { encodeDepthPng } = await import('./datasets.mjs');
  const depth = (w, h) => encodeDepthPng(w, h, new Uint16Array(w * h).fill(5000));
  const round = (p) => [p.fx, p.fy, p.cx, p.cy, p.width, p.height].map((v) => Math.round(v * 100) / 100);
  // Its own size: the preset as presets() gives it.
  const fr3 = m.presets().find((p) => p.name === 'tum-fr3');
  assert.deepEqual(m.presetForDepthImage('tum-fr3', depth(640, 480)), fr3);
  // Half the size: halved, pixel centres kept (as a pyramid level).
  const half = m.presetForDepthImage('tum-fr3', depth(320, 240));
  assert.deepEqual(round(half), [267.7, 269.6, 159.8, 123.55, 320, 240]);
  assert.equal(half.depthScale, fr3.depthScale);
  // Another aspect ratio: the focal lengths kept, and a Slam built on it warns that they are a guess.
  const wide = m.presetForDepthImage('tum-fr3', depth(848, 480));
  assert.deepEqual(round(wide).slice(0, 2), [535.4, 539.2]);
  const { name, ...config } = wide;
  const slam = new m.Slam({ preset: name, ...config });
  assert.match(slam.checkLayout('tum-fr3').join('\n'), /848x480, but tum-fr3 is calibrated at 640x480, another aspect ratio/);
  slam.free();
  assert.throws(() => m.presetForDepthImage('tum-fr9', depth(320, 240)), /unknown camera preset "tum-fr9"/);
  assert.throws(() => m.presetForDepthImage('tum-fr3', new Uint8Array([1, 2, 3])), /./);
  // Every preset at one size, each as presetForDepthImage gives it.
  const sized = m.presetsForImageSize(320, 240);
  assert.deepEqual(sized.map((p) => p.name), m.presets().map((p) => p.name));
  for (const p of sized) assert.deepEqual(p, m.presetForDepthImage(p.name, depth(320, 240)));
  // At a preset's own size, the preset as presets() gives it.
  const own = m.presetsForImageSize(640, 480);
  for (const p of m.presets().filter((q) => q.width === 640 && q.height === 480)) assert.deepEqual(own.find((q) => q.name === p.name), p);
  assert.throws(() => m.presetsForImageSize(0, 240), /./);
});
