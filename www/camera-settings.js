// The panel's camera and tracker settings: the preset list, the intrinsics
// fields, the tracker, noise model, half-resolution and loop-closure choices, and the Slam config they
// make (docs/js-api.md, "Config keys"). Used by app.js.

export class CameraSettings {
  /**
   * `el`: {preset, fx, fy, cx, cy, depthScale, tracker, noise, half, loopClosure, apply} elements;
   * `views`: the input views (their depth colour range follows the preset);
   * `onApply(config)`: the settings changed while a sequence is open;
   * `onError(text)`: the fields do not make a config.
   */
  constructor(el, { views, onApply, onError, hasSequence }) {
    this.el = el;
    this.views = views;
    this.presets = [];
    this.sequencePreset = null; // the open sequence's preset: the base of a 'custom' config
    // The open sequence's image size when its layout states one (a RealSense
    // JSON at 848x480, a Stray scan's 256x192): a preset's size is its
    // camera's default, and the frames do not change size with the preset.
    this.sequenceSize = null;
    // Every preset at the open sequence's frame size (presetsForImageSize):
    // choosing one for a resized recording gives its calibration scaled.
    this.sequencePresets = null;
    const apply = () => {
      // An empty field is refused, not filled from a preset behind the user's back.
      const empty = this.emptyFields();
      if (empty.length) {
        onError(`camera settings: ${empty.join(', ')} ${empty.length === 1 ? 'is' : 'are'} empty: type a value, or choose a preset to fill every field`);
        return;
      }
      const c = this.current();
      if (![c.fx, c.fy, c.cx, c.cy, c.depthScale].every(Number.isFinite)) onError('camera settings: fx, fy, cx, cy and depth scale must be numbers');
      else onApply(c);
    };
    el.preset.addEventListener('change', () => {
      if (el.preset.value === 'custom') return;
      this.show(el.preset.value);
      if (hasSequence()) apply();
    });
    for (const field of [el.fx, el.fy, el.cx, el.cy, el.depthScale]) {
      field.addEventListener('input', () => {
        el.preset.value = 'custom';
      });
    }
    el.apply.addEventListener('click', apply);
    for (const choice of [el.tracker, el.noise, el.half, el.loopClosure]) {
      choice.addEventListener('change', () => {
        if (hasSequence()) apply();
      });
    }
  }

  /** presets(): [{name, fx, fy, cx, cy, width, height, depthScale, depthMin, depthMax}]. */
  setPresets(presets) {
    this.presets = presets;
    this.el.preset.replaceChildren(
      ...presets.map((p) => new Option(`${p.name} (${p.width}×${p.height})`, p.name)),
      new Option('custom', 'custom'),
    );
  }

  /** Preset `name` at the open sequence's frame size (its own size without one), or undefined. */
  preset(name) {
    return (this.sequencePresets ?? this.presets).find((x) => x.name === name);
  }

  /** Shows preset `name`'s intrinsics with `overrides` (a Slam config's fields) on top. */
  show(name, overrides = {}) {
    const el = this.el;
    const p = this.preset(name) ?? {};
    const v = { ...p, ...overrides };
    el.preset.value = this.presets.some((x) => x.name === name) ? name : 'custom';
    // Presets arrive as f32 values (535.4000244...): show them as published.
    const tidy = (x) => (Number.isFinite(x) ? String(Number(x.toFixed(4))) : '');
    el.fx.value = tidy(v.fx);
    el.fy.value = tidy(v.fy);
    el.cx.value = tidy(v.cx);
    el.cy.value = tidy(v.cy);
    el.depthScale.value = tidy(v.depthScale);
    if (v.depthMin !== undefined && v.depthMax !== undefined) this.views.setDepthRange(v.depthMin, Math.min(v.depthMax, 6));
  }

  /** Names of the intrinsics fields left empty (or holding no number). */
  emptyFields() {
    const el = this.el;
    const fields = { fx: el.fx, fy: el.fy, cx: el.cx, cy: el.cy, 'depth scale': el.depthScale };
    return Object.entries(fields)
      .filter(([, f]) => f.value.trim() === '' || !Number.isFinite(Number(f.value)))
      .map(([name]) => name);
  }

  /** The Slam config the fields make. */
  current() {
    const el = this.el;
    const base = this.preset(el.preset.value) ?? this.preset(this.sequencePreset) ?? {};
    const num = (field, fallback) => (field.value === '' || !Number.isFinite(Number(field.value)) ? fallback : Number(field.value));
    return {
      preset: base.name,
      width: this.sequenceSize?.width ?? base.width ?? 640,
      height: this.sequenceSize?.height ?? base.height ?? 480,
      fx: num(el.fx, base.fx),
      fy: num(el.fy, base.fy),
      cx: num(el.cx, base.cx),
      cy: num(el.cy, base.cy),
      depthScale: num(el.depthScale, base.depthScale),
      ...this.pageOptions(),
    };
  }

  /** The choices on the page that a newly opened sequence keeps. */
  pageOptions() {
    const el = this.el;
    // No noise or tracker key: the preset's own.
    const noise = el.noise.value ? { noise: el.noise.value } : {};
    const tracker = el.tracker.value ? { tracker: el.tracker.value } : {};
    return { ...tracker, halfResolution: el.half.checked, loopClosure: el.loopClosure.checked, ...noise };
  }
}
