// The page state and the links made of it: the page's own URL (a shared link reopens the view; js/linkcheck.js
// reads it back) and the download links of the current sample.
import { DEFAULT_NPZ, setDownloads } from "./forms.js";
import { zoomLink } from "./zoom.js";

export const lib = { scenes: [], sensors: null, illuminants: null };
export const state = {};

export const currentScene = () => lib.scenes.find((s) => s.name === state.scene);
export const currentView = () => currentScene().views.find((v) => v.name === state.view);

/** The /sample parameters of the current view (shared by the frame request and the downloads), or of `st`. */
export function sampleParams(st = state) {
  const p = { scene: st.scene, view: st.view, sensor: st.sensor, illuminants: st.illuminants.join(","),
    intensities: st.intensities.join(",") };
  if (st.size) p.size = st.size; // WxH, as /sample takes it; none: the view's own size
  if (st.gt) p.gt = st.gt;
  if (st.denoise) p.denoise = st.denoise; // none: the cubes as rendered; unset: the stored copies
  return p;
}

const r4 = (x) => String(Number(x.toFixed(4)));

/**
 * The state into the URL. Zoom and pan go in as `zoom=s` and `at=u,v`: the image point at the panels'
 * centre in fractions of the image (0–1), not pixels, so a link shows the same spot at any frame size
 * (size=…); at no zoom neither is written (a reset drops them).
 */
export function writeURL() {
  const q = new URLSearchParams(sampleParams());
  if (state.ev) q.set("ev", state.ev);
  if (state.gain !== "br") q.set("gain", state.gain);
  if (String(state.npz) !== String(DEFAULT_NPZ)) q.set("npz", state.npz.join(","));
  if (state.aov) q.set("aov", state.aov);
  if (state.noise) q.set("noise", state.noise);
  const z = zoomLink();
  if (z) {
    q.set("zoom", r4(z.s));
    q.set("at", `${r4(z.u)},${r4(z.v)}`);
  }
  history.replaceState(null, "", `?${q}`);
}

let zoomTimer = null;
/** After a zoom or pan step: the URL follows once the gesture rests (a drag moves the view on every
 * mouse event, and the browser throttles replaceState called that often). */
export function writeURLSoon() {
  clearTimeout(zoomTimer);
  zoomTimer = setTimeout(writeURL, 150);
}

export function downloads() {
  setDownloads(sampleParams(), `${state.scene}-${state.view}`, state.npz);
}

/** The link values that were replaced: one line above the images (a click shows it all; × clears it). */
export function notice(notes) {
  const box = document.getElementById("notice"), text = document.getElementById("notice-text");
  box.hidden = !notes.length;
  text.textContent = notes.length ? `Link values replaced: ${notes.join("; ")}` : "";
  text.title = "click to show it all";
}
