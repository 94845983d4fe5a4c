// The page state from a shared link (the URL's query string), checked against what this service
// offers and the controls' ranges before the first request: a value that is not there or out of
// range is replaced and named in one line, so a stale or hand-edited link still draws the page.
import { DEFAULT_NPZ, NPZ_OUTPUTS } from "./forms.js";
import { MAX_ZOOM } from "./zoom.js";

/** The sensor export and evaluate default to: a measured camera colour-science ships on every install. */
export const PREFERRED_SENSOR = "Nikon 5100 (NPL)";
export const DEFAULT_LIGHTS = ["A", "D65", "FL11", "D50"];
export const CCT = { blackbody: [1500, 15000, 50, 3200], daylight: [4000, 20000, 100, 6500] }; // min, max, step, start
export const INTENSITY = [0, 4, 0.05]; // min, max, step of a group's intensity slider
export const EV = [-4, 4, 0.25]; // of the raw exposure slider
const GT = ["physical", "formula"]; // or "": the service's default
const GAIN = ["br", "r", "g", "b"];
const DENOISE = ["none"]; // or "": the stored denoised copies where the view has them
export const AOVS = ["albedo", "normal", "depth"]; // or "": no geometry panel
export const NOISES = ["low", "phone", "high", "camera"]; // or "": no noise preview (js/noise.js)

const quote = (v) => `'${v.length > 40 ? `${v.slice(0, 40)}…` : v}'`;
const same = (names, v) => names.find((n) => n.toLowerCase() === v.toLowerCase()); // names are case-insensitive

/** The camera the page opens with: the preferred one, else the first built-in camera, else XYZ. */
export function defaultSensor(sensors) {
  if (sensors.builtin.includes(PREFERRED_SENSOR)) return PREFERRED_SENSOR;
  return sensors.builtin.find((s) => s !== "XYZ") ?? "XYZ";
}

/** A number from the link, clamped to `[min, max]`: `[value, why it was replaced or null]`. */
function number(text, [lo, hi], fallback) {
  const v = Number(text);
  if (text.trim() === "" || !Number.isFinite(v)) return [fallback, "not a number"];
  const c = Math.min(hi, Math.max(lo, v));
  return [c, c === v ? null : `${v > hi ? ">" : "<"} ${c}`];
}

/** One illuminant of the link: a listed name (any case) or blackbody:K / daylight:K in the slider's range. */
function illuminant(text, k, names, unavailable = {}) {
  const fallback = DEFAULT_LIGHTS[k % DEFAULT_LIGHTS.length];
  const listed = same(names, text);
  if (listed) return [listed, null];
  if (same(Object.keys(unavailable), text)) return [fallback, `illuminant ${quote(text)} unavailable here → ${fallback}`];
  const [kind, kelvin, ...rest] = text.split(":");
  const cct = same(Object.keys(CCT), kind);
  if (!cct || rest.length) return [fallback, `illuminant ${quote(text)} unknown → ${fallback}`];
  if (kelvin === undefined) return [cct, null]; // the slider's start
  const [v, why] = number(kelvin, CCT[cct], CCT[cct][3]);
  return [`${cct}:${v}`, why && `illuminant ${quote(text)} ${why}${why === "not a number" ? "" : " K"} → ${cct}:${v}`];
}

/**
 * The zoom and pan of the link (js/link.js writes them): `zoom` in [1, MAX_ZOOM] and `at=u,v`, the image
 * point at the panels' centre in fractions of the image (0–1; the centre when absent; `at` alone means
 * nothing). `[{s, u, v} or null, why it was dropped or null]`: anything malformed opens the default view.
 */
function zoomFromLink(zoom, at) {
  if (!zoom) return [null, null];
  const s = Number(zoom), uv = (at || "0.5,0.5").split(",").map((t) => (t.trim() ? Number(t) : NaN));
  const inside = (x, lo, hi) => Number.isFinite(x) && x >= lo && x <= hi;
  if (!inside(s, 1, MAX_ZOOM) || uv.length !== 2 || !uv.every((x) => inside(x, 0, 1))) {
    return [null, `zoom ${quote(zoom)}${at ? `, at ${quote(at)}` : ""}: not a zoom 1–${MAX_ZOOM} at an image point u,v in 0–1 → no zoom`];
  }
  return [s === 1 ? null : { s, u: uv[0], v: uv[1] }, null];
}

