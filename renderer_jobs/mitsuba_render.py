"""Rendering: one spectral transport cube per (view, light group), plus view AOVs.

Mitsuba stays behind the ``mitsuba_*`` modules: callers pass a :class:`scene.model.Scene`
and get numpy. Variant: :mod:`renderer_jobs.mitsuba_variant`; scene dictionary:
:mod:`renderer_jobs.mitsuba_scene`; tracing: :mod:`renderer_jobs.mitsuba_trace`.

What a cube is
--------------
``T[v, g](x, λ_i)`` — for view ``v`` and light group ``g`` — is the band average over band ``i`` of the
spectral radiance reaching pixel ``x`` (box pixel filter) when only ``g``'s emitters are on, each
emitting ``strength × Ē_g(λ)`` with ``Ē_g`` the group's emission (flat, value 1, by default) held
constant over each band; every other group's emitters are removed (their geometry and materials
stay). Unidirectional path tracing with next-event estimation and MIS, emitter selection weighted
by approximate power via ``sampling_weight``, no denoiser, no clamping, emitters visible. Portal
emitters (``emitter.portal``, e.g. the sky filling a window) are not geometry: they are traced in
a second pass with the same schedule and added (linearity), so they never shadow the group's other
emitters. Non-finite samples (none seen so far) are dropped and counted in the cube's stats.

Wavelength sampling (issues 4 and 17, see ``bench/render.py`` for the measurements)
-------------------------------------------------------------------------------------
- ``"all-bands"`` (default, issue 17): every path carries many bands at once (no material disperses,
  so a path sampled once serves every wavelength), rendered by Mitsuba's own loop with a
  low-discrepancy pixel sampler: :mod:`renderer_jobs.mitsuba_bands` (the integrator) and
  :mod:`renderer_jobs.mitsuba_band_render` (band sets, passes). ``bench/RENDER_PERF.md`` measures it
  against the modes below and against Cycles run the thesis way.

The two 4-wavelength modes below are this module's own numpy-driven paths (Mitsuba's ``path``
integrator on rays illumix generates); adaptive spp and noise targets work with them only.
Mitsuba traces 4 wavelengths per path ("hero" wavelengths). Its spectral film draws them at random
over the whole range, so each 5 nm band of a pixel receives a *random number* of samples and the
per-band estimate carries that count's binomial noise (≈ 1/√(expected count): 12 % at 1024 spp for
63 bands). This backend drives the integrator itself (``Integrator.sample`` on rays it generates) and
chooses every wavelength:

- ``"stratified"``: path ``s`` of pixel ``p`` starts at band ``k = (s + o_p) mod n`` and its
  four wavelengths lie in bands ``k, k+16, k+32, k+48 (mod n)`` — spread over the spectrum so one
  path's noise does not pile up in one camera channel — each uniformly jittered inside its band.
  Every ``n`` consecutive paths put exactly 4 samples in every band, so a band's sample count is
  fixed (⌊4·spp/n⌋ or one more, known exactly) and its estimate is the plain mean of its samples.
  ``o_p`` is a per-pixel hash that decorrelates neighbouring pixels when spp < n. Here ``n`` counts
  the bands where the cube's emission is non-zero (all 63 for the default flat emission): a band a
  group does not emit is exactly zero in its cube, so the schedule skips it (``live_bands``) and
  the other bands get its share; the stride is ``round(n/4)``.
- ``"random"``: Mitsuba's default behaviour, for comparison — four wavelengths uniform over the grid
  span with Mitsuba's shifted stratification (``sample_shifted``), each band estimated as
  ``Σ L / E[count]`` exactly as the ``specfilm`` does.

Adaptive spp (``RenderSettings.adaptive``, 4-wavelength modes)
---------------------------------------------------------------
The cube's ``spp · pixels`` paths are not spread evenly: every pixel first gets the pilot (16 paths:
every band sampled once), then the rest goes where the pilot's neighbourhood saw the most relative
variance (:mod:`renderer_jobs.adaptive_spp`). The stratified schedule simply runs longer in those
pixels, so band counts stay exact. Measured at equal paths and CPU time: see ``bench/RENDER_PERF.md``.
With ``RenderSettings.noise_target`` the total is not fixed: each pixel gets the paths the pilot
predicts for that relative noise (``spp`` caps it), so a cube costs what its light needs.

Illumination cube (default, ``RenderSettings.illumination``; DESIGN.md "Physical GT")
-----------------------------------------------------------------------------------
Beside ``T`` the same paths estimate ``U[v, g](x, λ_i)``: the radiance a white Lambertian surface at
the first visible point would send to the camera (``E/π``, bounces off coloured surfaces included),
in ``T``'s units and schedule, so it relights exactly like ``T``. Per path sample: where the first hit
is purely diffuse (and not emitting) ``U = L/ρ`` — exact, every contribution of the path carries
``ρ(λ)`` — at the cost of one more intersection in the same kernel; elsewhere (glossy, metal, glass,
black or emitting first hits) a white-Lambertian estimate is traced for that sample
(:meth:`renderer_jobs.mitsuba_trace.Tracer.white_lambertian`). Samples that hit nothing add 0; the
view's ``mask``/``emitter`` AOVs flag pixels where illumination is undefined. The ``"all-bands"``
mode estimates it band by band in its own kernel (:mod:`renderer_jobs.mitsuba_bands`).

Per-band sums are accumulated in float64 by ``numpy.bincount`` (no atomics), so the same seed gives
the same cube bit for bit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from illumix.renderer_jobs import adaptive_spp
from illumix.renderer_jobs.band_schedule import band_counts, group_seed, hash_u32, lane_stride, live_bands, mix_seed, pass_sizes
from illumix.renderer_jobs.mitsuba_bands import RR_DEPTH
from illumix.renderer_jobs.mitsuba_scene import band_guard, group_emission
from illumix.renderer_jobs.mitsuba_trace import Tracer
from illumix.renderer_jobs.mitsuba_variant import import_mitsuba, libllvm_path, select_variant
from illumix.renderer_jobs.render_settings import RenderSettings  # noqa: F401 — re-exported
from illumix.scene.model import Scene
from illumix.scene.schema import SceneError
from illumix.renderer_jobs.view_coverage import covered_pixels, group_sees_sky


@dataclass
class CubeResult:
    """A rendered cube ``(H, W, n_bands)`` float32 of band averages, with what it was rendered with
    (and its illumination cube, same shape and units)."""

    cube: np.ndarray
    emission: np.ndarray
    emission_name: str
    renderer: dict
    stats: dict = field(default_factory=dict)
    illumination: np.ndarray | None = None  # (H, W, n_bands) float32, when RenderSettings.illumination
    #: (H, W, 2) float32: the cube's band sum and its variance from the band sets' spread, or None
    #: (renderer_jobs.mitsuba_band_render.set_noise; the denoiser weighs its bias against it)
    noise: np.ndarray | None = None


def group_list(scene: Scene, group: str | list[str] | None) -> list[str]:
    """``group`` as a list of checked group names (``None``: every group of the scene)."""
    groups = [group] if isinstance(group, str) else (scene.group_names if group is None else list(group))
    for g in groups:
        scene.group(g)
    return groups


def emitter_passes(scene: Scene, groups: list[str]) -> list[str]:
    """The passes a cube of ``groups`` needs: ``"without"`` (every emitter but portals) when the groups
    have non-portal emitters, ``"only"`` (portals alone) when they have portals. Portals render in a
    pass of their own (they occlude nothing); the cube is the passes' sum."""
    emitters = [e for g in groups for e in scene.emitters_of(g)]
    return [p for p, present in (("without", any(not scene.is_portal(e) for e in emitters)),
                                 ("only", any(scene.is_portal(e) for e in emitters))) if present]


