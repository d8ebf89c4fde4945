// Where the map view stands to fill the view with the map ("Fit map",
// double-click): the map's robust bounds as seen along the view direction.
// DOM-free and WebGL-free (renderer.js hands it a sample of the surfels'
// positions), so it is tested on its own.

const LOW = 0.02; // the bounds run from the 2nd ...
const HIGH = 0.98; // ... to the 98th percentile of the points along each axis
const MARGIN = 1.08; // a little room around the map (the 2 % trimmed off each side included)

function percentile(sorted, q) {
  if (sorted.length === 0) return NaN;
  return sorted[Math.min(sorted.length - 1, Math.max(0, Math.round(q * (sorted.length - 1))))];
}

/**
 * points: Float32Array of x, y, z (world, display frame); axes: {right, up,
 * toEye} (unit vectors of the view); fovy: vertical field of view, radians;
 * aspect: width / height. Returns {target, distance} that put the points
 * between the percentiles on every axis inside the view (the rest, a few
 * stray surfels far off, may fall outside), or null without points.
 */
export function fitPoints(points, { right, up, toEye }, fovy, aspect) {
  const n = Math.floor(points.length / 3);
  if (n === 0) return null;
  const xs = new Float64Array(n);
  const ys = new Float64Array(n);
  const zs = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    const p = [points[3 * i], points[3 * i + 1], points[3 * i + 2]];
    xs[i] = p[0] * right[0] + p[1] * right[1] + p[2] * right[2];
    ys[i] = p[0] * up[0] + p[1] * up[1] + p[2] * up[2];
    zs[i] = p[0] * toEye[0] + p[1] * toEye[1] + p[2] * toEye[2];
  }
  const bounds = [xs, ys, zs].map((v) => {
    const sorted = Float64Array.from(v).sort();
    return [percentile(sorted, LOW), percentile(sorted, HIGH)];
  });
  const [cx, cy, cz] = bounds.map(([lo, hi]) => (lo + hi) / 2);
  const tanY = Math.tan(fovy / 2);
  const tanX = tanY * (aspect > 0 ? aspect : 1);
  // The eye at distance d from the centre sees a point at (x, y, z) when
  // |x| <= (d - z) tanX and |y| <= (d - z) tanY (z towards the eye).
  let distance = 0;
  for (let i = 0; i < n; i++) {
    const inside = [xs[i], ys[i], zs[i]].every((v, k) => v >= bounds[k][0] && v <= bounds[k][1]);
    if (!inside) continue;
    const need = zs[i] - cz + Math.max(Math.abs(xs[i] - cx) / tanX, Math.abs(ys[i] - cy) / tanY);
    distance = Math.max(distance, need);
  }
  const target = [0, 1, 2].map((k) => right[k] * cx + up[k] * cy + toEye[k] * cz);
  return { target, distance: distance * MARGIN };
}
