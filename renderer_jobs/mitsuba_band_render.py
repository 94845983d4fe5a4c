"""The ``"all-bands"`` wavelength mode: a cube rendered by Mitsuba's own render loop with
:mod:`renderer_jobs.mitsuba_bands` (every band on every path) and a low-discrepancy sampler.

``mi.render`` runs the integrator over the sensor's film (``hdrfilm``, box filter: a sample adds only
to its own pixel) with the sampler named by ``RenderSettings.sampler``; the bands come back as AOV
channels, already averaged per pixel. Portal emitters render in a second pass, added (linearity),
as in :mod:`renderer_jobs.mitsuba_render`. Deterministic: the same seed gives the same cube bit for
bit, whatever the thread count (the film's sums run in a fixed order per pixel).
"""

from __future__ import annotations

import time

import numpy as np

from renderer_jobs.band_schedule import hash_u32, live_bands
from renderer_jobs.mitsuba_bands import band_quadruples, make_integrator
from renderer_jobs.mitsuba_scene import build_scene_dict
from renderer_jobs.mitsuba_variant import RenderError, import_mitsuba
from renderer_jobs.modes import SAMPLERS
from renderer_jobs.scene_model import Scene

# spp Mitsuba's samplers can take without rounding it up (they would, with a warning): the settings
# are checked against these so that the metadata's spp is the spp rendered.
SPP_RULES = {"ldsampler": "a power of 2", "orthogonal": "a prime squared (4, 9, 25, 49, 121, 169, …)"}


def _is_prime(n: int) -> bool:
    return n >= 2 and all(n % k for k in range(2, int(n ** 0.5) + 1))


def spp_allowed(sampler: str, spp: int) -> bool:
    """Whether Mitsuba's ``sampler`` renders exactly ``spp`` samples per pixel."""
    if sampler == "ldsampler":
        return spp & (spp - 1) == 0
    if sampler == "orthogonal":
        r = round(spp ** 0.5)
        return r * r == spp and _is_prime(r)
    return True


def render_all_bands(scene: Scene, view: str, groups: list[str], passes: list[str], settings,
                     emission: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, dict]:
    """``(cube (H, W, n_bands), illumination cube or None, stats)`` float32 of ``view`` lit by ``groups``
    (emitter ``passes`` from :func:`renderer_jobs.mitsuba_render.emitter_passes`), with ``settings``
    (a :class:`renderer_jobs.mitsuba_render.RenderSettings`)."""
    mi, dr = import_mitsuba()
    t0 = time.perf_counter()
    nb = scene.spectral_grid.n_bands
    live = live_bands(emission)
    grid = scene.spectral_grid
    quads, lanes = band_quadruples(grid.edges, live)
    integrator = make_integrator(quads, grid.step, scene.max_depth, settings.illumination)
    n_aov = len(integrator.aov_names())
    cube = illum = None
    bad = 0.0
    kinds = np.zeros(3)  # samples whose first hit's illumination was demodulated / in-path / traced
    t_load = t_render = 0.0
    for k, portals in enumerate(passes):
        t1 = time.perf_counter()
        doc = build_scene_dict(scene, view, groups, resolution=settings.resolution, portals=portals)
        doc["sensor"]["sampler"] = {"type": settings.sampler, "sample_count": settings.spp}
        try:
            ms = mi.load_dict(doc)
        except Exception as exc:  # noqa: BLE001 — Mitsuba's own message, on one line
            raise RenderError(f"scene {scene.name!r}: Mitsuba could not load it: {str(exc).splitlines()[0]}") from None
        sensor = ms.sensors()[0]
        w, h = (int(x) for x in sensor.film().crop_size())
        seed = int(hash_u32(np.array([k]), settings.seed)[0])
        t2 = time.perf_counter()
        out = np.asarray(mi.render(ms, sensor=sensor, integrator=integrator, spp=settings.spp, seed=seed))
        t_render += time.perf_counter() - t2
        t_load += t2 - t1
        aov = out[..., out.shape[-1] - n_aov:]
        if cube is None:
            cube = np.zeros((h, w, nb), np.float64)
            illum = np.zeros((h, w, nb), np.float64) if settings.illumination else None
        on = lanes >= 0
        cube[..., lanes[on]] += aov[..., :len(lanes)][..., on]
        if illum is not None:
            illum[..., lanes[on]] += aov[..., len(lanes):2 * len(lanes)][..., on]
            kinds += aov[..., 2 * len(lanes):2 * len(lanes) + 3].sum(axis=(0, 1), dtype=np.float64) * settings.spp
        bad += float(aov[..., -1].sum(dtype=np.float64)) * settings.spp
    stats = {"load_s": round(t_load, 4), "trace_s": round(t_render, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": int(round(bad)),
             "quadruples": len(quads),
             "sampler": settings.sampler}
    if illum is not None:
        n = int(round(kinds.sum()))
        stats["illumination"] = {"samples": n, "demodulated": int(round(kinds[0])),
                                 "in_path": int(round(kinds[1])), "traced": int(round(kinds[2]))}
    return (cube.astype(np.float32), None if illum is None else illum.astype(np.float32), stats)