def renderer_info(scene: Scene, settings: RenderSettings, passes: list[str]) -> dict:
    """The cube metadata's ``renderer`` record: Mitsuba version, variant and every setting that matters."""
    mi, _ = import_mitsuba()
    bands = settings.wavelengths == "all-bands"
    info = {"name": "mitsuba", "backend": "mitsuba", "version": str(mi.__version__), "variant": select_variant(),
            "method": (f"path tracing, up to {settings.bands_per_path} bands on every path (interleaved band sets "
                       f"sharing the spp), {settings.sampler} pixel samples, Mitsuba's render loop" if bands else
                       f"path tracing, 4 {settings.wavelengths} wavelengths per path (illumix sampling)"),
            "settings": {"integrator": "illumix band path" if bands else "path", "max_depth": scene.max_depth,
                         "rr_depth": RR_DEPTH, "mis": "power heuristic", "rfilter": "box",
                         "wavelength_sampling": settings.wavelengths, "denoiser": None, "clamp": None,
                         "emitter_sampling": "power", "spp": settings.spp, "seed": settings.seed,
                         "passes": passes, "libllvm": libllvm_path()}}
    if bands:
        # No material of the scene model disperses (dielectrics take one scalar IOR): every band
        # follows the path sampled once, none falls back to hero wavelengths.
        info["settings"].update({"sampler": settings.sampler, "bands_per_path": settings.bands_per_path,
                                 "dispersion": "none",
                                 "band_wavelengths": ("one offset per path inside every band (the band minus 1/20 at each edge): "
                                                     "step spectra exact, smooth ones band-averaged")})
        info["illumination_method"] = ILLUMINATION_METHOD_BANDS
    else:
        info["settings"].update({"adaptive_spp": settings.adaptive, "noise_target": settings.noise_target,
                                 "skip_background": settings.skip_background})
    return info


