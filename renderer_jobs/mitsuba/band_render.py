"""The ``"all-bands"`` wavelength mode: a cube rendered by Mitsuba's own render loop with
:mod:`renderer_jobs.mitsuba.bands` (every band on every path) and a low-discrepancy sampler.

``mi.render`` runs the integrator over the sensor's film (``hdrfilm``, box filter: a sample adds only
to its own pixel) with the sampler named by ``RenderSettings.sampler``; the bands come back as AOV
channels, already averaged per pixel. Portal emitters render in a second pass, added (linearity),
as in :mod:`renderer_jobs.mitsuba.render`. Deterministic: the same seed gives the same cube bit for
bit, whatever the thread count (the film's sums run in a fixed order per pixel).
"""

from __future__ import annotations

import time

import numpy as np

from illumix.renderer_jobs.band_schedule import live_bands, mix_seed
from illumix.renderer_jobs.mitsuba.boost_paths import extra_path_sums
from illumix.renderer_jobs.mitsuba.bands import band_quadruples, make_integrator
from illumix.renderer_jobs.mitsuba.guide_learning import learn_guide
from illumix.renderer_jobs.mitsuba.light_paths import light_paths_reach, light_set_aovs
from illumix.renderer_jobs.mitsuba.path_guide import GuideArrays
from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
from illumix.renderer_jobs.mitsuba.sun_windows import SunWindows, window_rects
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba
from illumix.scene.model import ConstantSky, DirectionalLight, EnvMapSky, Scene
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


