"""Which pixels ``dt-irradiance`` may average together: the class codes of its joint image.

A guide-only linear filter is biased wherever the light changes in a way no guide shows; the
pixels where that is known to happen get codes none of their neighbours has, so the filter leaves
them as rendered (their reach is then ~1, and the targeted extra paths of
:mod:`renderer_jobs.mitsuba.boost_paths` give them more paths). Every rule reads the guides alone, never
the cube, so the filter stays linear and the extra paths' placement unbiased. The rules and what
each bought are measured in ``bench/DENOISE.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from illumix.retarget.errors import SpectralError

if TYPE_CHECKING:
    from illumix.retarget.denoise import Guides

#: Surface pixels this close (pixels, chessboard distance) to an emitter pixel get codes of their own in
#: ``dt-irradiance``'s joint image: a lamp's edge spills light over two pixels (bench/DENOISE.md).
LAMP_RING = 2
#: A surface pixel whose group's direct light is blocked by glass alone for more than this share,
#: and its neighbours within GLASS_MARGIN pixels, get codes of their own: a caustic may lie there.
GLASS_SHARE = 0.05
GLASS_MARGIN = 1
#: ... unless glass shades more than this share of the surface pixels: then it encloses the light (a
#: bulb's envelope, a lamp cover, a glazed window) rather than throwing a caustic somewhere, and
#: leaving that much as rendered (and tracing it with the targeted paths' 8× the spp) would not pay
GLASS_MAX_COVER = 0.25
#: The direct-light test (:func:`direct_test`): a surface pixel is left as rendered when the filter,
#: applied to the group's own direct-light guide ``G``, moves it by more than ``tolerance × (G +
#: DIRECT_FLOOR × mean G)``: it would move the cube's direct light there as much (a spot cone's rim,
#: a hard shadow's edge, a sun patch). ``DIRECT_FLOOR × mean G`` stands in for the light the guide
#: does not show (bounce light), so a leak into a shadow counts against the light there. With the
#: cube's own noise known (``Guides.cube_noise``, relative), the tolerance is ``BIAS_SHARE`` of it,
#: within ``TOLERANCE_RANGE``: a bias under the noise it removes; else ``DIRECT_TOLERANCE``, with
#: ``DIRECT_NOISE_Z × σ_G`` added (the guide's own standard error: its noise flags nothing).
#: Set from what they mean (a bias under 1σ; a tenth of the mean direct light for bounce light),
#: checked on the suite's two small scenes, measured on the held-out corpus (bench/FIDELITY.md).
DIRECT_TOLERANCE = 0.02
DIRECT_FLOOR = 0.1
DIRECT_NOISE_Z = 3.0
BIAS_SHARE = 1.0
TOLERANCE_RANGE = (0.002, 0.05)
#: ... and, with the cube's noise known, where the guide's own noise exceeds ``GUIDE_NOISE_SHARE``
#: of the cube's: the filter divides the guide's light out and multiplies it back
#: (:func:`retarget.denoise_shading.shading`), so the guide's noise is printed on the result.
GUIDE_NOISE_SHARE = 0.7
#: Rounds of the direct-light test: a pixel left as rendered changes its neighbours' weights.
DIRECT_ROUNDS = 2


def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    """``mask`` grown by ``radius`` pixels (a (2r+1)² square)."""
    import cv2  # noqa: PLC0415 - heavy; only the filters need it

    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def irradiance_classes(guides: Guides, albedo_floor: float, kind: str = "transport") -> np.ndarray:
    """``(H, W)`` float32 class codes of ``dt-irradiance``'s joint image (the filter never averages
    across codes) for a ``kind`` ``"transport"`` or ``"illumination"`` cube: 0 a diffuse surface,
    3 metal and glass in an illumination cube, and 4–8 pixels the filter must leave as rendered,
    each with a code none of its eight neighbours has, so nothing flows in or out:

    - metal and glass (no diffuse reflectance) in a transport cube: what they show is the rest of
      the scene, reflected or refracted, which no guide describes (filtered among themselves, a glass
      ball's refraction was smeared: ``bench/DENOISE.md``). An illumination cube holds the light
      falling on them, as on any surface, which the guides do describe: there they are one class of
      their own (3), since their neighbours' light may differ in kind;
    - next to a background pixel, or within :data:`LAMP_RING` pixels of an emitter pixel: they may
      cover part of a light source or of the sky behind a window (the AOVs flag a pixel by its
      majority, or its centre), whose radiance dwarfs the surface's (a halo around every window and
      lamp otherwise);
    - where glass alone blocks more than :data:`GLASS_SHARE` of the group's direct light
      (``guides.behind_glass``), grown by :data:`GLASS_MARGIN`: the glass may focus light there (a
      caustic) that the direct guide shows as shadow, so no guide shows its edges — unless that is
      more than :data:`GLASS_MAX_COVER` of the surface (glass around the light itself);
    - straddling a geometric edge (``guides.straddle``, when the guides carry it; the renderer
      passes it only with its targeted extra paths): its sub-pixel rays hit two surfaces, so its
      light is a mix of theirs that no neighbour has, and its averaged normal and depth look like
      neither side's, or like the side with the larger share, which it would be averaged with.

    Emitter and background pixels are left as rendered too (codes 4–8): a light seen in frame is a
    radiance the guides do not describe (a lamp's pixels range over 100× from its rim to its
    centre); averaged among themselves they inflated a visible fixture 20× (bench/FIDELITY.md).
    :func:`direct_test` adds the pixels where the filter would move the group's direct light.

    The targeted extra paths (:mod:`renderer_jobs.mitsuba.boost_paths`) then find their reach ~1 and give
    them more paths."""
    if kind not in ("transport", "illumination"):
        raise SpectralError(f"denoise: kind must be 'transport' or 'illumination', got {kind!r}")
    cls = guides.pixel_class().astype(np.float32)
    surface = cls == 0
    near = _dilate(guides.emitter, LAMP_RING) | _dilate(~surface & ~guides.emitter, 1)
    if guides.albedo_bands is not None:
        specular = surface & (guides.albedo_bands.max(axis=-1) < albedo_floor)
        if kind == "transport":
            near |= specular
        else:
            cls[specular] = 3
    if guides.behind_glass is not None:
        shaded = guides.behind_glass > GLASS_SHARE
        if surface.any() and shaded[surface].mean() <= GLASS_MAX_COVER:
            near |= _dilate(shaded, GLASS_MARGIN)
    if guides.straddle is not None:
        near |= guides.straddle
    near &= surface
    return isolate(cls, near | ~surface)


def isolate(cls: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``cls`` with the pixels of ``mask`` given codes 4–8, each unlike all its eight neighbours'
    (the filter leaves them as rendered); in place, returned."""
    y, x = np.indices(cls.shape)
    cls[mask] = 4 + ((x + 2 * y) % 5)[mask]  # 8-neighbours differ by ±1, ±2, ±3 (mod 5): never equal
    return cls


