"""The filters behind :func:`retarget.denoise.denoise` (the methods and why they stay linear are
described in :mod:`retarget.denoise`): the domain transform with a guide-only joint image
(``dt-guides``, ``dt-irradiance``) and the edge-avoiding à-trous wavelet with guide-only weights
(``atrous-guides``). Each takes the cube and a :class:`retarget.denoise.Guides` and reads only the
guides to set its weights.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from illumix.retarget.denoise_classes import DIRECT_ROUNDS, direct_test, irradiance_classes, isolate
from illumix.retarget.denoise_shading import shading

if TYPE_CHECKING:
    from illumix.retarget.denoise import Guides


#: Normal axis the DT guide projects onto: oblique, so the six axis-aligned normals of a room (and
#: most others) map to distinct values.
_NORMAL_AXIS = np.array([0.53, 0.71, 0.46]) / np.linalg.norm([0.53, 0.71, 0.46])
_FAR = 1e4  # guide offset separating emitter / background pixels from surfaces


# ---------------------------------------------------------------------------------------------
# Domain transform with a guide-only joint image


def dt_guide_image(guides: Guides, sigma_albedo: float, sigma_normal: float) -> np.ndarray:
    """The DT filter's joint image ``(H, W, 4)`` float32 (OpenCV's limit is 4 channels)."""
    g = np.empty((*guides.shape, 4), np.float32)
    g[..., :3] = guides.albedo / sigma_albedo
    g[..., 3] = (guides.normal @ _NORMAL_AXIS) / sigma_normal
    g[..., 3] += _FAR * guides.pixel_class()
    return g


def _dt(cube: np.ndarray, guides: Guides, *, sigma_spatial: float = 4.0, sigma_albedo: float = 0.05,
        sigma_normal: float = 0.2, iterations: int = 3) -> np.ndarray:
    return dt_filter(cube, dt_guide_image(guides, sigma_albedo, sigma_normal), sigma_spatial, iterations)


def irradiance_guide_image(guides: Guides, sigma_normal: float, sigma_depth: float, sigma_direct: float,
                           albedo_floor: float = 0.01, kind: str = "transport", *, sigma_spatial: float = 4.0,
                           iterations: int = 3) -> np.ndarray:
    """``dt-irradiance``'s joint image ``(H, W, 3)`` float32 for a ``kind`` of cube: the normal's
    component along a fixed axis with the classes of :func:`irradiance_classes` pushed apart,
    ``log depth`` (a relative step) and ``log(direct + 10⁻³·max)`` (a shadow edge is a step in it),
    each over its sigma. Then, for up to ``DIRECT_ROUNDS`` rounds, the filter (``sigma_spatial``,
    ``iterations``) is applied to the direct-light guide itself and the pixels it would move
    (:func:`retarget.denoise_classes.direct_test`) are left as rendered: a guide-only test, so the
    filter stays linear in the cube."""
    g = np.empty((*guides.shape, 3), np.float32)
    classes = irradiance_classes(guides, albedo_floor, kind)
    axis = (guides.normal @ _NORMAL_AXIS) / sigma_normal
    g[..., 0] = axis + _FAR * classes
    g[..., 1] = np.log(np.maximum(guides.depth, 1e-3)) / sigma_depth
    d = guides.direct
    g[..., 2] = np.log(np.maximum(d, 0.0) + 1e-3 * max(float(d.max()), 1e-30)) / sigma_direct
    free = classes < 4  # pixels the filter may still average
    shade = shading(guides, kind)[..., 0]
    # the light the filter must keep: in a transport cube as the camera sees it (a highlight included)
    light = guides.direct_seen if kind == "transport" and guides.direct_seen is not None else d
    for _ in range(DIRECT_ROUNDS):
        moved = free & direct_test(guides, dt_filter((light / shade)[..., None], g, sigma_spatial, iterations)[..., 0]
                                   * shade, None if light is d else light)
        if not moved.any():
            break
        isolate(classes, moved)
        free &= ~moved
        g[..., 0] = axis + _FAR * classes
    return g


def _dt_irradiance(cube: np.ndarray, guides: Guides, *, kind: str, sigma_spatial: float = 4.0,
                   sigma_normal: float = 0.05, sigma_depth: float = 0.04, sigma_direct: float = 0.4,
                   albedo_floor: float = 0.01, iterations: int = 3) -> np.ndarray:
    """Filter ``cube / ρ`` (transport) or ``cube`` (illumination), then multiply ``ρ`` back;
    ``ρ = max(albedo_bands, albedo_floor)`` (the floor keeps metal and glass, with no diffuse
    reflectance, from dividing by zero: any fixed positive ρ keeps the filter linear; the joint
    image leaves them as rendered, so their ``cube / ρ`` never mixes with another pixel's)."""
    joint = irradiance_guide_image(guides, sigma_normal, sigma_depth, sigma_direct, albedo_floor, kind,
                                   sigma_spatial=sigma_spatial, iterations=iterations)
    mod = shading(guides, kind)
    if kind == "transport":
        mod = mod * np.maximum(guides.albedo_bands, np.float32(albedo_floor))
    out = dt_filter(cube / mod, joint, sigma_spatial, iterations) * mod
    return keep_frame_sum(cube, out, mod, joint[..., 0] < 3.5 * _FAR, sigma_spatial)


def keep_frame_sum(cube: np.ndarray, out: np.ndarray, mod: np.ndarray, free: np.ndarray,
                   radius: float = 4.0) -> np.ndarray:
    """``out`` (the filtered ``cube``, both ``(H, W, C)``) with each channel's frame sum restored,
    in place, near where it was lost: each filtered pixel's deficit ``d = cube − out`` is handed back
    to the filtered pixels (``free (H, W)``) around it, in proportion to ``mod`` (what was divided
    out before filtering, ``(H, W, 1 or C)``) times a Gaussian of ``radius`` pixels (the filter's
    own ``sigma_spatial``).

    A normalised filter ``F`` is row-stochastic (a flat image stays flat) but its columns do not sum
    to 1 where it stops (a border, a class edge, a pixel left as rendered), so it moves light between
    pixels of different ``mod`` and changes the frame's sum (room-4242's floor lamp +0.42 %:
    bench/FIDELITY.md). The correction is ``out + w · K(d / K w)`` with ``w = mod · free`` and ``K``
    the Gaussian with zero borders, a symmetric matrix: ``Σ w · K(d / K w) = Σ d``, so every channel's
    frame sum is kept exactly. It is a fixed linear map of ``d``, set by the guides alone, so the
    result stays linear in the cube (relighting and composition exact); a flat ``cube / mod`` gives
    ``d = 0`` and stays flat; pixels left as rendered are untouched. (Handing the deficit back over
    the whole frame instead moved light far from where the filter lost it: two-lamps-640's dim
    ambient group, 87 % of it left as rendered, 0.21 → 0.23 % biased pixels.)"""
    from scipy.ndimage import gaussian_filter  # noqa: PLC0415 - only the filter needs it

    def blur(a: np.ndarray) -> np.ndarray:
        return gaussian_filter(a, sigma=(radius, radius, 0), mode="constant", cval=0.0, truncate=3.0)

    w = (mod * free[..., None]).astype(np.float32)
    d = np.where(free[..., None], cube - out, np.float32(0.0)).astype(np.float32)
    kw = blur(w)  # (H, W, 1) when mod is one channel: broadcast over the bands below
    q = np.divide(d, kw, out=np.zeros_like(d), where=kw > 0)
    out += w * blur(q)
    return out


def dt_filter(cube: np.ndarray, joint: np.ndarray, sigma_spatial: float, iterations: int = 3) -> np.ndarray:
    """OpenCV's domain-transform RF filter of ``cube (H, W, C)`` with the joint image ``joint``
    (already divided by its sigmas, so sigmaColor is 1), 4 channels per call (OpenCV's limit)."""
    import cv2  # noqa: PLC0415 - heavy; only the filters need it

    out = np.empty(cube.shape, np.float32)
    for k in range(0, cube.shape[-1], 4):  # dtFilter takes at most 4 source channels
        src = np.ascontiguousarray(cube[..., k:k + 4], dtype=np.float32)
        res = cv2.ximgproc.dtFilter(joint, src, sigmaSpatial=float(sigma_spatial), sigmaColor=1.0,
                                    mode=cv2.ximgproc.DTF_RF, numIters=int(iterations))
        out[..., k:k + 4] = res.reshape(src.shape)
    return out


# ---------------------------------------------------------------------------------------------
# Edge-avoiding à-trous with guide-only weights

_B3 = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0  # B3-spline taps of each level


def _shifted(a: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """``out[y, x] = a[clamp(y + dy), clamp(x + dx)]`` (edge replicated)."""
    h, w = a.shape[:2]
    ys = np.clip(np.arange(h) + dy, 0, h - 1)
    xs = np.clip(np.arange(w) + dx, 0, w - 1)
    return a[ys][:, xs]


def atrous_weights(guides: Guides, levels: int, sigma_albedo: float, sigma_normal: float,
                   sigma_depth: float) -> list[np.ndarray]:
    """Per level, the normalised tap weights ``(25, H, W)`` float32 (Dammertz et al. 2010, eq. 4–6
    without the colour term): ``h(tap) · exp(−|Δalbedo|²/2σa²) · exp(−max(0, 1 − n·n')/σn) ·
    exp(−|Δz|/(z σz))``, zero between pixel classes."""
    cls = guides.pixel_class()
    z = np.maximum(guides.depth, 1e-3)
    out = []
    for level in range(levels):
        s = 1 << level
        taps = []
        for i, dy in enumerate(range(-2, 3)):
            for j, dx in enumerate(range(-2, 3)):
                da = np.sum((_shifted(guides.albedo, dy * s, dx * s) - guides.albedo) ** 2, axis=-1)
                dn = np.maximum(0.0, 1.0 - np.sum(_shifted(guides.normal, dy * s, dx * s) * guides.normal, axis=-1))
                dz = np.abs(_shifted(guides.depth, dy * s, dx * s) - guides.depth) / z
                w = _B3[i] * _B3[j] * np.exp(-da / (2 * sigma_albedo ** 2) - dn / sigma_normal - dz / sigma_depth)
                taps.append(np.where(_shifted(cls, dy * s, dx * s) == cls, w, 0.0))
        t = np.stack(taps)
        out.append((t / t.sum(axis=0, keepdims=True)).astype(np.float32))  # the centre tap keeps it > 0
    return out


def _atrous(cube: np.ndarray, guides: Guides, *, levels: int = 3, sigma_albedo: float = 0.02,
            sigma_normal: float = 0.05, sigma_depth: float = 0.02) -> np.ndarray:
    img = np.asarray(cube, np.float32)
    for level, taps in enumerate(atrous_weights(guides, levels, sigma_albedo, sigma_normal, sigma_depth)):
        s = 1 << level
        acc = np.zeros(img.shape, np.float32)
        t = 0
        for dy in range(-2, 3):
            for dx in range(-2, 3):
                acc += taps[t][..., None] * _shifted(img, dy * s, dx * s)
                t += 1
        img = acc
    return img
