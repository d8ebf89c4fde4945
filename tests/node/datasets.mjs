// Dataset fixtures built from the bundled clip (in the repo, always present),
// shared by the Node and browser tests: archives of a folder (.tar, .tar.gz,
// .zip, written here with node:zlib, no archiver dependency), and a small
// 7-Scenes-layout folder (frame-NNNNNN.color.png / .depth.png / .pose.txt)
// made from TUM frames and their ground truth.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { fileURLToPath } from 'node:url';
import { crc32, decodePng } from './png.mjs';

export const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
export const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');

/** Every file under `dir`, '/' separated, relative, sorted. */
export function listTree(dir, rel = '') {
  const out = [];
  for (const e of fs.readdirSync(path.join(dir, rel), { withFileTypes: true })) {
    const child = rel ? `${rel}/${e.name}` : e.name;
    if (e.isDirectory()) out.push(...listTree(dir, child));
    else out.push(child);
  }
  return out.sort();
}

// ---- archives -------------------------------------------------------------------

/** A ustar archive of `files` ([name, Buffer]). */
export function tarBytes(files) {
  const blocks = [];
  for (const [name, data] of files) {
    const h = Buffer.alloc(512);
    if (Buffer.byteLength(name) > 100) throw new Error(`name too long for this writer: ${name}`);
    h.write(name, 0, 'utf8');
    h.write('0000644\0', 100);
    h.write('0000000\0', 108);
    h.write('0000000\0', 116);
    h.write(data.length.toString(8).padStart(11, '0') + '\0', 124);
    h.write('00000000000\0', 136);
    h.fill(' ', 148, 156);
    h.write('0', 156);
    h.write('ustar\0', 257);
    h.write('00', 263);
    let sum = 0;
    for (const b of h) sum += b;
    h.write(sum.toString(8).padStart(6, '0') + '\0 ', 148);
    blocks.push(h, data, Buffer.alloc((512 - (data.length % 512)) % 512));
  }
  blocks.push(Buffer.alloc(1024));
  return Buffer.concat(blocks);
}

/** A zip archive of `files` ([name, Buffer]), entries deflated. */
export function zipBytes(files) {
  const locals = [];
  const central = [];
  let offset = 0;
  for (const [name, data] of files) {
    const nameBuf = Buffer.from(name);
    const packed = zlib.deflateRawSync(data, { level: 1 });
    const crc = crc32(data);
    const local = Buffer.alloc(30);
    local.writeUInt32LE(0x04034b50, 0);
    local.writeUInt16LE(20, 4);
    local.writeUInt16LE(8, 8); // deflate
    local.writeUInt32LE(crc, 14);
    local.writeUInt32LE(packed.length, 18);
    local.writeUInt32LE(data.length, 22);
    local.writeUInt16LE(nameBuf.length, 26);
    const entry = Buffer.alloc(46);
    entry.writeUInt32LE(0x02014b50, 0);
    entry.writeUInt16LE(20, 4);
    entry.writeUInt16LE(20, 6);
    entry.writeUInt16LE(8, 10);
    entry.writeUInt32LE(crc, 16);
    entry.writeUInt32LE(packed.length, 20);
    entry.writeUInt32LE(data.length, 24);
    entry.writeUInt16LE(nameBuf.length, 28);
    entry.writeUInt32LE(offset, 42);
    locals.push(local, nameBuf, packed);
    central.push(entry, nameBuf);
    offset += 30 + nameBuf.length + packed.length;
  }
  const dir = Buffer.concat(central);
  const end = Buffer.alloc(22);
  end.writeUInt32LE(0x06054b50, 0);
  end.writeUInt16LE(files.length, 8);
  end.writeUInt16LE(files.length, 10);
  end.writeUInt32LE(dir.length, 12);
  end.writeUInt32LE(offset, 16);
  return Buffer.concat([...locals, dir, end]);
}

/** The files of `dir` as [`${top}/${relative}`, bytes]. */
export function filesOf(dir, top) {
  return listTree(dir).map((rel) => [`${top}/${rel}`, fs.readFileSync(path.join(dir, rel))]);
}

