// A reference trajectory the user brings ("reference…" on the page), read
// by the library's `parseReference` (TUM text, or CSV with a header naming
// `frame` or `timestamp` and `x, y, z, qx, qy, qz, qw`; docs/js-api.md) and
// matched to the open sequence's frames. DOM-free: the SLAM worker reads it
// (tests/node/page_inputs.test.mjs).
import { toPlain } from './wasm-module.js';

/**
 * Reads the reference file `{name, text}` against `frames` (parseSequence's,
 * frame i at index i) with the wasm module `wasm`. Returns {key: 'frame' |
 * 'timestamp', poses (as in the file), rows, tum, matched, warnings}: rows
 * [t, tx, ty, tz, qx, qy, qz, qw] and tum (what Slam.ate reads) at the
 * sequence's timestamps, matched the frames with a pose (within `maxDt`, as
 * the ATE pairs them). Throws what parseReference throws: the file and line
 * at fault.
 */
export function readReference(wasm, { name, text }, frames, maxDt = 0.02) {
  const ref = toPlain(wasm.parseReference(String(text), name, frames.map((f) => f.timestamp)));
  // The poses in the sequence's time, as the library wrote them for the ATE (none: no frame numbered).
  const rows = ref.tum ? toPlain(wasm.parseReference(ref.tum, name)).poses.map((r) => Array.from(r)) : [];
  return { ...ref, rows, matched: matchedFrames(rows, frames, maxDt) };
}

/** How many of `frames` have a row within `maxDt` of their timestamp. */
function matchedFrames(rows, frames, maxDt) {
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
  return matched;
}
