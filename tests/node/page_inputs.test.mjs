// The page's own readers and texts, without a browser: a reference
// trajectory file (www/reference.js: the library's parseReference, TUM or
// CSV by frame number, matched to the frames; needs www/pkg/), the
// sequence line while a sequence is read (www/sequence.js), what the page
// says after a run that mapped nothing (www/map-notice.js), and where "Fit
// map" puts the view (www/view-fit.js).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFile } from 'node:fs/promises';
import { readReference } from '../../www/reference.js';
import { readingLine } from '../../www/sequence.js';
import { nothingTrackedText } from '../../www/map-notice.js';
import { fitPoints } from '../../www/view-fit.js';

const frames = [0.5, 0.533, 0.566, 0.6].map((timestamp, index) => ({ index, timestamp }));

// The page's module (scripts/build.sh puts it in www/pkg/): the library's parseReference.
const pkg = new URL('../../www/pkg/', import.meta.url);
const wasm = await import(new URL('surfel_slam.js', pkg));
await wasm.default({ module_or_path: await readFile(new URL('surfel_slam_bg.wasm', pkg)) });
const read = (name, text) => readReference(wasm, { name, text }, frames);

test('a TUM reference reads as timestamped poses, quaternions normalised', () => {
  const r = read('tracker.txt', '# ground truth\n0.5 1 2 3 0 0 0 2\n0.566 1.1 2 3 0 0 0.6 0.8\n\n');
  assert.equal(r.key, 'timestamp');
  assert.deepEqual(Array.from(r.poses[0]), [0.5, 1, 2, 3, 0, 0, 0, 1]);
  assert.equal(r.rows.length, 2);
  assert.equal(r.matched, 2);
  assert.deepEqual(r.warnings, []);
  assert.match(r.tum, /^# timestamp tx ty tz qx qy qz qw\n0\.5\d* 1\.0* 2\.0* 3\.0* 0\.0* 0\.0* 0\.0* 1\.0*\n/);
});

test("a CSV reference by frame number (from 0) takes the frames' timestamps", () => {
  const r = read('tracker.csv', 'frame, x, y, z, qx, qy, qz, qw\n0, 0, 0, 0, 0, 0, 0, 1\n3, 0.1, 0, 0, 0, 0, 0, 1\n9, 5, 5, 5, 0, 0, 0, 1\n');
  assert.equal(r.key, 'frame');
  assert.equal(r.poses.length, 3);
  assert.deepEqual(r.rows.map((row) => row[0]), [0.5, 0.6], 'frame 9 is past the sequence');
  assert.equal(r.matched, 2);
  // Columns in another order, a timestamp column instead of frame numbers.
  const t = read('tracker.csv', 'qw,qx,qy,qz,timestamp,x,y,z\n1,0,0,0,0.533,1,2,3\n');
  assert.equal(t.key, 'timestamp');
  assert.deepEqual(t.rows, [[0.533, 1, 2, 3, 0, 0, 0, 1]]);
  assert.equal(t.matched, 1);
  // A cut-off last row (the recorder stopped mid-write) is skipped, said.
  const cut = read('cut.csv', 'frame, x, y, z, qx, qy, qz, qw\n0, 0, 0, 0, 0, 0, 0, 1\n1, 0, 0');
  assert.equal(cut.poses.length, 1);
  assert.equal(cut.warnings.length, 1);
  assert.match(cut.warnings[0], /cut\.csv, line 3/);
});

test('a reference that cannot be read names the file and the line', () => {
  const cases = [
    ['', /no pose/],
    ['0.5 1 2 3 0 0 0\n0.6 1 2 3 0 0 0 1\n', /r\.txt, line 1: .*expected 8 numbers/],
    ['0.5 1 2 3 0 0 0 1\n0.6 1 x 3 0 0 0 1\n0.7 1 2 3 0 0 0 1\n', /r\.txt, line 2/],
    ['0.5 1 2 3 0 0 0 0\n0.6 1 2 3 0 0 0 1\n', /r\.txt, line 1: .*zero quaternion/],
    ['frame,x,y,z\n0,1,2,3\n', /r\.txt, line 1: .*no `qx` column/],
    ['frame,x,y,z,qx,qy,qz,qw\n1.5,0,0,0,0,0,0,1\n2,0,0,0,0,0,0,1\n', /r\.txt, line 2: .*whole number/],
  ];
  for (const [text, message] of cases) assert.throws(() => read('r.txt', text), (e) => message.test(String(e?.message ?? e)), text);
});

test('the sequence line says what is read: an archive by name and size, a folder by its files', () => {
  const archive = { name: 'stray_demo2', entries: [['stray_demo2.zip', { size: 12.3 * 2 ** 20 }]] };
  assert.equal(readingLine(archive), 'reading archive stray_demo2.zip (12 MB)…');
  assert.equal(readingLine({ name: 'a', entries: [['a.tgz', { size: 3 * 2 ** 20 + 1 }]] }), 'reading archive a.tgz (3.0 MB)…');
  assert.equal(readingLine({ name: 'teddy', entries: [['teddy/rgb.txt', {}], ['teddy/depth.txt', {}]] }), 'reading teddy (2 files)…');
});

test('a whole run that mapped nothing is said; one with a map is not', () => {
  const base = { frameCount: 6, framesLost: 0, name: 'broken' };
  assert.match(nothingTrackedText({ ...base, framesProcessed: 0, framesFailed: 6, surfels: 0 }), /^Nothing could be tracked: all 6 frames of broken were skipped/);
  assert.match(nothingTrackedText({ ...base, framesProcessed: 2, framesFailed: 4, framesLost: 2, surfels: 0 }), /2 frames of broken ran and 4 frames were skipped, but none was placed/);
  assert.equal(nothingTrackedText({ ...base, framesProcessed: 5, framesFailed: 1, surfels: 1000 }), null);
  assert.equal(nothingTrackedText({ ...base, framesProcessed: 0, framesFailed: 0, surfels: 0 }), null, 'nothing ran yet');
});

test('fit: the robust bounds fill the view, a few far outliers do not shrink the map', () => {
  // A 2 m x 1 m wall at z = 0 seen head-on (toEye +z), and 1 % of points 50 m away.
  const points = [];
  for (let i = 0; i < 100; i++) for (let j = 0; j < 50; j++) points.push(-1 + i * 0.02, -0.5 + j * 0.02, 0);
  for (let k = 0; k < 50; k++) points.push(50, 50, -50);
  const axes = { right: [1, 0, 0], up: [0, 1, 0], toEye: [0, 0, 1] };
  const fovy = (55 * Math.PI) / 180;
  const fit = fitPoints(new Float32Array(points), axes, fovy, 1.5);
  const tanY = Math.tan(fovy / 2);
  const shownWidth = 2 * fit.distance * tanY * 1.5; // of the view at the wall
  const shownHeight = 2 * fit.distance * tanY;
  assert.ok(Math.abs(fit.target[0]) < 0.05 && Math.abs(fit.target[1]) < 0.05, `centred on the wall: ${fit.target}`);
  // The wall (about 1.92 m of its 2 m between the percentiles) fills the width of a 3:2 view.
  assert.ok(shownWidth > 1.9 && shownWidth < 2.2, `view ${shownWidth.toFixed(2)} m wide for a 2 m wall`);
  assert.ok(shownHeight > 1, `the wall's height fits too: ${shownHeight.toFixed(2)} m`);
  assert.equal(fitPoints(new Float32Array(0), axes, fovy, 1), null);
});
