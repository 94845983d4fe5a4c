"""Part ``backends`` of ``bench/render.py``: Mitsuba (illumix default settings) against Cycles run the
thesis way (21 passes × 3 fixed wavelengths, same seed per pass) on the same scenes, in one run.

Per scene (``probe`` = ``shared/bench-scenes/probe.yaml``, ``demo`` = the seeded demo room), view
and resolution:

- each backend renders every group twice (seeds 0 and 1) at its default settings, transport only
  (as the thesis rendered); CPU seconds of the render (Mitsuba: this process, after a warm-up render
  that compiles its kernels; Cycles: the Blender child processes); and once more with the
  illumination cubes;
- the raw image: the cubes relit (probe: A → D65, B → illuminant A, as issue 17 measured; demo:
  every group → D65) and projected through ``--backends-sensor``;
- **noise** from the seed pair, ``std(a − b)/√2`` over a region divided by the region's mean: raw R,
  G, B on the *lit region* (flat floor pixels whose raw G is above the median: the probe's lit
  floor) and over the whole image, and the 550 nm band of the summed cube on the lit region;
- **cross-check**: mean raw per region (image, lit region, and one region per material, from the
  albedo AOV) of each backend against a Mitsuba reference at ``--backends-ref-spp`` (uniform), in
  percent; and the same for the illumination cubes (white-Lambertian first hit), which isolates
  geometry, lights and spectra from the BSDF models;
- the closed-form validation chart (``illumix validate``) on both backends: mean and max ΔE00;
- ``vs_thesis`` (issue 17's figures): illumix's CPU time to the thesis method's noise over the thesis
  method's CPU time — raw G on the lit region and the image, raw G under FL11 relighting of every
  group, and the 550 nm band — assuming illumix's noise falls as 1/√time.
"""

from __future__ import annotations

import math
import resource
import time

import numpy as np

PROBE = "probe.yaml"


def _cpu_self() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def render_all(scene, view: str, settings) -> tuple[dict, dict, float]:
    """``({group: cube}, {group: illumination cube}, CPU seconds)`` of every group with ``settings``."""
    from illumix.renderer_jobs.cycles import render as cycles_render
    from illumix.renderer_jobs.mitsuba import render as mitsuba_render

    c0 = _cpu_self() + _cpu_children()
    if settings.backend == "cycles":
        res = cycles_render.render_cubes(scene, view, settings)
    else:
        res = {g: mitsuba_render.render_cube(scene, view, g, settings) for g in scene.group_names}
    cpu = _cpu_self() + _cpu_children() - c0
    return ({g: r.cube.astype(np.float64) for g, r in res.items()},
            {g: r.illumination.astype(np.float64) for g, r in res.items() if r.illumination is not None}, cpu)


def relit_raw(cubes: dict, relight: dict, weights: np.ndarray) -> np.ndarray:
    return sum((cubes[g] * relight[g]) @ weights for g in cubes)


def regions(aovs: dict, raw_ref: np.ndarray) -> dict[str, np.ndarray]:
    """``image`` (geometry pixels), ``lit`` (upward-facing flat pixels brighter than their median),
    and one region per distinct albedo (materials, albedo AOV rounded to 0.05), at least 30 pixels
    each, away from edges."""
    from scipy import ndimage

    mask = aovs["mask"] & ~aovs["emitter"]
    n = aovs["normal"]
    up_axis = int(np.argmax(np.abs(n[mask]).mean(axis=0)))
    flat = mask & (np.abs(n[..., up_axis]) > 0.99)
    g = raw_ref[..., 1]
    lit = flat & (g > np.median(g[flat])) if flat.any() else flat
    out = {"image": mask, "lit": lit}
    key = np.round(aovs["albedo"] * 20) / 20  # materials: albedo to 0.05 (the AOV's noise splits finer bins)
    inner = ndimage.binary_erosion(mask, iterations=1)
    codes, inverse, counts = np.unique(key[inner].reshape(-1, 3), axis=0, return_inverse=True, return_counts=True)
    order = np.argsort(-counts)
    for i in order[:6]:
        if counts[i] < 30:
            break
        sel = np.zeros(mask.shape, bool)
        sel[inner] = inverse.ravel() == i
        out[f"albedo {tuple(round(float(x), 2) for x in codes[i])}"] = sel
    return out


def noise(a: np.ndarray, b: np.ndarray, sel: np.ndarray) -> list[float]:
    """Relative noise per channel over ``sel`` from two independent renders: ``std((a−b)/√2)/mean``."""
    d = (a[sel] - b[sel]) / math.sqrt(2)
    m = 0.5 * (a[sel] + b[sel])
    return [round(float(100 * d[:, c].std() / m[:, c].mean()), 3) for c in range(a.shape[-1])]


