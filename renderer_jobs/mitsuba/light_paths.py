"""Light paths: a cube estimated by tracing from the lights to the camera (issue 39).

Where a group's light reaches the view only after bounces (a desk lamp lighting the ceiling above
the sofa, a lamp in the next room), a path from the camera must find a small bright patch by chance,
and paths that do carry a large weight: the noise that keeps such cubes from being clean. A path from
the light finds that patch at once, and every surface it then hits is connected to the camera
(Veach's light tracing, Mitsuba's ``ptracer``). bench/SCENES.md ("Light paths") measures where it
wins. It runs with every band on every path, as :mod:`renderer_jobs.mitsuba.bands` does, and gives
the same cube layout, so the until-clean rule (:mod:`renderer_jobs.mitsuba.until_clean`) can weigh
its rounds against the camera paths' like any other unbiased estimate.

Estimator, per light path (lane) and band: an emitter chosen by the scene's sampling weights, a
ray from it (Mitsuba's ``sample_emitter_ray``; flat emission, so the ray's weight divided by the
spectral sampling weight is the group's per-unit-spectrum weight in every band), then at every
surface vertex ``x``: a connection to the camera — ``β · f(x, ωi → ω_cam) · correction · W`` where
``W`` is the camera's importance weight and the shading-normal correction is Veach's (1997, p. 155)
— splatted into the pixel the camera sees ``x`` in, then a bounce drawn from the BSDF in importance
mode (every band valued on the one direction). Russian roulette from the 5th segment on the largest
throughput over all bands. A path of ``d`` segments counts when ``d ≤ max_depth``.

Caustics of point, spot and directional lights (the sun through a glass vase onto the table) are
left out: camera paths cannot find them (a light sample does not pass through glass, a bounce never
hits a delta light), so the cube the store has always held lacks them, and a light path whose first
bounce off such a light is a delta one ends there (light paths alone would add them: +3 % on a test
room with a glass ball in the sun).

Two parts of the camera's estimate cannot come from light paths, and come from camera paths in the
same round (``complement``): emitters seen directly (no surface scatters), and everything seen *in*
a delta surface — glass, a mirror — (a delta BSDF cannot be connected to): the band integrator's
``delta_first`` mode keeps exactly those paths (the first vertex's emission, and the continuation of
first bounces drawn from a delta lobe), so light + complement is the whole cube, each part
unbiased.

Illumination (DESIGN.md "Physical GT"): the white Lambertian surface at the first visible point,
lit by what arrives there from the camera's side, with its own emission excluded — which is what
each of the camera integrator's three estimators (L/ρ, in-path, traced) estimates. From light paths
it is the same connection with ``f`` replaced by ``1/π`` (the surface's own BSDF never enters), so
one estimator serves every kind of first vertex, glass and emitters included.

Splatting adds float64 atomics: sums in another order differ in the last float32 bits, so two
renders with the same seed agree to about 1e-7, not bit for bit.
"""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.band_schedule import mix_seed
from illumix.renderer_jobs.mitsuba.bands import RR_DEPTH, make_integrator
from illumix.renderer_jobs.mitsuba.scene_dict import band_guard
from illumix.renderer_jobs.mitsuba.sun_windows import SunWindows
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

MAX_LANES = 1 << 20  # light paths per launch (the state of each is a few registers per band)
# a sun's light along lines through no window, by camera paths at a quarter of the light paths' spp:
# in a closed room it is nothing (or a leak), and a light sample of the sun finds it at once
SUN_REST_SPP_DIVISOR = 4


