"""Ground truth for pixel-wise colour constancy (thesis §3.2, eqs. 3.2–3.3; DESIGN.md "Ground truth").

::

    w_{g,k}   = Σ_i C_k(λ_i) Φ̄_g(λ_i) Δλ,  normalised w_{g,G} = 1     sensor white point (eq. 3.2)
    ω_g(x)    = R_{g,G}(x) / Σ_h R_{h,G}(x)                          illuminant weight (eq. 3.3)
    W_k(x)    = Σ_g ω_g(x) · w_{g,k}                                 mixed white point (LSMI map)
    gain_k(x) = max_j W_j(x) / W_k(x)                                white-balance gain (eq. 3.3)
    CCM(x)    = Σ_g ω_g(x) · CCM_g                                   CCM map

Pixels with no light (``Σ_h R_{h,G}`` at most ``rel_eps`` of the frame's brightest pixel) have no
defined weight: they are flagged ``False`` in the validity mask and given the frame-average weights
(the light-weighted mean over valid pixels, or equal weights if the frame is dark), so that every
output stays finite.
"""

from __future__ import annotations

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite

DEFAULT_REL_EPS = 1e-7
# A channel answering less than this fraction of the strongest channel has no meaningful
# white-balance gain (it would exceed 1e10 and, mixed across groups, overflow float32).
MIN_CHANNEL_RATIO = 1e-10


def white_point(sensor_weights: np.ndarray, spd: np.ndarray, what: str = "illuminant") -> np.ndarray:
    """Sensor white point of one illuminant, eq. 3.2: ``(3,)`` float64 with G = 1.

    sensor_weights : ``(n_bands, 3)`` = ``C_k(λ_i) Δλ``; spd : ``(n_bands,)`` band averages.
    """
    rgb = np.asarray(spd, dtype=np.float64) @ np.asarray(sensor_weights, dtype=np.float64)
    if not (np.all(np.isfinite(rgb)) and rgb[1] > 0 and np.all(rgb >= 0)):
        raise SpectralError(f"white point: {what} gives no green response on this sensor "
                            f"(raw {rgb.tolist()}); the illuminant and sensor do not overlap")
    if rgb[0] <= 0 or rgb[2] <= 0:
        ch = "R" if rgb[0] <= 0 else "B"
        raise SpectralError(f"white point: {what} gives zero {ch} response on this sensor; no finite "
                            "white-balance gain exists")
    if rgb.min() < MIN_CHANNEL_RATIO * rgb.max():
        ch = "RGB"[int(np.argmin(rgb))]
        raise SpectralError(f"white point: {what} gives channel {ch} only {rgb.min() / rgb.max():.3g} of "
                            f"the strongest channel's response on this sensor (below "
                            f"{MIN_CHANNEL_RATIO:g}); no meaningful white-balance gain exists")
    return rgb / rgb[1]


def white_points(sensor_weights: np.ndarray, spds: np.ndarray) -> np.ndarray:
    """``(G, 3)`` white points for ``(G, n_bands)`` SPDs."""
    return np.stack([white_point(sensor_weights, s, what=f"illuminant #{g}") for g, s in enumerate(spds)])


def lit_white_points(sensor_weights: np.ndarray, spds: np.ndarray, intensities) -> np.ndarray:
    """``(G, 3)`` :func:`white_points` of the lit groups (intensity > 0) and ones for the others: a
    switched-off group gets no weight anywhere, so its white point is never used, and an illuminant
    the sensor cannot see must not refuse a request that does not light it."""
    spds = np.atleast_2d(spds)
    lit = np.asarray(intensities, dtype=np.float64).reshape(-1) > 0
    wps = np.ones((len(spds), 3))
    for g in np.flatnonzero(lit):  # numbered as the request numbers them, unlit groups included
        wps[g] = white_point(sensor_weights, spds[g], what=f"illuminant #{g}")
    return wps