def sets_give_halves(emission: np.ndarray, bands_per_path: int) -> bool:
    """Whether a cube of this emission renders in an even number of band sets, so that
    :func:`render_all_bands` returns its two halves."""
    n = len(band_sets(live_bands(emission), max(1, bands_per_path // 4)))
    return n >= 2 and n % 2 == 0


def render_all_bands(scene: Scene, view: str, groups: list[str], passes: list[str], settings,
                     emission: np.ndarray, boost: np.ndarray | None = None, loaded: dict | None = None,
                     kind: str = "plain") -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None, np.ndarray | None]:
    """``(cube (H, W, n_bands), illumination cube or None, stats, noise, halves)`` of ``view`` lit by ``groups``
    (emitter ``passes`` from :func:`renderer_jobs.mitsuba.render.emitter_passes`), with ``settings``
    (a :class:`renderer_jobs.mitsuba.render.RenderSettings`).

    The live bands render in interleaved sets (:func:`band_sets`) of at most ``settings.bands_per_path``
    bands; the pixel's ``settings.spp`` paths are shared equally among the sets (:func:`set_spp`), so
    every band's value averages ``spp / sets`` paths. ``boost``: flat pixel indices that get
    ``settings.boost_factor`` × the paths (:mod:`renderer_jobs.mitsuba.boost_paths`: the film's estimate and
    the extra paths' combined by path counts; every other pixel exactly as without it).

    ``noise`` ``(H, W, 2)``: the cube's band sum weighted by the emission and its variance, from the
    spread of the band sets' own estimates of it (each set spans the spectrum with its own paths:
    :func:`set_noise`); None with one set. The denoiser reads it to weigh its bias against the noise
    (:func:`retarget.denoise.relative_noise`). ``halves`` ``(H, W, 2)`` float64: two independent
    estimates of that band sum, the even band sets' and the odd ones', each from half the paths (the
    until-clean rule's halves, free: :mod:`renderer_jobs.mitsuba.until_clean`); None unless the sets
    are an even number. ``kind``: ``"plain"`` camera paths, ``"guided"`` (below) or ``"light"``: light
    paths (:mod:`renderer_jobs.mitsuba.light_paths`; one group of flat emission only,
    :func:`light_paths_apply`). ``loaded``: a dict the caller keeps between calls
    for the same view and groups (:mod:`renderer_jobs.mitsuba.until_clean`'s rounds): each pass's
    loaded Mitsuba scene is kept there and reused, its sampler set to this call's spp, instead of
    loading the scene again (the same pixels as a fresh load: tests/test_until_clean.py). ``"guided"``: the
    paths take some bounces from a path guide learnt for each pass (:mod:`renderer_jobs.mitsuba.path_guide`;
    learnt once and kept in ``loaded`` when given). Fewer bands per path make a path cheaper (raw
    noise per CPU second falls), more make a band sample cheaper (band noise per CPU second falls):
    ``bench/RENDER_PERF.md`` ("Bands per path") measures both."""
    mi, dr = import_mitsuba()
    t0 = time.perf_counter()
    sets = band_sets(live_bands(emission), max(1, settings.bands_per_path // 4))
    spp = set_spp(settings.sampler, settings.spp, len(sets))
    flat = flat_emission(scene, groups)
    if kind == "light" and not light_paths_apply(scene, groups):
        raise ValueError("light paths need one group of flat emission with a lamp in it (light_paths_apply)")
    boosting = boost is not None
    boost = np.asarray([] if boost is None else boost, np.int64)
    extra = (int(settings.boost_factor) - 1) * spp if boost.size else 0  # extra paths per boosted pixel and set
    e_live = np.where(np.asarray(emission, np.float64) > 0, emission, 0.0) if flat else np.ones(scene.spectral_grid.n_bands)
    noise = np.zeros((2,), np.float64) if len(sets) > 1 else None
    halves = 0.0 if sets_give_halves(emission, settings.bands_per_path) else None
    run = _Run(scene, settings, spp, flat, boost, extra, sets, e_live)
    for k, portals in enumerate(passes):
        ms, sensor = run.load_pass(view, groups, portals, loaded, k)
        # light paths for lamps and a sun through windows: a portal pass, or one with a sky, keeps to camera paths
        run.light = kind == "light" and portals != "only" and light_paths_reach(ms, run.windows is not None)
        # a pass a light round leaves to camera paths takes them as a camera round would
        camera_guided = kind == "guided" or (kind == "light" and not run.light and settings.guide_paths)
        run.guide = run.guide_of(ms, sensor, loaded, k, live_bands(emission)) if camera_guided else None
        # this pass's band sets' estimates of the band sum
        estimates = [run.render_set(mi, ms, sensor, bands, k, j, noise is not None) for j, bands in enumerate(sets)]
        if noise is not None:
            noise = noise + set_noise(np.stack(estimates))
        if halves is not None:  # the passes add up, as the cube's do
            halves = halves + np.stack([np.mean(estimates[0::2], 0), np.mean(estimates[1::2], 0)], -1)
    cube, illum = run.cube, run.illum
    if flat:
        cube *= emission
        if illum is not None:
            illum *= emission
    stats = run.stats(t0, len(passes), boosting)
    return (cube.astype(np.float32), None if illum is None else illum.astype(np.float32), stats,
            None if noise is None else noise.astype(np.float32), halves)


def flat_emission(scene: Scene, groups: list[str]) -> bool:
    """Whether the cube of ``groups`` renders with flat emission — one group without an envmap: every
    emitter emits strength × the group's emission, so the bands render with emission 1 (emitters
    evaluated once per vertex, not per quadruple) and are scaled by the emission after, the
    relighting identity, exact per band."""
    return len(groups) == 1 and not any(isinstance(e, EnvMapSky) for e in scene.emitters_of(groups[0]))


def light_paths_apply(scene: Scene, groups: list[str]) -> bool:
    """Whether the cube of ``groups`` may take light paths (:mod:`renderer_jobs.mitsuba.light_paths`):
    flat emission, and among its emitters a lamp — one that is neither a sky portal nor at infinity —
    or a sun in a scene with windows to draw its paths through
    (:mod:`renderer_jobs.mitsuba.sun_windows`). A window's sky portal keeps to camera paths: its light
    paths did worse than camera paths on every daylight cube measured (bench/SCENES.md, "Light
    paths"); so does a sky at infinity, and a sun with no window."""
    if not flat_emission(scene, groups):
        return False
    ems = scene.emitters_of(groups[0])
    lamp = any(not scene.is_portal(e) and not isinstance(e, (DirectionalLight, ConstantSky, EnvMapSky)) for e in ems)
    sun = any(isinstance(e, DirectionalLight) for e in ems) and window_rects(scene) is not None
    return lamp or sun


class _Run:
    """One cube's render through Mitsuba's loop: the sums over passes and band sets, and what the
    stats report (times, non-finite samples, how each first hit's illumination was estimated)."""

    def __init__(self, scene: Scene, settings, spp: int, flat: bool, boost: np.ndarray, extra: int,
                 sets: list[np.ndarray], e_live: np.ndarray) -> None:
        self.scene, self.settings, self.spp, self.flat = scene, settings, spp, flat
        self.boost, self.extra, self.sets, self.e_live = boost, extra, sets, e_live
        self.cube = self.illum = None
        self.bad = 0.0
        self.kinds = np.zeros(3)  # samples whose first hit's illumination was demodulated / in-path / traced
        self.t_load = self.t_render = self.t_boost = 0.0
        self.n_quads = self.n_film = 0
        self.shape = (0, 0)
        self.guide, self.guides = None, []  # this pass's GuideArrays; each pass's learning stats
        self.light = False  # this pass: light paths (with their camera-path complement), not camera paths
        self.light_sets = 0  # band sets (over passes) that took them: not portal passes, none with a sky
        rects = window_rects(scene)
        self.windows = None if rects is None else SunWindows(rects)  # a sun's light paths start in them

    def guide_of(self, ms, sensor, loaded: dict | None, k: int, live: np.ndarray):
        """The path guide of pass ``k`` on the Dr.Jit side: from ``loaded``, else learnt (and kept)."""
        mi, dr = import_mitsuba()
        key = ("guide", k)
        if loaded is not None and key in loaded:
            return GuideArrays(mi, dr, loaded[key])
        c0 = time.process_time()
        field, info = learn_guide(self.scene, ms, sensor, live, self.flat, self.settings.seed)
        self.guides.append({**info, "learn_cpu_s": round(time.process_time() - c0, 4)})
        if loaded is not None:
            loaded[key] = field
        return GuideArrays(mi, dr, field)

    def load_pass(self, view: str, groups: list[str], portals, loaded: dict | None, k: int):
        """The Mitsuba scene and sensor of emitter pass ``k`` (the film allocated on the first): from
        ``loaded`` when it holds them, else loaded (and kept there)."""
        t1 = time.perf_counter()
        st = self.settings
        if loaded is not None and k in loaded:
            ms, sensor = loaded[k]
            sensor.sampler().set_sample_count(self.spp)
        else:
            ms, sensor = load_mitsuba_scene(self.scene, view, groups, st.resolution, portals=portals, flat_emission=self.flat,
                                            sampler={"type": st.sampler, "sample_count": self.spp})
            if loaded is not None:
                loaded[k] = ms, sensor
        w, h = (int(x) for x in sensor.film().crop_size())
        # the film's paths per pixel, which weight its estimate against the extra paths': what the sampler
        # renders (multijitter rounds some counts up, e.g. 32 -> 35: the stats state both)
        self.n_film = int(sensor.sampler().sample_count())
        self.t_load += time.perf_counter() - t1
        self.shape = (h, w)
        if self.cube is None:
            nb = self.scene.spectral_grid.n_bands
            self.cube = np.zeros((h, w, nb), np.float64)
            self.illum = np.zeros((h, w, nb), np.float64) if st.illumination else None
        return ms, sensor

    def render_set(self, mi, ms, sensor, bands: np.ndarray, k: int, j: int, estimate: bool) -> np.ndarray | None:
        """Render band set ``j`` of pass ``k`` and add it to the sums; its estimate of the band sum
        (``estimate``) for the noise."""
        grid, st = self.scene.spectral_grid, self.settings
        quads, lanes = band_quadruples(grid.edges, bands)
        self.n_quads += len(quads)
        integrator = make_integrator(quads, grid.step, self.scene.max_depth, st.illumination, self.flat, self.guide)
        n_aov = len(integrator.aov_names())
        seed = mix_seed(st.seed, k, j)
        t2 = time.perf_counter()
        if self.light:
            self.light_sets += 1
            aov = light_set_aovs(quads, grid.step, self.scene.max_depth, st.illumination, ms, sensor, self.spp, seed,
                                 self.windows)
        else:
            out = np.asarray(mi.render(ms, sensor=sensor, integrator=integrator, spp=self.spp, seed=seed))
            aov = out[..., out.shape[-1] - n_aov:]
        self.t_render += time.perf_counter() - t2
        if self.illum is not None:  # every set sees the same first hits: count them once (the film's paths)
            part = aov[..., 2 * len(lanes):2 * len(lanes) + 3].sum(axis=(0, 1), dtype=np.float64)
            self.kinds += part * self.n_film / len(self.sets)
        self.bad += float(aov[..., -1].sum(dtype=np.float64)) * self.n_film  # per-pixel means -> counts
        if self.extra and not self.light:
            aov = self._boosted(ms, sensor, integrator, aov, seed, quads, n_aov)
        on = lanes >= 0
        self.cube[..., lanes[on]] += aov[..., :len(lanes)][..., on]
        if self.illum is not None:
            self.illum[..., lanes[on]] += aov[..., len(lanes):2 * len(lanes)][..., on]
        return _set_estimate(aov[..., :len(lanes)][..., on], lanes[on], self.e_live, self.sets) if estimate else None

    def _boosted(self, ms, sensor, integrator, aov: np.ndarray, seed: int, quads, n_aov: int) -> np.ndarray:
        """``aov`` with the boosted pixels' targeted extra paths combined in by path counts."""
        t3 = time.perf_counter()
        h, w = self.shape
        sums = extra_path_sums(ms, sensor, integrator, self.boost, self.extra, seed,
                               self.settings.max_lanes, np.asarray(quads[0], np.float32))
        self.bad += float(sums[:, -1].sum())
        aov = aov.reshape(-1, n_aov).astype(np.float64)  # exact: the others add as before
        aov[self.boost] = (self.n_film * aov[self.boost] + sums) / (self.n_film + self.extra)
        self.t_boost += time.perf_counter() - t3
        return aov.reshape(h, w, n_aov)

    def stats(self, t0: float, n_passes: int, boosting: bool) -> dict:
        spp, sets, (h, w) = self.spp, self.sets, self.shape
        stats = {"load_s": round(self.t_load, 4), "trace_s": round(self.t_render, 4),
                 "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": int(round(self.bad)),
                 "band_sets": len(sets), "quadruples": self.n_quads // max(1, n_passes),
                 "paths_per_pixel": spp * len(sets), "samples_per_band": spp, "sampler": self.settings.sampler,
                 # what the sampler rendered: multijitter renders ⌊√n⌋·⌈n/⌊√n⌋⌉ of n asked (32 -> 35)
                 "paths_per_pixel_rendered": self.n_film * len(sets), "samples_per_band_rendered": self.n_film,
                 "flat_emission_scaled": self.flat, "light_paths": self.light_sets > 0,
                 "light_path_sets": self.light_sets}
        if self.guide is not None:
            stats["guided"] = {"learnt": self.guides,
                               "learn_s": round(sum(g["learn_s"] for g in self.guides), 4),
                               "learn_cpu_s": round(sum(g["learn_cpu_s"] for g in self.guides), 4)}
        if boosting:
            b = self.boost
            stats["targeted_paths"] = {"pixels": int(b.size), "pixel_fraction": round(b.size / (h * w), 5),
                                       "paths_per_pixel": (spp + self.extra) * len(sets),
                                       "extra_paths_fraction": round(b.size * self.extra / (h * w * spp), 5),
                                       "trace_s": round(self.t_boost, 4)}
        if self.illum is not None:
            k = self.kinds
            stats["illumination"] = {"samples": int(round(k.sum())), "demodulated": int(round(k[0])),
                                     "in_path": int(round(k[1])), "traced": int(round(k[2]))}
        return stats


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