/** Writes `dir` as `<outDir>/<top>.<ext>` (ext 'tar', 'tgz', 'tar.gz' or 'zip'); returns its path. */
export function writeArchive(dir, top, outDir, ext) {
  const files = filesOf(dir, top);
  const bytes = ext === 'zip' ? zipBytes(files) : ext === 'tar' ? tarBytes(files) : zlib.gzipSync(tarBytes(files), { level: 1 });
  const out = path.join(outDir, `${top}.${ext}`);
  fs.writeFileSync(out, bytes);
  return out;
}

/** A TUM folder with the first `frames` frames of `src` (index files and ground truth). */
export function tumSubset(src, frames, dst) {
  for (const sub of ['rgb', 'depth']) fs.mkdirSync(path.join(dst, sub), { recursive: true });
  for (const file of ['rgb.txt', 'depth.txt']) {
    const lines = fs.readFileSync(path.join(src, file), 'utf8').split('\n');
    const rows = lines.filter((l) => l.trim() && !l.startsWith('#')).slice(0, frames);
    fs.writeFileSync(path.join(dst, file), [...lines.filter((l) => l.startsWith('#')), ...rows, ''].join('\n'));
    for (const row of rows) {
      const rel = row.split(/\s+/)[1];
      fs.copyFileSync(path.join(src, rel), path.join(dst, rel));
    }
  }
  fs.copyFileSync(path.join(src, 'groundtruth.txt'), path.join(dst, 'groundtruth.txt'));
  return dst;
}

/**
 * A TUM folder `dst` of the first `frames` frames of `src` at half their
 * size, as a recording resized by 2 is: colour the mean of each 2x2 block,
 * depth the mean of a block's measured values when they lie within 2 % of
 * each other (else none: an edge). Index files and ground truth as `src`'s.
 */
export function tumHalved(src, frames, dst) {
  tumSubset(src, frames, dst);
  for (const list of ['rgb.txt', 'depth.txt']) {
    const rows = fs.readFileSync(path.join(dst, list), 'utf8').split('\n').filter((l) => l.trim() && !l.startsWith('#'));
    for (const row of rows) {
      const file = path.join(dst, row.split(/\s+/)[1]);
      fs.writeFileSync(file, list === 'rgb.txt' ? colourHalved(file) : depthHalved(file));
    }
  }
  return dst;
}

/** The 2x2 blocks of a `width` x `height` image: per block, the row-major indices of its four pixels. */
function* blocks(width, height) {
  for (let v = 0; v + 1 < height; v += 2) {
    for (let u = 0; u + 1 < width; u += 2) yield [v * width + u, v * width + u + 1, (v + 1) * width + u, (v + 1) * width + u + 1];
  }
}

function colourHalved(file) {
  const png = decodePng(fs.readFileSync(file));
  if (png.bitDepth !== 8 || png.channels !== 3) throw new Error(`${file}: expected 8-bit RGB`);
  const out = new Uint8Array(3 * (png.width >> 1) * (png.height >> 1));
  let o = 0;
  for (const block of blocks(png.width, png.height)) {
    for (let c = 0; c < 3; c++) out[o++] = Math.round(block.reduce((sum, i) => sum + png.data[3 * i + c], 0) / 4);
  }
  return encodeRgbPng(png.width >> 1, png.height >> 1, out);
}

function depthHalved(file) {
  const png = decodeDepthPng(fs.readFileSync(file));
  const out = new Uint16Array((png.width >> 1) * (png.height >> 1));
  let o = 0;
  for (const block of blocks(png.width, png.height)) {
    const measured = block.map((i) => png.data[i]).filter((d) => d > 0);
    const [lo, hi] = [Math.min(...measured), Math.max(...measured)];
    out[o++] = measured.length && hi <= 1.02 * lo ? Math.round(measured.reduce((a, b) => a + b, 0) / measured.length) : 0;
  }
  return encodeDepthPng(png.width >> 1, png.height >> 1, out);
}

// ---- 16-bit PNG (depth) ---------------------------------------------------------

/** Decodes a non-interlaced 16-bit greyscale PNG: { width, height, data: Uint16Array }. */
export function decodeDepthPng(buffer) {
  const { width, height, channels, bitDepth, data: bytes } = decodePng(buffer);
  if (bitDepth !== 16 || channels !== 1) throw new Error('expected a 16-bit greyscale PNG');
  const data = new Uint16Array(width * height);
  for (let i = 0; i < data.length; i++) data[i] = bytes.readUInt16BE(2 * i);
  return { width, height, data };
}

