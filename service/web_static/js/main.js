// The web explorer: controls ↔ URL query string ↔ one /explore/frame request per update.
import { getArrays, getJSON } from "./api.js";
import { outputChecks, wireUploads } from "./forms.js";
import { chooseScene, chooseView, sensorOptions, wireControls } from "./controls.js";
import { drawMixture, esc, drawRGB8, drawRaw, drawScalar, gainValues, mixtureLegend, rawScale, scalarLegend } from "./images.js";
import { DEFAULT_POOL, drawGallery } from "./gallery.js";
import { currentScene, downloads, lib, notice, sampleParams, state, writeURL, writeURLSoon } from "./link.js";
import { EV, stateFromLink } from "./linkcheck.js";
import { loadNoise, noisyAt } from "./noise.js";
import { hoverSpectrum, wireSpectrum } from "./pixel.js";
import { chromaHover, plotChroma, plotSensor, plotSpectra, resizePlots } from "./plots.js";
import { onZoom, panelFraction, toImage, toPanel, wireZoom } from "./zoom.js";

const $ = (id) => document.getElementById(id);
let frame = null, spectra = null, spectraKey = "", inflight = null, timer = null;
//: the state the images show: a failed update puts the controls back to it (js/main.js restore)
let rendered = null;
//: what the frame depends on (ev, gain and npz are applied to the drawn frame or the links alone)
const FRAME_KEYS = ["scene", "view", "sensor", "illuminants", "intensities", "size", "gt", "denoise"];
let aov = null, aovKey = "";
let hovered = null; //: [x, y] of the frame pixel under the cursor (the marker follows zoom and pan)

/** The parameters of the frame on screen without gt (its spectra and noisy raw do not depend on it). */
function shownParams() {
  const { gt, ...p } = sampleParams(rendered);
  return p;
}

// -- updates -----------------------------------------------------------------------------------
function status(text, error = false) {
  $("status").textContent = text;
  $("status").className = error ? "error" : "muted";
}

/** Slider drags: one request when the hand pauses, not one per pixel of travel. */
function later() {
  clearTimeout(timer);
  timer = setTimeout(update, 80);
}

async function loadSpectra() {
  const lit = state.illuminants.filter((_, k) => state.intensities[k] > 0);
  const key = `${state.sensor}|${lit}`;
  if (key !== spectraKey) {
    const q = new URLSearchParams({ sensor: state.sensor, illuminants: lit.join(",") });
    spectra = await getJSON(`/explore/spectra?${q}`);
    spectraKey = key;
  }
  return spectra;
}

/** Compose the current view: one /explore/frame request (a newer update aborts an older one). */
async function update() {
  clearTimeout(timer);
  writeURL();
  downloads();
  inflight?.abort();
  const mine = (inflight = new AbortController());
  status("composing…");
  const t0 = performance.now();
  try {
    const [f, s] = await Promise.all([getArrays(`/explore/frame?${new URLSearchParams(sampleParams())}`, mine.signal),
      loadSpectra()]);
    if (mine !== inflight) return;
    const t1 = performance.now();
    frame = prepare(f);
    rendered = snapshot();
    drawAll(s);
    $("views").classList.remove("stale");
    const [h, w] = f.arrays.raw.shape;
    const dn = f.meta.denoise ? ` · denoise: ${f.meta.denoise.method}` : "";
    status(`${w}×${h} · server ${Math.round(f.timing.total)} ms, request ${Math.round(t1 - t0)} ms, `
      + `draw ${Math.round(performance.now() - t1)} ms · ground truth: ${f.meta.ground_truth.method}${dn}`);
    document.body.dataset.ready = String(Number(document.body.dataset.ready || 0) + 1); // for tests
    loadAov();
    noise();
    // the chart follows the new lights at the pixel last hovered (when the new frame still has it)
    if (hovered && hovered[0] < frame.w && hovered[1] < frame.h) hoverSpectrum(shownParams(), ...hovered);
  } catch (e) {
    if (e.name === "AbortError" || mine !== inflight) return; // a newer update decides
    await restore(e);
  }
}

/** The frame-defining part of the state, deep-copied. */
function snapshot() {
  return JSON.parse(JSON.stringify(Object.fromEntries(FRAME_KEYS.map((k) => [k, state[k]]))));
}

