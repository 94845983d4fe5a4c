// The noise preview: the frame's raw as a camera would record it — GET /sample with noise=<model>
// (shot + read noise, black and white levels, bit depth: retarget/sensor_model.py) — at the exposure
// the raw panel shows: the sensor gain is the display's (the clean raw's 99th percentile at
// saturation at +0 EV, × 2^EV), so the noisy panel differs from the clean one by the noise alone.
import { getArrays } from "./api.js";
import { drawRaw, esc } from "./images.js";

const NOISE_SEED = "1"; // one fixed draw: toggling back and forth shows the same grain
let key = "", noisy = null, inflight = null;

/** The noisy raw's digital number at pixel index `i` ([R, G, B]), or null when none is shown. */
export function noisyAt(i, w, h) {
  if (!noisy || noisy.shape[0] !== h || noisy.shape[1] !== w) return null;
  return [0, 1, 2].map((c) => noisy.dn[3 * i + c]);
}

/**
 * Show (or hide, `model` "") the noisy raw of the frame `params` describe; `scale` is the clean
 * raw's display scale (js/images.js rawScale), `ev` the raw exposure slider.
 */
export async function loadNoise(params, model, scale, ev) {
  const canvas = document.getElementById("c-noisy"), legend = document.getElementById("noisy-legend");
  canvas.closest(".panel").hidden = !model;
  if (!model) { inflight?.abort(); key = ""; noisy = null; return; }
  const gain = scale * 2 ** ev;
  const q = new URLSearchParams({ ...params, outputs: "raw,meta", format: "arrays", noise: model,
    exposure: gain.toPrecision(6), seed: NOISE_SEED }).toString();
  if (q === key) return;
  inflight?.abort();
  const mine = (inflight = new AbortController());
  try {
    const got = await getArrays(`/sample?${q}`, mine.signal);
    if (mine !== inflight) return;
    const raw = got.arrays.raw, m = got.meta.noise;
    const white = m.white_level ?? 2 ** m.bit_depth - 1, black = m.black_level;
    // digital numbers → relative to saturation, drawn like the clean raw at scale 1
    const rel = Float32Array.from(raw.data, (dn) => (dn - black) / (white - black));
    noisy = { dn: raw.data, shape: raw.shape };
    drawRaw(canvas, { data: rel, shape: raw.shape }, 1, 0);
    key = q;
    legend.className = "legend";
    legend.innerHTML = `${esc(model)}: full well ${m.full_well} e⁻, read noise ${m.read_noise} e⁻ RMS, `
      + `${m.bit_depth} bit, black ${black}, white ${white} DN · sensor gain ×${got.meta.exposure_gain.toPrecision(4)} `
      + `(the raw panel's ${ev >= 0 ? "+" : ""}${ev} EV) · noise seed ${NOISE_SEED}`;
    document.body.dataset.noisy = String(Number(document.body.dataset.noisy || 0) + 1); // for tests
  } catch (e) {
    if (e.name === "AbortError" || mine !== inflight) return;
    key = ""; noisy = null;
    canvas.width = canvas.height = 0;
    legend.className = "legend error";
    legend.textContent = e.message;
  }
}
