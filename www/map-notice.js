// A run that went through the whole sequence and left nothing in the map
// says so over the (empty) map, rather than leaving an empty view to be
// read as a result (issue 84, part 2: as the CLI exits 1 then). The frames'
// own messages (why each was skipped) stay in the message box. Used by app.js.

/**
 * What to say after a whole run, or null when the map holds something.
 * s: {framesProcessed, framesFailed, framesLost, surfels, frameCount, name}.
 */
export function nothingTrackedText(s) {
  const ran = s.framesProcessed + s.framesFailed;
  if (s.surfels > 0 || ran === 0) return null;
  const frames = (n) => `${n} frame${n === 1 ? '' : 's'}`;
  const what =
    s.framesProcessed === 0
      ? `all ${frames(s.framesFailed)} of ${s.name} were skipped`
      : `${frames(s.framesProcessed)} of ${s.name} ran${s.framesFailed ? ` and ${frames(s.framesFailed)} were skipped` : ''}, but none was placed in a map (${s.framesLost} lost)`;
  return `Nothing could be tracked: ${what}, so the map is empty. The messages above say why; the camera settings (preset, depth scale) are the first thing to check.`;
}

export class MapNotice {
  constructor(el) {
    this.el = el;
  }

  /** After a whole run (status plus the sequence's name): shows the notice when nothing was mapped; returns its text or null. */
  afterRun(s) {
    const text = nothingTrackedText(s);
    this.el.textContent = text ?? '';
    this.el.hidden = !text;
    return text;
  }

  hide() {
    this.el.hidden = true;
    this.el.textContent = '';
  }
}