class LightTracer:
    """Light paths carrying the bands whose lower edges are ``quads`` (nm; width ``step``), with
    ``illumination`` (the white-surface bands) or not; emission flat (the caller scales after)."""

    def __init__(self, quads: list[tuple[float, ...]], step: float, max_depth: int, illumination: bool,
                 windows: SunWindows | None = None):
        mi, dr = import_mitsuba()
        self.windows = windows  # a sun's paths drawn through these (None: from Mitsuba's disk)
        self.lows = [mi.Spectrum(*q) for q in quads]
        dr.make_opaque(*self.lows)  # one compiled kernel for every band set (as bands.py)
        self.guard = band_guard(step)
        self.width = float(step) - 2 * self.guard
        self.max_depth = int(max_depth)
        self.illumination = bool(illumination)
        # Mitsuba samples a flat spectrum's wavelengths uniformly over its CIE range: the ray weight
        # carries 1/pdf(λ) = that range, which a per-unit-spectrum weight must not
        self.wavelength_range = float(mi.MI_CIE_MAX - mi.MI_CIE_MIN)

    @property
    def n_lanes(self) -> int:
        return 4 * len(self.lows)

    def render(self, ms, sensor, paths_per_pixel: int, seed: int) -> tuple[np.ndarray, np.ndarray | None, int]:
        """``(radiance (H, W, 4·quads), illumination or None, non-finite values dropped)`` from
        ``paths_per_pixel × H × W`` light paths (their splats averaged per pixel)."""
        mi, dr = import_mitsuba()
        w, h = (int(x) for x in sensor.film().crop_size())
        nl, total = self.n_lanes, paths_per_pixel * w * h
        size = h * w * nl
        rad = dr.zeros(mi.Float64, size)
        ill = dr.zeros(mi.Float64, size) if self.illumination else None
        bad = dr.zeros(mi.Float64, 1)
        for b, start in enumerate(range(0, total, MAX_LANES)):
            n = min(MAX_LANES, total - start)
            sampler = mi.load_dict({"type": "independent"})
            sampler.seed(dr.opaque(mi.UInt32, (seed * 0x9E3779B1 + b) & 0xFFFFFFFF), n)
            self._trace(mi, dr, ms, sensor, sampler, (w, h), rad, ill, bad)
            dr.eval(rad, ill, bad)
        scale = w * h / total  # each light path's splats are one sample of the whole film
        out = np.asarray(rad, np.float64).reshape(h, w, nl) * scale
        u = None if ill is None else np.asarray(ill, np.float64).reshape(h, w, nl) * scale
        return out, u, int(np.asarray(bad)[0])

    def _trace(self, mi, dr, ms, sensor, sampler, size, rad, ill, bad) -> None:
        offset = self.guard + self.width * sampler.next_1d()
        quads = [low + offset for low in self.lows]
        ray, weight, emitter = ms.sample_emitter_ray(0.0, sampler.next_1d(), sampler.next_2d(), sampler.next_2d(), True)
        if self.windows is not None:
            ray, weight = self.windows.draw(mi, dr, ms, ray, weight, emitter, sampler)
        delta_light = mi.has_flag(emitter.flags(), mi.EmitterFlags.Delta)
        w0 = weight[0] / self.wavelength_range
        beta = [mi.Spectrum(w0) for _ in quads]
        si = ms.ray_intersect(ray, mi.RayFlags.All, False)
        depth = mi.UInt32(1)
        active = si.is_valid() & (w0 > 0.0) & (depth < self.max_depth)
        state = (sampler, ray, si, depth, beta, mi.Float(1.0), active)

        def cond(sampler, ray, si, depth, beta, eta, active):
            return active

        def body(sampler, ray, si, depth, beta, eta, active):
            bsdf = si.bsdf(ray)
            self._connect(mi, dr, ms, sensor, sampler, si, bsdf, beta, quads, size, rad, ill, bad, active)
            ctx = mi.BSDFContext(mi.TransportMode.Importance)
            s1, s2 = sampler.next_1d(active), sampler.next_2d(active)
            bs = None
            for q in range(len(quads)):  # one direction (non-dispersive BSDFs), each band's weight
                si.wavelengths = quads[q]
                bs_q, w_q = bsdf.sample(ctx, si, s1, s2, active)
                bs = bs_q if bs is None else bs
                beta[q] = beta[q] * w_q
            wi_geo = dr.dot(si.n, -ray.d)
            wo_world = si.to_world(bs.wo)
            wo_geo = dr.dot(si.n, wo_world)
            # no light through a surface by its shading normal; the adjoint BSDF's correction
            active &= (wi_geo * mi.Frame3f.cos_theta(si.wi) > 0.0) & (wo_geo * mi.Frame3f.cos_theta(bs.wo) > 0.0)
            corr = dr.abs(mi.Frame3f.cos_theta(si.wi) * wo_geo / (mi.Frame3f.cos_theta(bs.wo) * wi_geo))
            bmax = mi.Float(0.0)
            for q in range(len(quads)):
                beta[q] = beta[q] * corr
                bmax = dr.maximum(bmax, dr.max(beta[q]))
            eta = eta * bs.eta
            active &= (bmax > 0.0) & dr.isfinite(bmax)
            # camera paths reach a point, spot or directional light only by a light sample from a
            # non-delta vertex: light from one that first bounces off glass or a mirror (a caustic)
            # is not in their cube, so it is not in this one either
            active &= ~(delta_light & (depth == 1) & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta))
            ray = si.spawn_ray(wo_world)
            si = ms.ray_intersect(ray, mi.RayFlags.All, False, active)
            depth = depth + 1
            active &= si.is_valid() & (depth < self.max_depth)
            rr = active & (depth >= RR_DEPTH)
            q_rr = dr.minimum(bmax * dr.square(eta), 0.95)
            active &= ~rr | (sampler.next_1d(rr) < q_rr)
            for q in range(len(quads)):
                beta[q] = dr.select(rr, beta[q] / q_rr, beta[q])
            return sampler, ray, si, depth, beta, eta, active

        dr.while_loop(state, cond, body, label="illumix light path")

    def _connect(self, mi, dr, ms, sensor, sampler, si, bsdf, beta, quads, size, rad, ill, bad, active) -> None:
        """Splat this vertex's light into the pixel the camera sees it in (module docstring)."""
        w, h = size
        ds, s_weight = sensor.sample_direction(si, sampler.next_2d(active), active)
        ok = active & (ds.pdf > 0.0)
        ok &= ~ms.ray_test(si.spawn_ray_to(ds.p), ok)
        d_local = si.to_local(ds.d)
        wi_geo, wo_geo = dr.dot(si.n, si.to_world(si.wi)), dr.dot(si.n, ds.d)
        ok &= (wi_geo * mi.Frame3f.cos_theta(si.wi) > 0.0) & (wo_geo * mi.Frame3f.cos_theta(d_local) > 0.0)
        corr = dr.abs(mi.Frame3f.cos_theta(si.wi) * wo_geo / (mi.Frame3f.cos_theta(d_local) * wi_geo))
        col = dr.clip(mi.Int32(dr.floor(ds.uv.x)), 0, w - 1)
        row = dr.clip(mi.Int32(dr.floor(ds.uv.y)), 0, h - 1)
        base = mi.UInt32(row * w + col) * self.n_lanes
        common = corr * s_weight[0]
        ctx = mi.BSDFContext(mi.TransportMode.Importance)
        # the white surface faces the camera: light from the camera's side of the surface only
        white = dr.select(mi.Frame3f.cos_theta(si.wi) * mi.Frame3f.cos_theta(d_local) > 0.0,
                          dr.abs(mi.Frame3f.cos_theta(d_local)) / dr.pi, 0.0)
        for q in range(len(quads)):
            si.wavelengths = quads[q]
            f = bsdf.eval(ctx, si, d_local, ok)
            for k in range(4):
                self._splat(mi, dr, rad, bad, beta[q][k] * f[k] * common, base + 4 * q + k, ok)
                if ill is not None:
                    self._splat(mi, dr, ill, bad, beta[q][k] * white * common, base + 4 * q + k, ok)

    @staticmethod
    def _splat(mi, dr, buf, bad, value, index, ok) -> None:
        finite = dr.isfinite(value)
        dr.scatter_reduce(dr.ReduceOp.Add, buf, mi.Float64(value), index, ok & finite)
        dr.scatter_reduce(dr.ReduceOp.Add, bad, mi.Float64(1.0), mi.UInt32(0), ok & ~finite)


