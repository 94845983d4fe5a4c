"""Independent reference computations for the tests (no ``retarget`` imports here).

Band averages are recomputed the slow, obvious way: evaluate the piecewise-linear interpolant of the
tabulated samples (``np.interp``) on a fine 0.05 nm lattice and integrate it with the trapezoid rule.
Every tabulation the tests use (1, 4, 5, 10 nm steps starting on whole or half nanometres) has its
knots on that lattice, so the trapezoid rule integrates the interpolant exactly up to float rounding
(≈1e-13 relative) — a different algorithm for the same mathematical quantity as
``retarget.grid.resample`` (closed-form cumulative integral), not a copy of it.
"""

from __future__ import annotations

import numpy as np

FINE_STEP = 0.05  # nm


def fine_lattice(start: float = 395.0, end: float = 705.0, step: float = 5.0) -> np.ndarray:
    """Fine wavelengths covering the grid's span ``[start − step/2, end + step/2]``."""
    per_band = int(round(step / FINE_STEP))
    n_bands = int(round((end - start) / step)) + 1
    return (start - step / 2) + FINE_STEP * np.arange(n_bands * per_band + 1)


def interp(wl: np.ndarray, values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolant of ``(wl, values)`` at ``x``; values ``(n,)`` or ``(n, k)``.

    Outside the samples ``np.interp`` holds the end values (a 'constant' extension).
    """
    wl = np.asarray(wl, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1:
        return np.interp(x, wl, v)
    return np.stack([np.interp(x, wl, v[:, k]) for k in range(v.shape[1])], axis=-1)


def band_average_fine(y_fine: np.ndarray, step: float = 5.0) -> np.ndarray:
    """Band averages of a function given on :func:`fine_lattice` (trapezoid rule per band)."""
    per_band = int(round(step / FINE_STEP))
    y = np.asarray(y_fine, dtype=np.float64)
    seg = 0.5 * (y[1:] + y[:-1]) * FINE_STEP
    n = seg.shape[0] // per_band
    return seg.reshape(n, per_band, *seg.shape[1:]).sum(axis=1) / step


def band_sd_fine(y_fine: np.ndarray, step: float = 5.0) -> np.ndarray:
    """Per-band standard deviation of a function on the fine lattice (trapezoid rule)."""
    per_band = int(round(step / FINE_STEP))
    y = np.asarray(y_fine, dtype=np.float64)
    mean = band_average_fine(y, step)
    n = mean.shape[0]
    body = y[:-1].reshape(n, per_band, *y.shape[1:])
    nxt = y[1:].reshape(n, per_band, *y.shape[1:])
    m = mean[:, None]
    var = (0.5 * ((body - m) ** 2 + (nxt - m) ** 2) * FINE_STEP).sum(axis=1) / step
    return np.sqrt(np.maximum(var, 0.0))


def integral_fine(y_fine: np.ndarray) -> np.ndarray:
    """∫ over the whole lattice (trapezoid) of a function on :func:`fine_lattice`."""
    return np.trapezoid(np.asarray(y_fine, dtype=np.float64), dx=FINE_STEP, axis=0)


def product_bound(f_fine: np.ndarray, g_fine: np.ndarray, step: float = 5.0) -> np.ndarray:
    """Bound on ``|Σ_i f̄_i ḡ_i Δλ − ∫ f g dλ|`` (product of band averages vs the true integral).

    Per band, ``avg(f g) − avg(f) avg(g) = cov_band(f, g)`` and ``|cov| ≤ sd(f) sd(g)``
    (Cauchy–Schwarz), so the total error is at most ``Σ_i Δλ sd_i(f) sd_i(g)``. ``g`` may have
    several columns ``(n, k)``; the result then has shape ``(k,)``.
    """
    sf = band_sd_fine(f_fine, step)
    sg = band_sd_fine(g_fine, step)
    if sg.ndim == 2:
        sf = sf[:, None]
    return step * np.sum(sf * sg, axis=0)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB transfer function written out (no colour-science)."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
