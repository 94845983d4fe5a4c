// The spectrum at the hovered pixel: GET /explore/pixel (each light group's relit radiance and
// illumination there, their sum and the reflectance), drawn with uPlot on a wavelength axis.
import uPlot from "../vendor/uPlot.esm.js";
import { getJSON } from "./api.js";
import { GROUP_COLOURS, esc } from "./images.js";

const REST_MS = 60; // ask when the pointer rests this long: not one request per pixel of travel
let timer = null, inflight = null, chart = null, shown = "", last = null;

/** What the chart shows: "radiance" (the light each group sends to the camera) or "illumination". */
const kind = () => document.getElementById("px-kind").value;

/** Ask for the spectra at frame pixel (x, y) of the frame `params` describe (once the pointer rests). */
export function hoverSpectrum(params, x, y) {
  const q = new URLSearchParams({ ...params, x, y });
  const key = q.toString();
  if (key === shown) return;
  clearTimeout(timer);
  timer = setTimeout(() => fetchSpectrum(key, x, y), REST_MS);
}

async function fetchSpectrum(key, x, y) {
  inflight?.abort();
  const mine = (inflight = new AbortController());
  const note = document.getElementById("px-note");
  try {
    const s = await getJSON(`/explore/pixel?${key}`, { signal: mine.signal });
    if (mine !== inflight) return;
    shown = key;
    last = s;
    draw();
    const fp = s.footprint;
    note.className = "legend muted";
    note.textContent = `pixel ${x}, ${y}` + (fp[2] * fp[3] > 1 ? ` = mean of view pixels ${fp[0]}..${fp[0] + fp[2] - 1}, `
      + `${fp[1]}..${fp[1] + fp[3] - 1}${s.area_weighted ? "" : " (approximately the frame's area weights)"}` : "")
      + (s.valid === false ? " · no ground truth here" : "");
    document.body.dataset.spectra = String(Number(document.body.dataset.spectra || 0) + 1); // for tests
  } catch (e) {
    if (e.name === "AbortError" || mine !== inflight) return;
    note.className = "legend error";
    note.textContent = `spectrum: ${e.message}`;
  }
}

/** (Re)draw the last answer: one curve per lit group, their sum in black. */
export function draw() {
  if (!last) return;
  const el = document.getElementById("p-pixel");
  const k = kind(), s = last;
  const data = [s.wavelengths], series = [{ label: "λ (nm)" }];
  if (k === "reflectance" && s.total.reflectance) {
    series.push({ label: "reflectance (ΣT / ΣU)", stroke: "#111", width: 2 });
    data.push(s.total.reflectance);
  }
  if (k !== "reflectance") s.groups.forEach((g, i) => {
    if (!(g.intensity > 0) || !g[k]) return;
    series.push({ label: `${g.group}: ${g.illuminant}`, stroke: GROUP_COLOURS[i % GROUP_COLOURS.length], width: 2 });
    data.push(g[k]);
  });
  if (k !== "reflectance" && s.total[k]) {
    series.push({ label: "sum", stroke: "#111", width: 1.5, dash: [4, 3] });
    data.push(s.total[k]);
  }
  if (data.length === 1) {
    el.textContent = "this view has no illumination cubes: only the radiance is available";
    chart?.destroy(); chart = null;
    return;
  }
  const opts = {
    width: Math.max(240, el.clientWidth - 8), height: 190, series, legend: { live: false },
    axes: [{ label: "wavelength (nm)", size: 36 }, { label: { radiance: "radiance (relative)", illumination: "white-surface radiance (relative)", reflectance: "reflectance" }[k], size: 60 }],
    scales: { x: { time: false }, y: { range: (u, lo, hi) => [0, hi > 0 ? hi * 1.05 : 1] } },
  };
  chart?.destroy();
  el.textContent = "";
  chart = new uPlot(opts, data, el);
  el.dataset.bands = `${data[0].length} bands, ${data[0][0]}-${data[0].at(-1)} nm`; // for tests
  const rgb = s.total.raw_rgb.map((v) => v.toPrecision(4)).join(", ");
  document.getElementById("px-raw").innerHTML = `raw (R, G, B) of the sum: ${esc(rgb)}`
    + (s.total.reflectance ? "" : ' <span class="muted">(no reflectance: no illumination cubes)</span>');
}

/** The panel's controls (radiance / illumination). */
export function wireSpectrum() {
  document.getElementById("px-kind").onchange = draw;
}
