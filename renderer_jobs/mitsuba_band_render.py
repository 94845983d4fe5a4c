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

from illumix.renderer_jobs.band_schedule import live_bands, mix_seed
from illumix.renderer_jobs.boost_paths import extra_path_sums
from illumix.renderer_jobs.mitsuba_bands import band_quadruples, make_integrator
from illumix.renderer_jobs.mitsuba_scene import load_mitsuba_scene
from illumix.renderer_jobs.mitsuba_variant import import_mitsuba
from illumix.scene.model import EnvMapSky, Scene
from illumix.scene.schema import SceneError

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


def set_spp(sampler: str, spp: int, n_sets: int) -> int:
    """Paths per pixel of each of ``n_sets`` band sets sharing ``spp``; a :class:`SceneError` naming
    the fix when ``spp`` does not split into sets the sampler can render exactly."""
    per = spp // n_sets
    if per * n_sets != spp or per < 1 or not spp_allowed(sampler, per):
        rule = SPP_RULES.get(sampler)
        raise SceneError(f"spp {spp} does not split into {n_sets} band set(s) of equal spp"
                         + (f" that the {sampler} sampler takes ({rule} each)" if rule else "")
                         + f": use a multiple of {n_sets}" + (f" whose quotient is {rule}" if rule else "")
                         + ", or change --bands-per-path / --sampler")
    return per


