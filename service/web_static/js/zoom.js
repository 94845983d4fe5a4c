// Zoom and pan on the image panels, one view shared by all of them (they show the same frame):
// the wheel zooms about the cursor, a drag pans, a double-click resets. The view is a CSS transform
// on each canvas — no redraw, the pixels stay crisp (image-rendering: pixelated).
//
// Coordinates: u, v ∈ [0, 1] across the image; a panel shows image point u at panel fraction
// ox + s·u (s ≥ 1 the zoom, ox ∈ [1 − s, 0] the offset), likewise v with oy.

export const MAX_ZOOM = 64;
const view = { s: 1, ox: 0, oy: 0 };
const listeners = [];

/** The current view {s, ox, oy} (a copy). */
export const zoomState = () => ({ ...view });

/** Call `fn(view)` after every change (the hover marker follows). */
export function onZoom(fn) { listeners.push(fn); }

function clamp() {
  view.s = Math.min(MAX_ZOOM, Math.max(1, view.s));
  view.ox = Math.min(0, Math.max(1 - view.s, view.ox));
  view.oy = Math.min(0, Math.max(1 - view.s, view.oy));
}

function apply() {
  clamp();
  const t = view.s === 1 ? "" : `translate(${100 * view.ox}%, ${100 * view.oy}%) scale(${view.s})`;
  for (const c of document.querySelectorAll(".frame canvas")) c.style.transform = t;
  document.body.dataset.zoom = view.s.toFixed(4); // for tests and the status line
  for (const fn of listeners) fn(zoomState());
}

/** Zoom by `factor` keeping the image point under panel fraction (mx, my) where it is. */
export function zoomAt(mx, my, factor) {
  const u = (mx - view.ox) / view.s, v = (my - view.oy) / view.s;
  view.s = Math.min(MAX_ZOOM, Math.max(1, view.s * factor));
  view.ox = mx - view.s * u;
  view.oy = my - view.s * v;
  apply();
}

export function resetZoom() {
  Object.assign(view, { s: 1, ox: 0, oy: 0 });
  apply();
}

/** The view for the page link (js/link.js): null at no zoom, else {s, u, v}, (u, v) the image point at the panels' centre. */
export function zoomLink() {
  return view.s === 1 ? null : { s: view.s, u: (0.5 - view.ox) / view.s, v: (0.5 - view.oy) / view.s };
}

/** Panel fraction (mx, my) of a pointer event over `frame` (an element of class .frame). */
export function panelFraction(frame, ev) {
  const r = frame.getBoundingClientRect();
  return [(ev.clientX - r.left) / r.width, (ev.clientY - r.top) / r.height];
}

/** The image point [u, v] under panel fraction (mx, my). */
export const toImage = (mx, my) => [(mx - view.ox) / view.s, (my - view.oy) / view.s];

/** The panel fraction [mx, my] where image point (u, v) is shown. */
export const toPanel = (u, v) => [view.ox + view.s * u, view.oy + view.s * v];

/**
 * Wire every .frame: wheel (zoom about the cursor), drag (pan), double-click (reset); the view starts at
 * `start` ({s, u, v}: zoom s with image point (u, v) at the panels' centre, clamped as any view) or unzoomed.
 */
export function wireZoom(start = null) {
  if (start) Object.assign(view, { s: start.s, ox: 0.5 - start.s * start.u, oy: 0.5 - start.s * start.v });
  let drag = null;
  for (const frame of document.querySelectorAll(".frame")) {
    frame.addEventListener("wheel", (ev) => {
      if (view.s === 1 && ev.deltaY > 0) return; // nothing to zoom out of: the page scrolls as usual
      ev.preventDefault(); // the page must not scroll while zooming
      const [mx, my] = panelFraction(frame, ev);
      // a wheel notch (deltaY ±100) zooms by 1.25; trackpads send smaller deltas: smaller steps
      zoomAt(mx, my, Math.exp(-Math.max(-300, Math.min(300, ev.deltaY)) * (Math.log(1.25) / 100)));
    }, { passive: false });
    frame.addEventListener("mousedown", (ev) => {
      if (ev.button !== 0) return;
      ev.preventDefault(); // no text selection while dragging
      const r = frame.getBoundingClientRect();
      drag = { x: ev.clientX, y: ev.clientY, w: r.width, h: r.height, ox: view.ox, oy: view.oy };
      frame.classList.add("dragging");
    });
    frame.addEventListener("dblclick", resetZoom);
  }
  window.addEventListener("mousemove", (ev) => {
    if (!drag) return;
    view.ox = drag.ox + (ev.clientX - drag.x) / drag.w;
    view.oy = drag.oy + (ev.clientY - drag.y) / drag.h;
    apply();
  });
  window.addEventListener("mouseup", () => {
    drag = null;
    for (const f of document.querySelectorAll(".frame.dragging")) f.classList.remove("dragging");
  });
  apply();
}