def compare_scene(name: str, scene, view: str, relight: dict, weights: np.ndarray, ref_spp: int, log) -> dict:
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.retarget.illuminants import illuminant_spd

    fl11 = {g: illuminant_spd("FL11", scene.spectral_grid) for g in relight}  # a spiky illuminant
    band = int(np.argmin(np.abs(scene.spectral_grid.wavelengths - 550)))
    log(f"  backends/{name}: Mitsuba reference at {ref_spp} spp")
    ref_t, ref_u, ref_cpu = render_all(scene, view, RenderSettings(spp=ref_spp, adaptive=False, seed=7))
    aovs = render_aovs(scene, view, RenderSettings())
    raw_ref = relit_raw(ref_t, relight, weights)
    uraw_ref = relit_raw(ref_u, relight, weights)
    regs = regions(aovs, raw_ref)
    out: dict = {"view": view, "resolution": list(raw_ref.shape[1::-1]), "reference_spp": ref_spp,
                 "reference_cpu_s": round(ref_cpu, 1), "region_pixels": {k: int(v.sum()) for k, v in regs.items()},
                 "backends": {}}
    for backend in ("mitsuba", "cycles"):
        if backend == "mitsuba":  # compile the kernels first (Dr.Jit; cached on disk): timings are of rendering
            for ill in (False, True):
                render_all(scene, view, RenderSettings(seed=99, illumination=ill))
        runs = []
        for seed in (0, 1):  # transport only, as the thesis method rendered
            log(f"  backends/{name}: {backend} seed {seed}")
            t, _, cpu = render_all(scene, view, RenderSettings(seed=seed, backend=backend, illumination=False))
            runs.append((t, cpu))
        log(f"  backends/{name}: {backend} with illumination cubes")
        _, u, cpu_u = render_all(scene, view, RenderSettings(seed=2, backend=backend))
        raws = [relit_raw(t, relight, weights) for t, _ in runs]
        spectra = [sum(t[g] * relight[g] for g in t)[..., band:band + 1] for t, _ in runs]
        mean_raw, mean_uraw = 0.5 * (raws[0] + raws[1]), relit_raw(u, relight, weights)
        out["backends"][backend] = {
            "cpu_s": round(float(np.median([r[1] for r in runs])), 2),
            "cpu_with_illumination_s": round(cpu_u, 2),
            "raw_noise_lit_pct": noise(raws[0], raws[1], regs["lit"]),
            "raw_noise_image_pct": noise(raws[0], raws[1], regs["image"]),
            "band_550_noise_lit_pct": noise(spectra[0], spectra[1], regs["lit"])[0],
            "fl11_raw_noise_lit_pct": noise(*(relit_raw(t, fl11, weights) for t, _ in runs), regs["lit"]),
            "mean_raw_vs_reference_pct": {k: [round(float(100 * (mean_raw[r][:, c].mean() / raw_ref[r][:, c].mean()
                                                                  - 1)), 2) for c in range(3)]
                                          for k, r in regs.items()},
            "illumination_vs_reference_pct": {k: [round(float(100 * (mean_uraw[r][:, c].mean()
                                                                     / uraw_ref[r][:, c].mean() - 1)), 2)
                                                  for c in range(3)] for k, r in regs.items()},
        }
    m, c = out["backends"]["mitsuba"], out["backends"]["cycles"]
    out["cycles_cpu_over_mitsuba"] = round(c["cpu_s"] / m["cpu_s"], 3)
    out["vs_thesis"] = vs_thesis(m, c)
    # illumix also renders the illumination cubes the thesis method had no counterpart of: its CPU
    # time with them, against the thesis method's transport-only time
    out["vs_thesis_with_illumination"] = vs_thesis({**m, "cpu_s": m["cpu_with_illumination_s"]}, c)
    out["max_abs_region_diff_pct"] = max(abs(v) for vals in c["mean_raw_vs_reference_pct"].values() for v in vals)
    return out


def vs_thesis(ill: dict, thesis: dict) -> dict:
    """CPU time of illumix's default settings to the thesis method's noise, over the thesis method's
    CPU time (issue 17's ratios): ``(cpu_i / cpu_t) · (noise_i / noise_t)²``, Monte-Carlo noise
    falling as 1/√time for the illumix renderer at fixed settings."""
    def ratio(key: str, channel: int | None = 1) -> float:
        ni, nt = ill[key], thesis[key]
        if channel is not None:
            ni, nt = ni[channel], nt[channel]
        return round(ill["cpu_s"] / thesis["cpu_s"] * (ni / nt) ** 2, 3)
    return {"raw_g_lit": ratio("raw_noise_lit_pct"), "raw_g_image": ratio("raw_noise_image_pct"),
            "fl11_raw_g_lit": ratio("fl11_raw_noise_lit_pct"), "band_550": ratio("band_550_noise_lit_pct", None)}


def validation(spp: int, log) -> dict:
    from illumix.renderer_jobs.validate import run_validation

    out = {}
    for backend in ("mitsuba", "cycles"):
        log(f"  backends/validation: {backend}")
        t0 = time.perf_counter()
        res = run_validation(spp=spp, backend=backend)
        de = [p["delta_e00"] for p in res.patches]
        out[backend] = {"mean_delta_e00": round(float(np.mean(de)), 4), "max_delta_e00": round(float(np.max(de)), 4),
                        "seconds": round(time.perf_counter() - t0, 1)}
    return out


def part_backends(args, log) -> dict:
    from pathlib import Path

    from illumix.scene import demo
    from illumix.renderer_jobs.jobs import apply_resolution
    from illumix.scene.load import load_scenes
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    scenes_dir = Path(args.bench_scenes)
    out: dict = {"sensor": args.backends_sensor}
    probe = apply_resolution(load_scenes(scenes_dir / PROBE)[0], tuple(args.probe_size))
    grid = probe.spectral_grid
    w = get_sensor(args.backends_sensor, grid).weights()
    relight = {"A": illuminant_spd("D65", grid), "B": illuminant_spd("A", grid)}
    out["probe"] = compare_scene("probe", probe, "cam", relight, w, args.backends_ref_spp, log)
    room = demo.demo_room(args.seed, resolution=tuple(args.demo_size))
    relight = {g: illuminant_spd("D65", grid) for g in room.group_names}
    out["demo"] = compare_scene("demo", room, args.view, relight, w, args.backends_ref_spp, log)
    out["validation"] = validation(64, log)
    out["vs_thesis"] = {"probe": out["probe"]["vs_thesis"], "demo": out["demo"]["vs_thesis"]}
    return out
