"""The guides of ``dt-irradiance`` (:mod:`retarget.denoise`) that only the renderer can make.

- **Per-band albedo** (the ``albedo_bands`` AOV, ``(H, W, bands)``): the first hit's diffuse
  reflectance at every band centre (Mitsuba's ``eval_diffuse_reflectance``; step spectra are exact
  there), averaged over a Hammersley set of sub-pixel positions. No wavelength is sampled, so it
  carries no colour noise; the positions stratify both axes, so a pixel that straddles two materials
  gets its coverage to 1/rays (a regular n×n grid quantises an axis-aligned edge to 1/n, and the
  remodulated cube inherits that error: bench/DENOISE.md).
- **Direct light of one group** (``(H, W)``): the mean of next-event samples of the light a white
  Lambertian surface at the first hit receives straight from the group's emitters, with visibility
  (:meth:`renderer_jobs.mitsuba.trace.Tracer.direct_irradiance`). Shadows and sunlit patches are
  sharp steps in it, and a few dozen shadow rays per pixel make it nearly noise-free, at a small
  fraction of the cube's cost. It is traced with its own seed, so its noise is independent of the
  cube's (the filter's weights never follow the cube's noise).
- **Behind glass** (``(H, W)``, same samples): the light those shadow rays would bring if the glass
  (dielectrics) blocking them were not there, crossed in a straight line. Glass focuses light (a
  caustic) where the direct guide shows its shadow; ``dt-irradiance`` averages nothing there
  (:func:`retarget.denoise_classes.irradiance_classes`), and the targeted extra paths go there instead.
- **Straddle** (the ``straddle`` AOV, ``(H, W)`` bool): the pixel's sub-pixel rays hit more than one
  surface (two of them with normals more than 20° apart, or one more than 5 % of its depth off the
  other's tangent plane, or some rays miss). Its light
  is then a mix of two surfaces' that no neighbour has, and its averaged normal and depth look like
  neither side's, or like the side with the larger share: ``dt-irradiance`` leaves it as rendered
  (bench/DENOISE.md measures what that bought). Used only with the targeted extra paths
  (:func:`uses_straddle`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from illumix.renderer_jobs.band_schedule import group_seed, mix_seed
from illumix.renderer_jobs.mitsuba.trace import Tracer
from illumix.scene.model import Scene

ALBEDO_RAYS = 64  # sub-pixel positions of the albedo_bands AOV (coverage to 1/64 at a material edge)
DIRECT_SAMPLES = 64  # next-event samples per pixel of the direct-light guide
STRADDLE_RAYS = 16  # sub-pixel positions of the straddle AOV (finds a second surface covering >= ~1/16)
STRADDLE_COS = 0.94  # two hits whose normals are more than 20° apart are on different surfaces
STRADDLE_LOG_DEPTH = 0.05  # ... and so are two off each other's tangent plane by more than 5 % of the depth
#: a pixel whose hits all lie within these of the first hit's plane and normal skips the pairwise test
FLAT_LOG_DEPTH, FLAT_DEGREES = 0.01, 2.0
_CHUNK = 1 << 20  # rays per Dr.Jit batch (bounds memory at any resolution)
_DIRECT_SEED = 0xD1EC7  # mixed with the render's seed: the guide's random numbers are its own


def guides_needed(settings) -> tuple[str, ...]:
    """The guides ``settings`` (a :class:`RenderSettings`) denoise with: those its ``denoise``
    method reads (none for ``None``), less ``straddle`` without the targeted extra paths
    (:func:`uses_straddle`)."""
    from illumix.retarget.denoise import method_guides

    names = () if settings.denoise is None else method_guides(settings.denoise)
    return tuple(n for n in names if n != "straddle" or uses_straddle(settings))


def uses_straddle(settings) -> bool:
    """The ``straddle`` AOV is used only when the targeted extra paths are on
    (``settings.boost_factor > 1``): the pixels it leaves as rendered have the filter's largest
    reach, so the extra paths go there; without them they keep the spp's noise, which costs more
    than their bias (``front`` p99.3 3.05 → 3.50 % at 64 spp, bench/DENOISE.md)."""
    return settings.denoise is not None and settings.boost_factor > 1


def hammersley(n: int) -> np.ndarray:
    """``(n, 2)`` float32 sub-pixel positions: x = (i + ½)/n, y = the base-2 radical inverse of i
    (+ ½/n): one point in each of n columns and in each of n rows."""
    i = np.arange(n, dtype=np.uint64)
    y = np.zeros(n)
    f, j = 0.5, i.copy()
    while j.any():
        y += f * (j & np.uint64(1))
        j >>= np.uint64(1)
        f *= 0.5
    return np.stack([(np.arange(n) + 0.5) / n, (y + 0.5 / n) % 1.0], -1).astype(np.float32)


def _per_pixel(tracer: Tracer, rays: int, fn: Callable[[np.ndarray, np.ndarray], np.ndarray],
               pixels: np.ndarray | None = None) -> np.ndarray:
    """``fn(pix, jitter) → (n, C)`` over ``rays`` Hammersley positions per pixel, in batches;
    the per-pixel mean ``(H, W, C)`` float32 (``pixels``: only these flat indices, the others 0)."""
    npix = tracer.width * tracer.height
    todo = np.arange(npix) if pixels is None else np.asarray(pixels, np.int64)
    jit = hammersley(rays)
    per = max(1, _CHUNK // rays)
    out = None
    for start in range(0, len(todo), per):
        p = todo[start:start + per]
        vals = fn(np.repeat(p, rays), np.tile(jit, (len(p), 1)))
        if out is None:
            out = np.zeros((npix, vals.shape[1]), np.float32)
        out[p] = vals.reshape(len(p), rays, -1).mean(axis=1)
    return out.reshape(tracer.height, tracer.width, -1)


def albedo_bands(tracer: Tracer, rays: int = ALBEDO_RAYS) -> np.ndarray:
    """The ``albedo_bands`` AOV ``(H, W, bands)`` float32 of the tracer's view (module docstring)."""
    lam = tracer.grid.wavelengths
    return _per_pixel(tracer, rays, lambda pix, jit: tracer.spectral_albedo(pix, jit, lam))


