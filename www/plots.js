// Small live charts, plain canvas 2D: ms per frame by pipeline stage
// (stacked), the map's surfel count, and the position error per frame
// against the reference (ground truth, the device's odometry or the user's
// reference, when the sequence has one), with the verdict
// strip under it (one colour per frame's verdict) and a tick at each frame
// placed by relocalisation or closing a loop. x = frame number.
// Redrawn at most a few times a second: on a machine without a GPU the
// page's drawing shares the cores with the SLAM threads.
import { inProse } from './scoring.js';

export const STAGE_COLOURS = {
  decode: '#8ab4ff',
  preprocess: '#b38aff',
  track: '#ff9a3c',
  fuse: '#3ee6a0',
  loop: '#ff6ad5',
  predict: '#ffd84a',
};
/**
 * Verdict strip colours, least to most alarming; 'held' is fused with some
 * directions held at the motion prior, 'relocalised' a recovered frame
 * placed from a keyframe, 'restarted' a frame that began a new segment of
 * the map after a long loss.
 */
export const VERDICT_COLOURS = {
  tracked: '#2f8f5b',
  initialised: '#2f8f5b',
  held: '#b5d33d',
  recovered: '#e0b23a',
  relocalised: '#3fc8ff',
  restarted: '#a45cf0',
  lost: '#e5484d',
};
const VERDICT_CODES = Object.keys(VERDICT_COLOURS);
const MARK_COLOURS = { relocalised: VERDICT_COLOURS.relocalised, loop: '#ff6ad5' };
const STAGES = Object.keys(STAGE_COLOURS);
const REDRAW_MS = 250;

/**
 * One chart: a title, a y axis from 0 to a rounded maximum, filled or line
 * series. The title is the first of `titles` (longest first) that fits the
 * chart's width with the note after it, at 10 px, else at 9 px, else the
 * last cut short with an ellipsis.
 */
class Chart {
  constructor(canvas, titles, unit) {
    this.canvas = canvas;
    this.titles = [titles].flat();
    this.unit = unit;
    this.ctx = canvas.getContext('2d');
    this.drawnTitle = null; // {text, fits}: the title as last drawn
  }

  /** Draws the title that fits in `width` (css pixels) and remembers it. */
  drawTitle(note, width) {
    const ctx = this.ctx;
    const texts = this.titles.map((t) => (note ? `${t} — ${note}` : t));
    // Each title at 10 px, then at 9 px, before a shorter one.
    const fits = (t, px) => {
      ctx.font = `${px}px system-ui, sans-serif`;
      return ctx.measureText(t).width <= width;
    };
    let text = texts.find((t) => fits(t, 10) || fits(t, 9)) ?? null;
    if (!text) {
      text = texts[texts.length - 1];
      while (text.length > 1 && ctx.measureText(`${text}…`).width > width) text = text.slice(0, -1);
      text = `${text}…`;
    }
    ctx.fillText(text, 2, 1);
    this.drawnTitle = { text, fits: ctx.measureText(text).width <= width };
    ctx.font = '10px system-ui, sans-serif';
  }

