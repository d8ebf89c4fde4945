// Copies of surfel ranges out of wasm memory, for posting to the page (the
// zero-copy views are invalidated by the next call into the module, so the
// worker copies what the page needs right after each frame). Used by
// worker.js only.

const REFRESH_SURFELS = 65536;

/** `{count, start, end, positions, normals, colours, radii, confidences}`: slots [start, end) of the map. */
export function copySurfels(slam, count, start, end) {
  return {
    count,
    start,
    end,
    positions: slam.positions().slice(3 * start, 3 * end),
    normals: slam.normals().slice(3 * start, 3 * end),
    colours: slam.colours().slice(4 * start, 4 * end),
    radii: slam.radii().slice(start, end),
    confidences: slam.confidences().slice(start, end),
  };
}

/** The buffers of copySurfels' arrays, to transfer rather than clone. */
export const surfelBuffers = (c) => [c.positions.buffer, c.normals.buffer, c.colours.buffer, c.radii.buffer, c.confidences.buffer];

/** The surfels new or moved since the last call (the module's changed range), clamped to the map. */
export function copyChanged(slam, count) {
  let [start, end] = Array.from(slam.takeChangedRange());
  start = Math.max(0, Math.min(start, count));
  end = Math.max(start, Math.min(end, count));
  return copySurfels(slam, count, start, end);
}

/**
 * Merges are not in the changed range (they refine surfels by less than the
 * noise): a rolling window of the map, copied each frame, brings merged
 * colours and positions to the GPU within count / REFRESH_SURFELS frames.
 */
export class RollingRefresh {
  constructor() {
    this.cursor = 0; // start of the next window (surfel index)
  }

  restart() {
    this.cursor = 0;
  }

  /** The next window of a map of `count` surfels. */
  next(slam, count) {
    const start = this.cursor < count ? this.cursor : 0;
    const end = Math.min(count, start + REFRESH_SURFELS);
    this.cursor = end >= count ? 0 : end;
    return copySurfels(slam, count, start, end);
  }
}
