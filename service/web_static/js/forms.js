// Uploads (sensor, illuminant) and the download links of the current sample.
import { postForm } from "./api.js";

//: what the npz download may hold (GET /sample outputs; ccm is 36 bytes a pixel, so off by default)
export const NPZ_OUTPUTS = ["raw", "gain", "srgb", "weights", "mask", "illum", "mixture", "ccm"];
export const DEFAULT_NPZ = NPZ_OUTPUTS.filter((o) => o !== "ccm");

/** One checkbox per output the npz may hold; `onChange(list)` when one is toggled. */
export function outputChecks(chosen, onChange) {
  const box = document.getElementById("dl-outputs");
  for (const name of NPZ_OUTPUTS) {
    const label = document.createElement("label");
    label.innerHTML = `<input type="checkbox" value="${name}"${chosen.includes(name) ? " checked" : ""}> ${name}`;
    box.append(label);
  }
  box.addEventListener("change", () =>
    onChange([...box.querySelectorAll("input:checked")].map((c) => c.value)));
}

/** Point the download links at GET /sample with the page's parameters (`outputs`: the npz's and the EXR's). */
export function setDownloads(params, stem, outputs) {
  const link = (id, extra, ext) => {
    const a = document.getElementById(id);
    const q = new URLSearchParams(params);
    for (const [k, v] of Object.entries(extra)) q.set(k, v);
    a.href = `/sample?${q}`;
    a.download = `${stem}${ext}`;
  };
  link("dl-npz", { format: "npz", outputs: [...outputs, "meta"].join(",") }, ".npz");
  link("dl-exr", { format: "exr", outputs: [...outputs, "meta"].join(",") }, ".exr");
  if (!outputs.length) document.getElementById("dl-exr").removeAttribute("href"); // an EXR needs an image layer
  link("dl-srgb", { format: "png", outputs: "srgb" }, "-srgb.png");
  link("dl-raw", { format: "png", outputs: "raw" }, "-raw.png");
  link("dl-dng", { format: "dng", outputs: "raw" }, ".dng");
}

/**
 * Wire the upload forms: a sensor file, a DNG (the service estimates the sensor from its colour
 * matrices) and an illuminant. `onUploaded(kind, name)` runs after the service accepted it (kind
 * "sensors" or "illuminants"); errors are shown as the service's one-line detail.
 */
export function wireUploads(onUploaded) {
  const status = document.getElementById("upload-status");
  const forms = [["up-sensor", "sensors", "/sensors"], ["up-dng", "sensors", "/sensors/estimate"],
                 ["up-illuminant", "illuminants", "/illuminants"]];
  for (const [id, kind, path] of forms) {
    const form = document.getElementById(id);
    form.addEventListener("submit", async (ev) => {
      ev.preventDefault();
      const data = new FormData(form);
      const name = String(data.get("name")).trim();
      status.className = "";
      status.textContent = `uploading ${kind.slice(0, -1)} '${name}'…`;
      try {
        await postForm(path, data, document.getElementById("token").value.trim());
        status.textContent = `uploaded ${kind.slice(0, -1)} '${name}'`;
        form.reset();
        await onUploaded(kind, name);
      } catch (e) {
        status.className = "error";
        status.textContent = `upload refused: ${e.message}`;
      }
    });
  }
}