  /**
   * series: [{colour, values: Float64Array|number[] (NaN = no value), fill}]
   * drawn in order, all over frames 0..n-1. robust: the y axis ends at the
   * 98th percentile, so that one slow frame (the first, a page busy
   * elsewhere) does not flatten the rest. strip: per-frame indices into
   * VERDICT_CODES (0 = none) drawn as a band under the plot; marks:
   * [{frame, kind}] drawn as vertical ticks (kind: 'relocalised' | 'loop').
   */
  draw(series, n, note = '', robust = false, strip = null, marks = []) {
    const dpr = Math.min(self.devicePixelRatio || 1, 2);
    const cw = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    const ch = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    if (this.canvas.width !== cw || this.canvas.height !== ch) {
      this.canvas.width = cw;
      this.canvas.height = ch;
    }
    const ctx = this.ctx;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const w = cw / dpr;
    const h = ch / dpr;
    ctx.clearRect(0, 0, w, h);
    const left = 34;
    const top = 16;
    const plotW = w - left - 6;
    const stripH = strip ? 4 : 0;
    const plotH = h - top - 14 - stripH;
    let max = 0;
    if (robust && n > 0) {
      const all = [];
      for (const s of series) for (let i = 0; i < n; i++) if (Number.isFinite(s.values[i])) all.push(s.values[i]);
      all.sort((a, b) => a - b);
      max = all.length ? all[Math.min(all.length - 1, Math.floor(all.length * 0.98))] : 0;
    } else {
      for (const s of series) for (let i = 0; i < n; i++) if (Number.isFinite(s.values[i])) max = Math.max(max, s.values[i]);
    }
    const yMax = niceCeil(max);
    ctx.font = '10px system-ui, sans-serif';
    ctx.fillStyle = '#9aa3b2';
    ctx.textBaseline = 'top';
    this.drawTitle(note, w - 4);
    ctx.textAlign = 'right';
    ctx.fillText(formatTick(yMax), left - 3, top - 4);
    ctx.textBaseline = 'bottom';
    ctx.fillText('0', left - 3, top + plotH + 5);
    ctx.textAlign = 'left';
    ctx.fillText(this.unit, 2, top + plotH / 2 + 5);
    ctx.textAlign = 'right';
    ctx.fillText(`frame ${Math.max(0, n - 1)}`, w - 4, h); // frames are numbered from 0, as in the CLI
    ctx.textAlign = 'left';
    ctx.strokeStyle = '#3a4252';
    ctx.lineWidth = 1;
    ctx.strokeRect(left + 0.5, top + 0.5, plotW, plotH);
    if (n === 0) return;
    const x = (i) => left + (n === 1 ? plotW : (i / (n - 1)) * plotW);
    if (strip && n > 0) {
      // Per pixel column the worst verdict of its frames (lost over relocalised over ...).
      const colW = plotW / n;
      const columns = Math.min(n, Math.ceil(plotW));
      for (let c = 0; c < columns; c++) {
        const from = Math.floor((c * n) / columns);
        const to = Math.max(from + 1, Math.floor(((c + 1) * n) / columns));
        let code = 0;
        for (let i = from; i < to; i++) code = Math.max(code, strip[i] ?? 0);
        if (code === 0) continue;
        ctx.fillStyle = VERDICT_COLOURS[VERDICT_CODES[code - 1]];
        ctx.fillRect(left + from * colW, top + plotH + 1, Math.max(1, (to - from) * colW), stripH);
      }
    }
    for (const m of marks) {
      if (m.frame >= n) continue;
      ctx.strokeStyle = MARK_COLOURS[m.kind] ?? '#fff';
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(Math.round(x(m.frame)) + 0.5, top);
      ctx.lineTo(Math.round(x(m.frame)) + 0.5, top + plotH + stripH);
      ctx.stroke();
    }
    if (yMax <= 0) return;
    const y = (v) => top + plotH - (Math.min(v, yMax) / yMax) * plotH;
    // At most about one point per pixel column: the largest value of each column's frames.
    const step = Math.max(1, Math.floor(n / plotW));
    for (const s of series) {
      ctx.beginPath();
      let open = false;
      let firstX = null;
      let lastX = null;
      for (let i = 0; i < n; i += step) {
        let v = NaN;
        for (let j = i; j < Math.min(n, i + step); j++) if (Number.isFinite(s.values[j]) && !(v >= s.values[j])) v = s.values[j];
        if (!Number.isFinite(v)) {
          open = false;
          continue;
        }
        if (open) ctx.lineTo(x(i), y(v));
        else {
          if (s.fill && firstX !== null) break; // a filled series is drawn up to its first gap
          ctx.moveTo(x(i), y(v));
          firstX ??= x(i);
        }
        open = true;
        lastX = x(i);
      }
      if (s.fill && firstX !== null) {
        ctx.lineTo(lastX, top + plotH);
        ctx.lineTo(firstX, top + plotH);
        ctx.closePath();
        ctx.fillStyle = s.colour;
        ctx.fill();
      } else {
        ctx.strokeStyle = s.colour;
        ctx.lineWidth = 1.5;
        ctx.stroke();
      }
    }
  }
}

function niceCeil(v) {
  if (!(v > 0)) return 0;
  const p = 10 ** Math.floor(Math.log10(v));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= v) return m * p;
  return 10 * p;
}

function formatTick(v) {
  if (v >= 1e6) return `${v / 1e6}M`;
  if (v >= 1e3) return `${v / 1e3}k`;
  return String(Number(v.toPrecision(3)));
}

/** Growable per-frame series (Float64Array, NaN where a frame has no value). */
class Series {
  constructor() {
    this.values = new Float64Array(256).fill(NaN);
    this.length = 0;
  }

  set(i, v) {
    if (i >= this.values.length) {
      const grown = new Float64Array(Math.max(i + 1, 2 * this.values.length)).fill(NaN);
      grown.set(this.values);
      this.values = grown;
    }
    this.values[i] = v;
    this.length = Math.max(this.length, i + 1);
  }
}

