"""The four-wavelengths-per-path renders (``wavelengths`` ``"stratified"`` or ``"random"``): numpy
drives the paths through :class:`renderer_jobs.mitsuba.trace.Tracer` in blocks, accumulating per-band
sums, with adaptive spp and noise targets spread by a pilot (:mod:`renderer_jobs.adaptive_spp`) and
the illumination cube from the same paths (module docstring of :mod:`renderer_jobs.mitsuba.render`,
"Illumination cube"). :func:`renderer_jobs.mitsuba.render.render_cube` calls :func:`render_hero`.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from illumix.renderer_jobs import adaptive_spp
from illumix.renderer_jobs.band_schedule import band_counts, hash_u32, lane_stride, live_bands, mix_seed, pass_sizes
from illumix.renderer_jobs.mitsuba.scene_dict import band_guard, group_emission
from illumix.renderer_jobs.mitsuba.trace import Tracer
from illumix.renderer_jobs.mitsuba.view_coverage import covered_pixels, group_sees_sky
from illumix.scene.schema import SceneError

if TYPE_CHECKING:
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.scene.model import Scene


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


def render_hero(scene: Scene, view: str, groups: list[str], passes: list[str], settings: RenderSettings,
                t0: float) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray, str]:
    """``(cube, illumination cube or None, stats, emission, emission name)`` of ``view`` lit by
    ``groups`` (``t0``: when the render started, for the stats)."""
    tracers = [Tracer(scene, view, groups, settings.resolution, portals=p) for p in passes]
    t_load = time.perf_counter() - t0
    nb = tracers[0].grid.n_bands
    w, h = tracers[0].width, tracers[0].height
    emission, name = (group_emission(scene, groups[0]) if len(groups) == 1 else (np.ones(nb), "flat"))
    n_live = live_bands(emission).size if settings.wavelengths == "stratified" else nb
    if settings.wavelengths == "stratified" and 4 * settings.spp < n_live:
        raise SceneError(f"spp {settings.spp} is too low for stratified wavelengths: every one of the "
                         f"{n_live} emitting bands needs a sample, so spp >= {math.ceil(n_live / 4)}")
    blocks = _PathBlocks(tracers, settings, np.asarray(emission, dtype=np.float64))
    active = np.arange(w * h, dtype=np.int64)  # pixels that get paths (the others are exactly zero)
    if settings.skip_background and not group_sees_sky(scene, groups):
        cov = covered_pixels(scene, view, (w, h))
        active = active if cov is None else np.flatnonzero(cov.ravel())
    pilot = adaptive_spp.pilot_spp(n_live)
    target = settings.noise_target
    adaptive = (target is not None and settings.spp > pilot) or (settings.adaptive and settings.spp >= 2 * pilot)
    ysum, ysq = _first_paths(blocks, active, settings, pilot if adaptive else settings.spp, adaptive)
    spp_map = np.zeros(w * h, dtype=np.int64)
    spp_map[active] = settings.spp
    v = None
    if adaptive and active.size:
        spp_map, v = _more_paths(blocks, active, settings, pilot, ysum, ysq, (h, w))
    if blocks.acc_u is not None:
        blocks.trace_pending(settings.seed)
    cube, illum = _band_averages(blocks, spp_map, settings, (h, w))
    stats = {"load_s": round(t_load, 4), "trace_s": round(blocks.t_trace, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": blocks.n_bad,
             "mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min()),
             "background_pixels_skipped": int(w * h - active.size)}
    if illum is not None:
        stats["illumination"] = {"samples": blocks.n_samples, "demodulated": blocks.n_demodulated,
                                 "traced": blocks.n_traced, "traced_s": round(blocks.t_illum, 4)}
    if adaptive and active.size:
        stats |= _adaptive_stats(spp_map[active], v, active, pilot, target, settings.spp)
    return cube, illum, stats, emission, name


def _first_paths(blocks: _PathBlocks, active: np.ndarray, settings: RenderSettings, first: int,
                 adaptive: bool) -> tuple[np.ndarray, np.ndarray]:
    """Trace ``first`` paths in every active pixel (in passes of at most ``max_lanes``); with
    ``adaptive``, each pixel's sum and sum of squares of the paths' spectral sums (the pilot)."""
    npix = blocks.npix
    ysum, ysq = np.zeros(npix), np.zeros(npix)
    s0 = 0
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
    return ysum, ysq


def _more_paths(blocks: _PathBlocks, active: np.ndarray, settings: RenderSettings, pilot: int, ysum: np.ndarray,
                ysq: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """After the pilot: each pixel's paths (the budget spread by the pilot's variance, or what the
    noise target needs), the extra ones traced. Returns ``(paths per pixel, relative variance)``."""
    h, w = shape
    on = np.zeros(h * w, dtype=bool)
    on[active] = True
    pilot_map = np.where(on, pilot, 0).reshape(h, w)  # pilot paths per pixel (none in skipped ones)
    spp_map = np.zeros(h * w, dtype=np.int64)
    spp_map[active] = settings.spp
    if settings.noise_target is None:
        n2, v2 = adaptive_spp.allocate(ysum.reshape(h, w), ysq.reshape(h, w), pilot_map, settings.spp, pilot,
                                       seed=settings.seed, active=on.reshape(h, w))
        spp_map, v = n2.ravel(), v2.ravel()
    else:
        v = adaptive_spp.relative_variance(ysum.reshape(h, w), ysq.reshape(h, w), pilot_map).ravel()
        spp_map[active] = adaptive_spp.to_target(v[active], settings.noise_target, pilot, settings.spp)
    more = spp_map[active] - pilot
    pix = np.repeat(active, more)
    s = pilot + np.arange(len(pix), dtype=np.int64) - np.repeat(np.cumsum(more) - more, more)
    for c, a in enumerate(range(0, len(pix), settings.max_lanes)):
        blocks.trace(pix[a:a + settings.max_lanes], s[a:a + settings.max_lanes], c, salt=0xADA)
    return spp_map, v


def _band_averages(blocks: _PathBlocks, spp_map: np.ndarray, settings: RenderSettings,
                   shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray | None]:
    """The band sums divided by each (pixel, band)'s exact sample count: float32 ``(H, W, n_bands)``
    cube and illumination cube (None without)."""
    h, w = shape
    npix, nb = h * w, blocks.nb
    acc = blocks.acc.reshape(npix, nb)
    if settings.wavelengths == "stratified":
        counts = band_counts(npix, nb, spp_map, settings.seed, blocks.live).astype(np.float64)
    else:
        counts = np.broadcast_to(4.0 * spp_map[:, None] / nb, acc.shape)
    cube = np.divide(acc, counts, out=np.zeros_like(acc), where=counts > 0).reshape(h, w, nb).astype(np.float32)
    illum = None
    if blocks.acc_u is not None:
        illum = np.divide(blocks.acc_u.reshape(npix, nb), counts, out=np.zeros_like(acc), where=counts > 0)
        illum = illum.reshape(h, w, nb).astype(np.float32)
    return cube, illum


def _adaptive_stats(traced: np.ndarray, v: np.ndarray | None, active: np.ndarray, pilot: int,
                    target: float | None, spp: int) -> dict:
    out = {"spp_per_pixel": {"min": int(traced.min()), "median": float(np.median(traced)),
                             "mean": round(float(traced.mean()), 3), "max": int(traced.max()), "pilot": pilot}}
    if target is not None:
        pred = adaptive_spp.predicted_noise(v[active], traced)
        out["noise_target"] = {"target": target, "predicted_p50": round(float(np.median(pred)), 5),
                               "predicted_p99": round(float(np.percentile(pred, 99)), 5),
                               "pixels_at_max_spp": int(np.count_nonzero(traced >= spp)),
                               "fraction_predicted_on_target": round(float(np.mean(pred <= target)), 4)}
    return out