def straddle(tracer: Tracer, rays: int = STRADDLE_RAYS) -> np.ndarray:
    """The ``straddle`` AOV ``(H, W)`` bool of the tracer's view (module docstring): a pixel whose
    ``rays`` Hammersley positions' first hits are not all on one surface. Every pair of hits is
    compared, so a half-and-half pixel is found as surely as a sliver: some rays miss; or two
    normals are further apart than :data:`STRADDLE_COS` (a crease); or a hit lies off the plane
    of another — its depth differs by more than :data:`STRADDLE_LOG_DEPTH` from where its ray
    meets the other hit's tangent plane (one surface in front of another; a plane seen at a
    grazing angle spans a range of depths in one pixel, but all on that plane). Pixels whose hits
    all lie on the first hit's plane, with its normal (:data:`FLAT_LOG_DEPTH`, :data:`FLAT_DEGREES`), pass
    without the pairwise test: most pixels (at 960×720 the AOV took 16 s CPU with it everywhere,
    7 s now, nearly all of it tracing)."""
    lam = np.float32([450.0, 550.0, 650.0, 550.0])  # geometry only: any wavelengths
    jit = hammersley(rays)
    npix = tracer.width * tracer.height
    out = np.zeros(npix, bool)
    per = max(1, _CHUNK // rays)
    for start in range(0, npix, per):
        p = np.arange(start, min(npix, start + per))
        h = tracer.first_hit(np.repeat(p, rays), np.tile(jit, (len(p), 1)), np.tile(lam, (len(p) * rays, 1)),
                             rays=True)
        hit = h["hit"].reshape(len(p), rays)
        geo = (h["normal"].reshape(len(p), rays, 3).astype(np.float64),
               *(h[k].reshape(len(p), rays, 3).astype(np.float64) for k in ("origin", "direction")),
               h["distance"].reshape(len(p), rays).astype(np.float64))
        full = hit.all(axis=1)
        flat = np.zeros(len(p), bool)
        flat[full] = _on_first_plane(*(g[full] for g in geo))
        check = np.flatnonzero(full & ~flat)
        for c in range(0, len(check), max(1, _CHUNK // (rays * rays))):  # pairwise: rays² per pixel
            sub = check[c:c + max(1, _CHUNK // (rays * rays))]
            out[p[sub]] = _two_surfaces(*(g[sub] for g in geo))
        out[p] |= hit.any(axis=1) & ~full  # some rays miss
    return out.reshape(tracer.height, tracer.width)


def _plane_depths(n: np.ndarray, o: np.ndarray, d: np.ndarray, t: np.ndarray, k: slice) -> np.ndarray:
    """``(P, K, R)``: where ray j meets hit k's tangent plane, ``n_k·(o_k + t_k d_k − o_j) / (n_k·d_j)``
    (inf/NaN where ray j runs along the plane: no verdict)."""
    nk = n[:, k]
    num = np.einsum("pkc,pkc->pk", nk, o[:, k] + t[:, k, None] * d[:, k])[:, :, None] - np.einsum("pkc,pjc->pkj", nk, o)
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / np.einsum("pkc,pjc->pkj", nk, d)


def _off_plane(t: np.ndarray, on_plane: np.ndarray, tol: float) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.isfinite(on_plane) & (on_plane > 0) & (np.abs(np.log(t[:, None, :] / on_plane)) > tol)


def _on_first_plane(n, o, d, t) -> np.ndarray:
    """``(P,)``: every hit of the pixel (all hit) on the first hit's plane and facing its way."""
    near = np.einsum("pjc,pc->pj", n, n[:, 0]) >= np.cos(np.radians(FLAT_DEGREES))
    return near.all(axis=1) & ~_off_plane(t, _plane_depths(n, o, d, t, slice(0, 1)), FLAT_LOG_DEPTH).any(axis=(1, 2))


def _two_surfaces(n, o, d, t) -> np.ndarray:
    """``(P,)``: the pixel's hits (all hit) are on two surfaces (:func:`straddle`'s pairwise test)."""
    crease = np.einsum("pkc,pjc->pkj", n, n) < STRADDLE_COS
    off = _off_plane(t, _plane_depths(n, o, d, t, slice(None)), STRADDLE_LOG_DEPTH)
    return crease.any(axis=(1, 2)) | off.any(axis=(1, 2))


def guide_wavelengths(emission: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
    """Four band centres (nm) at the 1/8, 3/8, 5/8 and 7/8 quantiles of a group's emission over the
    bands: the guide sees the light where the group emits (a narrow-band group too)."""
    e = np.clip(np.nan_to_num(np.asarray(emission, np.float64)), 0.0, None)
    if e.sum() <= 0:
        e = np.ones_like(e)
    cdf = np.cumsum(e) / e.sum()
    idx = np.searchsorted(cdf, [0.125, 0.375, 0.625, 0.875])
    return np.asarray(wavelengths, np.float64)[np.minimum(idx, len(e) - 1)]


@dataclass(frozen=True)
class DirectGuide:
    """One group's direct-light guide of a view: ``direct`` ``(H, W)`` float32 (:func:`direct_light`),
    ``behind`` the light glass keeps from each pixel (or None), ``noise`` the standard error of
    ``direct`` from its samples' spread (the direct-light test's noise allowance), ``seen`` the same
    light as the camera sees it through each surface's own BSDF, per unit of its diffuse
    reflectance, over the pixel's surface hits (``direct`` on a Lambertian surface; a glossy
    highlight on top elsewhere; 0 where the surface has no diffuse reflectance)."""

    direct: np.ndarray
    behind: np.ndarray | None
    noise: np.ndarray
    seen: np.ndarray | None = None


SEEN_ALBEDO_MIN = 0.01  # below this diffuse reflectance (metal, glass) ``seen`` is 0: left as rendered anyway
NOISE_GOAL = 0.01  # the guide's relative standard error it aims under, with ...
MORE_PAIRS = 12  # ... this many more pairs of light samples per position where it is above (13× the samples there)


def direct_guide(scene: Scene, view: str, group: str, resolution, seed: int, samples: int = DIRECT_SAMPLES,
                 behind_glass: bool = False) -> DirectGuide:
    """The direct-light guide ``(H, W)`` float32 of ``group`` in ``view`` (module docstring): the
    mean over four wavelengths (:func:`guide_wavelengths`), ``samples`` sub-pixel positions and two
    light samples at each, with its standard error (from the two light samples' differences) and
    the light as the camera sees it (:class:`DirectGuide`). ``behind_glass``: also the light the
    same samples' shadow rays would bring if the dielectrics (glass) that block them were not there
    — where glass may focus or bend the group's light (a caustic) that the first image shows as
    shadow."""
    from illumix.renderer_jobs.mitsuba.scene_dict import group_emission
    from illumix.retarget.denoise_classes import DIRECT_FLOOR  # the direct-light test's scale, for the same light

    tracer = Tracer(scene, view, [group], resolution)
    seed = group_seed(seed, [group])  # as the cube's: each group's guide its own light samples
    lam = guide_wavelengths(group_emission(scene, group)[0], tracer.grid.wavelengths).astype(np.float32)

    def light_samples(pairs: int, first: int):
        def one(pix, jit):  # a batch's seed: its first pixel; 2 × pairs light samples per position
            outs = [tracer.direct_irradiance(pix, jit, np.tile(lam, (len(pix), 1)),
                                             mix_seed(seed, _DIRECT_SEED ^ k, int(pix[0])),
                                             behind_dielectric=behind_glass, seen=True)
                    for k in range(first, first + 2 * pairs)]
            d = [o[0].mean(axis=1).astype(np.float64) for o in outs]
            cols = [np.mean(d, axis=0), np.mean([(d[2 * j] - d[2 * j + 1]) ** 2 for j in range(pairs)], axis=0),
                    np.mean([o[-2].mean(axis=1) for o in outs], axis=0), outs[0][-1].mean(axis=1)]
            if behind_glass:
                cols.append(np.mean([o[1].mean(axis=1) for o in outs], axis=0))
            return np.stack(cols, -1)
        return one

    img = _per_pixel(tracer, samples, light_samples(1, 0)).astype(np.float64)
    # the spread of the light samples at each position: the light sampling's error alone (the
    # positions are stratified, so at a shadow edge their spread is coverage, not noise)
    var = np.maximum(img[..., 1], 0.0) / (4 * samples)
    # where that error is above NOISE_GOAL of the light there, MORE_PAIRS more pairs per position
    # (an area light's guide; a delta light's has none): the direct-light test leaves as rendered
    # the pixels where the guide is noisier than the cube, and they would lose their denoising
    surface = img[..., 3] > 0
    scale = img[..., 0] + DIRECT_FLOOR * (float(img[..., 0][surface].mean()) if surface.any() else 0.0)
    noisy = np.flatnonzero(surface & (np.sqrt(var) > NOISE_GOAL * scale))
    if noisy.size:
        more = _per_pixel(tracer, samples, light_samples(MORE_PAIRS, 2), noisy).astype(np.float64)
        w = MORE_PAIRS / (1 + MORE_PAIRS)  # each light sample weighs the same
        flat, mflat = img.reshape(-1, img.shape[-1]), more.reshape(-1, more.shape[-1])
        v2 = np.maximum(mflat[noisy, 1], 0.0) / (4 * MORE_PAIRS * samples)
        var.reshape(-1)[noisy] = (1 - w) ** 2 * var.reshape(-1)[noisy] + w ** 2 * v2
        cols = [0, 2] + ([4] if behind_glass else [])
        flat[np.ix_(noisy, cols)] = (1 - w) * flat[np.ix_(noisy, cols)] + w * mflat[np.ix_(noisy, cols)]
    albedo = img[..., 3]
    seen = np.divide(img[..., 2], albedo, out=np.zeros_like(albedo), where=albedo >= SEEN_ALBEDO_MIN)
    return DirectGuide(img[..., 0].astype(np.float32), img[..., 4].astype(np.float32) if behind_glass else None,
                       np.sqrt(var).astype(np.float32), np.maximum(seen, 0.0).astype(np.float32))


def direct_light(scene: Scene, view: str, group: str, resolution, seed: int,
                 samples: int = DIRECT_SAMPLES, behind_glass: bool = False):
    """:func:`direct_guide`'s image alone ``(H, W)``, or ``(direct, behind)`` with ``behind_glass``."""
    g = direct_guide(scene, view, group, resolution, seed, samples, behind_glass)
    return (g.direct, g.behind) if behind_glass else g.direct


__all__ = ["ALBEDO_RAYS", "DIRECT_SAMPLES", "STRADDLE_RAYS", "DirectGuide", "albedo_bands", "direct_guide",
           "direct_light", "guide_wavelengths",
           "guides_needed", "hammersley", "straddle", "uses_straddle"]