def direct_test(guides: Guides, filtered: np.ndarray, light: np.ndarray | None = None) -> np.ndarray:
    """``(H, W)`` bool: surface pixels where ``filtered`` — the filter applied to the group's
    direct-light guide ``G`` with the joint image it would use for the cube — differs from ``G``
    by more than the tolerance (module constants), or, with the cube's noise known, where the
    guide is noisier than the cube. The filter is linear and the guide's light is the cube's direct
    light up to a factor, so where it cannot keep ``G`` it cannot keep the cube: such a pixel is
    left as rendered. Reads the guides and the cube's pooled noise *level* only, never the cube's
    values: the choice stays independent of the served samples (the band sets' spread is
    independent of their mean), and the filter linear. ``σ_G``: ``guides.direct_noise`` (0 when
    absent). ``light``: the image ``filtered`` was filtered from, when not ``G`` itself (the same
    light as the camera sees it, ``guides.direct_seen``: a glossy highlight the filter would
    smear); the tolerance's scale stays ``G``'s."""
    g = guides.direct if light is None else light
    surface = guides.hit & ~guides.emitter
    lit = guides.direct[surface]
    scale = np.maximum(g, guides.direct) + DIRECT_FLOOR * (float(lit.mean()) if lit.size else 0.0)
    sigma_g = 0.0 if guides.direct_noise is None else guides.direct_noise
    if guides.cube_noise is None:
        moved = np.abs(filtered - g) > DIRECT_TOLERANCE * scale + DIRECT_NOISE_Z * sigma_g
    else:
        tol = np.clip(BIAS_SHARE * guides.cube_noise, *TOLERANCE_RANGE)
        moved = (np.abs(filtered - g) > tol * scale) | (sigma_g > GUIDE_NOISE_SHARE * guides.cube_noise * scale)
    return surface & moved & (scale > 0)


__all__ = ["BIAS_SHARE", "DIRECT_FLOOR", "DIRECT_NOISE_Z", "DIRECT_ROUNDS", "DIRECT_TOLERANCE", "GLASS_MARGIN",
           "GLASS_MAX_COVER", "GLASS_SHARE", "GUIDE_NOISE_SHARE", "LAMP_RING", "TOLERANCE_RANGE", "direct_test",
           "irradiance_classes", "isolate"]