def check_spp(sampler: str, spp: int, bands_per_path: int, n_bands: int) -> None:
    """:func:`set_spp` for a group emitting in all ``n_bands`` bands (the most sets a cube needs)."""
    set_spp(sampler, spp, len(band_sets(np.arange(n_bands), max(1, bands_per_path // 4))))


def band_sets(live: np.ndarray, max_quads: int) -> list[np.ndarray]:
    """The live bands split into the fewest interleaved sets of at most ``4·max_quads`` bands (set
    ``j`` holds every ``k``-th band from the ``j``-th): each set spans the whole spectrum, so each
    pass's paths sample every camera channel alike."""
    live = np.asarray(live, dtype=np.int64)
    k = max(1, -(-live.size // (4 * max_quads)))
    return [live[j::k] for j in range(k)]


def render_all_bands(scene: Scene, view: str, groups: list[str], passes: list[str], settings,
                     emission: np.ndarray, boost: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None]:
    """``(cube (H, W, n_bands), illumination cube or None, stats, noise)`` float32 of ``view`` lit by ``groups``
    (emitter ``passes`` from :func:`renderer_jobs.mitsuba_render.emitter_passes`), with ``settings``
    (a :class:`renderer_jobs.mitsuba_render.RenderSettings`).

    The live bands render in interleaved sets (:func:`band_sets`) of at most ``settings.bands_per_path``
    bands; the pixel's ``settings.spp`` paths are shared equally among the sets (:func:`set_spp`), so
    every band's value averages ``spp / sets`` paths. ``boost``: flat pixel indices that get
    ``settings.boost_factor`` × the paths (:mod:`renderer_jobs.boost_paths`: the film's estimate and
    the extra paths' combined by path counts; every other pixel exactly as without it).

    ``noise`` ``(H, W, 2)``: the cube's band sum weighted by the emission and its variance, from the
    spread of the band sets' own estimates of it (each set spans the spectrum with its own paths:
    :func:`set_noise`); None with one set. The denoiser reads it to weigh its bias against the noise
    (:func:`retarget.denoise.relative_noise`). Fewer bands per path make a path cheaper (raw
    noise per CPU second falls), more make a band sample cheaper (band noise per CPU second falls):
    ``bench/RENDER_PERF.md`` ("Bands per path") measures both."""
    mi, dr = import_mitsuba()
    t0 = time.perf_counter()
    grid = scene.spectral_grid
    nb = grid.n_bands
    sets = band_sets(live_bands(emission), max(1, settings.bands_per_path // 4))
    spp = set_spp(settings.sampler, settings.spp, len(sets))
    # One group without an envmap: every emitter emits strength × the group's emission, so the bands
    # render with flat emission (emitters evaluated once per vertex, not per quadruple) and are
    # scaled by the emission after — the relighting identity, exact per band.
    flat = len(groups) == 1 and not any(isinstance(e, EnvMapSky) for e in scene.emitters_of(groups[0]))
    cube = illum = None
    bad = 0.0
    kinds = np.zeros(3)  # samples whose first hit's illumination was demodulated / in-path / traced
    t_load = t_render = 0.0
    n_quads = 0
    boosting = boost is not None
    boost = np.asarray([] if boost is None else boost, np.int64)
    extra = (int(settings.boost_factor) - 1) * spp if boost.size else 0  # extra paths per boosted pixel and set
    t_boost = 0.0
    e_live = np.where(np.asarray(emission, np.float64) > 0, emission, 0.0) if flat else np.ones(nb)
    noise = np.zeros((2,), np.float64) if len(sets) > 1 else None
    for k, portals in enumerate(passes):
        t1 = time.perf_counter()
        ms, sensor = load_mitsuba_scene(scene, view, groups, settings.resolution, portals=portals, flat_emission=flat,
                                        sampler={"type": settings.sampler, "sample_count": spp})
        w, h = (int(x) for x in sensor.film().crop_size())
        # the film's paths per pixel, which weight its estimate against the extra paths': what the sampler
        # renders (multijitter rounds some counts up, e.g. 32 -> 35: the stats state both)
        n_film = int(sensor.sampler().sample_count())
        t_load += time.perf_counter() - t1
        estimates: list[np.ndarray] = []  # this pass's band sets' estimates of the band sum
        if cube is None:
            cube = np.zeros((h, w, nb), np.float64)
            illum = np.zeros((h, w, nb), np.float64) if settings.illumination else None
        for j, bands in enumerate(sets):
            quads, lanes = band_quadruples(grid.edges, bands)
            n_quads += len(quads)
            integrator = make_integrator(quads, grid.step, scene.max_depth, settings.illumination, flat)
            n_aov = len(integrator.aov_names())
            seed = mix_seed(settings.seed, k, j)
            t2 = time.perf_counter()
            out = np.asarray(mi.render(ms, sensor=sensor, integrator=integrator, spp=spp, seed=seed))
            t_render += time.perf_counter() - t2
            aov = out[..., out.shape[-1] - n_aov:]
            if illum is not None:  # every set sees the same first hits: count them once (the film's paths)
                part = aov[..., 2 * len(lanes):2 * len(lanes) + 3].sum(axis=(0, 1), dtype=np.float64)
                kinds += part * n_film / len(sets)
            bad += float(aov[..., -1].sum(dtype=np.float64)) * n_film  # per-pixel means -> counts
            if extra:
                t3 = time.perf_counter()
                sums = extra_path_sums(ms, sensor, integrator, boost, extra, seed,
                                       settings.max_lanes, np.asarray(quads[0], np.float32))
                bad += float(sums[:, -1].sum())
                aov = aov.reshape(-1, n_aov).astype(np.float64)  # exact: the others add as before
                aov[boost] = (n_film * aov[boost] + sums) / (n_film + extra)
                aov = aov.reshape(h, w, n_aov)
                t_boost += time.perf_counter() - t3
            on = lanes >= 0
            cube[..., lanes[on]] += aov[..., :len(lanes)][..., on]
            if illum is not None:
                illum[..., lanes[on]] += aov[..., len(lanes):2 * len(lanes)][..., on]
            if noise is not None:
                estimates.append(_set_estimate(aov[..., :len(lanes)][..., on], lanes[on], e_live, sets))
        if noise is not None:
            noise = noise + set_noise(np.stack(estimates))
    if flat:
        cube *= emission
        if illum is not None:
            illum *= emission
    stats = {"load_s": round(t_load, 4), "trace_s": round(t_render, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": int(round(bad)),
             "band_sets": len(sets), "quadruples": n_quads // max(1, len(passes)),
             "paths_per_pixel": spp * len(sets), "samples_per_band": spp, "sampler": settings.sampler,
             # what the sampler rendered: multijitter renders ⌊√n⌋·⌈n/⌊√n⌋⌉ of n asked (32 -> 35)
             "paths_per_pixel_rendered": n_film * len(sets), "samples_per_band_rendered": n_film,
             "flat_emission_scaled": flat}
    if boosting:
        stats["targeted_paths"] = {"pixels": int(boost.size), "pixel_fraction": round(boost.size / (h * w), 5),
                                   "paths_per_pixel": (spp + extra) * len(sets),
                                   "extra_paths_fraction": round(boost.size * extra / (h * w * spp), 5),
                                   "trace_s": round(t_boost, 4)}
    if illum is not None:
        stats["illumination"] = {"samples": int(round(kinds.sum())), "demodulated": int(round(kinds[0])),
                                 "in_path": int(round(kinds[1])), "traced": int(round(kinds[2]))}
    return (cube.astype(np.float32), None if illum is None else illum.astype(np.float32), stats,
            None if noise is None else noise.astype(np.float32))


def _set_estimate(values: np.ndarray, lanes: np.ndarray, weight: np.ndarray, sets: list[np.ndarray]) -> np.ndarray:
    """``(H, W)``: one band set's estimate of the weighted sum over every live band — its own
    bands' sum scaled by the weight they carry of the whole."""
    all_live = float(weight[np.concatenate(sets)].sum())
    own = float(weight[lanes].sum())
    return (values.astype(np.float64) @ weight[lanes]) * (all_live / own if own > 0 else 0.0)


def set_noise(estimates: np.ndarray) -> np.ndarray:
    """``(H, W, 2)``: from ``k`` band sets' independent estimates ``(k, H, W)`` of one pass's
    weighted band sum, that sum (their mean, which is how the cube adds its sets up to their
    spectral detail) and its variance, ``s²/k`` (each set has its own paths and seed; a set's
    bands differ from another's only as the spectrum does, which a smooth one hardly does)."""
    k = estimates.shape[0]
    return np.stack([estimates.mean(0), estimates.var(0, ddof=1) / k], -1)
