// Drawing a frame's arrays on canvases: display-ready sRGB, the raw preview, and false-colour maps
// with their legends. Arrays are flat typed arrays in C order, (H, W, C).

// Okabe–Ito colours (distinguishable with colour-vision deficiencies), one per light group.
export const GROUP_COLOURS = ["#e69f00", "#56b4e9", "#009e73", "#cc79a7", "#f0e442", "#0072b2", "#d55e00", "#999999"];

// viridis (matplotlib), 9 stops; interpolated to a 256-entry table
const VIRIDIS = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962", "#addc30", "#fde725"];
const LUT = buildLut(VIRIDIS.map(hexRgb));

/** Text for an innerHTML template: names come from the store and from uploads. */
export function esc(text) {
  return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

export function hexRgb(hex) {
  const n = parseInt(hex.slice(1), 16);
  return [(n >> 16) & 255, (n >> 8) & 255, n & 255];
}

function buildLut(stops) {
  const lut = new Uint8Array(256 * 3);
  for (let i = 0; i < 256; i++) {
    const t = (i / 255) * (stops.length - 1);
    const k = Math.min(Math.floor(t), stops.length - 2);
    const f = t - k;
    for (let c = 0; c < 3; c++) lut[3 * i + c] = Math.round(stops[k][c] * (1 - f) + stops[k + 1][c] * f);
  }
  return lut;
}

// sRGB transfer function (IEC 61966-2-1) as a 4096-entry table from linear [0, 1] to 0..255
const SRGB = new Uint8Array(4096);
for (let i = 0; i < 4096; i++) {
  const x = i / 4095;
  SRGB[i] = Math.round(255 * (x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055));
}

function imageFor(canvas, w, h) {
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const ctx = canvas.getContext("2d");
  return [ctx, ctx.createImageData(w, h)];
}

// pixels with no ground truth (mask false): a dark checker, so they never read as a colour
function invalid(px, o, x, y) {
  const v = ((x >> 2) + (y >> 2)) & 1 ? 48 : 72;
  px[o] = px[o + 1] = px[o + 2] = v;
}

/** uint8 (H, W, 3) → canvas. */
export function drawRGB8(canvas, arr) {
  const [h, w] = arr.shape;
  const [ctx, img] = imageFor(canvas, w, h);
  const src = arr.data, px = img.data;
  for (let i = 0, j = 0; i < w * h; i++, j += 3) {
    px[4 * i] = src[j]; px[4 * i + 1] = src[j + 1]; px[4 * i + 2] = src[j + 2]; px[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
}

/** The `q` quantile (0..1) of `f(i)` over (a stride sample of) pixels where `keep(i)`. */
export function quantile(n, f, keep, q) {
  const step = Math.max(1, Math.floor(n / 20000));
  const vals = [];
  for (let i = 0; i < n; i += step) if (keep(i)) vals.push(f(i));
  if (!vals.length) return NaN;
  vals.sort((a, b) => a - b);
  return vals[Math.min(vals.length - 1, Math.floor(q * vals.length))];
}

/** Scale that maps the raw's 99th percentile (of each pixel's brightest channel) to white. */
export function rawScale(raw) {
  const d = raw.data, n = raw.shape[0] * raw.shape[1];
  const p = quantile(n, (i) => Math.max(d[3 * i], d[3 * i + 1], d[3 * i + 2]), () => true, 0.99);
  return p > 0 && isFinite(p) ? 1 / p : 1;
}

/** Camera raw, linear: × scale × 2^ev, clipped, through the sRGB curve for display (no white balance). */
export function drawRaw(canvas, raw, scale, ev) {
  const [h, w] = raw.shape;
  const [ctx, img] = imageFor(canvas, w, h);
  const k = scale * Math.pow(2, ev) * 4095, d = raw.data, px = img.data;
  for (let i = 0; i < w * h; i++) {
    for (let c = 0; c < 3; c++) px[4 * i + c] = SRGB[Math.max(0, Math.min(4095, Math.round(d[3 * i + c] * k)))];
    px[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
}

/** What the gain map shows: per pixel value and how to label it. */
export function gainValues(gain, channel) {
  const d = gain.data, n = gain.shape[0] * gain.shape[1];
  const out = new Float32Array(n);
  const c = { r: 0, g: 1, b: 2 }[channel];
  // B÷R on a log scale: warm light (needs a large B gain) and cool light sit symmetric around equal gains
  for (let i = 0; i < n; i++) out[i] = channel === "br" ? Math.log2(d[3 * i + 2] / d[3 * i]) : d[3 * i + c];
  const label = channel === "br" ? "gain B ÷ gain R, log scale: high where the light is warm (blue boosted), low where it is cool"
    : `gain ${channel.toUpperCase()}: the factor raw ${channel.toUpperCase()} is multiplied by (the strongest channel gets 1)`;
  return { values: out, log: channel === "br", label };
}

/** A scalar map in viridis over [lo, hi] (robust 1st–99th percentile of valid pixels). */
export function drawScalar(canvas, values, mask, w, h) {
  const m = mask.data;
  let lo = quantile(w * h, (i) => values[i], (i) => m[i], 0.01);
  let hi = quantile(w * h, (i) => values[i], (i) => m[i], 0.99);
  if (!isFinite(lo)) { lo = 0; hi = 1; }
  if (hi - lo < 1e-6) { lo -= 0.05; hi += 0.05; }
  const [ctx, img] = imageFor(canvas, w, h);
  const px = img.data, s = 255 / (hi - lo);
  for (let i = 0; i < w * h; i++) {
    const o = 4 * i;
    if (!m[i]) invalid(px, o, i % w, (i / w) | 0);
    else {
      const k = 3 * Math.max(0, Math.min(255, Math.round((values[i] - lo) * s)));
      px[o] = LUT[k]; px[o + 1] = LUT[k + 1]; px[o + 2] = LUT[k + 2];
    }
    px[o + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
  return [lo, hi];
}

/** The mixture (H, W, G): each pixel the share-weighted mix of the groups' colours. */
export function drawMixture(canvas, mixture, mask) {
  const [h, w, g] = mixture.shape;
  const [ctx, img] = imageFor(canvas, w, h);
  const cols = GROUP_COLOURS.map(hexRgb), d = mixture.data, m = mask.data, px = img.data;
  for (let i = 0; i < w * h; i++) {
    const o = 4 * i;
    if (!m[i]) invalid(px, o, i % w, (i / w) | 0);
    else {
      let r = 0, gg = 0, b = 0;
      for (let k = 0; k < g; k++) {
        const s = d[g * i + k], c = cols[k % cols.length];
        r += s * c[0]; gg += s * c[1]; b += s * c[2];
      }
      px[o] = r; px[o + 1] = gg; px[o + 2] = b;
    }
    px[o + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
}

const NO_GT = '<span class="swatch invalid"></span> no ground truth (sky, light source, no light)';

function fmt(v) {
  return Math.abs(v) >= 100 ? v.toFixed(0) : Math.abs(v) >= 10 ? v.toFixed(1) : v.toFixed(2);
}

/** Colour bar with five tick labels; `log`: the values are log2 and labelled as ratios. */
export function scalarLegend(el, lo, hi, log, label) {
  const ticks = [0, 0.25, 0.5, 0.75, 1].map((t) => lo + t * (hi - lo)).map((v) => fmt(log ? 2 ** v : v));
  const bar = VIRIDIS.join(", ");
  el.innerHTML = `<div class="bar" style="background: linear-gradient(to right, ${bar})"></div>
    <div class="ticks">${ticks.map((t) => `<span>${t}</span>`).join("")}</div>
    <div>${label}</div><div class="muted">${NO_GT}</div>`;
}

/** Group swatches (and, for two lit groups, the gradient between them). */
export function mixtureLegend(el, groups) {
  const colour = (k) => GROUP_COLOURS[k % GROUP_COLOURS.length];
  const items = groups.map((g, k) =>
    `<span class="swatch" style="background:${colour(k)}"></span>${esc(g.group)}: ${g.intensity > 0 ? esc(g.illuminant) : "off"}`);
  let html = `<div>${items.join(" &nbsp; ")}</div>`;
  const lit = groups.map((g, k) => [g, k]).filter(([g]) => g.intensity > 0);
  if (lit.length === 2) {
    const [[a, i], [b, j]] = lit;
    html = `<div class="bar" style="background: linear-gradient(to right, ${colour(i)}, ${colour(j)})"></div>
      <div class="ticks"><span>100 % ${esc(a.group)}</span><span>50 / 50</span><span>100 % ${esc(b.group)}</span></div>` + html;
  }
  el.innerHTML = html + `<div class="muted">${NO_GT}</div>`;
}
