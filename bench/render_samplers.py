"""Part ``samplers`` of ``bench/render.py``: what each step of the all-bands renderer buys, on its own.

Three scenes (the suite the defaults are chosen on): ``probe`` (``shared/bench-scenes/probe.yaml``,
relit A → D65, B → illuminant A, as issue 17 measured), ``demo`` (the seeded demo room, every group →
D65) and ``window`` (the demo room lit by its window alone: sun + sky portal, → D65). For every
configuration below, two seeds of every group (transport only), CPU seconds of this process (kernels
compiled in a warm-up render first), and the noise of ``bench/render_backends.py``: raw G on the lit
region and the image, raw G with every group relit by FL11, the 550 nm band of the summed cube.

The figure of merit is the CPU time to a given noise, ``cpu · noise²`` (Monte-Carlo noise² falls as
1/time at fixed settings), reported as a speed-up over the previous default (4 stratified
wavelengths per path, adaptive spp): ``(cpu_prev · noise_prev²) / (cpu · noise²)``.

Configurations: the previous default and its uniform-spp variant; all-bands paths with each of
Mitsuba's samplers (``independent`` isolates carrying every band; the others add quasi-random
samples); multijitter with 8 to 64 bands per path (``spp`` samples of every band either way); the
default with uniform instead of power-weighted light selection; and the default at half the spp
(whether noise falls faster than 1/√spp, as quasi-random samples can).
"""

from __future__ import annotations

import numpy as np
from render_backends import PROBE, _cpu_self, noise, regions, relit_raw

CONFIGS = {
    "stratified 4-wl, adaptive (previous default)": {"wavelengths": "stratified", "adaptive": True},
    "stratified 4-wl, uniform": {"wavelengths": "stratified"},
    "all-bands, independent": {"sampler": "independent"},
    "all-bands, stratified": {"sampler": "stratified"},
    "all-bands, ldsampler": {"sampler": "ldsampler"},
    "all-bands, orthogonal (36 spp: 4 sets × 9)": {"sampler": "orthogonal", "spp": 36},
    "all-bands, multijitter, 64 bands per path": {"bands_per_path": 64},
    "all-bands, multijitter, 32 bands per path": {"bands_per_path": 32},
    "all-bands, multijitter, 16 bands per path (default)": {"bands_per_path": 16},
    "all-bands, multijitter, 8 bands per path": {"bands_per_path": 8},
    "all-bands, multijitter, uniform light selection": {"emitter_selection": "uniform"},
    "all-bands, multijitter, 32 spp": {"spp": 32},
}
PREVIOUS = "stratified 4-wl, adaptive (previous default)"
METRICS = ("raw_g_lit", "raw_g_image", "fl11_raw_g_lit", "band_550")


def _render(scene, view, groups, settings):
    from illumix.renderer_jobs.mitsuba import render as mitsuba_render

    c0 = _cpu_self()
    cubes = {g: mitsuba_render.render_cube(scene, view, g, settings).cube.astype(np.float64) for g in groups}
    return cubes, _cpu_self() - c0


def measure(scene, view: str, groups: list[str], relight: dict, weights, spp: int, log, name: str) -> dict:
    from illumix.renderer_jobs.mitsuba import scene_dict as mitsuba_scene
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.retarget.illuminants import illuminant_spd

    fl11 = {g: illuminant_spd("FL11", scene.spectral_grid) for g in groups}
    band = int(np.argmin(np.abs(scene.spectral_grid.wavelengths - 550)))
    aovs = render_aovs(scene, view, RenderSettings())
    regs = None
    out: dict = {}
    for cname, cfg in CONFIGS.items():
        cfg = dict(cfg)
        mitsuba_scene.EMITTER_SELECTION = cfg.pop("emitter_selection", "power")
        try:
            kw = {"spp": spp, "illumination": False, **cfg}
            _render(scene, view, groups, RenderSettings(seed=99, **kw))  # warm-up: compile the kernels
            runs = [_render(scene, view, groups, RenderSettings(seed=s, **kw)) for s in (0, 1)]
        finally:
            mitsuba_scene.EMITTER_SELECTION = "power"
        raws = [relit_raw(t, relight, weights) for t, _ in runs]
        if regs is None:
            regs = regions(aovs, raws[0])
        spectra = [sum(t[g] * relight[g] for g in t)[..., band:band + 1] for t, _ in runs]
        row = {"spp": kw["spp"], "cpu_s": round(float(np.mean([c for _, c in runs])), 2),
               "raw_g_lit": noise(raws[0], raws[1], regs["lit"])[1],
               "raw_g_image": noise(raws[0], raws[1], regs["image"])[1],
               "fl11_raw_g_lit": noise(*(relit_raw(t, fl11, weights) for t, _ in runs), regs["lit"])[1],
               "band_550": noise(spectra[0], spectra[1], regs["lit"])[0]}
        out[cname] = row
        log(f"  samplers/{name}: {cname:48s} {row['cpu_s']:6.1f} CPU s  raw G lit {row['raw_g_lit']:.2f} %  "
            f"image {row['raw_g_image']:.2f} %  FL11 {row['fl11_raw_g_lit']:.2f} %  550 nm {row['band_550']:.2f} %")
    prev = out[PREVIOUS]
    for row in out.values():
        row["speedup_vs_previous"] = {m: round(prev["cpu_s"] * prev[m] ** 2 / (row["cpu_s"] * row[m] ** 2), 2)
                                      for m in METRICS}
    return {"view": view, "groups": groups, "resolution": list(raws[0].shape[1::-1]), "configs": out}


def part_samplers(args, log) -> dict:
    from pathlib import Path

    from illumix.scene import demo
    from illumix.renderer_jobs.jobs import apply_resolution
    from illumix.scene.load import load_scenes
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    probe_size, demo_size = (tuple(s) for s in args.samplers_sizes)
    probe = apply_resolution(load_scenes(Path(args.bench_scenes) / PROBE)[0], probe_size)
    grid = probe.spectral_grid
    w = get_sensor(args.backends_sensor, grid).weights()
    out: dict = {"sensor": args.backends_sensor}
    out["probe"] = measure(probe, "cam", probe.group_names,
                           {"A": illuminant_spd("D65", grid), "B": illuminant_spd("A", grid)}, w, 64, log, "probe")
    room = demo.demo_room(args.seed, resolution=demo_size)
    d65 = {g: illuminant_spd("D65", grid) for g in room.group_names}
    out["demo"] = measure(room, args.view, room.group_names, d65, w, 64, log, "demo")
    out["window"] = measure(room, args.view, ["daylight"], {"daylight": d65["daylight"]}, w, 64, log, "window")
    return out
