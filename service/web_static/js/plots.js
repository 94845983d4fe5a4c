// The three plots, drawn with uPlot (vendored, see ../vendor/VENDOR.md): the groups' illuminant
// spectra, the sensor's sensitivities, and white points in the sensor's R/G–B/G plane.
import uPlot from "../vendor/uPlot.esm.js";
import { GROUP_COLOURS } from "./images.js";

const LABELLED_KELVIN = [2000, 3000, 4000, 5000, 6500, 10000];
const charts = {};

function size(el) {
  return { width: Math.max(240, el.clientWidth - 8), height: el.id === "p-chroma" ? 300 : 220 };
}

function replace(id, opts, data) {
  const el = document.getElementById(id);
  charts[id]?.destroy();
  charts[id] = new uPlot({ ...size(el), ...opts }, data, el);
  return charts[id];
}

const nm = { label: "wavelength (nm)", size: 40 };
const rel = { label: "relative", size: 50 };

/** Each lit group's illuminant SPD (peak 1), coloured like the mixture map; `lit`: [{group, index}]. */
export function plotSpectra(spectra, lit) {
  const series = [{ label: "λ (nm)" }];
  const data = [spectra.wavelengths];
  spectra.illuminants.forEach((c, k) => {
    const { group, index } = lit[k];
    series.push({ label: `${group}: ${c.name}`, stroke: GROUP_COLOURS[index % GROUP_COLOURS.length], width: 2 });
    data.push(c.spd);
  });
  replace("p-spd", { series, axes: [nm, rel], scales: { x: { time: false }, y: { range: [0, 1.05] } } }, data);
}

/** The sensor's R, G, B sensitivities (peak 1). */
export function plotSensor(spectra) {
  const s = spectra.sensitivities;
  const data = [spectra.wavelengths, s.map((v) => v[0]), s.map((v) => v[1]), s.map((v) => v[2])];
  const series = [{ label: "λ (nm)" }, ...["R", "G", "B"].map((c, k) =>
    ({ label: `${spectra.sensor} ${c}`, stroke: ["#d62728", "#2ca02c", "#1f77b4"][k], width: 2 }))];
  replace("p-sensor", { series, axes: [nm, rel], scales: { x: { time: false }, y: { range: [0, 1.05] } } }, data);
}

// -- chromaticity ------------------------------------------------------------------------------
// uPlot's mode 2: every series has its own [xs, ys] (a locus need not be monotonic in R/G: on the
// XYZ "sensor" X/Y turns back near 7000 K).
let chroma = null;
let bounds = { x: [0, 2], y: [0, 2] };

function pad([lo, hi], f = 0.12) {
  const d = Math.max(hi - lo, 0.05) * f;
  return [lo - d, hi + d];
}

function labelKelvin(planckian) {
  return (u) => {
    const ctx = u.ctx;
    ctx.save();
    ctx.fillStyle = "#555";
    ctx.font = `${11 * devicePixelRatio}px sans-serif`;
    for (const p of planckian) {
      if (!LABELLED_KELVIN.includes(p.kelvin)) continue;
      const x = u.valToPos(p.r_over_g, "x", true), y = u.valToPos(p.b_over_g, "y", true);
      if (x < u.bbox.left || x > u.bbox.left + u.bbox.width || y < u.bbox.top || y > u.bbox.top + u.bbox.height) continue;
      ctx.fillText(`${p.kelvin} K`, x + 5 * devicePixelRatio, y + 12 * devicePixelRatio);
    }
    ctx.restore();
  };
}

const line = (stroke, width, dash) => ({ paths: uPlot.paths.linear(), stroke, width, dash });
const dots = (fill, size, stroke = "#222") =>
  ({ paths: uPlot.paths.points(), fill, stroke, width: 1, points: { show: false, size, width: 1 } });
const xy = (pts) => [pts.map((p) => p[0]), pts.map((p) => p[1])];

/**
 * Planckian and daylight loci of the sensor, each group's white point, the single global white
 * point of the baseline, a sample of the frame's per-pixel white points, and `hover` ([r/g, b/g]).
 */
export function plotChroma(spectra, frame, hover) {
  const groups = frame.meta.illuminants.filter((g) => g.intensity > 0);
  const base = frame.meta.baseline.white_point_rgb;
  const near = spectra.planckian.filter((p) => p.kelvin >= 2500 && p.kelvin <= 10000); // the usual AWB range
  const xs = [...groups.map((g) => g.white_point_rgb[0]), base[0], ...near.map((p) => p.r_over_g)];
  const ys = [...groups.map((g) => g.white_point_rgb[2]), base[2], ...near.map((p) => p.b_over_g)];
  bounds = { x: pad([Math.min(...xs), Math.max(...xs)]), y: pad([Math.min(...ys), Math.max(...ys)]) };
  const loc = (pts) => pts.map((p) => [p.r_over_g, p.b_over_g]);
  const sets = [loc(spectra.planckian), loc(spectra.daylight), frame.pixelWhitePoints];
  const series = [{},
    { label: "Planckian locus", ...line("#444", 1.5) },
    { label: "daylight locus", ...line("#888", 1, [5, 4]) },
    { label: "pixels of the frame (sample)", ...dots("rgba(90,90,90,0.45)", 5, "rgba(0,0,0,0)") }];
  groups.forEach((g) => {
    const k = frame.meta.illuminants.indexOf(g);
    sets.push([[g.white_point_rgb[0], g.white_point_rgb[2]]]);
    series.push({ label: `${g.group}: ${g.illuminant}`, ...dots(GROUP_COLOURS[k % GROUP_COLOURS.length], 12) });
  });
  sets.push([[base[0], base[2]]]);
  series.push({ label: "global white point (baseline)", ...dots("#fff", 12, "#000") });
  sets.push(hover ? [hover] : []);
  series.push({ label: "pixel under the cursor", ...dots("rgba(0,0,0,0)", 14, "#d00") });
  const opts = {
    mode: 2, series, legend: { live: false }, cursor: { show: false, drag: { x: false, y: false } },
    axes: [{ label: "R/G (camera raw)", size: 40 }, { label: "B/G", size: 50 }],
    scales: { x: { time: false, range: () => bounds.x }, y: { range: () => bounds.y } },
    hooks: { draw: [labelKelvin(spectra.planckian)] },
  };
  chroma = { sets, u: replace("p-chroma", opts, [null, ...sets.map(xy)]) };
}

/** Move the hovered pixel's marker (cheap: only the data changes). */
export function chromaHover(point) {
  if (!chroma) return;
  chroma.sets[chroma.sets.length - 1] = point ? [point] : [];
  chroma.u.setData([null, ...chroma.sets.map(xy)]); // the scales' ranges are fixed: nothing jumps
}

export function resizePlots() {
  for (const [id, u] of Object.entries(charts)) u.setSize(size(document.getElementById(id)));
}