ILLUMINATION_METHOD = ("per-sample L/rho at purely diffuse first hits; elsewhere a white-Lambertian first-hit "
                       "estimate (light sampling + one cosine-sampled continuation) in the same paths")
ILLUMINATION_METHOD_BANDS = ("per band, in the same paths: L/rho at purely diffuse first hits; at first hits with "
                             "a diffuse lobe a white-Lambertian estimate along the path's own BSDF-sampled "
                             "continuation (MIS with its light sample); elsewhere a second path from a white "
                             "Lambertian first vertex")


class _PathBlocks:
    """Traces blocks of paths ``(pixel, sample index)`` of one cube and accumulates per-band sums."""

    def __init__(self, tracers: list[Tracer], settings: RenderSettings, emission: np.ndarray) -> None:
        self.tracers, self.settings = tracers, settings
        grid = tracers[0].grid
        self.nb, self.lo, self.step = grid.n_bands, grid.edges[0], grid.step
        self.guard = band_guard(self.step)
        self.npix = tracers[0].width * tracers[0].height
        self.live = live_bands(emission)
        self.off = (hash_u32(np.arange(self.npix), settings.seed ^ 0x5BD1E995)
                    % np.uint64(self.live.size)).astype(np.int64)
        self.acc = np.zeros(self.npix * self.nb, dtype=np.float64)
        self.acc_u = np.zeros(self.npix * self.nb, dtype=np.float64) if settings.illumination else None
        self.inv_emission = np.where(emission > 0, 1.0 / np.where(emission > 0, emission, 1.0), 0.0)
        self.n_bad, self.t_trace, self.t_illum = 0, 0.0, 0.0
        self.n_samples = self.n_demodulated = self.n_traced = 0
        # samples whose illumination must be traced, per tracer: (pix, jitter, lam, idx, weight);
        # traced together at the end (each Dr.Jit call has a fixed cost that small batches pay)
        self.pending: list[list[tuple]] = [[] for _ in tracers]
        self.flushes = 0

    def trace(self, pix: np.ndarray, s: np.ndarray, key: int, salt: int = 0x1C0) -> np.ndarray:
        """Trace path ``s[i]`` of pixel ``pix[i]``; add to the band sums. Returns each path's
        spectral sum per unit emission ``Y = Σ_j L_j / Ē(λ_j)`` ``(n,)`` (for adaptive sampling)."""
        st, nb = self.settings, self.nb
        rng = np.random.default_rng([st.seed & 0xFFFFFFFF, key, salt])
        jitter = rng.random((len(pix), 2), dtype=np.float32)
        u = rng.random((len(pix), 4))
        if st.wavelengths == "stratified":
            m = self.live.size
            bands = self.live[(((s + self.off[pix]) % m)[:, None] + lane_stride(m) * np.arange(4)[None, :]) % m]
            lam = self.lo + self.step * bands + self.guard + (self.step - 2 * self.guard) * u
        else:
            # Mitsuba's default: one uniform sample over the span, shifted by 1/4 for the others.
            frac = (u[:, :1] + np.arange(4)[None, :] / 4.0) % 1.0
            lam = self.lo + nb * self.step * frac
            bands = np.minimum((frac * nb).astype(np.int64), nb - 1)
        idx = (pix[:, None] * nb + bands).ravel()
        total = np.zeros((len(pix), 4), dtype=np.float64)
        lam32 = lam.astype(np.float32)
        for j, tracer in enumerate(self.tracers):
            seed = mix_seed(st.seed, salt, key, j)
            t1 = time.perf_counter()
            out = tracer.trace(pix, jitter, lam32, seed=seed, first_hit=self.acc_u is not None)
            self.t_trace += time.perf_counter() - t1
            L = _finite(out[0] if isinstance(out, tuple) else out, self)
            self.acc += np.bincount(idx, weights=L.ravel().astype(np.float64), minlength=self.npix * nb)
            total += L
            if self.acc_u is not None:  # from the sanitised L: a bad sample is counted once
                U = self._illumination(j, (L, *out[1:]), pix, jitter, lam32, idx, seed)
                self.acc_u += np.bincount(idx, weights=U.ravel().astype(np.float64), minlength=self.npix * nb)
        return (total * self.inv_emission[bands]).sum(axis=1)

    def _illumination(self, j: int, out, pix, jitter, lam, idx, seed: int) -> np.ndarray:
        """Illumination samples of the paths just traced: ``L/ρ`` where the first hit is purely
        diffuse; where it is not, the sample is queued for :meth:`trace_pending`."""
        L, albedo, diffuse, hit = out
        ok = diffuse & (albedo.min(axis=1) > RHO_MIN)
        U = np.divide(L, albedo, out=np.zeros_like(L), where=ok[:, None])
        need = np.flatnonzero(hit & ~ok)
        self.n_samples += len(L)
        self.n_demodulated += int(ok.sum())
        if need.size:
            # Trace at most TRACE_BUDGET × the batch's paths (each costs about two paths), each with
            # weight 1/p so the mean stays unbiased: the cost stays bounded however much of the view
            # is glossy or glass, at the price of more noise there.
            p = min(1.0, TRACE_BUDGET * len(L) / need.size)
            if p < 1.0:
                rng = np.random.default_rng([seed, 0x5EED])
                need = need[rng.random(need.size) < p]
            rows = idx.reshape(-1, 4)[need]
            self.pending[j].append((pix[need], jitter[need], lam[need], rows, np.float64(1.0 / p)))
            if sum(len(q[0]) for q in self.pending[j]) >= self.settings.max_lanes:
                self.trace_pending(seed, only=j)  # bounded memory: at most one lane block queued
        return _finite(U, self)

    def trace_pending(self, seed: int, only: int | None = None) -> None:
        """Trace the queued white-Lambertian estimates, one Dr.Jit call per tracer and lane block
        (of tracer ``only``, or of all)."""
        lanes = self.settings.max_lanes
        for j, (tracer, queue) in enumerate(zip(self.tracers, self.pending)):
            if not queue or (only is not None and j != only):
                continue
            self.flushes += 1
            seed = int(hash_u32(np.array([self.flushes]), seed)[0])  # each flush its own random numbers
            pix, jitter, lam, rows = (np.concatenate([q[k] for q in queue]) for k in range(4))
            weight = np.concatenate([np.full(len(q[0]), q[4]) for q in queue])
            self.pending[j] = []
            t1 = time.perf_counter()
            for c, a in enumerate(range(0, len(pix), lanes)):
                part = slice(a, a + lanes)
                key = int(hash_u32(np.array([j * 4096 + c]), seed ^ 0x5EED)[0])
                U = _finite(tracer.white_lambertian(pix[part], jitter[part], lam[part], seed=key), self)
                self.acc_u += np.bincount(rows[part].ravel(), weights=(U * weight[part, None]).ravel(),
                                          minlength=self.npix * self.nb)
            self.t_illum += time.perf_counter() - t1
            self.n_traced += len(pix)


