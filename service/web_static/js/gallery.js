// The dataset gallery: samples drawn as the Python client's IllumixDataset draws them
// (clients/python/illumix_client/draw.py, SpecSampler.spec: a view uniformly, one illuminant per
// light group from the pool — a CCT range drawn uniformly and rounded to 50 K — redrawn up to 8
// times to differ from the groups before it, intensities U(lo, hi) divided by their maximum, a
// sensor uniformly), each fetched as a small GET /sample, with statistics over the drawn set:
// the illuminants' CIE xy chromaticities, a histogram of the mixture (the strongest group's share
// per pixel) and each sample's white-balance gain range.
//
// The generator is a seeded JavaScript one (mulberry32 per item of (seed, index)): the same
// distribution as the client's numpy generator, not its bit stream. For the exact items of a
// dataset, paste their specs ([ds.spec(i) for i in range(24)] as JSON).
import uPlot from "../vendor/uPlot.esm.js";
import { getArrays, getJSON } from "./api.js";
import { GROUP_COLOURS, drawRGB8, esc } from "./images.js";

export const COUNTS = [12, 16, 24];
export const DEFAULT_POOL = "A,D65,FL11,blackbody:2500-7500,daylight:4000-10000"; // IllumixDataset's default
const THUMB_W = 96, CCT_STEP = 50, PARALLEL = 4, MIXED = 0.9;
const RANGE = /^\s*(blackbody|daylight)\s*:\s*(\d+(?:\.\d*)?)\s*[-–]\s*(\d+(?:\.\d*)?)\s*[kK]?\s*$/;
const charts = {};
let run = 0;

