"""What ``dt-irradiance`` divides out before it filters, and the noise it weighs its bias against.

Both are per-pixel quantities fixed before the cube's values are read — the group's direct-light
guide, and the cube's noise *level* pooled from the renderer's band sets (whose spread is
independent of their mean) — so the filter stays a linear operator on the cube, one for every
band: relighting and composition stay exact (``retarget.denoise``). Measured in
``bench/FIDELITY.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from illumix.retarget.denoise import Guides


#: ``shading``'s floor, as a share of the direct-light guide's mean over the surface: it stands in
#: for the bounce light the guide does not show (bench/FIDELITY.md).
SHADE_FLOOR = 0.25


def shading(guides: Guides, kind: str = "transport") -> np.ndarray:
    """``(H, W, 1)`` float32 > 0: the light ``dt-irradiance`` divides out before it filters (and
    multiplies back after), ``L + SHADE_FLOOR · mean G``: ``G`` the group's direct-light guide (the
    mean over the surface pixels), ``L`` the same light as the camera sees it through each
    surface's BSDF per unit diffuse reflectance (``guides.direct_seen``: a glossy highlight
    included) for a ``"transport"`` cube, ``G`` itself for an ``"illumination"`` cube (a white
    Lambertian surface) or when the guides lack it. Where the direct light dominates, what is
    filtered is then nearly flat — a spot's falloff, a point light's ``cos/r²``, a sun's highlight
    on a glossy floor — so averaging it is unbiased to first order (dividing by the albedo alone
    left those ramps in, and the filter bent them at every border it stops at). A fixed per-pixel
    factor from the guides: the filter stays linear."""
    g = guides.direct
    surface = guides.hit & ~guides.emitter
    mean = float(g[surface].mean()) if surface.any() else 0.0
    if not mean > 0:
        return np.ones((*guides.shape, 1), np.float32)
    light = guides.direct_seen if kind == "transport" and guides.direct_seen is not None else g
    return (np.maximum(light, 0.0) + np.float32(SHADE_FLOOR * mean))[..., None].astype(np.float32)


#: The window (pixels, square side 2r+1) over which a cube's noise is pooled: the band sets give
#: each pixel's variance from a few degrees of freedom (3 with the default 4 sets), 25 pixels 75.
NOISE_RADIUS = 2


def relative_noise(total: np.ndarray, var: np.ndarray, radius: int = NOISE_RADIUS) -> np.ndarray:
    """``(H, W)`` float32: ``√(mean var) / mean |total|`` over each pixel's (2r+1)² window — the
    relative noise of a cube's band sum, pooled (the windows' means are OpenCV box filters)."""
    import cv2  # noqa: PLC0415 - heavy; only the filters need it

    k = (2 * radius + 1, 2 * radius + 1)
    v = cv2.blur(np.maximum(var, 0).astype(np.float32), k, borderType=cv2.BORDER_REPLICATE)
    t = cv2.blur(np.abs(total).astype(np.float32), k, borderType=cv2.BORDER_REPLICATE)
    floor = np.float32(1e-6 * max(float(t.max()), 1e-30))
    return (np.sqrt(v) / np.maximum(t, floor)).astype(np.float32)


__all__ = ["NOISE_RADIUS", "SHADE_FLOOR", "relative_noise", "shading"]
