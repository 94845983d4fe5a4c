"""Every band on every path: a Mitsuba integrator whose paths carry all the cube's bands at once.

Mitsuba's spectral variants trace 4 wavelengths per ray. Every material of the scene model is
non-dispersive (diffuse, rough plastic, rough conductor, dielectric with a scalar IOR): a BSDF's
sampled direction and its pdf do not depend on the wavelength, only its value does. So one path,
sampled once, can carry many bands: the integrator keeps a throughput per *quadruple* of bands (up
to 16 quadruples = 64 lanes for 63 bands; :mod:`renderer_jobs.mitsuba.band_render` splits the bands
into sets) and re-evaluates the BSDF, the emitters and the light samples at each quadruple along the
same path. That removes wavelength sampling from the noise (issue 17: a band sees every path of its
set, not 4 of every 63 band samples), and because the integrator is
a standard ``SamplingIntegrator`` returning the bands as AOVs of an ``hdrfilm`` with a box filter,
Mitsuba's own render loop and its low-discrepancy samplers (``multijitter``, ``ldsampler``,
``orthogonal``, ``stratified``) drive it at compiled speed (the Python ``sample`` is traced once into
a Dr.Jit kernel per pass).

Estimator (per path, each band ``b`` of quadruple ``q``): unidirectional path tracing with next-event
estimation and MIS (power heuristic), emitters selected by Mitsuba's ``sampling_weight`` (their
approximate power per unit group spectrum, so a relit render selects exactly the same lights),
Russian roulette from the 5th vertex on the largest throughput over *all* bands (independent of the
emission spectrum, so relighting stays exact). ``max_depth`` as Mitsuba's ``path``: 1 = emitters
seen directly, 2 = direct light, …

Each path draws one offset inside the bands (the same for all its bands): a step spectrum is exact
there, a smooth one (Mitsuba's D65 of envmaps, conductor tables) is averaged over the band.

Illumination (DESIGN.md "Physical GT"), band by band, from the same paths: where the first hit is
purely diffuse and not emitting, ``U = L/ρ`` (every contribution of the path carries ``ρ``); where it
has a diffuse lobe and no delta one (rough plastic), a white Lambertian surface followed along the
path's own BSDF-sampled continuation — weight ``(cos/π)/pdf``, its own light sample, the same MIS
weights — with a second throughput and radiance in the loop (no extra rays); elsewhere (glass,
metal, emitters, black) a second path from the same camera ray whose first vertex is a white
Lambertian surface (BSDF ``1/π``, cosine sampling, its own emission excluded), in the same kernel.
Samples that hit nothing add 0.

AOVs: ``b000…`` the bands (radiance), ``u000…`` the illumination bands, ``first_pure``,
``first_mixed``, ``first_traced`` (which estimator the sample's illumination used), ``bad`` the number
of non-finite values the sample dropped. Bands a group does not emit are left out of the quadruples
(exactly zero in the cube).
"""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.mitsuba.path_guide import GuidedBounce, add_record, empty_records, light_of
from illumix.renderer_jobs.mitsuba.scene_dict import band_guard
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

RR_DEPTH = 5  # Mitsuba's path default: Russian roulette from the 5th vertex
RHO_MIN = 1e-6  # below this diffuse reflectance L/ρ carries nothing usable: trace U instead


