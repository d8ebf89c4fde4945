// Cuts the bundled sample clip from the TUM RGB-D freiburg3_teddy sequence.
//   node www/sample/cut-clip.mjs [../shared/data/tum_fr3_teddy] [frames=44]
// Copies the first N colour and depth images byte for byte, trims rgb.txt,
// depth.txt and groundtruth.txt to the clip, and writes manifest.json.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const src = path.resolve(process.argv[2] ?? path.join(here, '../../../shared/data/tum_fr3_teddy'));
const count = Number(process.argv[3] ?? 44);
const name = 'tum_fr3_teddy_clip';
const dst = path.join(here, name);

function readList(file) {
  const lines = fs.readFileSync(path.join(src, file), 'utf8').split('\n');
  const header = lines.filter((l) => l.startsWith('#'));
  const rows = lines.filter((l) => l.trim() && !l.startsWith('#'));
  return { header, rows };
}

const rgb = readList('rgb.txt');
const depth = readList('depth.txt');
const gt = readList('groundtruth.txt');
const rgbRows = rgb.rows.slice(0, count);
const depthRows = depth.rows.slice(0, count);
const t0 = Math.min(Number(rgbRows[0].split(/\s+/)[0]), Number(depthRows[0].split(/\s+/)[0]));
const t1 = Math.max(Number(rgbRows.at(-1).split(/\s+/)[0]), Number(depthRows.at(-1).split(/\s+/)[0]));
// Keep ground truth over the clip's time range plus one sample either side
// (nearest-timestamp association at the ends).
const gtTimes = gt.rows.map((r) => Number(r.split(/\s+/)[0]));
let first = gtTimes.findIndex((t) => t >= t0);
let last = gtTimes.findLastIndex((t) => t <= t1);
first = Math.max(0, first - 1);
last = Math.min(gt.rows.length - 1, last + 1);
const gtRows = gt.rows.slice(first, last + 1);

fs.rmSync(dst, { recursive: true, force: true });
fs.mkdirSync(path.join(dst, 'rgb'), { recursive: true });
fs.mkdirSync(path.join(dst, 'depth'), { recursive: true });
const note = `# cut for surfel-slam's bundled sample: first ${count} frames`;
const write = (file, header, rows) =>
  fs.writeFileSync(path.join(dst, file), [...header.slice(0, 1), note, ...header.slice(1), ...rows, ''].join('\n'));
write('rgb.txt', rgb.header, rgbRows);
write('depth.txt', depth.header, depthRows);
write('groundtruth.txt', gt.header, gtRows);
const files = ['rgb.txt', 'depth.txt', 'groundtruth.txt'];
for (const row of [...rgbRows, ...depthRows]) {
  const rel = row.split(/\s+/)[1];
  fs.copyFileSync(path.join(src, rel), path.join(dst, rel));
  files.push(rel);
}
files.sort();
const manifest = {
  name,
  description: `TUM RGB-D freiburg3_teddy, first ${count} frames`,
  licence: 'CC BY 4.0',
  credit: 'TUM RGB-D benchmark (Sturm et al., IROS 2012)',
  files: files.map((f) => ({ path: `${name}/${f}`, size: fs.statSync(path.join(dst, f)).size })),
};
fs.writeFileSync(path.join(here, 'manifest.json'), JSON.stringify(manifest, null, 1) + '\n');
const total = manifest.files.reduce((s, f) => s + f.size, 0);
console.log(`${count} frames, ${gtRows.length} ground-truth poses, ${(total / 1e6).toFixed(1)} MB -> ${dst}`);
