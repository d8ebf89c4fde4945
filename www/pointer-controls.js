// Mouse, wheel and touch input of the map view: drag orbits, right / shift /
// middle drag pans, the wheel zooms, a double click fits the map; on touch,
// one finger orbits and two pinch-zoom and pan. Any of them leaves the
// follow-the-camera mode. `view` is the Renderer (orbit, pan, zoom,
// leaveFollow, fitView).

/** Installs the handlers on canvas `c`. */
export function installPointerControls(c, view) {
  c.style.touchAction = 'none';
  let drag = null;
  c.addEventListener('contextmenu', (e) => e.preventDefault());
  c.addEventListener('pointerdown', (e) => {
    if (e.pointerType === 'touch') return;
    c.setPointerCapture(e.pointerId);
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.button === 1 || e.shiftKey };
  });
  c.addEventListener('pointermove', (e) => {
    if (!drag || e.pointerType === 'touch') return;
    const dx = e.clientX - drag.x;
    const dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    view.leaveFollow();
    if (drag.pan) view.pan(dx, dy);
    else view.orbit(dx, dy);
  });
  const end = () => (drag = null);
  c.addEventListener('pointerup', end);
  c.addEventListener('pointercancel', end);
  c.addEventListener(
    'wheel',
    (e) => {
      e.preventDefault();
      view.leaveFollow();
      view.zoom(Math.exp(Math.sign(e.deltaY) * Math.min(Math.abs(e.deltaY), 200) * 0.0015));
    },
    { passive: false },
  );
  c.addEventListener('dblclick', () => view.fitView());

  // touch: one finger orbits, two fingers pinch-zoom and pan
  let touches = null;
  const snapshot = (list) => [...list].map((t) => ({ x: t.clientX, y: t.clientY }));
  const centre = (t) => ({ x: (t[0].x + t[1].x) / 2, y: (t[0].y + t[1].y) / 2 });
  const spread = (t) => Math.hypot(t[0].x - t[1].x, t[0].y - t[1].y);
  c.addEventListener('touchstart', (e) => {
    e.preventDefault();
    touches = snapshot(e.touches);
  }, { passive: false });
  c.addEventListener('touchmove', (e) => {
    e.preventDefault();
    const now = snapshot(e.touches);
    if (!touches || now.length !== touches.length) {
      touches = now;
      return;
    }
    view.leaveFollow();
    if (now.length === 1) {
      view.orbit(now[0].x - touches[0].x, now[0].y - touches[0].y);
    } else if (now.length >= 2) {
      const a = centre(touches), b = centre(now);
      view.pan(b.x - a.x, b.y - a.y);
      const s0 = spread(touches), s1 = spread(now);
      if (s0 > 0 && s1 > 0) view.zoom(s0 / s1);
    }
    touches = now;
  }, { passive: false });
  c.addEventListener('touchend', (e) => {
    touches = e.touches.length ? snapshot(e.touches) : null;
  });
}
