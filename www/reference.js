// A reference trajectory the user brings ("reference…" on the page): TUM
// text (`t tx ty tz qx qy qz qw`, '#' comments) or CSV with a header naming
// `frame, x, y, z, qx, qy, qz, qw` (a `timestamp` or `t` column instead of
// `frame` also reads). Poses are world_from_camera, metres, as ground truth.
// DOM-free: the SLAM worker reads it (tests/node/page_inputs.test.mjs).
//
// The library gets its own parser (`parseReference`, for the CLI's
// --reference); this one is the page's until then, kept to the same two
// formats.

const POSE = ['x', 'y', 'z', 'qx', 'qy', 'qz', 'qw'];
const ALIASES = { tx: 'x', ty: 'y', tz: 'z', timestamp: 't', time: 't', frame_index: 'frame', index: 'frame' };

/** A reference file that cannot be read: the message names the line. */
export class ReferenceError extends Error {}

const fail = (message) => {
  throw new ReferenceError(message);
};

function numbers(fields, lineNo) {
  const values = fields.map(Number);
  const bad = fields.findIndex((f, i) => f.trim() === '' || !Number.isFinite(values[i]));
  if (bad >= 0) fail(`line ${lineNo}: ${JSON.stringify(fields[bad])} is not a number`);
  return values;
}

/** The rotation must be a quaternion (not all zero); it is normalised. */
function pose(key, [x, y, z, qx, qy, qz, qw], lineNo) {
  const n = Math.hypot(qx, qy, qz, qw);
  if (!(n > 1e-6)) fail(`line ${lineNo}: the quaternion is zero`);
  return [key, x, y, z, qx / n, qy / n, qz / n, qw / n];
}

/**
 * Reads a reference file's text. Returns {format: 'tum' | 'csv', byFrame,
 * rows: [[key, tx, ty, tz, qx, qy, qz, qw], ...]}: key a timestamp, or with
 * byFrame (a CSV's `frame` column) a frame number, from 0 as the page
 * numbers frames. Throws ReferenceError naming the line at fault.
 */
export function parseReference(text) {
  const lines = String(text).split(/\r?\n/).map((l, i) => ({ l: l.trim(), n: i + 1 })).filter(({ l }) => l && !l.startsWith('#'));
  if (lines.length === 0) fail('no poses in the file');
  const first = lines[0].l;
  if (/[a-z]/i.test(first.replace(/e[+-]?\d/gi, ''))) return parseCsv(lines);
  const rows = lines.map(({ l, n }) => {
    const fields = l.split(/[\s,]+/);
    if (fields.length !== 8) fail(`line ${n}: ${fields.length} values, a TUM pose has 8 (t tx ty tz qx qy qz qw)`);
    const v = numbers(fields, n);
    return pose(v[0], v.slice(1), n);
  });
  return { format: 'tum', byFrame: false, rows };
}

function parseCsv(lines) {
  const header = lines[0].l.split(',').map((h) => h.trim().toLowerCase().replace(/^"|"$/g, '')).map((h) => ALIASES[h] ?? h);
  const keyName = header.includes('frame') ? 'frame' : header.includes('t') ? 't' : null;
  const missing = [keyName ?? 'frame', ...POSE].filter((c) => !header.includes(c));
  if (missing.length) fail(`line ${lines[0].n}: the CSV header lacks ${missing.join(', ')} (it needs frame, x, y, z, qx, qy, qz, qw)`);
  const columns = [keyName, ...POSE].map((c) => header.indexOf(c));
  const rows = lines.slice(1).map(({ l, n }) => {
    const fields = l.split(',');
    if (fields.length < header.length) fail(`line ${n}: ${fields.length} values for ${header.length} columns`);
    const v = numbers(columns.map((c) => fields[c]), n);
    if (keyName === 'frame' && !(Number.isInteger(v[0]) && v[0] >= 0)) fail(`line ${n}: frame ${fields[columns[0]].trim()} is not a frame number`);
    return pose(v[0], v.slice(1), n);
  });
  if (rows.length === 0) fail('no poses under the CSV header');
  return { format: 'csv', byFrame: keyName === 'frame', rows };
}

/**
 * The reference's poses at the sequence's timestamps: a frame-numbered
 * reference takes each frame's timestamp (`frames`: parseSequence's, frame
 * i at index i); a timestamped one is kept as it is. Returns {rows,
 * matched}: matched, the frames of the sequence with a pose (within
 * `maxDt`, as the ATE pairs them).
 */
export function atFrames(parsed, frames, maxDt = 0.02) {
  const rows = parsed.byFrame
    ? parsed.rows.filter((r) => r[0] < frames.length).map((r) => [frames[r[0]].timestamp, ...r.slice(1)])
    : parsed.rows;
  const times = rows.map((r) => r[0]).sort((a, b) => a - b);
  let matched = 0;
  for (const f of frames) {
    let lo = 0;
    let hi = times.length;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (times[mid] < f.timestamp) lo = mid + 1;
      else hi = mid;
    }
    const near = [times[lo - 1], times[lo]].filter((t) => t !== undefined).some((t) => Math.abs(t - f.timestamp) <= maxDt);
    if (near) matched++;
  }
  return { rows, matched };
}

/** Rows as TUM text (what Slam.ate reads). */
export function formatTum(rows) {
  return ['# timestamp tx ty tz qx qy qz qw', ...rows.map((r) => r.map((v) => String(v)).join(' ')), ''].join('\n');
}
