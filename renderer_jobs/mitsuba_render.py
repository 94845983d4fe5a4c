"""Rendering: one spectral transport cube per (view, light group), plus view AOVs.

Mitsuba stays behind the ``mitsuba_*`` modules: callers pass a :class:`renderer_jobs.scene_model.Scene`
and get numpy. Variant: :mod:`renderer_jobs.mitsuba_variant`; scene dictionary:
:mod:`renderer_jobs.mitsuba_scene`; tracing: :mod:`renderer_jobs.mitsuba_trace`.

What a cube is
--------------
``T[v, g](x, λ_i)`` — for view ``v`` and light group ``g`` — is the band average over band ``i`` of the
spectral radiance reaching pixel ``x`` (box pixel filter) when only ``g``'s emitters are on, each
emitting ``strength × Ē_g(λ)`` with ``Ē_g`` the group's emission (flat, value 1, by default) held
constant over each band; every other group's emitters are removed (their geometry and materials
stay). Path tracing (Mitsuba's ``path`` integrator, unidirectional with next-event estimation,
emitter selection weighted by approximate power via ``sampling_weight``), no denoiser, no clamping,
emitters visible. Portal emitters (``emitter.portal``, e.g. the sky filling a window) are not
geometry: they are traced in a second pass with the same schedule and added (linearity), so they
never shadow the group's other emitters. Non-finite samples (none seen so far) are dropped and
counted in the cube's stats.

Wavelength sampling (issue 4, see ``bench/render.py`` for the measurements)
-------------------------------------------------------------------------
Mitsuba traces 4 wavelengths per path ("hero" wavelengths). Its spectral film draws them at random
over the whole range, so each 5 nm band of a pixel receives a *random number* of samples and the
per-band estimate carries that count's binomial noise (≈ 1/√(expected count): 12 % at 1024 spp for
63 bands). This backend drives the integrator itself (``Integrator.sample`` on rays it generates) and
chooses every wavelength:

- ``"stratified"`` (default): path ``s`` of pixel ``p`` starts at band ``k = (s + o_p) mod n`` and its
  four wavelengths lie in bands ``k, k+16, k+32, k+48 (mod n)`` — spread over the spectrum so one
  path's noise does not pile up in one camera channel — each uniformly jittered inside its band.
  Every ``n`` consecutive paths put exactly 4 samples in every band, so a band's sample count is
  fixed (⌊4·spp/n⌋ or one more, known exactly) and its estimate is the plain mean of its samples.
  ``o_p`` is a per-pixel hash that decorrelates neighbouring pixels when spp < n.
- ``"random"``: Mitsuba's default behaviour, for comparison — four wavelengths uniform over the grid
  span with Mitsuba's shifted stratification (``sample_shifted``), each band estimated as
  ``Σ L / E[count]`` exactly as the ``specfilm`` does.

Per-band sums are accumulated in float64 by ``numpy.bincount`` (no atomics), so the same seed gives
the same cube bit for bit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from renderer_jobs.mitsuba_scene import EDGE_GUARD_NM, group_emission
from renderer_jobs.mitsuba_trace import Tracer
from renderer_jobs.mitsuba_variant import import_mitsuba, libllvm_path, select_variant
from renderer_jobs.scene_model import Scene
from renderer_jobs.scene_schema import SceneError

WAVELENGTH_MODES = ("stratified", "random")
LANE_STRIDE = 16  # band offset between a path's 4 wavelengths in "stratified" mode


@dataclass(frozen=True)
class RenderSettings:
    """spp: paths per pixel (each carries 4 wavelengths); seed: RNG seed of the cube;
    wavelengths: ``"stratified"`` or ``"random"`` (module docstring); max_lanes: paths traced per pass
    (bounds memory: ~1 kB per lane on the LLVM backend); aov_spp: samples per pixel of the AOV pass."""

    spp: int = 64
    seed: int = 0
    wavelengths: str = "stratified"
    max_lanes: int = 1 << 20
    aov_spp: int = 4
    resolution: tuple[int, int] | None = None  # (width, height) overriding the view's

    def __post_init__(self) -> None:
        if self.spp < 1:
            raise SceneError(f"spp must be >= 1, got {self.spp}")
        if self.wavelengths not in WAVELENGTH_MODES:
            raise SceneError(f"wavelength sampling {self.wavelengths!r} unknown; use one of {', '.join(WAVELENGTH_MODES)}")
        if self.max_lanes < 1:
            raise SceneError("max_lanes must be >= 1")

    def to_dict(self) -> dict:
        return {"spp": self.spp, "seed": self.seed, "wavelengths": self.wavelengths,
                "max_lanes": self.max_lanes, "aov_spp": self.aov_spp,
                "resolution": list(self.resolution) if self.resolution else None}


@dataclass
class CubeResult:
    """A rendered cube ``(H, W, n_bands)`` float32 of band averages, with what it was rendered with."""

    cube: np.ndarray
    emission: np.ndarray
    emission_name: str
    renderer: dict
    stats: dict = field(default_factory=dict)


def _hash_u32(x: np.ndarray, salt: int) -> np.ndarray:
    """A 32-bit integer hash (lowbias32) of ``x`` with ``salt``; vectorised, uint64 → uint64 < 2³²."""
    x = (x.astype(np.uint64) ^ np.uint64(salt & 0xFFFFFFFF)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    return x


def band_counts(n_pixels: int, n_bands: int, spp: int, seed: int) -> np.ndarray:
    """Exact samples per (pixel, band) of the ``"stratified"`` schedule: ``(n_pixels, n_bands)`` int."""
    off = (_hash_u32(np.arange(n_pixels), seed ^ 0x5BD1E995) % np.uint64(n_bands)).astype(np.int64)
    q, r = divmod(spp, n_bands)
    b = np.arange(n_bands)
    counts = np.zeros((n_pixels, n_bands), dtype=np.int64)
    for i in range(4):
        counts += q + (((b[None, :] - off[:, None] - LANE_STRIDE * i) % n_bands) < r)
    return counts


def _pass_sizes(spp: int, n_pixels: int, max_lanes: int) -> list[int]:
    per = max(1, min(spp, max_lanes // max(n_pixels, 1)))
    sizes = [per] * (spp // per)
    if spp % per:
        sizes.append(spp % per)
    return sizes


def render_cube(scene: Scene, view: str, group: str | list[str] | None,
                settings: RenderSettings = RenderSettings()) -> CubeResult:
    """Render the transport cube of ``view`` lit by ``group`` (see module docstring).

    ``group`` may be a list of groups (rendered together, all with their own emission) or ``None``
    for every group at once (the "all-on" render used to check additivity). Returns float32 band
    averages ``(H, W, n_bands)`` of radiance per unit emission spectrum.
    """
    groups = [group] if isinstance(group, str) else (scene.group_names if group is None else list(group))
    for g in groups:
        scene.group(g)
    t0 = time.perf_counter()
    # Portals render in a pass of their own (they occlude nothing); the cube is the passes' sum.
    passes = [p for p, present in (
        ("without", any(not scene.is_portal(e) for g in groups for e in scene.emitters_of(g))),
        ("only", any(scene.is_portal(e) for g in groups for e in scene.emitters_of(g)))) if present]
    tracers = [Tracer(scene, view, groups, settings.resolution, portals=p) for p in passes]
    t_load = time.perf_counter() - t0
    grid = tracers[0].grid
    nb = grid.n_bands
    w, h = tracers[0].width, tracers[0].height
    npix = w * h
    if settings.wavelengths == "stratified" and 4 * settings.spp < nb:
        raise SceneError(f"spp {settings.spp} is too low for stratified wavelengths: every band of the "
                         f"{nb}-band grid needs a sample, so spp >= {math.ceil(nb / 4)}")
    acc = np.zeros(npix * nb, dtype=np.float64)
    lo = grid.edges[0]
    step = grid.step
    guard = min(EDGE_GUARD_NM, step / 10)
    off = (_hash_u32(np.arange(npix), settings.seed ^ 0x5BD1E995) % np.uint64(nb)).astype(np.int64)
    s0 = 0
    n_bad = 0
    t_trace = 0.0
    for k, spp_pass in enumerate(_pass_sizes(settings.spp, npix, settings.max_lanes)):
        rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, k, 0x1C0])
        pix = np.repeat(np.arange(npix, dtype=np.int64), spp_pass)
        s = s0 + np.tile(np.arange(spp_pass, dtype=np.int64), npix)
        jitter = rng.random((len(pix), 2), dtype=np.float32)
        u = rng.random((len(pix), 4))
        if settings.wavelengths == "stratified":
            base = (s + off[pix]) % nb
            bands = (base[:, None] + LANE_STRIDE * np.arange(4)[None, :]) % nb
            lam = lo + step * bands + guard + (step - 2 * guard) * u
        else:
            # Mitsuba's default: one uniform sample over the span, shifted by 1/4 for the others.
            span = nb * step
            u0 = u[:, :1]
            frac = (u0 + np.arange(4)[None, :] / 4.0) % 1.0
            lam = lo + span * frac
            bands = np.minimum((frac * nb).astype(np.int64), nb - 1)
        idx = (pix[:, None] * nb + bands).ravel()
        for j, tracer in enumerate(tracers):
            t1 = time.perf_counter()
            L = tracer.trace(pix, jitter, lam.astype(np.float32),
                             seed=int(_hash_u32(np.array([k * 8 + j]), settings.seed)[0]))
            t_trace += time.perf_counter() - t1
            bad = ~np.isfinite(L)
            if bad.any():
                n_bad += int(bad.sum())
                L = np.where(bad, 0.0, L)
            acc += np.bincount(idx, weights=L.ravel().astype(np.float64), minlength=npix * nb)
        s0 += spp_pass
    acc = acc.reshape(npix, nb)
    if settings.wavelengths == "stratified":
        cube = acc / band_counts(npix, nb, settings.spp, settings.seed)
    else:
        cube = acc / (4.0 * settings.spp / nb)
    cube = cube.reshape(h, w, nb).astype(np.float32)
    emission = np.ones(nb)
    name = "flat"
    if len(groups) == 1:
        emission, name = group_emission(scene, groups[0])
    mi, _ = import_mitsuba()
    renderer = {"name": "mitsuba", "version": str(mi.__version__), "variant": select_variant(),
                "settings": {"integrator": "path", "max_depth": scene.max_depth, "rfilter": "box",
                             "wavelength_sampling": settings.wavelengths, "denoiser": None, "clamp": None,
                             "emitter_sampling": "power", "spp": settings.spp, "seed": settings.seed,
                             "passes": passes,
                             "libllvm": libllvm_path()}}
    stats = {"load_s": round(t_load, 4), "trace_s": round(t_trace, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": n_bad,
             "mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min())}
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=renderer, stats=stats)


# Broad bands (nm) whose mean reflectance forms the RGB albedo AOV.
ALBEDO_BANDS = ((600.0, 700.0), (500.0, 600.0), (400.0, 500.0))


def render_aovs(scene: Scene, view: str, settings: RenderSettings = RenderSettings()) -> dict[str, np.ndarray]:
    """Geometry AOVs of a view, averaged over ``aov_spp`` jittered primary rays per pixel.

    albedo ``(H, W, 3)``: mean diffuse reflectance (Mitsuba's ``eval_diffuse_reflectance``) over
    600–700, 500–600, 400–500 nm (R, G, B); normal ``(H, W, 3)``: world-space shading normal
    (unit, of the hits); depth ``(H, W)``: distance from the camera along the ray in metres (0 where
    nothing is hit); mask ``(H, W)`` bool: the pixel centre ray hits geometry. float32 except mask.
    """
    tracer = Tracer(scene, view, [], settings.resolution)
    w, h = tracer.width, tracer.height
    npix = w * h
    k = max(1, settings.aov_spp)
    rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, 0xA0F])
    pix = np.repeat(np.arange(npix, dtype=np.int64), k)
    jitter = rng.random((len(pix), 2), dtype=np.float32)
    jitter[::k] = 0.5  # the first sample of every pixel is its centre (for the mask)
    u = rng.random((len(pix), 3))
    lam = np.empty((len(pix), 4), dtype=np.float32)
    for c, (a, b) in enumerate(ALBEDO_BANDS):
        lam[:, c] = a + (b - a) * u[:, c]
    lam[:, 3] = 550.0
    out = tracer.first_hit(pix, jitter, lam)
    hit = out["hit"].reshape(npix, k)
    hitf = hit.astype(np.float64)
    nh = np.maximum(hitf.sum(axis=1), 1)
    albedo = (out["albedo"][:, :3].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1) / nh[:, None]
    normal = (out["normal"].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1)
    norm = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(norm > 0, normal / np.where(norm > 0, norm, 1), 0.0)
    depth = (out["distance"].reshape(npix, k) * hitf).sum(axis=1) / nh
    return {"albedo": albedo.reshape(h, w, 3).astype(np.float32),
            "normal": normal.reshape(h, w, 3).astype(np.float32),
            "depth": depth.reshape(h, w).astype(np.float32),
            "mask": hit[:, 0].reshape(h, w)}


def camera_meta(scene: Scene, view: str, resolution: tuple[int, int] | None = None) -> dict:
    v = scene.view(view)
    w, h = resolution or v.resolution
    return {"width": int(w), "height": int(h), "camera": {"origin": list(v.origin), "target": list(v.target),
                                                          "up": list(v.up)}, "fov": v.fov, "fov_axis": "x"}
