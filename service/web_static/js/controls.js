// The sampling controls: scene and view thumbnails, a group's illuminant (list or CCT slider) and
// intensity, the frame size and the sensor, each kept in `state` (js/link.js).
import { GROUP_COLOURS, esc } from "./images.js";
import { CCT, DEFAULT_LIGHTS, INTENSITY } from "./linkcheck.js";
import { currentScene, currentView, downloads, lib, state } from "./link.js";

const $ = (id) => document.getElementById(id);
let changed = () => {}, soon = () => {};

/** What the controls call: `update` on a choice, `later` while a slider moves (one request when it rests). */
export function wireControls(update, later) {
  changed = update;
  soon = later;
}

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

export function chooseScene() {
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
    b.onclick = () => { state.view = v.name; state.size = ""; chooseScene(); chooseView(); changed(); };
    thumbs.append(b);
  }
}

/** Per light group: an illuminant (list or CCT slider) and an intensity. */
export function chooseView() {
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
  sel.onchange = () => { state.illuminants[k] = sel.value; show(); changed(); };
  slider.oninput = () => { state.illuminants[k] = `${state.illuminants[k].split(":")[0]}:${slider.value}`; show(); soon(); };
  int.oninput = () => { state.intensities[k] = Number(int.value); show(); soon(); };
}

export function sensorOptions() {
  options($("sensor"), [["uploaded", lib.sensors.uploaded.map((x) => [x, x])],
    ["built in", lib.sensors.builtin.map((x) => [x, x])]], state.sensor);
}
