"""Auto exposure control, thesis §4.3, eq. 4.2 (linear AEC after [64])::

    M_tgt = min(max(M_cur · H_tgt / H_cur, M_min), M_max),      gain = M_tgt / M_cur

``M_cur`` is the mean of all colour components, ``H_cur`` the bright end of their histogram (a high
percentile), ``H_tgt`` the level the bright end should reach. Values are relative to the white
level (1.0 = saturation). The gain multiplies the whole image, so the signal stays linear.

Methods (``method=``, looked up in :data:`EXPOSURE_METHODS`, case-insensitive): ``"constant"`` (alias
``"auto"``) — fixed ``M_min``; ``"adaptive"`` — ``M_min`` chosen where the
saturated-pixel fraction, as a function of ``M_min``, changes fastest (thesis: "highest gradient
change point"), taking the largest ``M_min`` before that jump.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite
from illumix.retarget.registry import MethodRegistry

EXPOSURE_METHODS: MethodRegistry[str] = MethodRegistry(
    "exposure method", {"constant": "constant", "adaptive": "adaptive"}, aliases={"auto": "constant"})


@dataclass(frozen=True)
class AECParams:
    """Parameters of eq. 4.2 (levels relative to white level 1.0)."""

    h_percentile: float = 99.0
    h_target: float = 0.9
    m_min: float = 0.10
    m_max: float = 0.45
    adaptive_candidates: int = 33


def _stats(image: np.ndarray, p: AECParams) -> tuple[float, float]:
    x = np.asarray(image, dtype=np.float32).ravel()
    if not all_finite(x):
        x = x[np.isfinite(x)]
    if x.size == 0:
        return 0.0, 0.0
    return float(x.mean(dtype=np.float64)), float(np.percentile(x, p.h_percentile))


def _gain(m_cur: float, h_cur: float, m_min: float, p: AECParams) -> float:
    m_tgt = min(max(m_cur * p.h_target / h_cur, m_min), p.m_max)
    return m_tgt / m_cur


def aec_gain(image: np.ndarray, method: str = "constant", params: AECParams | None = None) -> float:
    """Exposure gain for ``image`` ``(H, W, C)`` by eq. 4.2. A black image gets gain 1.0."""
    p = params or AECParams()
    method = EXPOSURE_METHODS.canonical(method)
    if not (0 < p.m_min <= p.m_max and p.h_target > 0 and 0 < p.h_percentile <= 100):
        raise SpectralError(f"exposure: invalid parameters {p}")
    m_cur, h_cur = _stats(image, p)
    if m_cur <= 0 or h_cur <= 0:
        return 1.0
    if method == "constant":
        return _gain(m_cur, h_cur, p.m_min, p)
    candidates = np.linspace(p.m_min, p.m_max, p.adaptive_candidates)
    gains = np.array([_gain(m_cur, h_cur, m, p) for m in candidates])
    flat = np.asarray(image, dtype=np.float32).reshape(-1, image.shape[-1] if image.ndim == 3 else 1)
    brightest = np.nanmax(flat, axis=1)
    saturated = np.array([np.mean(brightest * g >= 1.0) for g in gains])
    jumps = np.diff(saturated)
    if not np.any(jumps > 0):
        return float(gains[-1])  # saturation never grows: the brightest allowed mean is safe
    return float(gains[int(np.argmax(jumps))])
