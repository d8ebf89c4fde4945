// The view options of the panel (colour mode, splat size, follow, what is
// drawn, plots) and the hint naming the panel's sections below the fold.
// Used by app.js.
import { STAGE_COLOURS, VERDICT_COLOURS } from './plots.js';

const $ = (id) => document.getElementById(id);

/** Wires the view controls to `renderer` (null when WebGL is unavailable) and `plots`. */
export function wireViewControls({ renderer, plots }) {
  // The stage colours of the timing chart, then the verdict strip's.
  const legend = ([name, colour]) => {
    const swatch = document.createElement('span');
    swatch.style.background = colour;
    return [swatch, document.createTextNode(name)];
  };
  const verdicts = Object.entries(VERDICT_COLOURS).filter(([name]) => name !== 'initialised');
  $('plot-legend').replaceChildren(
    ...Object.entries(STAGE_COLOURS).flatMap(legend),
    document.createTextNode(' · frames:'),
    ...verdicts.flatMap(legend),
  );

  // A hint naming the panel's sections below the fold (at 1280x800 the
  // camera and view settings are); a click scrolls to the first.
  const panel = $('panel');
  const moreBelow = $('more-below');
  function updateMoreBelow() {
    const bottom = panel.getBoundingClientRect().bottom - moreBelow.offsetHeight;
    const hidden = [...panel.querySelectorAll('section h2')].filter((h) => h.getBoundingClientRect().top > bottom);
    moreBelow.hidden = hidden.length === 0;
    $('more-below-text').textContent = `below: ${hidden.map((h) => h.textContent).join(' · ')}`;
    moreBelow.onclick = () => hidden[0]?.scrollIntoView({ behavior: 'smooth', block: 'start' });
  }
  panel.addEventListener('scroll', updateMoreBelow, { passive: true });
  window.addEventListener('resize', updateMoreBelow);
  const panelObserver = new ResizeObserver(updateMoreBelow); // messages and stats change the sections' heights
  for (const el of panel.children) panelObserver.observe(el);
  $('show-plots').addEventListener('change', (e) => {
    $('plots').hidden = !e.target.checked;
    plots.setVisible(e.target.checked);
  });

  $('colour-mode').addEventListener('change', (e) => renderer?.setMode(e.target.value));
  $('splat-size').addEventListener('input', (e) => {
    if (renderer) {
      renderer.sizeScale = Number(e.target.value);
      renderer.dirty = true;
    }
  });
  const follow = $('follow');
  follow.addEventListener('change', () => {
    if (!renderer) return;
    if (follow.checked) renderer.follow = true;
    else renderer.leaveFollow();
    renderer.dirty = true;
  });
  if (renderer) renderer.onFollowChange = (on) => (follow.checked = on);
  for (const [id, key] of [['show-trajectory', 'trajectory'], ['show-gt', 'groundTruth'], ['show-frustum', 'frustum']]) {
    $(id).addEventListener('change', (e) => {
      if (!renderer) return;
      renderer.show[key] = e.target.checked;
      renderer.dirty = true;
    });
  }
  $('fit-button').addEventListener('click', () => renderer?.fitView());
  $('view-button').addEventListener('click', () => {
    if (!renderer) return;
    follow.checked = false;
    renderer.follow = false;
    renderer.resetView();
  });
}
