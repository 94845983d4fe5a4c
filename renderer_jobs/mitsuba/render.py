"""Rendering: one spectral transport cube per (view, light group), plus view AOVs.

Mitsuba stays behind the ``mitsuba_*`` modules: callers pass a :class:`scene.model.Scene`
and get numpy. Variant: :mod:`renderer_jobs.mitsuba.variant`; scene dictionary:
:mod:`renderer_jobs.mitsuba.scene_dict`; tracing: :mod:`renderer_jobs.mitsuba.trace`.

What a cube is
--------------
``T[v, g](x, λ_i)`` — for view ``v`` and light group ``g`` — is the band average over band ``i`` of the
spectral radiance reaching pixel ``x`` (box pixel filter) when only ``g``'s emitters are on, each
emitting ``strength × Ē_g(λ)`` with ``Ē_g`` the group's emission (flat, value 1, by default) held
constant over each band; every other group's emitters are removed (their geometry and materials
stay). Unidirectional path tracing with next-event estimation and MIS, emitter selection weighted
by approximate power via ``sampling_weight``, no denoiser, no clamping, emitters visible; the
until-clean rule's rounds from the third on draw half their bounces from a learnt path guide
(:mod:`renderer_jobs.mitsuba.path_guide`, unbiased by its MIS weights). Portal
emitters (``emitter.portal``, e.g. the sky filling a window) are not geometry: they are traced in
a second pass with the same schedule and added (linearity), so they never shadow the group's other
emitters. Non-finite samples (none seen so far) are dropped and counted in the cube's stats.

Wavelength sampling (issues 4 and 17, see ``bench/render.py`` for the measurements)
-------------------------------------------------------------------------------------
- ``"all-bands"`` (default, issue 17): every path carries many bands at once (no material disperses,
  so a path sampled once serves every wavelength), rendered by Mitsuba's own loop with a
  low-discrepancy pixel sampler: :mod:`renderer_jobs.mitsuba.bands` (the integrator) and
  :mod:`renderer_jobs.mitsuba.band_render` (band sets, passes). ``bench/RENDER_PERF.md`` measures it
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
(:meth:`renderer_jobs.mitsuba.trace.Tracer.white_lambertian`). Samples that hit nothing add 0; the
view's ``mask``/``emitter`` AOVs flag pixels where illumination is undefined. The ``"all-bands"``
mode estimates it band by band in its own kernel (:mod:`renderer_jobs.mitsuba.bands`).

Per-band sums are accumulated in float64 by ``numpy.bincount`` (no atomics), so the same seed gives
the same cube bit for bit.
"""

from __future__ import annotations

import time

import numpy as np

from illumix.renderer_jobs.band_schedule import group_seed
from illumix.renderer_jobs.cube import CubeResult, emitter_passes, group_list  # noqa: F401 - re-exported
from illumix.renderer_jobs.mitsuba.bands import RR_DEPTH
from illumix.renderer_jobs.mitsuba.scene_dict import group_emission
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba, libllvm_path, select_variant
from illumix.renderer_jobs.render_settings import RenderSettings  # noqa: F401 — re-exported
from illumix.scene.model import Scene
from illumix.scene.schema import SceneError