/**
 * A failed update (any 4xx/5xx, or no answer): the lists are re-read (an upload may have been
 * deleted meanwhile) and the controls, URL and downloads go back to the frame on screen; with no
 * frame drawn yet, the images are marked stale instead. Never new controls over old images.
 */
async function restore(e) {
  await refreshLists().catch(() => {});
  if (!rendered) {
    $("views").classList.add("stale");
    status(`${e.message} · nothing drawn yet`, true);
    document.body.dataset.failed = String(Number(document.body.dataset.failed || 0) + 1); // for tests
    return;
  }
  Object.assign(state, JSON.parse(JSON.stringify(rendered)));
  sensorOptions();
  chooseScene();
  chooseView();
  $("gt").value = state.gt;
  writeURL();
  status(`${e.message} · not applied: the controls are back at the frame shown`, true);
  document.body.dataset.failed = String(Number(document.body.dataset.failed || 0) + 1); // for tests
}

// -- geometry AOVs (GET /sample outputs albedo, normal, depth): they do not depend on the lights ----
async function loadAov() {
  const legend = $("aov-legend"), canvas = $("c-aov");
  canvas.closest(".panel").hidden = !state.aov;
  if (!state.aov || !rendered) return;
  const p = { scene: rendered.scene, view: rendered.view, outputs: state.aov, format: "arrays" };
  if (rendered.size) p.size = rendered.size;
  const key = new URLSearchParams(p).toString();
  if (key === aovKey) return;
  try {
    const got = await getArrays(`/sample?${key}`);
    if (p.outputs !== state.aov) return; // chosen again meanwhile
    aov = { name: state.aov, arr: got.arrays[state.aov] };
    aovKey = key;
    drawAov(legend, canvas);
  } catch (e) {
    aov = null; aovKey = "";
    canvas.width = canvas.height = 0;
    legend.className = "legend error";
    legend.textContent = e.message;
  }
}

function drawAov(legend, canvas) {
  const { name, arr } = aov;
  const [h, w] = arr.shape, d = arr.data;
  legend.className = "legend";
  if (name === "albedo") {
    drawRaw(canvas, arr, 1, 0);
    legend.textContent = "albedo: linear reflectance in the view's R, G, B, sRGB curve for display";
  } else if (name === "normal") {
    const rgb = new Uint8Array(w * h * 3);
    for (let i = 0; i < rgb.length; i++) rgb[i] = Math.round(127.5 * (d[i] + 1));
    drawRGB8(canvas, { data: rgb, shape: [h, w, 3] });
    legend.textContent = "normal: world-space unit vector, (x, y, z) → (R, G, B) = (n + 1) / 2";
  } else {
    const hit = { data: Uint8Array.from(d, (v) => (Number.isFinite(v) && v > 0 ? 1 : 0)) };
    const [lo, hi] = drawScalar(canvas, d, hit, w, h);
    scalarLegend(legend, lo, hi, false, "depth: distance along the camera ray (scene units)");
  }
}

function prepare(f) {
  const { raw, illum, mask } = f.arrays;
  const [h, w] = raw.shape;
  const pts = [];
  const step = Math.max(1, Math.floor((w * h) / 400));
  for (let i = 0; i < w * h; i += step) if (mask.data[i]) pts.push([illum.data[3 * i], illum.data[3 * i + 2]]);
  return { ...f, w, h, scale: rawScale(raw), pixelWhitePoints: pts };
}

function drawAll(s) {
  const { arrays: a, meta } = frame;
  drawRaw($("c-raw"), a.raw, frame.scale, state.ev);
  drawRGB8($("c-srgb"), a.srgb);
  drawRGB8($("c-baseline"), a.baseline);
  drawGain();
  drawMixture($("c-mixture"), a.mixture, a.mask);
  mixtureLegend($("mixture-legend"), meta.illuminants);
  const b = meta.baseline;
  const shares = Object.entries(b.shares).map(([g, v]) => `${g} ${(100 * v).toFixed(0)} %`).join(", ");
  $("baseline-note").textContent = `white point R/G ${b.white_point_rgb[0].toFixed(3)}, B/G `
    + `${b.white_point_rgb[2].toFixed(3)}: the groups' white points weighted by their share of the frame (${shares})`;
  const lit = meta.illuminants.map((g, index) => ({ group: g.group, index, on: g.intensity > 0 })).filter((g) => g.on);
  plotSpectra(s, lit);
  plotSensor(s);
  plotChroma(s, frame, null);
}