export class Plots {
  /** canvases: {timing, surfels, error}; all optional. onDrawn(charts): after each draw. */
  constructor(canvases, onDrawn = null) {
    this.charts = {
      timing: canvases.timing ? new Chart(canvases.timing, 'ms per frame by stage', 'ms') : null,
      surfels: canvases.surfels ? new Chart(canvases.surfels, 'surfels in the map', '') : null,
      error: canvases.error ? new Chart(canvases.error, 'drift', 'cm') : null,
    };
    this.onDrawn = onDrawn;
    this.visible = true;
    this.timer = null;
    this.reset();
    this.setReference(null);
  }

  reset() {
    this.stages = Object.fromEntries(STAGES.map((s) => [s, new Series()]));
    this.surfels = new Series();
    this.error = new Series();
    this.verdicts = new Uint8Array(256); // VERDICT_CODES index + 1 per frame, 0 = none
    this.marks = []; // {frame, kind}: relocalised frames and loop closures
    this.frames = 0;
    this.schedule(true);
  }

  /**
   * One processed frame: its index, the report's timings (ms), the surfel
   * count, the position error (m) or null, and what happened to it:
   * {verdict, relocalised (placed from a keyframe), loopClosed (closed a loop)}.
   */
  add(index, timings, surfels, errorM, { verdict = null, relocalised = false, loopClosed = false } = {}) {
    for (const s of STAGES) this.stages[s].set(index, Number(timings?.[s]) || 0);
    const shown = relocalised ? 'relocalised' : verdict;
    if (VERDICT_CODES.includes(shown)) {
      if (index >= this.verdicts.length) {
        const grown = new Uint8Array(Math.max(index + 1, 2 * this.verdicts.length));
        grown.set(this.verdicts);
        this.verdicts = grown;
      }
      this.verdicts[index] = VERDICT_CODES.indexOf(shown) + 1;
    }
    if (relocalised) this.marks.push({ frame: index, kind: 'relocalised' });
    if (loopClosed) this.marks.push({ frame: index, kind: 'loop' });
    this.surfels.set(index, surfels);
    if (Number.isFinite(errorM)) this.error.set(index, errorM * 100);
    this.frames = Math.max(this.frames, index + 1);
    this.schedule();
  }

  /**
   * What the drift is measured from (GROUND_TRUTH, ODOMETRY, YOUR_REFERENCE
   * of www/scoring.js), null: none. Named in the title where it fits.
   */
  setReference(name) {
    this.reference = name;
    name = name && inProse(name);
    this.charts.error?.titles.splice(0, Infinity, ...(name ? [`drift from ${name} since frame 0 (not ATE)`, `drift from ${name}`, 'drift (not ATE)', 'drift'] : ['drift since frame 0', 'drift']));
    this.schedule(true);
  }

  /** A reference loaded after frames ran: the drift of each is set again (errorsM: [[index, metres or null]]). */
  setErrors(errorsM) {
    this.error = new Series();
    for (const [index, e] of errorsM) if (Number.isFinite(e)) this.error.set(index, e * 100);
    this.schedule(true);
  }

  setVisible(on) {
    this.visible = on;
    this.schedule(true);
  }

  /** Latest position error (cm) or null. */
  latestErrorCm() {
    for (let i = this.error.length - 1; i >= 0; i--) if (Number.isFinite(this.error.values[i])) return this.error.values[i];
    return null;
  }

  schedule(now = false) {
    if (!this.visible) return;
    if (now) {
      clearTimeout(this.timer);
      this.timer = null;
      this.draw();
      return;
    }
    if (this.timer !== null) return;
    this.timer = setTimeout(() => {
      this.timer = null;
      this.draw();
    }, REDRAW_MS);
  }

  draw() {
    const n = this.frames;
    const { timing, surfels, error } = this.charts;
    if (timing) {
      // Stacked: each stage's band drawn from the sum of the stages up to it, largest first.
      const sums = [];
      let acc = new Float64Array(n);
      for (const s of STAGES) {
        const next = new Float64Array(n);
        for (let i = 0; i < n; i++) next[i] = acc[i] + (Number.isFinite(this.stages[s].values[i]) ? this.stages[s].values[i] : 0);
        sums.push({ colour: STAGE_COLOURS[s], values: next, fill: true });
        acc = next;
      }
      timing.draw(sums.reverse(), n, '', true);
    }
    if (surfels) surfels.draw([{ colour: '#8ab4ff', values: this.surfels.values }], n);
    if (error) {
      const latest = this.latestErrorCm();
      const note = !this.reference ? 'no reference' : latest === null ? '' : `${latest.toFixed(2)} cm`;
      error.draw([{ colour: '#3ee65a', values: this.error.values }], n, note, false, this.verdicts, this.marks);
    }
    this.onDrawn?.(this.charts);
  }
}