/**
 * The page state from the query string `q` and the service's lists `lib` ({scenes, sensors,
 * illuminants}, scenes with views): `{ state, notes }`, `notes` naming each replaced value.
 */
export function stateFromLink(q, lib) {
  const notes = [];
  const get = (k) => q.get(k) ?? "";
  const pick = (what, given, names, fallback, why = "unknown") => {
    if (!given) return fallback;
    const found = same(names, given);
    if (!found) notes.push(`${what} ${quote(given)} ${why} → ${fallback || "default"}`);
    return found ?? fallback;
  };
  const num = (what, text, range, fallback) => {
    const [v, why] = number(text, range, fallback);
    if (why) notes.push(`${what} ${quote(text)} ${why} → ${v}`);
    return v;
  };
  const scenes = lib.scenes.map((s) => s.name);
  const scene = pick("scene", get("scene"), scenes, scenes[0], "not in the store");
  const views = lib.scenes.find((s) => s.name === scene).views;
  const view = views.find((v) => v.name === pick("view", get("view"), views.map((v) => v.name), views[0].name,
    `not a view of ${scene}`));
  const sensors = [...lib.sensors.uploaded, ...lib.sensors.builtin];
  const sensor = pick("sensor", get("sensor"), sensors, defaultSensor(lib.sensors),
    Object.hasOwn(lib.sensors.unavailable || {}, get("sensor")) ? "unavailable here" : "unknown");
  const illNames = [...lib.illuminants.uploaded, ...lib.illuminants.builtin];
  const illuminants = get("illuminants").split(",").map((t, k) => {
    const [v, note] = t.trim() ? illuminant(t.trim(), k, illNames, lib.illuminants.unavailable) : ["", null];
    if (note) notes.push(note);
    return v;
  });
  // an empty entry is not given: the group's default
  const intensities = get("intensities").split(",").map((t) => (t.trim() ? num("intensity", t, INTENSITY, 1) : NaN));
  const size = get("size");
  const m = /^(\d{1,5})x(\d{1,5})$/.exec(size);
  const sizeOk = !size || (m && +m[1] >= 1 && +m[2] >= 1 && +m[1] <= view.width && +m[2] <= view.height);
  if (!sizeOk) notes.push(`size ${quote(size)} not WxH ≤ ${view.width}x${view.height} → full`);
  const gt = pick("gt", get("gt"), GT, "", `not ${GT.join(" or ")}`);
  const ev = get("ev") ? num("ev", get("ev"), EV, 0) : 0;
  const gain = pick("gain", get("gain"), GAIN, "br", `not ${GAIN.join(", ")}`);
  const denoise = pick("denoise", get("denoise"), DENOISE, "", "not none");
  const aov = pick("aov", get("aov"), AOVS, "", `not ${AOVS.join(", ")}`);
  const noise = pick("noise", get("noise"), NOISES, "", `not ${NOISES.join(", ")}`);
  const npz = q.has("npz") ? get("npz").split(",").filter((x) => x) : DEFAULT_NPZ;
  const unknown = npz.filter((x) => !NPZ_OUTPUTS.includes(x));
  if (unknown.length) notes.push(`npz ${unknown.map(quote).join(", ")} unknown, dropped`);
  const [zoom, zoomNote] = zoomFromLink(get("zoom"), get("at"));
  if (zoomNote) notes.push(zoomNote);
  return {
    state: {
      scene, view: view.name, sensor, illuminants, intensities, size: sizeOk ? size : "", gt, denoise, aov, noise, ev, gain,
      npz: npz.filter((x) => NPZ_OUTPUTS.includes(x)),
    },
    zoom,
    notes,
  };
}
