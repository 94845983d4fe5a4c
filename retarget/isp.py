"""A minimal ISP: white-balance gain map → CCM map → exposure → clip → sRGB transfer function.

Images are ``(H, W, 3)`` float32 linear camera raw; ``gain`` is ``(H, W, 3)`` or ``(3,)``; ``ccm`` is
``(H, W, 3, 3)`` or ``(3, 3)`` (rows = output sRGB channels). The transfer function is IEC 61966-2-1
(checked against colour-science's ``eotf_inverse_sRGB``).
"""

from __future__ import annotations

import numpy as np


def apply_ccm(rgb: np.ndarray, ccm: np.ndarray) -> np.ndarray:
    """``out_i = Σ_j CCM_ij · rgb_j`` per pixel; ``ccm`` ``(3, 3)`` or ``(H, W, 3, 3)``. float32."""
    rgb = np.asarray(rgb, dtype=np.float32)
    ccm = np.asarray(ccm, dtype=np.float32)
    if ccm.ndim == 2:
        return rgb @ ccm.T
    # Three broadcast multiply-adds beat einsum here and need no (H, W, 3, 3) temporary.
    return (ccm[..., 0] * rgb[..., 0:1] + ccm[..., 1] * rgb[..., 1:2] + ccm[..., 2] * rgb[..., 2:3])


def encode_srgb(linear: np.ndarray) -> np.ndarray:
    """Clip linear sRGB to [0, 1] and apply the sRGB transfer function. float32 in [0, 1].

    The IEC 61966-2-1 piecewise curve evaluated in float32 (twice as fast as colour-science's
    float64 ``eotf_inverse_sRGB``, which the tests use as the reference); NaN → 0, ±inf → 1/0.
    """
    x = np.asarray(linear, dtype=np.float32)
    if not np.all(np.isfinite(x)):
        x = np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0)
    x = np.clip(x, np.float32(0), np.float32(1))
    root = np.power(x, np.float32(1 / 2.4))
    curve = root + np.float32(0.055) * (root - np.float32(1))  # = 1.055·root − 0.055, exactly 1 at 1
    return np.where(x <= np.float32(0.0031308), x * np.float32(12.92), curve).astype(np.float32, copy=False)


def render_srgb(raw: np.ndarray, gain: np.ndarray, ccm: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Gamma-encoded sRGB ``(H, W, 3)`` float32 in [0, 1] from raw, gain map and CCM map."""
    balanced = np.asarray(raw, dtype=np.float32) * np.asarray(gain, dtype=np.float32)
    return encode_srgb(apply_ccm(balanced, ccm) * np.float32(exposure))


def preview(raw: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """A gamma-encoded view of raw itself (no white balance, no CCM), for looking at it."""
    return encode_srgb(np.asarray(raw, dtype=np.float32) * np.float32(exposure))
