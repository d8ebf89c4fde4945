// What the page calls the trajectory the run is compared with, wherever it
// names it: the view's checkbox (hidden when there is none), the drift
// plot (its title and description), the statistics' ATE line and
// window.surfelSlamStatus.reference; and the "Reference…" button, which reads a reference
// trajectory file for the worker (the library's parseReference reads it there,
// www/reference.js, as "your reference"). Used by app.js.
import { GROUND_TRUTH, ODOMETRY, YOUR_REFERENCE, inProse } from './scoring.js';

export { GROUND_TRUTH, ODOMETRY, YOUR_REFERENCE };

/** The largest reference file read (a pose a line: far more poses than any sequence has frames). */
const MAX_BYTES = 64 * 2 ** 20;

export class ReferenceView {
  /**
   * el: {name (the checkbox's text), check (its label), input (the file
   * input), plot (the drift plot's canvas)}; onFile(name, text) gets a file
   * chosen, onError(message) a file that cannot be read; namedIn: [plots
   * (www/plots.js), stats (www/stats.js), status (www/page-status.js)].
   */
  constructor(el, { onFile, onError, namedIn: [plots, stats, status] }) {
    this.el = el;
    this.named = { plots, stats, status };
    this.name = null;
    el.input.addEventListener('change', async () => {
      const file = el.input.files?.[0];
      el.input.value = ''; // the same file chosen again is a new change
      if (!file) return;
      if (file.size > MAX_BYTES) {
        onError(`${file.name}: ${(file.size / 2 ** 20).toFixed(0)} MB is too big for a reference trajectory (a text file of poses)`);
        return;
      }
      try {
        onFile(file.name, await file.text());
      } catch (e) {
        onError(`${file.name}: cannot read the file (${e.message})`);
      }
    });
    this.show(null);
  }

  /** name: GROUND_TRUTH, ODOMETRY, YOUR_REFERENCE or null (none: the checkbox goes). */
  show(name) {
    this.name = name;
    const { plots, stats, status } = this.named;
    status.reference = name;
    plots.setReference(name);
    stats.reference = name;
    stats.render();
    this.el.name.textContent = name ?? '';
    this.el.check.hidden = !name;
    const against = name ? inProse(name) : 'a reference (none for this sequence: "Reference…" loads one)';
    const text = `drift: distance from the estimated camera position to ${against}, aligned at the first frame (not ATE, which aligns the whole trajectory); under it each frame's verdict, with ticks at relocalised frames and loop closures`;
    this.el.plot.setAttribute('aria-label', text);
    this.el.plot.title = text;
  }
}