function drawGain() {
  const { values, log, label } = gainValues(frame.arrays.gain, state.gain);
  const [lo, hi] = drawScalar($("c-gain"), values, frame.arrays.mask, frame.w, frame.h);
  scalarLegend($("gain-legend"), lo, hi, log, label);
}

// -- hover -------------------------------------------------------------------------------------
const f3 = (v) => (Math.abs(v) >= 1000 || (Math.abs(v) < 0.001 && v !== 0) ? v.toExponential(2) : v.toFixed(3));

function hover(ev) {
  if (!frame) return;
  const [u, v] = toImage(...panelFraction(ev.currentTarget, ev)); // through the zoom and pan
  const x = Math.floor(u * frame.w), y = Math.floor(v * frame.h);
  if (x < 0 || y < 0 || x >= frame.w || y >= frame.h) return;
  hovered = [x, y];
  const i = y * frame.w + x, a = frame.arrays, g = a.mixture.shape[2];
  const rgb = (arr) => [0, 1, 2].map((c) => arr.data[3 * i + c]);
  const [raw, gain, wp] = [rgb(a.raw), rgb(a.gain), rgb(a.illum)];
  const valid = a.mask.data[i];
  const mix = frame.meta.illuminants.map((m, k) =>
    `${esc(m.group)} (${m.intensity > 0 ? esc(m.illuminant) : "off"}) ${(100 * a.mixture.data[g * i + k]).toFixed(1)} %`);
  $("readout").className = "readout";
  $("readout").innerHTML = `<div>pixel x ${x}, y ${y} ${valid ? "" : '<b class="error">· no ground truth here</b>'}</div>
    <table><tr><th></th><th>R</th><th>G</th><th>B</th></tr>
    <tr><td>raw <span class="muted">(relative)</span></td>${raw.map((v) => `<td>${f3(v)}</td>`).join("")}</tr>
    <tr><td>gain</td>${gain.map((v) => `<td>${f3(v)}</td>`).join("")}</tr>
    <tr><td>white point <span class="muted">(R/G, 1, B/G)</span></td>${wp.map((v) => `<td>${f3(v)}</td>`).join("")}</tr></table>
    <div>mixture: ${mix.join(" · ")}</div>${aovReadout(i)}${noisyReadout(i)}`;
  placeCross();
  chromaHover(valid ? [wp[0], wp[2]] : null);
  hoverSpectrum(shownParams(), x, y);
}

/** The hovered pixel's marker on every panel, where zoom and pan show it (hidden when out of view). */
function placeCross() {
  if (!hovered || !frame) return;
  const [mx, my] = toPanel((hovered[0] + 0.5) / frame.w, (hovered[1] + 0.5) / frame.h);
  for (const c of document.querySelectorAll(".cross")) {
    c.hidden = mx < 0 || my < 0 || mx > 1 || my > 1;
    c.style.left = `${100 * mx}%`;
    c.style.top = `${100 * my}%`;
  }
}

function noisyReadout(i) {
  const dn = noisyAt(i, frame.w, frame.h);
  return dn ? `<div>noisy raw (${esc(state.noise)}): ${dn.join(", ")} DN</div>` : "";
}

/** The noise preview of the frame on screen (hidden when the control is off). */
function noise() {
  if (frame && rendered) loadNoise(shownParams(), state.noise, frame.scale, state.ev);
}

function aovReadout(i) {
  if (!aov || aov.arr.shape[0] !== frame.h || aov.arr.shape[1] !== frame.w) return "";
  const d = aov.arr.data, v = aov.name === "depth" ? [d[i]] : [0, 1, 2].map((c) => d[3 * i + c]);
  return `<div>${aov.name}: ${v.map(f3).join(", ")}</div>`;
}

// -- start -------------------------------------------------------------------------------------
async function refreshLists() {
  [lib.sensors, lib.illuminants] = await Promise.all([getJSON("/sensors"), getJSON("/illuminants")]);
}

