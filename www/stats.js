// Live statistics: frames, tracked / held / lost, relocalised frames and loop
// closures, surfels, frames per second, ms per pipeline stage (moving
// average), ATE so far (computed in the worker with the wasm module's
// Slam.ate against the sequence's reference: its ground truth, the device's
// odometry, named as the CLI names it, or the user's reference).
import { ODOMETRY, YOUR_REFERENCE } from './scoring.js';

// 'loop' (loop closure) is reported by modules that have the stage; shown only then.
const STAGES = ['decode', 'preprocess', 'track', 'fuse', 'loop', 'predict', 'total'];
// The worker's own time per frame around the wasm call (see worker.js processNext).
const WORKER_STEPS = ['read', 'push', 'copy', 'ate', 'gap', 'wall'];
const WINDOW = 15;

function medians(keys, history) {
  const median = (v) => {
    const sorted = [...v].sort((a, b) => a - b);
    return sorted.length ? sorted[Math.floor(sorted.length / 2)] : 0;
  };
  return Object.fromEntries(keys.map((k) => [k, Number(median(history[k]).toFixed(2))]));
}

export class Stats {
  constructor(table) {
    this.table = table;
    this.reference = null; // what the ATE is against (www/scoring.js's names); a sequence's, kept over resets
    this.reset();
  }

  reset() {
    this.framesProcessed = 0;
    this.framesTracked = 0;
    this.framesLost = 0;
    this.framesRecovered = 0;
    this.framesHeld = 0;
    this.framesRestarted = 0; // lost long, mapped on in a new segment
    this.framesFailed = 0;
    this.surfels = 0;
    this.surfelSlots = 0;
    this.changed = undefined;
    this.ate = null;
    this.atePairs = 0;
    this.lastVerdict = '';
    this.lastLostReason = null;
    this.framesRelocalised = 0;
    // Frames whose near parts were masked as carried with the camera (a
    // hand in view), and the share of the image masked in the last frame.
    this.framesMasked = 0;
    this.maskedShare = 0;
    this.lastRelocalised = null; // {frame, keyframe}: the latest frame placed by relocalisation
    this.loopClosures = null; // closures so far (null: the module reports none)
    this.globalLoopClosures = 0; // of those, closed by the global check
    this.hasLoopStage = false;
    this.lastLoopDecision = null; // what the loop stage last checked and decided (report.loopDecision)
    this.recent = []; // {t, timings, wall}
    this.fps = 0;
    this.msPerFrame = 0;
    this.stageMs = Object.fromEntries(STAGES.map((s) => [s, 0]));
    this.stageHistory = Object.fromEntries(STAGES.map((s) => [s, []])); // every frame since reset
    this.workerHistory = Object.fromEntries(WORKER_STEPS.map((s) => [s, []]));
    this.wallMs = 0;
    this.frameIndex = -1;
    this.frameCount = 0;
    this.render();
  }

  /** One processed frame: message from the worker. */
  onFrame(msg) {
    const r = msg.result;
    this.framesProcessed++;
    if (r.verdict === 'lost') this.framesLost++;
    else if (r.verdict === 'recovered') this.framesRecovered++;
    else if (r.verdict === 'held') this.framesHeld++;
    else if (r.verdict === 'restarted') this.framesRestarted++;
    else this.framesTracked++;
    this.lastVerdict = r.verdict;
    this.lastLostReason = r.lostReason ?? null;
    this.maskedShare = Number.isFinite(r.cameraFixedShare) ? r.cameraFixedShare : 0;
    if (this.maskedShare > 0) this.framesMasked++;
    if (Number.isFinite(r.relocalisedFrom)) {
      this.framesRelocalised++;
      this.lastRelocalised = { frame: msg.index, keyframe: r.relocalisedFrom };
    }
    if (Number.isFinite(r.loopClosures)) this.loopClosures = r.loopClosures;
    if (Number.isFinite(r.globalLoopClosures)) this.globalLoopClosures = r.globalLoopClosures;
    if (Number.isFinite(r.timings?.loop)) this.hasLoopStage = true;
    if (typeof r.loopDecision === 'string') this.lastLoopDecision = r.loopDecision;
    // The report's count is what the map holds (absorbed surfels awaiting
    // compaction left out, as in the PLY); the arrays' length is only what is drawn.
    this.surfels = Number.isFinite(r.surfels) ? r.surfels : msg.surfels.count;
    this.surfelSlots = msg.surfels.count;
    this.changed = msg.surfels.end - msg.surfels.start;
    this.frameIndex = msg.index;
    this.frameCount = msg.frameCount;
    this.onScore(msg.ate);
    const now = msg.timing?.doneAt ?? performance.now() + performance.timeOrigin;
    this.recent.push({ t: now, timings: r.timings ?? {}, wall: msg.timing?.wall ?? 0 });
    if (this.recent.length > WINDOW) this.recent.shift();
    const n = this.recent.length;
    if (n >= 2) {
      const span = (this.recent[n - 1].t - this.recent[0].t) / 1000;
      this.fps = span > 0 ? (n - 1) / span : 0;
    }
    for (const s of STAGES) {
      this.stageMs[s] = this.recent.reduce((acc, f) => acc + (Number(f.timings[s]) || 0), 0) / n;
      this.stageHistory[s].push(Number(r.timings?.[s]) || 0);
    }
    for (const s of WORKER_STEPS) this.workerHistory[s].push(Number(msg.timing?.[s]) || 0);
    this.wallMs = this.recent.reduce((acc, f) => acc + f.wall, 0) / n;
    this.msPerFrame = this.stageMs.total || this.wallMs;
    this.render();
  }

