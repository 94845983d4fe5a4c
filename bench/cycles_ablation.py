"""Which Cycles setting or translation choice moves the probe scene's raw, and by how much?

Issue 16 reported two hand-made versions of ``shared/bench-scenes/probe.yaml`` (Mitsuba and Cycles)
differing by G −3.9 %, B −6.2 %. With one scene translation (:mod:`renderer_jobs.cycles.job`) the
backends agree within 1.3 % (``bench/render.py --parts backends``); this script measures the
plausible hand-made differences one at a time, each as the change of the lit floor's and the whole
image's mean raw (A → D65, B → illuminant A, Nikon D810) against the backend's own settings. A
variant is a textual edit of a copy of the worker and its node module (in a temporary folder) or of the job document:
nothing in the package changes.

    python bench/cycles_ablation.py [--spp 32] [--size 120x90]     # ~3 min on 2 cores; JSON last
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

WORKER_EDITS = {
    "Principled multiscatter GGX (Blender's default)": [('pr.distribution = "GGX"', 'pr.distribution = "MULTI_GGX"')],
    "point light radius 0.1 m + soft falloff (Blender's defaults)": [
        ("data.shadow_soft_size = 0.0\n            data.use_soft_falloff = False",
         "data.shadow_soft_size = 0.1\n            data.use_soft_falloff = True")],
    "12 bounces (Blender's default) instead of max_depth - 2": [('b = int(s["max_bounces"])', "b = 12")],
    "Blackman-Harris 1.5 px pixel filter (Blender's default)": [
        ('cy.pixel_filter_type = "BOX"\n        cy.filter_width = 1.0',
         'cy.pixel_filter_type = "BLACKMAN_HARRIS"\n        cy.filter_width = 1.5')],
    "filter glossy 1.0 (Blender's default)": [("cy.blur_glossy = 0.0", "cy.blur_glossy = 1.0")],
    "light tree off": [('cy.use_light_tree = bool(s["light_tree"])', "cy.use_light_tree = False")],
}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--size", default="120x90")
    ap.add_argument("--scene", default=str(ROOT.parent / "shared" / "bench-scenes" / "probe.yaml"))
    ap.add_argument("--sensor", default=str(ROOT.parent / "shared" / "data" / "rawtoaces-data" / "data" / "camera"
                                            / "Nikon_D810_380_780_5.json"))
    args = ap.parse_args(argv)
    from illumix.renderer_jobs.cycles import job as cj
    from illumix.renderer_jobs.cycles import render as cr
    from illumix.renderer_jobs.jobs import apply_resolution
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.scene.load import load_scenes
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    size = tuple(int(v) for v in args.size.split("x"))
    scene = apply_resolution(load_scenes(args.scene)[0], size)
    grid = scene.spectral_grid
    weights = get_sensor(args.sensor, grid).weights()
    relight = {"A": illuminant_spd("D65", grid), "B": illuminant_spd("A", grid)}
    sources = {name: (cr.WORKER.parent / name).read_text() for name in ("cycles_worker.py", "cycles_nodes.py")}
    write_job = cj.write_job
    tmp = Path(tempfile.mkdtemp(prefix="illumix-ablation-"))

    def project(cubes: dict, w: np.ndarray = weights) -> np.ndarray:
        return sum((cubes[g].cube * relight[g]) @ w for g in relight)

    def render(worker_edits=(), job_edit=None) -> dict:
        texts = dict(sources)
        for old, new in worker_edits:
            hits = [n for n, t in texts.items() if old in t]
            if not hits:
                raise SystemExit(f"the worker changed: {old!r} not found; update WORKER_EDITS")
            texts[hits[0]] = texts[hits[0]].replace(old, new)
        for name, text in texts.items():
            (tmp / name).write_text(text)
        cr.WORKER = tmp / "cycles_worker.py"

        def edited(*a, **k):
            job = write_job(*a, **k)
            if job_edit is not None:
                job_edit(job)
                (a[2] / "job.json").write_text(json.dumps(job))
            return job
        cr.write_job = edited
        return cr.render_cubes(scene, "cam", RenderSettings(spp=args.spp, illumination=False))

    def raw(worker_edits=(), job_edit=None) -> np.ndarray:
        return project(render(worker_edits, job_edit))

    base_cubes = render()
    base = project(base_cubes)
    aovs = render_aovs(scene, "cam", RenderSettings())
    floor = (aovs["normal"][..., 2] > 0.99) & aovs["mask"]
    lit = floor & (base[..., 1] > np.median(base[..., 1][floor]))

    def change(img: np.ndarray) -> dict:
        return {"lit_floor_pct": np.round(100 * (img[lit].mean(0) / base[lit].mean(0) - 1), 2).tolist(),
                "image_pct": np.round(100 * (img[aovs["mask"]].mean(0) / base[aovs["mask"]].mean(0) - 1), 2).tolist()}

    rows = {}
    c = {n: cj.plastic_diffuse_scale(m.alpha, m.int_ior / m.ext_ior) for n, m in scene.materials.items()}

    def unscaled(job):
        for name, m in job["materials"].items():
            if m["kind"] == "plastic":
                m["diffuse"] = [v / c[name] for v in m["diffuse"]]
    rows["Principled base colour = reflectance (no fit to Mitsuba's rough plastic)"] = change(raw(job_edit=unscaled))
    for label, edits in WORKER_EDITS.items():
        rows[label] = change(raw(edits))
        print(f"{label}: {rows[label]}", flush=True)
    # spectral misregistration: the sensor sampled 5 nm off the scene's bands (an off-by-one band)
    from illumix.retarget.grid import SpectralGrid

    shifted = get_sensor(args.sensor, SpectralGrid(grid.start + 5, grid.end + 5, grid.step)).weights()
    rows["sensor 5 nm off the bands (one band)"] = change(project(base_cubes, shifted))
    doc = {"benchmark": "cycles_ablation", "scene": args.scene, "size": list(size), "spp": args.spp,
           "lit_floor_pixels": int(lit.sum()), "changes_rgb": rows}
    print(json.dumps(doc, indent=1))
    return doc


if __name__ == "__main__":
    main()