def renderer_info(scene: Scene, settings: RenderSettings, passes: list[str]) -> dict:
    """The cube metadata's ``renderer`` record: Mitsuba version, variant and every setting that matters."""
    mi, _ = import_mitsuba()
    bands = settings.wavelengths == "all-bands"
    info = {"name": "mitsuba", "backend": "mitsuba", "version": str(mi.__version__), "variant": select_variant(),
            "method": (f"path tracing, up to {settings.bands_per_path} bands on every path (interleaved band sets "
                       f"sharing the spp), {settings.sampler} pixel samples, Mitsuba's render loop"
                       + ("; until clean, late rounds light tracing or path-guided, by measured variance per CPU s"
                          if settings.clean_cap(scene) and settings.light_paths else "") if bands else
                       f"path tracing, 4 {settings.wavelengths} wavelengths per path (illumix sampling)"),
            "settings": {"integrator": "illumix band path" if bands else "path", "max_depth": scene.max_depth,
                         "rr_depth": RR_DEPTH, "mis": "power heuristic", "rfilter": "box",
                         "wavelength_sampling": settings.wavelengths, "denoiser": None, "clamp": None,
                         "emitter_sampling": "power", "spp": settings.spp, "seed": settings.seed,
                         "clean_max_spp": settings.clean_cap(scene),
                         "guide_paths": bool(bands and settings.clean_cap(scene) and settings.guide_paths),
                         "light_paths": bool(bands and settings.clean_cap(scene) and settings.light_paths),
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


def render_cube(scene: Scene, view: str, group: str | list[str] | None,
                settings: RenderSettings = RenderSettings(), boost_mask: np.ndarray | None = None) -> CubeResult:
    """Render the transport cube of ``view`` lit by ``group`` (see module docstring).

    ``group`` may be a list of groups (rendered together, all with their own emission) or ``None``
    for every group at once (the "all-on" render used to check additivity). Returns float32 band
    averages ``(H, W, n_bands)`` of radiance per unit emission spectrum. With ``settings.adaptive``
    (and spp ≥ twice the pilot) the same total of paths (up to rounding) is spread by
    :mod:`renderer_jobs.adaptive_spp`; with ``settings.noise_target`` each pixel gets what its noise needs.
    ``boost_mask`` ``(H, W)`` bool (``"all-bands"`` only, from the guides alone:
    :func:`renderer_jobs.mitsuba.boost_paths.boost_mask`): those pixels get ``settings.boost_factor`` × spp.
    The paths' random numbers come from ``settings.seed`` mixed with the group names
    (:func:`renderer_jobs.band_schedule.group_seed`): two groups' cubes are independent estimates.
    """
    groups = group_list(scene, group)
    settings = settings.model_copy(update={"seed": group_seed(settings.seed, groups)})  # each group its own paths
    t0 = time.perf_counter()
    passes = emitter_passes(scene, groups)
    if settings.wavelengths == "all-bands":
        return _render_all_bands(scene, view, groups, passes, settings, boost_mask)
    from illumix.renderer_jobs.mitsuba.hero_paths import render_hero  # noqa: PLC0415

    cube, illum, stats, emission, name = render_hero(scene, view, groups, passes, settings, t0)
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=renderer_info(scene, settings, passes), stats=stats, illumination=illum)


def _render_all_bands(scene: Scene, view: str, groups: list[str], passes: list[str],
                      settings: RenderSettings, boost_mask: np.ndarray | None = None) -> CubeResult:
    from illumix.renderer_jobs.mitsuba.band_render import (light_paths_apply, render_all_bands,  # noqa: PLC0415
                                                          sets_give_halves)

    nb = scene.spectral_grid.n_bands
    emission, name = (group_emission(scene, groups[0]) if len(groups) == 1 else (np.ones(nb), "flat"))
    boost = None
    if boost_mask is not None and settings.boost_factor > 1:
        w, h = settings.resolution or scene.view(view).resolution
        if np.shape(boost_mask) != (h, w):
            raise SceneError(f"boost mask {np.shape(boost_mask)} does not match view {view!r}'s ({h}, {w}) (H, W)")
        boost = np.flatnonzero(np.asarray(boost_mask, bool).ravel())
    e = np.asarray(emission, np.float64)
    settings = settings.model_copy(update={"clean_max_spp": settings.clean_cap(scene)})  # unset → per scene
    if settings.clean_max_spp:
        from illumix.renderer_jobs.mitsuba.until_clean import render_until_clean  # noqa: PLC0415

        loaded: dict = {}  # the rounds share the loaded scene
        cube, illum, stats, noise = render_until_clean(
            lambda s, kind: render_all_bands(scene, view, groups, passes, s, e, boost, loaded, kind), settings,
            sets_give_halves(e, settings.bands_per_path), settings.guide_paths,
            settings.light_paths and light_paths_apply(scene, groups))
    else:
        cube, illum, stats, noise, _ = render_all_bands(scene, view, groups, passes, settings, e, boost)
    stats.update({"mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min())})
    info = renderer_info(scene, settings, passes)
    info["settings"]["targeted_paths"] = ({"spp_factor": settings.boost_factor, "reach": settings.boost_reach,
                                           "mask": "dt-irradiance reach of unit white noise > reach (guides only)"}
                                          if boost is not None else None)
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=info, stats=stats, illumination=illum, noise=noise)