# Below this diffuse reflectance a first hit carries no usable ratio L/ρ (ρ = 0 carries nothing): its
# illumination is traced instead. Above it L/ρ is exact whatever ρ (every contribution carries ρ).
RHO_MIN = 1e-6
# Most white-Lambertian estimates traced per path of a batch (bench/groundtruth.py measures the
# resulting cost against the transport cube alone; the goal is at most 1.3x).
TRACE_BUDGET = 0.04


def _finite(a: np.ndarray, blocks: _PathBlocks) -> np.ndarray:
    """``a`` with non-finite samples set to 0, counted in ``blocks.n_bad`` (none seen so far)."""
    bad = ~np.isfinite(a)
    if bad.any():
        blocks.n_bad += int(bad.sum())
        a = np.where(bad, 0.0, a)
    return a


def render_cube(scene: Scene, view: str, group: str | list[str] | None,
                settings: RenderSettings = RenderSettings(), boost_mask: np.ndarray | None = None) -> CubeResult:
    """Render the transport cube of ``view`` lit by ``group`` (see module docstring).

    ``group`` may be a list of groups (rendered together, all with their own emission) or ``None``
    for every group at once (the "all-on" render used to check additivity). Returns float32 band
    averages ``(H, W, n_bands)`` of radiance per unit emission spectrum. With ``settings.adaptive``
    (and spp ≥ twice the pilot) the same total of paths (up to rounding) is spread by
    :mod:`renderer_jobs.adaptive_spp`; with ``settings.noise_target`` each pixel gets what its noise needs.
    ``boost_mask`` ``(H, W)`` bool (``"all-bands"`` only, from the guides alone:
    :func:`renderer_jobs.boost_paths.boost_mask`): those pixels get ``settings.boost_factor`` × spp.
    The paths' random numbers come from ``settings.seed`` mixed with the group names
    (:func:`renderer_jobs.band_schedule.group_seed`): two groups' cubes are independent estimates.
    """
    groups = group_list(scene, group)
    settings = settings.model_copy(update={"seed": group_seed(settings.seed, groups)})  # each group its own paths
    t0 = time.perf_counter()
    passes = emitter_passes(scene, groups)
    if settings.wavelengths == "all-bands":
        return _render_all_bands(scene, view, groups, passes, settings, boost_mask)
    tracers = [Tracer(scene, view, groups, settings.resolution, portals=p) for p in passes]
    t_load = time.perf_counter() - t0
    nb = tracers[0].grid.n_bands
    w, h = tracers[0].width, tracers[0].height
    npix = w * h
    emission, name = (group_emission(scene, groups[0]) if len(groups) == 1 else (np.ones(nb), "flat"))
    n_live = live_bands(emission).size if settings.wavelengths == "stratified" else nb
    if settings.wavelengths == "stratified" and 4 * settings.spp < n_live:
        raise SceneError(f"spp {settings.spp} is too low for stratified wavelengths: every one of the "
                         f"{n_live} emitting bands needs a sample, so spp >= {math.ceil(n_live / 4)}")
    blocks = _PathBlocks(tracers, settings, np.asarray(emission, dtype=np.float64))
    active = np.arange(npix, dtype=np.int64)  # pixels that get paths (the others are exactly zero)
    if settings.skip_background and not group_sees_sky(scene, groups):
        cov = covered_pixels(scene, view, (w, h))
        active = active if cov is None else np.flatnonzero(cov.ravel())
    pilot = adaptive_spp.pilot_spp(n_live)
    target = settings.noise_target
    adaptive = (target is not None and settings.spp > pilot) or (settings.adaptive and settings.spp >= 2 * pilot)
    first = pilot if adaptive else settings.spp
    s0 = 0
    ysum, ysq = np.zeros(npix), np.zeros(npix)
    sizes = pass_sizes(first, active.size, settings.max_lanes) if active.size else []
    for k, spp_pass in enumerate(sizes):
        pix = np.repeat(active, spp_pass)
        s = s0 + np.tile(np.arange(spp_pass, dtype=np.int64), active.size)
        # A pass holds at least one path per pixel: split it when the film exceeds max_lanes.
        for c, a in enumerate(range(0, len(pix), settings.max_lanes)):
            part = slice(a, a + settings.max_lanes)
            y = blocks.trace(pix[part], s[part], k + c * len(sizes))
            if adaptive:
                ysum += np.bincount(pix[part], weights=y, minlength=npix)
                ysq += np.bincount(pix[part], weights=y * y, minlength=npix)
        s0 += spp_pass
    spp_map = np.zeros(npix, dtype=np.int64)
    spp_map[active] = settings.spp
    if adaptive and active.size:
        on = np.zeros(npix, dtype=bool)
        on[active] = True
        pilot_map = np.where(on, pilot, 0).reshape(h, w)  # pilot paths per pixel (none in skipped ones)
        if target is None:
            n2, v2 = adaptive_spp.allocate(ysum.reshape(h, w), ysq.reshape(h, w), pilot_map, settings.spp, pilot,
                                           seed=settings.seed, active=on.reshape(h, w))
            spp_map, v = n2.ravel(), v2.ravel()
        else:
            v = adaptive_spp.relative_variance(ysum.reshape(h, w), ysq.reshape(h, w), pilot_map).ravel()
            spp_map[active] = adaptive_spp.to_target(v[active], target, pilot, settings.spp)
        more = spp_map[active] - pilot
        pix = np.repeat(active, more)
        s = pilot + np.arange(len(pix), dtype=np.int64) - np.repeat(np.cumsum(more) - more, more)
        for c, a in enumerate(range(0, len(pix), settings.max_lanes)):
            blocks.trace(pix[a:a + settings.max_lanes], s[a:a + settings.max_lanes], c, salt=0xADA)
    if blocks.acc_u is not None:
        blocks.trace_pending(settings.seed)
    acc = blocks.acc.reshape(npix, nb)
    if settings.wavelengths == "stratified":
        counts = band_counts(npix, nb, spp_map, settings.seed, blocks.live).astype(np.float64)
    else:
        counts = np.broadcast_to(4.0 * spp_map[:, None] / nb, acc.shape)
    cube = np.divide(acc, counts, out=np.zeros_like(acc), where=counts > 0)
    cube = cube.reshape(h, w, nb).astype(np.float32)
    illum = None
    if blocks.acc_u is not None:
        illum = np.divide(blocks.acc_u.reshape(npix, nb), counts, out=np.zeros_like(acc), where=counts > 0)
        illum = illum.reshape(h, w, nb).astype(np.float32)
    renderer = renderer_info(scene, settings, passes)
    stats = {"load_s": round(t_load, 4), "trace_s": round(blocks.t_trace, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": blocks.n_bad,
             "mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min()),
             "background_pixels_skipped": int(npix - active.size)}
    if illum is not None:
        stats["illumination"] = {"samples": blocks.n_samples, "demodulated": blocks.n_demodulated,
                                 "traced": blocks.n_traced, "traced_s": round(blocks.t_illum, 4)}
    if adaptive and active.size:
        traced = spp_map[active]
        stats["spp_per_pixel"] = {"min": int(traced.min()), "median": float(np.median(traced)),
                                  "mean": round(float(traced.mean()), 3), "max": int(traced.max()),
                                  "pilot": pilot}
        if target is not None:
            pred = adaptive_spp.predicted_noise(v[active], traced)
            stats["noise_target"] = {"target": target, "predicted_p50": round(float(np.median(pred)), 5),
                                     "predicted_p99": round(float(np.percentile(pred, 99)), 5),
                                     "pixels_at_max_spp": int(np.count_nonzero(traced >= settings.spp)),
                                     "fraction_predicted_on_target": round(float(np.mean(pred <= target)), 4)}
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=renderer, stats=stats, illumination=illum)