  /** An ATE ({rmse, pairs, against}) from the worker, or null (none this frame). */
  onScore(ate) {
    if (!ate || !Number.isFinite(ate.rmse)) return;
    this.ate = ate.rmse;
    this.atePairs = ate.pairs ?? 0;
    if (ate.against) this.reference = ate.against;
    this.render();
  }

  /** The statistics' line of the ATE, named as the CLI names it: [label, value]. */
  ateRow() {
    const cm = this.ate === null ? '–' : `${(this.ate * 100).toFixed(this.ate < 0.01 ? 2 : 1)} cm`;
    const pairs = this.ate === null ? '' : ` (${this.atePairs} poses)`;
    if (this.reference === ODOMETRY) {
      return ["difference from the device's odometry", this.ate === null ? '–' : `${cm} RMS (${this.atePairs} poses; odometry, not ground truth)`];
    }
    if (this.reference === YOUR_REFERENCE) return ['ATE rmse against your reference', `${cm}${pairs}`];
    return ['ATE rmse', `${cm}${pairs}`];
  }

  /** A session was opened: its frames and surfels (the rest starts afresh). */
  onSession({ frames, surfels }) {
    this.reset();
    this.framesProcessed = frames;
    this.framesTracked = frames;
    this.surfels = surfels;
    this.surfelSlots = surfels;
    this.render();
  }

  onFailedFrame(msg) {
    this.framesFailed++;
    this.frameIndex = msg.index;
    this.frameCount = msg.frameCount ?? this.frameCount;
    this.render();
  }

  /** Median ms of each stage over every frame since the last reset. */
  stageMedians() {
    return medians(STAGES, this.stageHistory);
  }

  /** Median ms of each step of the worker's frame loop (read, push, copy, ate, gap, wall) since the last reset. */
  workerMedians() {
    return medians(WORKER_STEPS, this.workerHistory);
  }

  /** Paused: the next run's frame rate starts afresh (the last value stays shown). */
  onIdle() {
    this.recent = [];
  }

  render() {
    if (!this.table) return;
    const f1 = (x) => (Number.isFinite(x) ? x.toFixed(1) : '–');
    const rows = [
      ['frame', this.frameIndex >= 0 ? `${this.frameIndex + 1} / ${this.frameCount}` : '–'],
      ['processed', `${this.framesProcessed}`],
      [
        'tracked / held / lost / recovered / restarted',
        `${this.framesTracked} / ${this.framesHeld} / ${this.framesLost} / ${this.framesRecovered} / ${this.framesRestarted}`,
      ],
      [
        'relocalised',
        this.lastRelocalised
          ? `${this.framesRelocalised} (last: frame ${this.lastRelocalised.frame}, placed by the keyframe of frame ${this.lastRelocalised.keyframe})`
          : `${this.framesRelocalised}`,
      ],
      [
        'loop closures',
        this.loopClosures === null
          ? '–'
          : `${this.loopClosures}` + (this.globalLoopClosures > 0 ? ` (${this.globalLoopClosures} global)` : ''),
      ],
      ...(this.loopClosures === null ? [] : [['last loop decision', this.lastLoopDecision ?? '–']]),
      [
        'masked as carried with the camera',
        this.framesMasked > 0
          ? `${this.framesMasked} frame${this.framesMasked === 1 ? '' : 's'} (this one: ${(100 * this.maskedShare).toFixed(1)} % of the image)`
          : '0 frames',
      ],
      ['failed (errors)', `${this.framesFailed}`],
      ['last verdict', this.lastVerdict ? this.lastVerdict + (this.lastLostReason ? ` (${this.lastLostReason})` : '') : '–'],
      ['surfels', this.surfels.toLocaleString('en-US')],
      this.ateRow(),
      ['fps', this.fps > 0 ? f1(this.fps) : '–'],
      ['ms / frame (wasm)', f1(this.stageMs.total)],
      ...STAGES.slice(0, -1)
        .filter((s) => s !== 'loop' || this.hasLoopStage)
        .map((s) => [`\u2003${s}`, f1(this.stageMs[s])]),
      ['ms / frame (worker)', f1(this.wallMs)],
      ['changed surfels', this.changed === undefined ? '–' : this.changed.toLocaleString('en-US')],
    ];
    this.table.replaceChildren(
      ...rows.map(([k, v]) => {
        const tr = document.createElement('tr');
        const th = document.createElement('th');
        const td = document.createElement('td');
        th.textContent = k;
        td.textContent = v;
        tr.append(th, td);
        return tr;
      }),
    );
  }
}
