// What the SLAM worker scores the run against, and the score: the
// sequence's ground truth, else the recording device's own odometry (Stray
// Scanner's ARKit poses: the CLI's "difference from the device's odometry",
// not an error, the odometry drifts too), else nothing; a reference
// trajectory the user loads ("reference…", read by the library's
// parseReference in www/reference.js) replaces
// either, named "your reference". The figure is Slam.ate's: RMS after rigid
// alignment of the whole trajectory, as the CLI computes it.
import { readReference } from './reference.js';
import { errorText, isModuleFailure, toPlain } from './wasm-module.js';

export const GROUND_TRUTH = 'ground truth';
export const ODOMETRY = "device's odometry";
export const YOUR_REFERENCE = 'your reference';

/** A reference's name in a sentence ("drift from the device's odometry"). */
export const inProse = (name) => (name === ODOMETRY ? `the ${name}` : name);

export class Scoring {
  constructor() {
    this.name = null; // GROUND_TRUTH, ODOMETRY, YOUR_REFERENCE or null
    this.tum = null; // the reference as TUM text (Slam.ate reads it)
  }

  /** A new sequence (parseSequence's result): its own reference, if any. */
  setSequence(parsed) {
    const own = parsed.groundTruthTum ? [GROUND_TRUTH, parsed.groundTruthTum] : parsed.odometryTum ? [ODOMETRY, parsed.odometryTum] : [null, null];
    [this.name, this.tum] = own;
  }

  /** The ATE ({rmse, mean, median, max, pairs, against}) of `slam`'s trajectory so far, or null (no reference, too few poses). */
  now(slam) {
    if (!this.tum || !slam) return null;
    try {
      return { ...toPlain(slam.ate(this.tum)), against: this.name };
    } catch (e) {
      if (isModuleFailure(e)) throw e;
      return null; // too few associated poses yet
    }
  }

  /** After a frame: every frame of a short sequence, every 10th of a long one, and at the last. */
  afterFrame(slam, framesOk, frameCount, last) {
    const every = frameCount > 200 ? 10 : 1;
    return framesOk % every === 0 || last ? this.now(slam) : null;
  }

  /**
   * The user's reference file `{name, text}` for the open sequence `seq`,
   * read by the wasm module `wasm`: the answer for the page, {name, key,
   * poses, matched, rows, warnings, ate} (rows at the sequence's
   * timestamps) or {name, error}; a reference that matches none of the
   * frames is refused and the old one kept.
   */
  loadUser({ name, text }, seq, slam, wasm) {
    if (!seq) return { name, error: 'open a sequence first: the reference is matched to its frames' };
    let ref;
    try {
      ref = readReference(wasm, { name, text }, seq.frames);
    } catch (e) {
      if (isModuleFailure(e)) throw e;
      return { name, error: errorText(e) };
    }
    const { key, poses, rows, tum, matched, warnings } = ref;
    if (matched === 0) {
      const span = (list) => (list.length ? `${list[0]} to ${list[list.length - 1]}` : 'none');
      const keys = poses.map((r) => r[0]);
      const what = key === 'frame' ? `frames ${span(keys)}; the sequence has frames 0 to ${seq.frames.length - 1}` : `timestamps ${span(keys)}; the frames' run ${span(seq.frames.map((f) => f.timestamp))}`;
      return { name, error: `none of its ${poses.length} poses falls on a frame of ${seq.name} (${what})` };
    }
    this.name = YOUR_REFERENCE;
    this.tum = tum;
    return { name, key, poses: poses.length, matched, rows, warnings, ate: this.now(slam) };
  }
}
