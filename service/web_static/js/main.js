// The web explorer: controls ↔ URL query string ↔ one /explore/frame request per update.
import { getArrays, getJSON } from "./api.js";
import { DEFAULT_NPZ, outputChecks, setDownloads, wireUploads } from "./forms.js";
import {
  GROUP_COLOURS, drawMixture, esc, drawRGB8, drawRaw, drawScalar, gainValues, mixtureLegend, rawScale, scalarLegend,
} from "./images.js";
import { DEFAULT_POOL, drawGallery } from "./gallery.js";
import { CCT, DEFAULT_LIGHTS, EV, INTENSITY, stateFromLink } from "./linkcheck.js";
import { loadNoise, noisyAt } from "./noise.js";
import { hoverSpectrum, wireSpectrum } from "./pixel.js";
import { chromaHover, plotChroma, plotSensor, plotSpectra, resizePlots } from "./plots.js";
import { onZoom, panelFraction, toImage, toPanel, wireZoom } from "./zoom.js";

const $ = (id) => document.getElementById(id);
const lib = { scenes: [], sensors: null, illuminants: null };
const state = {};
let frame = null, spectra = null, spectraKey = "", inflight = null, timer = null;
//: the state the images show: a failed update puts the controls back to it (js/main.js restore)
let rendered = null;
//: what the frame depends on (ev, gain and npz are applied to the drawn frame or the links alone)
const FRAME_KEYS = ["scene", "view", "sensor", "illuminants", "intensities", "size", "gt", "denoise"];
let aov = null, aovKey = "";
let hovered = null; //: [x, y] of the frame pixel under the cursor (the marker follows zoom and pan)

// -- state ↔ URL (read once the lists are in: js/linkcheck.js checks every value) ----------------
/** The link values that were replaced: one line above the images (a click shows it all; × clears it). */
function notice(notes) {
  $("notice").hidden = !notes.length;
  $("notice-text").textContent = notes.length ? `Link values replaced: ${notes.join("; ")}` : "";
  $("notice-text").title = "click to show it all";
}

/** The /sample parameters of the current view (shared by the frame request and the downloads), or of `st`. */
function sampleParams(st = state) {
  const p = { scene: st.scene, view: st.view, sensor: st.sensor, illuminants: st.illuminants.join(","),
    intensities: st.intensities.join(",") };
  if (st.size) p.size = st.size; // WxH, as /sample takes it; none: the view's own size
  if (st.gt) p.gt = st.gt;
  if (st.denoise) p.denoise = st.denoise; // none: the cubes as rendered; unset: the stored copies
  return p;
}

/** The parameters of the frame on screen without gt (its spectra and noisy raw do not depend on it). */
function shownParams() {
  const { gt, ...p } = sampleParams(rendered);
  return p;
}

function writeURL() {
  const q = new URLSearchParams(sampleParams());
  if (state.ev) q.set("ev", state.ev);
  if (state.gain !== "br") q.set("gain", state.gain);
  if (String(state.npz) !== String(DEFAULT_NPZ)) q.set("npz", state.npz.join(","));
  if (state.aov) q.set("aov", state.aov);
  if (state.noise) q.set("noise", state.noise);
  history.replaceState(null, "", `?${q}`);
}

const currentScene = () => lib.scenes.find((s) => s.name === state.scene);
const currentView = () => currentScene().views.find((v) => v.name === state.view);

// -- controls ----------------------------------------------------------------------------------
/** `groups`: [[label, [[value, text, why?], …]], …]; an item with `why` is shown disabled, `why` its tooltip. */
function options(select, groups, selected) {
  select.innerHTML = "";
  for (const [label, items] of groups) {
    if (!items.length) continue;
    const og = document.createElement("optgroup");
    og.label = label;
    for (const [value, text, why] of items) {
      const o = new Option(text, value, false, value === selected && !why);
      if (why) Object.assign(o, { disabled: true, title: why });
      og.append(o);
    }
    select.append(og);
  }
}

function chooseScene() {
  const scene = currentScene();
  options($("scene"), [["scenes", lib.scenes.map((s) => [s.name, s.name])]], state.scene);
  const thumbs = $("thumbs");
  thumbs.innerHTML = "";
  for (const v of scene.views) {
    const w = 96, h = Math.max(1, Math.round((96 * v.height) / v.width));
    const b = document.createElement("button");
    b.className = v.name === state.view ? "thumb selected" : "thumb";
    b.title = `${v.name}: ${v.width}×${v.height}, groups ${v.groups.map((g) => g.name).join(", ")}`;
    const q = new URLSearchParams({ scene: scene.name, view: v.name, outputs: "srgb", format: "png", size: `${w}x${h}`, seed: "0" });
    b.innerHTML = `<img alt="${esc(v.name)}" width="${w}" height="${h}" src="/sample?${q}"><span>${esc(v.name)}</span>`;
    b.onclick = () => { state.view = v.name; state.size = ""; chooseScene(); chooseView(); update(); };
    thumbs.append(b);
  }
}