def _render_all_bands(scene: Scene, view: str, groups: list[str], passes: list[str],
                      settings: RenderSettings, boost_mask: np.ndarray | None = None) -> CubeResult:
    from illumix.renderer_jobs.mitsuba_band_render import render_all_bands  # noqa: PLC0415

    nb = scene.spectral_grid.n_bands
    emission, name = (group_emission(scene, groups[0]) if len(groups) == 1 else (np.ones(nb), "flat"))
    boost = None
    if boost_mask is not None and settings.boost_factor > 1:
        w, h = settings.resolution or scene.view(view).resolution
        if np.shape(boost_mask) != (h, w):
            raise SceneError(f"boost mask {np.shape(boost_mask)} does not match view {view!r}'s ({h}, {w}) (H, W)")
        boost = np.flatnonzero(np.asarray(boost_mask, bool).ravel())
    cube, illum, stats, noise = render_all_bands(scene, view, groups, passes, settings,
                                                 np.asarray(emission, np.float64), boost)
    stats.update({"mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min())})
    info = renderer_info(scene, settings, passes)
    info["settings"]["targeted_paths"] = ({"spp_factor": settings.boost_factor, "reach": settings.boost_reach,
                                           "mask": "dt-irradiance reach of unit white noise > reach (guides only)"}
                                          if boost is not None else None)
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=info, stats=stats, illumination=illum, noise=noise)