def illuminant_weights(group_green: np.ndarray, rel_eps: float = DEFAULT_REL_EPS,
                       prior: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Illuminant weights ω (eq. 3.3) and validity mask from per-group green raw.

    group_green : ``(G, H, W)`` ``R_{g,G}`` (negative noise is clipped to 0).
    prior : ``(G,)`` fallback weights when the whole frame is dark (default: equal); callers pass
    the groups' intensities so a switched-off group never gets weight.
    Returns ``(weights (H, W, G) float32 summing to 1, mask (H, W) bool)``.

    Evaluated in float32: a ratio of two float32 sums is exact to a few ulps (measured against
    float64 by ``bench/pareto.py``: gain error ≤ 1e-5°), at half the memory traffic. The frame
    average used where there is no light is accumulated in float64.
    """
    g = np.array(group_green, dtype=np.float32)  # a contiguous copy (the input is a strided view): ours to clip
    np.maximum(g, np.float32(0), out=g)
    n = g.shape[0]
    total = g.sum(axis=0)
    peak = float(total.max()) if total.size else 0.0
    mask = total > max(rel_eps * peak, float(np.finfo(np.float32).tiny))
    everywhere = bool(mask.all())
    if everywhere:
        fallback = None
    elif mask.any():
        lit = float(total[mask].sum(dtype=np.float64))
        fallback = np.array([gi[mask].sum(dtype=np.float64) / lit for gi in g])
    elif prior is not None and np.sum(prior) > 0:
        fallback = np.asarray(prior, dtype=np.float64) / np.sum(prior)
    else:
        fallback = np.full(n, 1.0 / n)
    # a division, not a reciprocal product: one lit group gets exactly 1
    np.divide(g, total if everywhere else np.where(mask, total, np.float32(1)), out=g)
    if not everywhere:
        g[:, ~mask] = fallback.astype(np.float32)[:, None]
    w = np.ascontiguousarray(np.moveaxis(g, 0, -1))
    return w, mask


def mixed_white_point(weights: np.ndarray, wps: np.ndarray) -> np.ndarray:
    """``W(x) = Σ_g ω_g(x) w_g`` — ``(H, W, 3)`` float32 from weights ``(H, W, G)`` and ``(G, 3)``."""
    # asarray, not astype: the weights are float32 already, and a copy of them cost more than the product
    return np.asarray(weights, dtype=np.float32) @ np.asarray(wps, dtype=np.float32)


def physical_white_point(illum_rgb: np.ndarray, valid: np.ndarray, fallback: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The physical white point ``U / U_G`` (G = 1) — ``(H, W, 3)`` float32 — from the camera RGB of
    the relit illumination cubes ``U`` ``(H, W, 3)`` (DESIGN.md "Physical GT"), and the validity mask.

    Where ``valid`` is False (no light, no geometry, an emitter) or a channel is not positive (noise
    at the edge of the light), the white point is ``fallback`` ``(H, W, 3)`` (the formula's mixed white
    point), so every value stays finite, and the returned mask is False there.
    """
    u = np.asarray(illum_rgb, dtype=np.float32)  # ratios of positive float32 sums: float32 is exact enough
    ok = valid & np.all(u > 0, axis=-1)
    wp = np.divide(u, u[..., 1:2], out=np.array(fallback, dtype=np.float32), where=ok[..., None])
    # A channel 1e10 times weaker than another has no meaningful gain (cf. MIN_CHANNEL_RATIO).
    np.maximum(wp, np.float32(MIN_CHANNEL_RATIO) * wp.max(axis=-1, keepdims=True), out=wp)
    return wp, ok


def gain_map(mixed_wp: np.ndarray) -> np.ndarray:
    """White-balance gains ``max_j W_j / W_k`` (eq. 3.3), ``(H, W, 3)`` float32, all ≥ 1.

    One float32 division per channel (float64 changes the gain by ≤ 1e-5°, ``bench/pareto.py``).
    """
    wp = np.asarray(mixed_wp)
    if wp.dtype != np.float32:
        wp = wp.astype(np.float32)
    low = float(wp.min()) if wp.size else 1.0
    if not low > 0:  # also catches NaN
        raise SpectralError("gain map: a white point has a zero, negative or NaN channel")
    # the channel maximum as two element-wise maxima: numpy's reduction along a length-3 axis is
    # several times slower than the whole division
    top = np.maximum(wp[..., 0], wp[..., 1])
    np.maximum(top, wp[..., 2], out=top)
    with np.errstate(over="ignore"):
        gain = top[..., None] / wp
    if not all_finite(gain):  # inf: channels ~1e-39 of each other
        raise SpectralError(f"gain map: a gain of {float(np.max(gain)):.3g} exceeds float32; one "
                            "white-point channel is (nearly) zero relative to another")
    return gain


def ccm_map(weights: np.ndarray, ccms: np.ndarray) -> np.ndarray:
    """``CCM(x) = Σ_g ω_g(x) CCM_g`` — ``(H, W, 3, 3)`` float32 from ``(H, W, G)`` and ``(G, 3, 3)``."""
    c = np.asarray(ccms, dtype=np.float32).reshape(len(ccms), 9)
    return (np.asarray(weights, dtype=np.float32) @ c).reshape(*weights.shape[:2], 3, 3)