def band_quadruples(edges: np.ndarray, live: np.ndarray) -> tuple[list[tuple[float, ...]], np.ndarray]:
    """The bands a path carries, in quadruples: ``(lower band edges (nm) per quadruple, band index of
    each lane (n_quads·4,))``. ``live`` bands only; the last quadruple repeats its last band to fill 4
    lanes (those copies are ignored: lane index ``-1``)."""
    live = np.asarray(live, dtype=np.int64)
    n = -(-live.size // 4)
    lanes = np.full(n * 4, -1, dtype=np.int64)
    lanes[:live.size] = live
    lo = np.asarray(edges, dtype=np.float64)[:-1][np.maximum(lanes, 0)]
    lo[live.size:] = lo[live.size - 1] if live.size else float(edges[0])
    return [tuple(float(x) for x in lo[4 * i:4 * i + 4]) for i in range(n)], lanes


def _power_heuristic(dr, a, b):
    a2, b2 = a * a, b * b
    w = a2 / (a2 + b2)
    return dr.select(dr.isfinite(w), w, 0.0)  # an infinite pdf (delta) gives 0, not NaN


# Tests force every first vertex through one illumination estimator (None: chosen per vertex).
FORCE_FIRST: str | None = None  # "mixed" (in-path, where a diffuse lobe exists) or "traced"


def make_integrator(quads: list[tuple[float, ...]], step: float, max_depth: int, illumination: bool,
                    flat_emission: bool = False, guide=None, record: bool = False, delta_first: bool = False,
                    sun_rest=None):
    """A ``BandPathIntegrator`` carrying the bands whose lower edges are ``quads`` (nm; width
    ``step``), for Mitsuba's ``mi.render``. The class is made here, not at import: it subclasses
    Mitsuba's, which needs the variant selected (its methods are :class:`_BandPath`'s, copied in:
    nanobind classes take a single base, so no mixin). Mitsuba's loop runs every sample of the film in
    one symbolic-loop kernel: the per-lane state lives in registers, the memory is the film's.
    ``flat_emission``: every emitter's spectrum is flat (the caller scales the bands by the emission
    after), so emitters are evaluated once per vertex, not once per quadruple. ``guide``: a
    :class:`renderer_jobs.mitsuba.path_guide.GuideArrays` whose learnt directions some bounces
    take; ``record``: :meth:`_BandPath.learn` returns the training records of its paths (same module).
    ``delta_first``: only what light paths cannot give (:mod:`renderer_jobs.mitsuba.light_paths`): the
    first vertex's emission, and paths whose first bounce is drawn from a delta lobe (no light sample
    at the first vertex, no other continuation). ``sun_rest``: a
    :class:`renderer_jobs.mitsuba.sun_windows.SunWindows`: only a sun's light samples along lines that
    cross none of its windows count, no emission, and nothing after a delta first bounce (the
    ``delta_first`` complement's) but the white estimate — what a sun's light paths through the
    windows and that complement leave (:mod:`renderer_jobs.mitsuba.sun_windows`)."""
    mi, _ = import_mitsuba()
    methods = {k: v for k, v in vars(_BandPath).items() if k not in ("__dict__", "__weakref__", "__qualname__")}
    cls = type("BandPathIntegrator", (mi.SamplingIntegrator,), methods)
    return cls(mi.Properties(), quads, step, max_depth, illumination, flat_emission, guide, record, delta_first,
               sun_rest)


class _BandPath:
    """See the module docstring. Loop state per lane: a throughput and a radiance per quadruple,
    and for the illumination estimate (``illumination``) a second throughput and radiance that
    follow the same path from its second vertex on (the "in-path" white estimate).

    The methods of :func:`make_integrator`'s ``BandPathIntegrator`` (a ``mi.SamplingIntegrator``).
    The loop-body steps (``_classify_first`` … ``_direction_and_roulette``) run symbolically inside
    ``dr.while_loop``: they update the per-quadruple lists ``paths = (beta, L, beta_u, U)`` (and
    ``rho``) in place and return the other loop values they change."""

    def __init__(self, props, quads, step, max_depth, illumination, flat_emission, guide=None, record=False,
                 delta_first=False, sun_rest=None):
        mi, dr = import_mitsuba()
        mi.SamplingIntegrator.__init__(self, props)
        # opaque: the band set's wavelengths are the kernel's inputs, not literals in its code, so
        # every band set and pass of a scene runs the one compiled kernel (as literals, each set
        # compiled its own: bench/RENDER_PERF.md "Fixed costs")
        self.lows = [mi.Spectrum(*q) for q in quads]
        dr.make_opaque(*self.lows)
        self.quads = list(self.lows)  # this path's wavelengths, set per sample (sample())
        self.guard = band_guard(step)
        self.width = float(step) - 2 * self.guard
        self.force = FORCE_FIRST
        self.flat = bool(flat_emission)
        self.max_depth = int(max_depth)
        self.illumination = bool(illumination)
        self.guide, self.record = guide, bool(record)
        self.delta_first = bool(delta_first)
        self.sun_rest = sun_rest

    def aov_names(self):
        names = [f"b{i:03d}" for i in range(4 * len(self.quads))]
        if self.illumination:
            names += [f"u{i:03d}" for i in range(4 * len(self.quads))]
            names += ["first_pure", "first_mixed", "first_traced"]
        return names + ["bad"]

    def _path(self, scene, sampler, ray, active, white0, split: bool):
        """Trace one path per lane. Returns per quadruple: the radiance ``L``, and (``split``) the
        first vertex's diffuse reflectance ``rho``, and the in-path white estimate ``U``, with the
        masks ``hit0`` (the camera ray hit something), ``diffuse0`` (first vertex purely diffuse:
        U = L/ρ) and ``mixed0`` (first vertex has a diffuse lobe and no delta one: U from this
        path, module docstring).
        ``white0``: lanes whose first vertex *is* a white Lambertian surface (the separate
        illumination path, for every other first vertex)."""
        mi, dr = import_mitsuba()
        nq = len(self.quads)
        zeros = [mi.Spectrum(0.0) for _ in range(nq)]
        state = (sampler, mi.Ray3f(ray), mi.UInt32(0), [mi.Spectrum(1.0) for _ in range(nq)], list(zeros),
                 list(zeros), list(zeros), list(zeros),
                 mi.Bool(False), mi.Bool(False), mi.Bool(False), dr.zeros(mi.Interaction3f), mi.Float(1.0),
                 mi.Bool(True), mi.Bool(active), empty_records(mi, self.max_depth if self.record else 0))

        def cond(sampler, ray, depth, beta, L, beta_u, U, rho, hit0, diffuse0, mixed0, prev, prev_pdf,
                 prev_delta, active, rec):
            return active

        def body(sampler, ray, depth, beta, L, beta_u, U, rho, hit0, diffuse0, mixed0, prev, prev_pdf,
                 prev_delta, active, rec):
            paths = (beta, L, beta_u, U)  # per quadruple, updated in place by the steps below
            before = light_of(dr, L) if self.record else None
            si = scene.ray_intersect(ray, mi.RayFlags.All, coherent=depth == 0, active=active)
            white = white0 & (depth == 0)
            first = active & (depth == 0) & si.is_valid()
            hit0 |= first
            bsdf = si.bsdf(ray)
            flags = bsdf.flags()
            if split:  # what the first vertex is, for the illumination estimate
                diffuse0, mixed0 = self._classify_first(si, bsdf, flags, first, rho, diffuse0, mixed0)
            u_first = split & first & mixed0  # the white estimate starts here (its own light sample)
            self._add_emission(scene, si, prev, prev_pdf, prev_delta, active, white, paths, split)
            go = active & si.is_valid() & (depth + 1 < self.max_depth)
            bs, side, s2 = self._light_and_continue(scene, sampler, si, bsdf, flags, white, u_first, go, paths,
                                                    split, depth)
            go, wo, pdf, delta = self._direction_and_roulette(sampler, bs, side, s2, white, u_first, go, depth,
                                                              paths, split)
            ray = si.spawn_ray(si.to_world(wo))
            if self.record:  # this vertex's light goes to the bounces before it; this bounce is one
                add_record(mi, dr, self.guide, rec, depth, light_of(dr, L) - before, si, ray.d, pdf, go & ~delta, beta)
            prev = dr.select(go, mi.Interaction3f(si), prev)
            prev_pdf = dr.select(go, pdf, prev_pdf)
            prev_delta = dr.select(go, delta, prev_delta)
            return (sampler, ray, depth + 1, beta, L, beta_u, U, rho, hit0, diffuse0, mixed0, prev, prev_pdf,
                    prev_delta, go, rec)

        out = dr.while_loop(state, cond, body, label="illumix band path")
        if self.record:
            return out[-1]
        return out[4], out[6], out[7], out[8], out[9], out[10]

    def _classify_first(self, si, bsdf, flags, first, rho, diffuse0, mixed0):
        """What the first vertex is, for the illumination estimate: purely diffuse, not emitting and
        ρ > ``RHO_MIN`` in every band (U = L/ρ; its diffuse reflectance per quadruple set in ``rho``,
        in place), or with a diffuse lobe and no delta one (the in-path estimate); ``FORCE_FIRST``
        overrides. Returns ``(diffuse0, mixed0)``, changed on ``first`` lanes only."""
        mi, dr = import_mitsuba()
        emits = si.shape.is_emitter()
        pure = mi.has_flag(flags, mi.BSDFFlags.DiffuseReflection) & ~emits
        for other in (mi.BSDFFlags.Glossy, mi.BSDFFlags.Delta, mi.BSDFFlags.Transmission):
            pure &= ~mi.has_flag(flags, other)
        for q in range(len(self.quads)):
            si.wavelengths = self.quads[q]
            r = bsdf.eval_diffuse_reflectance(si, first & pure)
            rho[q] = dr.select(first, r, rho[q])
            pure &= dr.min(r) > RHO_MIN
        mixed = (mi.has_flag(flags, mi.BSDFFlags.DiffuseReflection) & ~mi.has_flag(flags, mi.BSDFFlags.Delta)
                 & ~emits & ~pure)
        if self.force is not None:
            mixed = (pure | mixed) if self.force == "mixed" else mi.Bool(False)
            pure = mi.Bool(False)
        return dr.select(first, pure, diffuse0), dr.select(first, mixed, mixed0)

    def _add_emission(self, scene, si, prev, prev_pdf, prev_delta, active, white, paths, split):
        """The emission found by this ray, MIS-weighted against the light sample (from ``prev``) that
        could have found it, added to every quadruple's ``L`` (and ``U``) in place."""
        mi, dr = import_mitsuba()
        beta, L, beta_u, U = paths
        ds = mi.DirectionSample3f(scene, si, prev)
        em_pdf = scene.pdf_emitter_direction(prev, ds, ~prev_delta)
        mis = dr.select(prev_delta, 1.0, _power_heuristic(dr, prev_pdf, em_pdf))
        count = active & ~white  # a white first vertex does not emit
        if self.sun_rest is not None:  # light paths give every emitter's light but the sun's through no window
            count &= False
        emitter = si.emitter(scene)
        if self.flat:
            le_flat = mis * emitter.eval(si, count)
        for q in range(len(self.quads)):
            si.wavelengths = self.quads[q]
            le = le_flat if self.flat else mis * emitter.eval(si, count)
            L[q] = dr.select(count, L[q] + beta[q] * le, L[q])
            if split:
                U[q] = dr.select(count, U[q] + beta_u[q] * le, U[q])

    def _light_and_continue(self, scene, sampler, si, bsdf, flags, white, u_first, go, paths, split, depth):
        """The light sample: drawn once (hero quadruple), valued at every quadruple and added to ``L``
        (and ``U``); and the continuation: one direction (s1, s2), every quadruple's throughput weight,
        from the same call. Updates ``paths`` in place; returns the BSDF sample ``bs``, the side the
        white surface faces (±1 along the local normal) and ``s2`` (the white surface's direction)."""
        mi, dr = import_mitsuba()
        beta, L, beta_u, U = paths
        ctx = mi.BSDFContext()
        si.wavelengths = self.quads[0]
        em_on = go & (white | mi.has_flag(flags, mi.BSDFFlags.Smooth))
        if self.delta_first:  # light paths give the first vertex's light sample
            em_on &= depth > 0
        ds_em, _ = scene.sample_emitter_direction(si, sampler.next_2d(em_on), False, em_on)
        em_on &= ds_em.pdf != 0.0
        if self.sun_rest is not None:  # only the sun, along lines through no window
            sun = mi.has_flag(ds_em.emitter.flags(), mi.EmitterFlags.DeltaDirection)
            em_on &= sun & (self.sun_rest.crossings(mi, dr, si.p, ds_em.d) == 0.0)
        em_on &= ~scene.ray_test(si.spawn_ray_to(ds_em.p), em_on)
        wo_em = si.to_local(ds_em.d)
        # a white surface faces the camera, whichever side of the shape it sees
        side = dr.select(mi.Frame3f.cos_theta(si.wi) < 0.0, -1.0, 1.0)
        cos_em = dr.maximum(side * mi.Frame3f.cos_theta(wo_em), 0.0)
        s1, s2 = sampler.next_1d(go), sampler.next_2d(go)
        g = None if self.guide is None else GuidedBounce(mi, dr, self.guide, sampler, si, bsdf, ctx, flags,
                                                         go & ~white, ds_em.d, em_on)
        if self.flat:
            le = scene.eval_emitter_direction(si, ds_em, em_on) / ds_em.pdf
        bs = None
        for q in range(len(self.quads)):
            si.wavelengths = self.quads[q]
            if not self.flat:
                le = scene.eval_emitter_direction(si, ds_em, em_on) / ds_em.pdf
            f, f_pdf, bs_q, w_q = bsdf.eval_pdf_sample(ctx, si, wo_em, s1, s2, go)
            bs = bs_q if bs is None else bs
            if g is not None:  # the bounce drawn from the guide/BSDF mixture: its weight and MIS pdf
                w_q, f_pdf = g.weight(bs, w_q), g.mixture_pdf_em(f_pdf)
            f = dr.select(white, cos_em / dr.pi, f)
            f_pdf = dr.select(white, cos_em / dr.pi, f_pdf)
            mis_em = dr.select(ds_em.delta, 1.0, _power_heuristic(dr, ds_em.pdf, f_pdf))
            L[q] = dr.select(em_on, L[q] + beta[q] * mis_em * f * le, L[q])
            if split:  # the white surface sampled with the BSDF's pdf: same MIS weights
                f_u = dr.select(u_first, cos_em / dr.pi, beta_u[q] * f)
                U[q] = dr.select(em_on, U[q] + mis_em * f_u * le, U[q])
            beta[q] = beta[q] * w_q
            if split:
                beta_u[q] = beta_u[q] * w_q
        if g is not None:
            g.chosen(bs)  # the direction taken and its mixture pdf, as the steps after read them
        return bs, side, s2

    def _direction_and_roulette(self, sampler, bs, side, s2, white, u_first, go, depth, paths, split):
        """The next direction (a white first vertex: cosine-sampled from ``s2`` on its ``side``; else
        the BSDF's ``bs``), the white estimate's first weight, and Russian roulette. Updates the
        throughputs of ``paths`` in place; returns ``(go, wo, pdf, delta)``."""
        mi, dr = import_mitsuba()
        beta, _, beta_u, _ = paths
        wo_white = mi.warp.square_to_cosine_hemisphere(s2)
        pdf_white = mi.warp.square_to_cosine_hemisphere_pdf(wo_white)
        wo_white.z = side * wo_white.z
        wo = dr.select(white, wo_white, bs.wo)
        pdf = dr.select(white, pdf_white, bs.pdf)
        delta = ~white & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        if self.delta_first:  # light paths give every first bounce but a delta one
            go &= (depth > 0) | delta
        # sun_rest: what follows a delta first bounce is the delta_first complement's, every light in
        # it; only the white estimate (which that complement leaves to light paths) goes on here
        drop = (depth == 0) & delta if self.sun_rest is not None else None
        if split:  # white surface, BSDF-sampled direction: weight (cos/π)/pdf
            cos_u = dr.maximum(side * mi.Frame3f.cos_theta(bs.wo), 0.0)
            w_u = dr.select(bs.pdf > 0.0, cos_u / (dr.pi * bs.pdf), 0.0)
        bmax = mi.Float(0.0)
        for q in range(len(self.quads)):
            beta[q] = dr.select(white, mi.Spectrum(1.0), beta[q])
            if drop is not None:
                beta[q] = dr.select(drop, mi.Spectrum(0.0), beta[q])
            if split:
                beta_u[q] = dr.select(u_first, mi.Spectrum(w_u), beta_u[q])
                bmax = dr.maximum(bmax, dr.max(beta_u[q]))
            bmax = dr.maximum(bmax, dr.max(beta[q]))
        go &= bmax > 0.0
        # Russian roulette on the largest throughput over every band (and both estimates)
        rr = go & (depth + 1 >= RR_DEPTH)
        q_rr = dr.minimum(bmax * dr.square(dr.select(delta, bs.eta, 1.0)), 0.95)
        go &= ~rr | (sampler.next_1d(rr) < q_rr)
        for q in range(len(self.quads)):
            beta[q] = dr.select(rr, beta[q] / q_rr, beta[q])
            if split:
                beta_u[q] = dr.select(rr, beta_u[q] / q_rr, beta_u[q])
        return go, wo, pdf, delta

    def learn(self, scene, sampler, ray, active=True) -> tuple:
        """Training paths (``record``): their records (:func:`path_guide.add_record`), per bounce slot."""
        mi, _ = import_mitsuba()
        offset = self.guard + self.width * sampler.next_1d(active)
        self.quads = [low + offset for low in self.lows]
        return self._path(scene, sampler, ray, active, mi.Bool(False), False)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        mi, _ = import_mitsuba()
        # One offset inside the bands per path: step spectra are constant there (their band
        # average exactly), other spectra (envmap D65, conductor tables) averaged over the band.
        offset = self.guard + self.width * sampler.next_1d(active)
        self.quads = [low + offset for low in self.lows]
        path = self._path(scene, sampler, ray, active, mi.Bool(False), self.illumination)
        aovs = self._aovs(scene, sampler, ray, path)
        return mi.Spectrum(0.0), mi.Bool(active), aovs

    def _aovs(self, scene, sampler, ray, path):
        """The sample's AOVs (:meth:`aov_names`) from ``path`` (:meth:`_path`'s outputs): the bands,
        and (``illumination``) the illumination bands — L/ρ, the in-path estimate, or a separate white
        path — with which estimator each sample used; non-finite values set to 0, counted in ``bad``."""
        mi, dr = import_mitsuba()
        nq = len(self.quads)
        L, Uin, rho, hit0, diffuse0, mixed0 = path
        bad = mi.Float(0.0)
        aovs = []

        def keep(v):
            nonlocal bad
            ok = dr.isfinite(v)
            bad += dr.select(ok, 0.0, 1.0)
            aovs.append(dr.select(ok, v, 0.0))

        for q in range(nq):
            for k in range(4):
                keep(L[q][k])
        if self.illumination:
            # first vertices that are neither purely diffuse nor have a diffuse lobe (glass, metal,
            # emitters, black): a separate path whose first vertex is a white Lambertian surface
            need = hit0 & ~diffuse0 & ~mixed0
            W = self._path(scene, sampler, ray, need, need, False)[0]
            for q in range(nq):
                for k in range(4):
                    u_pure = L[q][k] / dr.maximum(rho[q][k], RHO_MIN)
                    keep(dr.select(diffuse0, u_pure, dr.select(mixed0, Uin[q][k], W[q][k])))
            aovs += [dr.select(hit0 & diffuse0, 1.0, 0.0), dr.select(hit0 & mixed0, 1.0, 0.0),
                     dr.select(need, 1.0, 0.0)]
        aovs.append(bad)
        return aovs