/** Per light group: an illuminant (list or CCT slider) and an intensity. */
function chooseView() {
  const v = currentView();
  const n = v.groups.length;
  state.illuminants = v.groups.map((g, k) => state.illuminants[k] || DEFAULT_LIGHTS[k % DEFAULT_LIGHTS.length]);
  state.intensities = v.groups.map((g, k) => (Number.isFinite(state.intensities[k]) ? state.intensities[k] : 1));
  state.illuminants.length = state.intensities.length = n;
  const box = $("groups");
  box.innerHTML = "";
  v.groups.forEach((g, k) => {
    const div = document.createElement("div");
    div.className = "group";
    div.innerHTML = `<div><span class="swatch" style="background:${GROUP_COLOURS[k % GROUP_COLOURS.length]}"></span>
        <b>${esc(g.name)}</b> <span class="muted">rendered with ${esc(g.emission)} emission</span></div>
      <select class="ill" aria-label="illuminant of ${esc(g.name)}"></select>
      <label class="cct">CCT <input type="range"> <output></output></label>
      <label>intensity <input class="int" type="range" min="${INTENSITY[0]}" max="${INTENSITY[1]}" step="${INTENSITY[2]}">
        <output></output></label>`;
    box.append(div);
    wireGroup(div, k);
  });
  sizeOptions(v);
  const denoised = v.groups.filter((g) => g.denoised).map((g) => `${g.name}: ${g.denoised}`);
  $("denoise-note").textContent = denoised.length ? `stored copies: ${denoised.join(", ")}` : "this view has no denoised copies";
  $("denoise").value = state.denoise;
  downloads();
}

/** Full, half and quarter size of the view; a size from the URL that is none of them is kept. */
function sizeOptions(v) {
  const sizes = [1, 2, 4].map((d) => `${Math.max(1, Math.round(v.width / d))}x${Math.max(1, Math.round(v.height / d))}`);
  if (state.size === sizes[0]) state.size = "";
  const items = sizes.map((s, k) => [k ? s : "", `${["full", "1/2", "1/4"][k]} (${s.replace("x", "×")})`]);
  if (state.size && !sizes.includes(state.size)) items.push([state.size, state.size.replace("x", "×")]);
  options($("size"), [["frame size", items]], state.size);
}

function illuminantOptions(select, name) {
  const kind = name.includes(":") ? name.split(":")[0] : name;
  options(select, [
    ["colour temperature (slider)", [["blackbody", "blackbody (Planck)"], ["daylight", "CIE daylight"]]],
    ["uploaded", lib.illuminants.uploaded.map((x) => [x, x])],
    ["CIE and measured", lib.illuminants.builtin.map((x) => [x, x])],
    ["not usable on this service's spectral grid", Object.entries(lib.illuminants.unavailable || {})
      .map(([x, why]) => [x, `${x} (${shortWhy(why)})`, why])],
  ], kind);
}

/** An unusable illuminant's reason in a few words: "covers 350-690 nm only" where the reason says so. */
function shortWhy(why) {
  const m = /cover (\d+(?:\.\d+)?-\d+(?:\.\d+)?) nm/.exec(why);
  return m ? `data cover ${m[1]} nm only` : "not usable here";
}

function wireGroup(div, k) {
  const sel = div.querySelector(".ill"), cct = div.querySelector(".cct"), slider = cct.querySelector("input");
  const int = div.querySelector(".int");
  const show = () => {
    const [kind, kelvin] = state.illuminants[k].split(":");
    cct.hidden = !(kind in CCT);
    if (kind in CCT) {
      const [lo, hi, step, start] = CCT[kind];
      Object.assign(slider, { min: lo, max: hi, step });
      slider.value = kelvin || start;
      state.illuminants[k] = `${kind}:${slider.value}`;
      cct.querySelector("output").textContent = `${slider.value} K`;
    }
    int.nextElementSibling.textContent = state.intensities[k].toFixed(2);
  };
  illuminantOptions(sel, state.illuminants[k]);
  int.value = state.intensities[k];
  show();
  sel.onchange = () => { state.illuminants[k] = sel.value; show(); update(); };
  slider.oninput = () => { state.illuminants[k] = `${state.illuminants[k].split(":")[0]}:${slider.value}`; show(); later(); };
  int.oninput = () => { state.intensities[k] = Number(int.value); show(); later(); };
}

function downloads() {
  setDownloads(sampleParams(), `${state.scene}-${state.view}`, state.npz);
}

function sensorOptions() {
  options($("sensor"), [["uploaded", lib.sensors.uploaded.map((x) => [x, x])],
    ["built in", lib.sensors.builtin.map((x) => [x, x])]], state.sensor);
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
  wireZoom();
  onZoom(placeCross);
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