async function start() {
  const [scenes, health] = await Promise.all([getJSON("/scenes"), getJSON("/health"), refreshLists()]);
  // a damaged view is listed with why (GET /scenes); it cannot be served, so it is left out here
  const damaged = scenes.scenes.flatMap((s) => s.views.filter((v) => v.damaged).map((v) => `${s.name}/${v.name}`));
  lib.scenes = scenes.scenes.map((s) => ({ ...s, views: s.views.filter((v) => !v.damaged) })).filter((s) => s.views.length);
  if (!lib.scenes.length) { status("the store holds no rendered views yet: run `illumix render`", true); return; }
  const link = stateFromLink(new URLSearchParams(location.search), lib);
  Object.assign(state, link.state);
  notice(damaged.length ? [...link.notes, `damaged, not shown (run \`illumix store verify\`): ${damaged.join(", ")}`] : link.notes);
  $("notice-close").onclick = () => notice([]);
  $("notice-text").onclick = () => $("notice").classList.toggle("open");
  const nviews = lib.scenes.reduce((n, s) => n + s.views.length, 0);
  $("summary").textContent = `${lib.scenes.length} scene(s), ${nviews} view(s)`;
  $("token-row").hidden = !health.auth;
  wireControls(update, later);
  sensorOptions();
  chooseScene();
  chooseView();
  $("gt").value = state.gt;
  $("aov").value = state.aov;
  $("gainch").value = state.gain;
  Object.assign($("ev"), { min: EV[0], max: EV[1], step: EV[2] });
  $("ev").value = state.ev;
  $("ev-out").textContent = `${state.ev >= 0 ? "+" : ""}${state.ev} EV`;
  for (const fr of document.querySelectorAll(".frame")) {
    const c = document.createElement("div");
    c.className = "cross"; c.hidden = true;
    fr.append(c);
    fr.addEventListener("mousemove", hover);
  }
  wireZoom(link.zoom); // the link's zoom and pan, or none
  onZoom(() => { placeCross(); writeURLSoon(); });
  wireSpectrum();
  $("noise").value = state.noise;
  $("noise").onchange = () => { state.noise = $("noise").value; writeURL(); noise(); };
  wireGallery();
  $("scene").onchange = () => {
    state.scene = $("scene").value;
    Object.assign(state, { view: currentScene().views[0].name, size: "" });
    chooseScene(); chooseView(); update();
  };
  $("sensor").onchange = () => { state.sensor = $("sensor").value; update(); };
  $("gt").onchange = () => { state.gt = $("gt").value; update(); };
  $("denoise").onchange = () => { state.denoise = $("denoise").value; update(); };
  $("aov").onchange = () => { state.aov = $("aov").value; writeURL(); loadAov(); };
  $("c-aov").closest(".panel").hidden = !state.aov;
  $("size").onchange = () => { state.size = $("size").value; update(); };
  $("ev").oninput = () => {
    state.ev = Number($("ev").value);
    $("ev-out").textContent = `${state.ev >= 0 ? "+" : ""}${state.ev} EV`;
    writeURL();
    if (frame) drawRaw($("c-raw"), frame.arrays.raw, frame.scale, state.ev);
    clearTimeout(evTimer);
    evTimer = setTimeout(noise, 150); // the noisy raw is exposed anew: one request when the slider rests
  };
  $("gainch").onchange = () => { state.gain = $("gainch").value; writeURL(); if (frame) drawGain(); };
  outputChecks(state.npz, (list) => { state.npz = list; writeURL(); downloads(); });
  wireUploads(async (kind, name) => {
    await refreshLists();
    if (kind === "sensors") state.sensor = name;
    sensorOptions();
    chooseView();
    if (kind === "sensors") update();
  });
  window.addEventListener("resize", resizePlots);
  await update();
}

let evTimer = null;

/** The gallery's controls: the dataset's default pool, the page's sensor; drawn on demand (or by ?gallery=SEED). */
function wireGallery() {
  const box = $("gallery"), q = new URLSearchParams(location.search);
  $("gal-pool").value = DEFAULT_POOL;
  $("gal-sensors").value = state.sensor;
  $("gal-draw").onclick = () => drawGallery(lib, box);
  if (/^\d{1,9}$/.test(q.get("gallery") || "")) {
    $("gal-seed").value = q.get("gallery");
    drawGallery(lib, box);
  }
}

start().catch((e) => status(`could not start: ${e.message}`, true));