def light_paths_reach(ms, windows: bool = False) -> bool:
    """Whether light paths suit this loaded scene (one emitter pass): no sky at infinity among its
    emitters, and a sun only when its paths can be drawn through ``windows``
    (:mod:`renderer_jobs.mitsuba.sun_windows`). From Mitsuba's disk as wide as the whole scene, a
    sun's light paths rarely pass a window (room 9130's sun, seen from the next room: 256 light paths
    per pixel came back with 46 % of what camera paths found, the rest in paths too rare to have been
    drawn, which a variance measured from the halves cannot see); a sky's likewise: such a pass keeps
    to camera paths."""
    mi, _ = import_mitsuba()
    sun_ok = bool(windows)
    return not any(mi.has_flag(e.flags(), mi.EmitterFlags.Infinite)
                   and not (sun_ok and mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)) for e in ms.emitters())


def light_set_aovs(quads, step: float, max_depth: int, illumination: bool, ms, sensor, spp: int,
                   seed: int, windows: SunWindows | None = None) -> np.ndarray:
    """One band set's ``(H, W, n_aov)`` in the band integrator's AOV layout (bands, illumination
    bands, the three first-hit kinds — 0 here —, non-finite values): ``spp`` light paths per pixel
    plus the camera-path complement (``delta_first``) at ``spp`` per pixel on the film's sampler.
    With a sun and ``windows``: the sun's light paths through the windows, and its light along lines
    through none from camera paths (``sun_rest``) at ``spp / SUN_REST_SPP_DIVISOR`` per pixel
    (:mod:`renderer_jobs.mitsuba.sun_windows`)."""
    sun_windows = windows if windows is not None and windows.has_sun(ms) else None  # lamps: Mitsuba's own rays
    tracer = LightTracer(quads, step, max_depth, illumination, sun_windows)
    rad, ill, bad = tracer.render(ms, sensor, spp, mix_seed(seed, 0x4C54))
    comp = _camera_part(quads, step, max_depth, False, ms, sensor, spp, seed, delta_first=True)
    h, w, nl = rad.shape
    parts = [rad + comp[..., :nl]]
    flags = comp[..., -1:].copy()  # non-finite values per pixel sample, as the film averages them
    if sun_windows is not None:
        rest_spp = max(1, spp // SUN_REST_SPP_DIVISOR)
        rest = _camera_part(quads, step, max_depth, illumination, ms, sensor, rest_spp, mix_seed(seed, 0x5355),
                            sun_rest=sun_windows)
        parts[0] += rest[..., :nl]
        if illumination:
            ill = ill + rest[..., nl:2 * nl]
        flags += rest[..., -1:] * rest_spp / max(1, int(sensor.sampler().sample_count()))
    if illumination:
        parts += [ill, np.zeros((h, w, 3))]
    flags[0, 0, 0] += bad / max(1, int(sensor.sampler().sample_count()))
    return np.concatenate(parts + [flags], -1)


def _camera_part(quads, step, max_depth, illumination, ms, sensor, spp, seed, **mode) -> np.ndarray:
    """A camera-path render of the part of the cube light paths leave (``mode``: ``delta_first`` or
    ``sun_rest``, :func:`renderer_jobs.mitsuba.bands.make_integrator`), its AOVs as float64."""
    mi, _ = import_mitsuba()
    integrator = make_integrator(quads, step, max_depth, illumination, True, **mode)
    n = len(integrator.aov_names())
    out = np.asarray(mi.render(ms, sensor=sensor, integrator=integrator, spp=spp, seed=seed))
    return out[..., out.shape[-1] - n:].astype(np.float64)