/** mulberry32: a small seeded generator of uniform [0, 1) numbers. */
function mulberry32(a) {
  return () => {
    a = (a + 0x6d2b79f5) | 0;
    let t = Math.imul(a ^ (a >>> 15), 1 | a);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/** The generator of item `index` for `seed` (independent items, like default_rng([seed, epoch, i])). */
export function itemRng(seed, index) {
  return mulberry32((Math.imul(seed >>> 0, 0x9e3779b1) ^ Math.imul(index + 1, 0x85ebca77)) >>> 0);
}

/** One pool entry drawn: a name, or "blackbody:K" / "daylight:K" from a range. */
function drawEntry(rng, entry) {
  const m = RANGE.exec(entry);
  if (!m) return entry.trim();
  const lo = Number(m[2]), hi = Number(m[3]);
  const k = Math.min(Math.max(Math.round((lo + rng() * (hi - lo)) / CCT_STEP) * CCT_STEP, lo), hi);
  return `${m[1]}:${k}`;
}

/** SpecSampler.spec of the client, for one item: {scene, view, sensor, illuminants, intensities, seed}. */
export function drawSpec(rng, views, pool, sensors, [lo, hi] = [0.25, 1]) {
  const pick = (list) => list[Math.floor(rng() * list.length)];
  const v = pick(views);
  const names = [];
  for (let g = 0; g < v.groups.length; g++) {
    let name = drawEntry(rng, pick(pool));
    for (let k = 0; k < 8 && names.includes(name); k++) name = drawEntry(rng, pick(pool));
    names.push(name);
  }
  const a = v.groups.map(() => lo + rng() * (hi - lo));
  const top = Math.max(...a);
  return { scene: v.scene, view: v.view, seed: Math.floor(rng() * 2147483647), sensor: pick(sensors),
    illuminants: names, intensities: a.map((x) => Math.round((x / top) * 1e6) / 1e6), width: v.width, height: v.height };
}

/** The specs to show: drawn from the controls, or the pasted ones (each needs scene and view). */
function specs(lib, box) {
  const pasted = box.querySelector("#gal-specs").value.trim();
  const views = lib.scenes.flatMap((s) => s.views.map((v) => ({ scene: s.name, view: v.name, width: v.width,
    height: v.height, groups: v.groups.map((g) => g.name) })));
  if (pasted) {
    const list = JSON.parse(pasted);
    if (!Array.isArray(list) || !list.length) throw new Error("pasted specs: a JSON list of /batch items");
    return list.slice(0, COUNTS.at(-1)).map((s) => {
      const v = views.find((w) => w.scene === s.scene && w.view === s.view);
      if (!v) throw new Error(`pasted specs: no view ${s.scene}/${s.view} in this store`);
      return { ...s, width: v.width, height: v.height };
    });
  }
  const seed = Number(box.querySelector("#gal-seed").value) >>> 0;
  const n = Number(box.querySelector("#gal-count").value);
  const pool = box.querySelector("#gal-pool").value.split(",").map((x) => x.trim()).filter(Boolean);
  const sensors = box.querySelector("#gal-sensors").value.split(",").map((x) => x.trim()).filter(Boolean);
  if (!pool.length || !sensors.length) throw new Error("the illuminant pool and the sensors need one name each");
  return Array.from({ length: n }, (_, i) => drawSpec(itemRng(seed, i), views, pool, sensors));
}

/** The GET /sample query of a spec, at thumbnail size. */
function sampleQuery(s) {
  const h = Math.max(1, Math.round((THUMB_W * s.height) / s.width));
  const q = { scene: s.scene, view: s.view, sensor: s.sensor || "XYZ", outputs: "srgb,gain,mixture,mask,meta",
    format: "arrays", size: `${THUMB_W}x${h}`, seed: String(s.seed ?? 0) };
  if (s.illuminants) q.illuminants = [].concat(s.illuminants).join(",");
  if (s.pair) q.pair = [].concat(s.pair).join(",");
  if (s.intensities) q.intensities = [].concat(s.intensities).join(",");
  for (const k of ["gt", "denoise", "crop"]) if (s[k] != null) q[k] = [].concat(s[k]).join(",");
  return new URLSearchParams(q);
}

/** Per sample: the strongest group's share at each valid pixel, and the gain range (1st–99th %). */
export function sampleStats(arrays) {
  const { mixture, gain, mask } = arrays;
  const [h, w, g] = mixture.shape, n = w * h;
  const top = [], gr = [], gb = [];
  for (let i = 0; i < n; i++) {
    if (!mask.data[i]) continue;
    let m = 0;
    for (let k = 0; k < g; k++) m = Math.max(m, mixture.data[g * i + k]);
    top.push(m);
    gr.push(gain.data[3 * i]); gb.push(gain.data[3 * i + 2]);
  }
  const q = (a, p) => { if (!a.length) return NaN; const s = [...a].sort((x, y) => x - y); return s[Math.min(s.length - 1, Math.floor(p * s.length))]; };
  return { top, mixed: top.length ? top.filter((m) => m < MIXED).length / top.length : NaN,
    gainR: [q(gr, 0.01), q(gr, 0.99)], gainB: [q(gb, 0.01), q(gb, 0.99)] };
}

function tile(grid, s, i) {
  const div = document.createElement("figure");
  div.className = "gal-item";
  const q = new URLSearchParams({ scene: s.scene, view: s.view, sensor: s.sensor || "XYZ",
    illuminants: [].concat(s.illuminants || []).join(","), intensities: [].concat(s.intensities || []).join(",") });
  div.innerHTML = `<a href="?${q}" title="open in the explorer"><canvas></canvas></a>
    <figcaption class="muted">#${i} ${esc(s.scene)}/${esc(s.view)}<br>${esc(s.sensor || "XYZ")}<br>
    ${[].concat(s.illuminants || s.pair || []).map(esc).join(" + ")}</figcaption>`;
  grid.append(div);
  return div;
}

/** Draw the gallery for the controls in `box`; `lib` = {scenes (views not damaged)}. */
export async function drawGallery(lib, box) {
  const mine = ++run;
  const grid = box.querySelector("#gal-grid"), note = box.querySelector("#gal-status");
  grid.innerHTML = "";
  let list;
  try { list = specs(lib, box); } catch (e) { note.className = "error"; note.textContent = e.message; return; }
  note.className = "muted";
  note.textContent = `composing ${list.length} samples…`;
  const results = new Array(list.length);
  const tiles = list.map((s, i) => tile(grid, s, i));
  let next = 0;
  const worker = async () => {
    while (next < list.length && mine === run) {
      const i = next++;
      try {
        const got = await getArrays(`/sample?${sampleQuery(list[i])}`);
        const srgb = got.arrays.srgb; // float32 in [0, 1] from /sample → bytes for the canvas
        drawRGB8(tiles[i].querySelector("canvas"),
          { data: Uint8Array.from(srgb.data, (v) => Math.round(255 * Math.min(1, Math.max(0, v)))), shape: srgb.shape });
        results[i] = { index: i, spec: list[i], meta: got.meta, ...sampleStats(got.arrays) };
        tiles[i].querySelector("figcaption").insertAdjacentHTML("beforeend",
          `<br>mixed ${(100 * results[i].mixed).toFixed(0)} %`);
      } catch (e) {
        tiles[i].classList.add("failed");
        tiles[i].querySelector("figcaption").insertAdjacentHTML("beforeend",
          `<br><span class="error gal-error" title="${esc(e.message)}">${esc(e.message)}</span>`);
      }
    }
  };
  await Promise.all(Array.from({ length: PARALLEL }, worker));
  if (mine !== run) return;
  const ok = results.filter(Boolean);
  await plotStats(ok, results.length);
  note.textContent = `${ok.length} of ${list.length} samples composed` + (ok.length < list.length ? " (see the red lines)" : "");
  document.body.dataset.gallery = String(Number(document.body.dataset.gallery || 0) + 1); // for tests
}

/** CIE xy of illuminant names, from GET /explore/spectra with the XYZ "sensor" (white point X/Y, 1, Z/Y). */
export async function chromaticities(names) {
  const xy = {};
  let locus = [];
  const xyOf = (rx, bz) => [rx / (rx + 1 + bz), 1 / (rx + 1 + bz)];
  for (let i = 0; i < Math.max(1, names.length); i += 16) {
    const q = new URLSearchParams({ sensor: "XYZ", illuminants: names.slice(i, i + 16).join(",") });
    const s = await getJSON(`/explore/spectra?${q}`);
    for (const c of s.illuminants) xy[c.name] = xyOf(c.r_over_g, c.b_over_g);
    locus = s.planckian.filter((p) => p.kelvin >= 1500).map((p) => xyOf(p.r_over_g, p.b_over_g));
  }
  return { xy, locus };
}

function replace(id, opts, data) {
  const el = document.getElementById(id);
  charts[id]?.destroy();
  el.textContent = "";
  charts[id] = new uPlot({ width: Math.max(240, el.clientWidth - 8), height: 240, ...opts }, data, el);
}

const dots = (fill, size) => ({ paths: uPlot.paths.points(), fill, stroke: "#222", width: 1, points: { show: false, size } });
const xyOf = (pts) => [pts.map((p) => p[0]), pts.map((p) => p[1])];

async function plotStats(ok, n) {
  const names = [...new Set(ok.flatMap((r) => r.meta.illuminants.filter((g) => g.intensity > 0).map((g) => g.illuminant)))];
  const { xy, locus } = await chromaticities(names);
  // chromaticities: one dot per lit group of each sample, coloured by the group's index
  const byGroup = [];
  for (const r of ok) r.meta.illuminants.forEach((g, k) => { if (g.intensity > 0 && xy[g.illuminant]) (byGroup[k] ||= []).push(xy[g.illuminant]); });
  const sets = [locus, ...byGroup.map((p) => p || [])];
  const series = [{}, { label: "Planckian locus", paths: uPlot.paths.linear(), stroke: "#444", width: 1.5 },
    ...byGroup.map((_, k) => ({ label: `light group ${k + 1}`, ...dots(GROUP_COLOURS[k % GROUP_COLOURS.length], 9) }))];
  // the axes span the drawn points and the locus' usual range (2500-10000 K), padded
  const span = [...byGroup.flat(), ...locus.filter((p) => p[0] > 0.28 && p[0] < 0.47)];
  const pad = (vals) => [Math.min(...vals) - 0.02, Math.max(...vals) + 0.02];
  const bx = pad(span.map((p) => p[0])), by = pad(span.map((p) => p[1]));
  replace("gal-xy", { mode: 2, series, legend: { live: false }, cursor: { show: false },
    axes: [{ label: "CIE x", size: 36 }, { label: "CIE y", size: 50 }],
    scales: { x: { time: false, range: () => bx }, y: { range: () => by } } }, [null, ...sets.map(xyOf)]);
  // mixture: histogram of the strongest group's share per valid pixel, over every sample
  const bins = 20, counts = new Array(bins).fill(0);
  let total = 0;
  for (const r of ok) for (const m of r.top) { counts[Math.min(bins - 1, Math.floor(m * bins))]++; total++; }
  replace("gal-mix", { series: [{ label: "share" }, { label: "pixels (%)", fill: "#56b4e988", stroke: "#0072b2",
    paths: uPlot.paths.bars({ size: [0.9] }) }], legend: { live: false },
    axes: [{ label: "strongest group's share of a pixel", size: 36 }, { label: "% of pixels", size: 50 }],
    scales: { x: { time: false, range: [0, 1] }, y: { range: (u, lo, hi) => [0, Math.max(1, hi * 1.1)] } } },
  [counts.map((_, k) => (k + 0.5) / bins), counts.map((c) => (total ? (100 * c) / total : 0))]);
  const mixed = ok.reduce((a, r) => a + r.top.filter((m) => m < MIXED).length, 0);
  document.getElementById("gal-mix-note").textContent = total
    ? `${(100 * mixed / total).toFixed(1)} % of ${total} valid pixels are mixed (no group gives ${100 * MIXED} % or more)` : "";
  plotGains(ok, n);
}

/** Each sample's gain R and gain B range (1st–99th percentile over its valid pixels), on a log axis. */
function plotGains(ok, n) {
  const sets = [], series = [{}];
  ok.forEach((r) => {
    const i = r.index; // the tile's number (failed samples leave a gap)
    for (const [c, range, dx, colour] of [["R", r.gainR, -0.12, "#d62728"], ["B", r.gainB, 0.12, "#1f77b4"]]) {
      if (!range.every(Number.isFinite)) continue;
      sets.push([[i + dx, range[0]], [i + dx, range[1]]]);
      series.push({ label: `#${i} gain ${c}`, paths: uPlot.paths.linear(), stroke: colour, width: 4 });
    }
  });
  replace("gal-gain", { mode: 2, series, legend: { show: false }, cursor: { show: false },
    axes: [{ label: "sample # (red: R, blue: B; 1–99 %)", size: 36 }, { label: "gain", size: 50 }],
    scales: { x: { time: false, range: [-0.7, Math.max(1, n) - 0.3] } } }, [null, ...sets.map(xyOf)]);
  const all = (k) => ok.map((r) => r[k]).filter((v) => v.every(Number.isFinite));
  const span = (list) => (list.length ? `${Math.min(...list.map((v) => v[0])).toFixed(2)}–${Math.max(...list.map((v) => v[1])).toFixed(2)}` : "–");
  document.getElementById("gal-gain-note").textContent = `over the set: gain R ${span(all("gainR"))}, gain B ${span(all("gainB"))}`;
}
