"""Skip what a scene doesn't need: does a light group reach a view at all?

Before a cube is rendered, :func:`probe_group` traces a small *pilot* of the same light transport
(same scene, integrator, depth, emitters, portal passes) on a coarse grid of pixel blocks
(``downsample``² film pixels each, one jittered path position anywhere in the block), with a budget
of ``1/ratio`` of the full render's paths. It runs on the full-resolution film, so the Mitsuba
kernels it compiles are the ones the render then reuses (a film of another size would compile its
own: ~1–2 s per group on the LLVM backend). A group is **dark** for the view when
every pilot path returns exactly zero radiance; the job runner then records the cube as empty
(:meth:`store.CubeStore.mark_empty`, reads give zeros) instead of rendering it. A lamp in a closed
box, a spot aimed away from everything the camera sees, a lamp in another room: all exactly dark.

Why exactly zero, and how small a pilot (the threshold, justified by noise)
---------------------------------------------------------------------------
The service rescales every group by an arbitrary intensity (1e-6 … 1e6), so no contribution that is
merely *small* next to other groups is safe to drop; the only loss-free test is "no light at all".
What a finite pilot can miss is light that reaches the view through rare paths. Suppose the full
render (``spp`` paths per pixel) would *measure* a lit region of ``n`` pixels — at least one
non-zero sample per pixel on average (per-pixel SNR ≥ 1), i.e. a per-path hit probability
``q ≥ 1/spp`` there. Pilot paths are spread uniformly over the image (jittered inside each coarse
pixel), so ``spp·n/ratio`` of them land in the region and all miss with probability
``(1 − q)^(spp·n/ratio) ≤ exp(−n/ratio)``. With the default ``ratio = 16``, a measurable lit region
of 48 pixels (7×7) is found with ≥ 95 % probability and one of 160 pixels with ≥ 99.995 %;
anything the pilot can miss is a handful of isolated single-sample fireflies in the full render.
``ProbeResult.detect_region_px`` reports that 95 % region size.

Wavelengths are drawn uniformly over the bands where the group emits (bands with ``Ē_g = 0``
contribute exactly zero, so sampling them could only hide light). The pilot stops at the first
non-zero path: a lit group costs a chunk of about one path per coarse pixel (measured in
``bench/render.py``); only a dark group pays the whole pilot, and it saves ``ratio``× that.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from illumix.renderer_jobs.band_schedule import mix_seed
from illumix.renderer_jobs.mitsuba.render import RenderSettings, emitter_passes, group_list
from illumix.renderer_jobs.mitsuba.scene_dict import group_emission
from illumix.renderer_jobs.mitsuba.trace import Tracer
from illumix.scene.model import Scene
from illumix.scene.schema import SceneError

PROBE_DOWNSAMPLE = 4  # pilot blocks are PROBE_DOWNSAMPLE × PROBE_DOWNSAMPLE film pixels


@dataclass(frozen=True)
class ProbeResult:
    """Outcome of :func:`probe_group`. ``lit``: some pilot path carried light into the view.
    ``paths``: pilot paths traced (of ``budget``); ``film``: the pilot's grid of pixel blocks
    ``(w, h)``; ``seconds``: wall time; ``detect_region_px``: size in full-resolution pixels of the
    smallest measurable lit region the pilot finds with ≥ 95 % probability (``3 · ratio``, module
    docstring)."""

    lit: bool
    paths: int
    budget: int
    ratio: int
    film: tuple[int, int]
    seconds: float
    detect_region_px: float

    def to_dict(self) -> dict:
        d = asdict(self)
        d["film"] = list(self.film)
        return d


def _emitting_bands(scene: Scene, groups: list[str]) -> np.ndarray:
    on = np.zeros(scene.spectral_grid.n_bands, dtype=bool)
    for g in groups:
        on |= np.asarray(group_emission(scene, g)[0]) > 0
    return np.flatnonzero(on)


def probe_group(scene: Scene, view: str, group: str | list[str] | None,
                settings: RenderSettings = RenderSettings(), *, ratio: int | None = None,
                downsample: int = PROBE_DOWNSAMPLE) -> ProbeResult:
    """Does ``group`` send any light into ``view``? A pilot of ``1/ratio`` (default
    ``settings.probe_ratio``) of the paths the cube ``render_cube(scene, view, group, settings)``
    would trace, stopping at the first non-zero one (module docstring). Deterministic for a given
    ``settings.seed``."""
    ratio = settings.probe_ratio if ratio is None else ratio
    if ratio < 1 or downsample < 1:
        raise SceneError("probe ratio and downsample must be >= 1")
    t0 = time.perf_counter()
    groups = group_list(scene, group)
    v = scene.view(view)
    w, h = settings.resolution or v.resolution
    film = (max(1, math.ceil(w / downsample)), max(1, math.ceil(h / downsample)))
    npix = film[0] * film[1]
    budget = max(npix, math.ceil(w * h * settings.spp / ratio))
    total_spp = math.ceil(budget / npix)

    def result(lit: bool, paths: int) -> ProbeResult:
        return ProbeResult(lit=lit, paths=paths, budget=budget, ratio=ratio, film=film,
                           seconds=round(time.perf_counter() - t0, 4), detect_region_px=3.0 * ratio)

    bands = _emitting_bands(scene, groups)
    if bands.size == 0:
        return result(False, 0)  # nothing emits (scene validation forbids it; kept for safety)
    # The pilot traces on the full-resolution film (the render's Mitsuba kernels, compiled once for
    # both): coarse pixel (bx, by) is the block of downsample² film pixels at its corner pixel.
    tracers = [Tracer(scene, view, groups, (w, h), portals=p) for p in emitter_passes(scene, groups)]
    bx, by = np.meshgrid(np.arange(film[0]) * downsample, np.arange(film[1]) * downsample)
    corner = (by * w + bx).ravel().astype(np.int64)
    extent = np.stack([np.minimum(downsample, w - bx).ravel(), np.minimum(downsample, h - by).ravel()], axis=1)
    grid = scene.spectral_grid
    guard = min(1e-3, grid.step / 10)
    per_pass_max = max(1, settings.max_lanes // npix)
    done, chunk, k, paths = 0, 1, 0, 0
    while done < total_spp:
        spp_k = min(chunk, total_spp - done, per_pass_max)
        rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, k, 0x9B0E])
        block = np.repeat(np.arange(npix, dtype=np.int64), spp_k)
        pix = corner[block]
        jitter = (rng.random((len(pix), 2)) * extent[block]).astype(np.float32)
        band = bands[rng.integers(0, bands.size, size=(len(pix), 4))]
        lam = (grid.edges[0] + grid.step * band + guard + (grid.step - 2 * guard) * rng.random((len(pix), 4)))
        lam = lam.astype(np.float32)
        for c, a in enumerate(range(0, len(pix), settings.max_lanes)):  # films wider than max_lanes
            part = slice(a, a + settings.max_lanes)
            paths += len(pix[part])
            for j, tracer in enumerate(tracers):
                L = tracer.trace(pix[part], jitter[part], lam[part],
                                 seed=mix_seed(settings.seed, 0x9B0E, k, j, c))
                if np.any(np.isfinite(L) & (L > 0)):
                    return result(True, paths)
        done += spp_k
        chunk *= 2
        k += 1
    return result(False, paths)
