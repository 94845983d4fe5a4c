"""The single-global-white-point baseline: a mixed-light frame white-balanced as if one light lit it.

The thesis (§5.2, the input it feeds Afifi et al.'s network) makes the "wrongly white-balanced"
image of a mixed-illuminant scene by averaging the illuminants' white points, weighted by how much
each contributes, and using that one white point (and the equally weighted CCM) for the whole
frame. With the per-pixel mixture ``m_g(x)`` (each group's share of the white point's G, ≥ 0,
Σ_g m_g = 1) and the groups' sensor white points ``w_g`` (eq. 3.2, G = 1)::

    m̄_g   = mean over valid pixels of m_g(x)                 each group's share of the frame
    W̄     = Σ_g m̄_g w_g                                     the single white point (G = 1)
    ḡ_k   = max_j W̄_j / W̄_k                                 one gain for the whole frame
    CCM̄   = Σ_g m̄_g CCM_g                                   one CCM
    sRGB  = encode(e · CCM̄ (ḡ ⊙ raw))                       e: the same exposure as the GT rendering

Where one light dominates the frame the baseline tends to the pixel-wise ground truth; where the
lights mix, regions lit mostly by one group keep that group's colour cast, which is the problem a
spatial AWB method has to solve. Images ``(H, W, 3)`` float32; mixture ``(H, W, G)``.
"""

from __future__ import annotations

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.groundtruth import gain_map
from illumix.retarget.isp import apply_ccm, encode_srgb


def frame_shares(mixture: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """``(G,)`` float64: each group's mean share ``m̄_g`` over the valid pixels (``mask`` True;
    every pixel when ``mask`` is None or selects none). Sums to 1."""
    m = np.asarray(mixture, dtype=np.float32).reshape(-1, mixture.shape[-1])
    if mask is not None and np.any(mask):
        m = m[np.asarray(mask, dtype=bool).reshape(-1)]
    shares = m.mean(axis=0, dtype=np.float64)
    total = shares.sum()
    if not (np.isfinite(total) and total > 0):
        raise SpectralError("global white point: the mixture has no positive share anywhere")
    return shares / total


def global_white_point(shares: np.ndarray, white_points: np.ndarray) -> np.ndarray:
    """``W̄ = Σ_g m̄_g w_g`` — ``(3,)`` float64, G = 1 — from shares ``(G,)`` and ``(G, 3)`` white points."""
    wp = np.asarray(shares, dtype=np.float64) @ np.asarray(white_points, dtype=np.float64)
    return wp / wp[1]


def frame_white_point(mixture: np.ndarray, mask: np.ndarray, white_points: np.ndarray) -> np.ndarray:
    """``W̄`` of a frame — ``(3,)`` float64, G = 1 — from its mixture ``(H, W, G)``, valid pixels
    ``(H, W)`` and the groups' white points ``(G, 3)``: :func:`frame_shares` over the valid pixels, or
    equal shares where no valid pixel carries any (nothing to weight by)."""
    wps = np.asarray(white_points, dtype=np.float64)
    try:
        shares = frame_shares(mixture, mask) if np.any(mask) else None
    except SpectralError:
        shares = None
    return global_white_point(np.full(len(wps), 1.0 / len(wps)) if shares is None else shares, wps)


def global_ccm(shares: np.ndarray, ccms: np.ndarray) -> np.ndarray:
    """``CCM̄ = Σ_g m̄_g CCM_g`` — ``(3, 3)`` float64 from shares ``(G,)`` and ``(G, 3, 3)`` CCMs."""
    return np.tensordot(np.asarray(shares, dtype=np.float64), np.asarray(ccms, dtype=np.float64), axes=1)


def render_global(raw: np.ndarray, white_point: np.ndarray, ccm: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Gamma-encoded sRGB ``(H, W, 3)`` float32 in [0, 1] of ``raw`` balanced by one white point
    ``(3,)`` and one CCM ``(3, 3)``, times ``exposure`` before clipping."""
    gain = gain_map(np.asarray(white_point, dtype=np.float32)[None, None])[0, 0]
    linear = apply_ccm(np.asarray(raw, dtype=np.float32) * gain, ccm)
    if exposure != 1.0:
        linear *= np.float32(exposure)
    return encode_srgb(linear)