/** Encodes a 16-bit greyscale PNG. */
export const encodeDepthPng = (width, height, data) => greyPng(width, height, data, 16);

/** Encodes an 8-bit RGB PNG from interleaved `data`. */
export const encodeRgbPng = (width, height, data) => greyPng(width, height, data, 8, 3);

/** Encodes an 8-bit greyscale PNG (a Stray Scanner confidence image). */
export const encodeGrey8Png = (width, height, data) => greyPng(width, height, data, 8);

function greyPng(width, height, data, bits, channels = 1) {
  const bytes = bits / 8;
  const samples = channels * width;
  const raw = Buffer.alloc((bytes * samples + 1) * height);
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < samples; x++) {
      const at = y * (bytes * samples + 1) + 1 + bytes * x;
      if (bits === 16) raw.writeUInt16BE(data[y * samples + x], at);
      else raw[at] = data[y * samples + x];
    }
  }
  const chunk = (type, body) => {
    const out = Buffer.alloc(12 + body.length);
    out.writeUInt32BE(body.length, 0);
    out.write(type, 4, 'latin1');
    body.copy(out, 8);
    out.writeUInt32BE(crc32(out.subarray(4, 8 + body.length)), 8 + body.length);
    return out;
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr[8] = bits;
  ihdr[9] = channels === 3 ? 2 : 0; // RGB or grey
  return Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', ihdr), chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

// ---- 7-Scenes ----------------------------------------------------------------------

const rows = (text) => text.split('\n').filter((l) => l.trim() && !l.startsWith('#')).map((l) => l.trim().split(/\s+/));

/** 4x4 row-major camera-to-world matrix text from a TUM pose row [t, tx, ty, tz, qx, qy, qz, qw]. */
function poseText(row) {
  const [tx, ty, tz, qx, qy, qz, qw] = row.slice(1).map(Number);
  const n = Math.hypot(qx, qy, qz, qw);
  const [x, y, z, w] = [qx / n, qy / n, qz / n, qw / n];
  const r = [
    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
  ];
  const f = (v) => v.toExponential(12);
  return [...r.map((row3, i) => [...row3, [tx, ty, tz][i]].map(f).join(' ')), '0 0 0 1'].join('\n') + '\n';
}

/**
 * The first `frames` colour images of the TUM folder `src` with a depth image
 * and a ground-truth pose each within 0.02 s: `[{ colour, depth, pose }]`,
 * paths relative to `src`, `pose` the ground-truth row [t, tx, ty, tz, qx,
 * qy, qz, qw] as strings.
 */
function alignedFrames(src, frames) {
  const rgb = rows(fs.readFileSync(path.join(src, 'rgb.txt'), 'utf8'));
  const depth = rows(fs.readFileSync(path.join(src, 'depth.txt'), 'utf8'));
  const gt = rows(fs.readFileSync(path.join(src, 'groundtruth.txt'), 'utf8'));
  const nearest = (list, t, maxDt) => {
    let best = null;
    for (const r of list) {
      const dt = Math.abs(Number(r[0]) - t);
      if (dt <= maxDt && (!best || dt < best.dt)) best = { dt, r };
    }
    return best?.r ?? null;
  };
  const out = [];
  for (const [t, colour] of rgb) {
    if (out.length === frames) break;
    const pose = nearest(gt, Number(t), 0.02);
    const d = nearest(depth, Number(t), 0.02);
    if (pose && d) out.push({ colour, depth: d[1], pose });
  }
  return out;
}

/** A TUM depth image (5000 units a metre) rewritten in millimetres, `width` wide (no depth to the right). */
function depthInMm(src, file, width = null) {
  const png = decodeDepthPng(fs.readFileSync(path.join(src, file)));
  const w = width ?? png.width;
  const mm = new Uint16Array(w * png.height);
  for (let i = 0; i < mm.length; i++) {
    const [u, v] = [i % w, Math.floor(i / w)];
    mm[i] = u < png.width ? Math.round(png.data[v * png.width + u] / 5) : 0;
  }
  return encodeDepthPng(w, png.height, mm);
}

/** An 8-bit RGB PNG `width` wide, the image of `file` on the left, black to the right. */
function colourWidened(file, width) {
  const png = decodePng(fs.readFileSync(file));
  if (png.bitDepth !== 8 || png.channels !== 3) throw new Error(`${file}: expected 8-bit RGB`);
  const out = new Uint8Array(3 * width * png.height);
  for (let v = 0; v < png.height; v++) out.set(png.data.subarray(3 * v * png.width, 3 * (v + 1) * png.width), 3 * v * width);
  return encodeRgbPng(width, png.height, out);
}

/**
 * A 7-Scenes-layout folder `<parent>/<name>/seq-01/frame-NNNNNN.*` from the
 * first `frames` frames of the TUM folder `src` that have a ground-truth pose
 * (within 0.02 s): colour copied, depth rescaled to millimetres (7-Scenes'
 * unit), pose from the ground truth. Returns { dir, poses: [[t, tx, ty, tz,
 * qx, qy, qz, qw] per frame] }.
 */
export function makeSevenScenes(src, frames, parent, name = 'seven_scenes_teddy') {
  const dir = path.join(parent, name);
  const seqDir = path.join(dir, 'seq-01');
  fs.mkdirSync(seqDir, { recursive: true });
  const poses = [];
  for (const { colour, depth, pose } of alignedFrames(src, frames)) {
    const stem = path.join(seqDir, `frame-${String(poses.length).padStart(6, '0')}`);
    fs.copyFileSync(path.join(src, colour), `${stem}.color.png`);
    fs.writeFileSync(`${stem}.depth.png`, depthInMm(src, depth));
    fs.writeFileSync(`${stem}.pose.txt`, poseText(pose));
    poses.push(pose.map(Number));
  }
  return { dir, poses };
}

/**
 * An ICL-NUIM "frei_png" folder `<parent>/<name>/` from the first `frames`
 * frames of the TUM folder `src` that have a ground-truth pose:
 * `rgb/N.png` and `depth/N.png` copied (both 5000 units a metre, as
 * ICL-NUIM's), `associations.txt` listing `N depth/N.png N rgb/N.png`, and
 * `traj0.gt.freiburg`, the truth stamped with the frame numbers N (from 1,
 * as ICL-NUIM's). The images are TUM's, so the ICL-NUIM preset (fy = -480)
 * is the wrong camera for them: a layout to read, not a scene to track
 * well. Returns the folder.
 */
export function makeIclNuim(src, frames, parent, name = 'icl_teddy') {
  const dir = path.join(parent, name);
  for (const sub of ['rgb', 'depth']) fs.mkdirSync(path.join(dir, sub), { recursive: true });
  let associations = '';
  let truth = '';
  alignedFrames(src, frames).forEach(({ colour, depth, pose }, i) => {
    const n = i + 1;
    fs.copyFileSync(path.join(src, colour), path.join(dir, 'rgb', `${n}.png`));
    fs.copyFileSync(path.join(src, depth), path.join(dir, 'depth', `${n}.png`));
    associations += `${n} depth/${n}.png ${n} rgb/${n}.png\n`;
    truth += `${n} ${pose.slice(1).join(' ')}\n`;
  });
  fs.writeFileSync(path.join(dir, 'associations.txt'), associations);
  fs.writeFileSync(path.join(dir, 'traj0.gt.freiburg'), truth);
  return dir;
}

/**
 * A RealSense folder as Open3D's recorder writes it, `<parent>/<name>/`, from
 * the first `frames` frames of the TUM folder `src` (Freiburg 3) that have a
 * ground-truth pose: `color/NNNNNN.png` copied, `depth/NNNNNN.png` in
 * millimetres (the D400's default unit), `camera_intrinsic.json` with
 * Freiburg 3's intrinsics column-major, and the recorder's `realsense.bag`
 * and `scene/` beside them (to be ignored). The layout has no timestamps: a
 * frame's is its file number. `width` beyond 640 widens every image on the
 * right with pixels that saw nothing (an 848x480 recording). Returns { dir,
 * truthTum }: the ground truth stamped with those numbers, as TUM text.
 */
export function makeRealSense(src, frames, parent, name = 'realsense_teddy', width = 640) {
  const dir = path.join(parent, name);
  for (const sub of ['color', 'depth', 'scene']) fs.mkdirSync(path.join(dir, sub), { recursive: true });
  const [fx, fy, cx, cy] = [535.4, 539.2, 320.1, 247.6];
  const intrinsic = { width, height: 480, intrinsic_matrix: [fx, 0, 0, 0, fy, 0, cx, cy, 1] };
  fs.writeFileSync(path.join(dir, 'camera_intrinsic.json'), JSON.stringify(intrinsic, null, 2));
  fs.writeFileSync(path.join(dir, 'realsense.bag'), 'not read');
  fs.writeFileSync(path.join(dir, 'scene', 'integrated.ply'), 'not read');
  let truthTum = '';
  alignedFrames(src, frames).forEach(({ colour, depth, pose }, i) => {
    const stem = String(i).padStart(6, '0');
    const colourOut = path.join(dir, 'color', `${stem}.png`);
    if (width === 640) fs.copyFileSync(path.join(src, colour), colourOut);
    else fs.writeFileSync(colourOut, colourWidened(path.join(src, colour), width));
    fs.writeFileSync(path.join(dir, 'depth', `${stem}.png`), depthInMm(src, depth, width));
    truthTum += `${i} ${pose.slice(1).join(' ')}\n`;
  });
  return { dir, truthTum };
}

/**
 * A Stray Scanner export `<parent>/<name>/` from the first `frames` depth
 * images of the TUM folder `src` (Freiburg 3, 640x480) that have a ground-
 * truth pose: depth resampled (nearest) to 256x192 and written in
 * millimetres, a confidence image per frame (2, with the leftmost
 * `lowColumns` columns 0: no depth there), `camera_matrix.csv` at the
 * 1920x1440 colour resolution (Freiburg 3's intrinsics times 3), and the
 * ground truth as `odometry.csv` (9 columns). No rgb/: depth only. Returns
 * { dir, poses }.
 */
export function makeStray(src, frames, parent, name = 'stray_teddy', lowColumns = 32) {
  const dir = path.join(parent, name);
  for (const sub of ['depth', 'confidence']) fs.mkdirSync(path.join(dir, sub), { recursive: true });
  const depth = rows(fs.readFileSync(path.join(src, 'depth.txt'), 'utf8'));
  const gt = rows(fs.readFileSync(path.join(src, 'groundtruth.txt'), 'utf8'));
  const [fx, fy, cx, cy] = [535.4, 539.2, 320.1, 247.6];
  fs.writeFileSync(path.join(dir, 'camera_matrix.csv'), `${3 * fx}, 0.0, ${3 * cx}\n0.0, ${3 * fy}, ${3 * cy}\n0.0, 0.0, 1.0\n`);
  let odometry = 'timestamp, frame, x, y, z, qx, qy, qz, qw\n';
  const poses = [];
  const [w, h] = [256, 192];
  for (const [t, file] of depth) {
    if (poses.length === frames) break;
    let pose = null;
    for (const r of gt) if (Math.abs(Number(r[0]) - Number(t)) <= 0.02 && (!pose || Math.abs(Number(r[0]) - Number(t)) < Math.abs(Number(pose[0]) - Number(t)))) pose = r;
    if (!pose) continue;
    const png = decodeDepthPng(fs.readFileSync(path.join(src, file)));
    const mm = new Uint16Array(w * h);
    const confidence = new Uint8Array(w * h);
    for (let v = 0; v < h; v++) {
      for (let u = 0; u < w; u++) {
        const [su, sv] = [Math.floor((u + 0.5) * (png.width / w)), Math.floor((v + 0.5) * (png.height / h))];
        mm[v * w + u] = Math.round(png.data[sv * png.width + su] / 5);
        confidence[v * w + u] = u < lowColumns ? 0 : 2;
      }
    }
    const stem = String(poses.length).padStart(6, '0');
    fs.writeFileSync(path.join(dir, 'depth', `${stem}.png`), encodeDepthPng(w, h, mm));
    fs.writeFileSync(path.join(dir, 'confidence', `${stem}.png`), encodeGrey8Png(w, h, confidence));
    odometry += `${t}, ${poses.length}, ${pose.slice(1).join(', ')}\n`;
    poses.push([Number(t), ...pose.slice(1).map(Number)]);
  }
  fs.writeFileSync(path.join(dir, 'odometry.csv'), odometry);
  return { dir, poses };
}

/** A fresh temporary directory. */
export const tempDir = (prefix) => fs.mkdtempSync(path.join(os.tmpdir(), prefix));
