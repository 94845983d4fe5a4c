"""The spectral grid and band-integrated resampling of tabulated spectra.

A grid is a list of contiguous bands ``[λ_i − Δλ/2, λ_i + Δλ/2]``. Every spectrum illumix uses is a
vector of *band averages* over those bands (the band integral divided by Δλ), so spiky fluorescent or
LED lines inside a band are integrated, not missed by point sampling. Band averages keep the input's
units (a relative SPD stays a relative SPD), and ``Σ_i f̄_i · Δλ`` is the exact integral of ``f`` over
the grid's span.

Resampling = piecewise-linear interpolation of the tabulated samples, then *exact* integration of
that interpolant over each band (closed form on the cumulative integral, no quadrature error).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from illumix.retarget.errors import SpectralError

Extension = Literal["refuse", "constant", "zero"]


@dataclass(frozen=True)
class SpectralGrid:
    """Band centres ``start, start+step, …, end`` in nm; each band is ``step`` nm wide.

    The default 395–705 nm at 5 nm gives the thesis's 63 bands.
    """

    start: float = 395.0
    end: float = 705.0
    step: float = 5.0

    def __post_init__(self) -> None:
        if not (self.step > 0 and self.end >= self.start):
            raise SpectralError(
                f"invalid spectral grid {self.start}-{self.end} nm step {self.step}: "
                "need step > 0 and end >= start"
            )
        n = (self.end - self.start) / self.step
        if abs(n - round(n)) > 1e-6:
            raise SpectralError(
                f"invalid spectral grid: {self.end}-{self.start} nm is not a multiple of {self.step} nm"
            )

    @property
    def n_bands(self) -> int:
        return int(round((self.end - self.start) / self.step)) + 1

    @property
    def wavelengths(self) -> np.ndarray:
        """Band centres in nm, shape ``(n_bands,)`` float64."""
        return self.start + self.step * np.arange(self.n_bands, dtype=np.float64)

    @property
    def edges(self) -> np.ndarray:
        """Band edges in nm, shape ``(n_bands + 1,)`` float64."""
        return self.start - self.step / 2 + self.step * np.arange(self.n_bands + 1, dtype=np.float64)

    @property
    def span(self) -> tuple[float, float]:
        """The wavelength interval in nm that a spectrum must cover to be resampled to this grid."""
        e = self.edges
        return float(e[0]), float(e[-1])

    def to_dict(self) -> dict[str, float]:
        return {"start": self.start, "end": self.end, "step": self.step}

    @classmethod
    def from_dict(cls, d: dict) -> SpectralGrid:
        return cls(float(d["start"]), float(d["end"]), float(d["step"]))

    def __str__(self) -> str:
        return f"{self.start:g}-{self.end:g} nm / {self.step:g} nm ({self.n_bands} bands)"


DEFAULT_GRID = SpectralGrid()


def _cumulative_linear(x: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """∫_{x0}^{at} of the piecewise-linear interpolant of ``(x, y)``; ``y`` is ``(n, k)``."""
    dx = np.diff(x)
    seg = 0.5 * (y[1:] + y[:-1]) * dx[:, None]
    cum = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(seg, axis=0)])
    j = np.clip(np.searchsorted(x, at, side="right") - 1, 0, len(x) - 2)
    t = (at - x[j])[:, None]
    slope = (y[j + 1] - y[j]) / dx[j][:, None]
    return cum[j] + y[j] * t + 0.5 * slope * t * t


def resample(
    wavelengths: np.ndarray,
    values: np.ndarray,
    grid: SpectralGrid = DEFAULT_GRID,
    *,
    extend: Extension = "refuse",
    what: str = "spectrum",
) -> np.ndarray:
    """Band averages of a tabulated spectrum on ``grid``.

    Parameters
    ----------
    wavelengths : ``(n,)`` nm, strictly increasing (sorted here if not; duplicates refused).
    values : ``(n,)`` or ``(n, k)`` samples of ``k`` spectra (any units; the result keeps them).
    extend : what to do where the samples do not cover the grid's span ``[edges[0], edges[-1]]``:
        ``"refuse"`` (default) raises; ``"constant"`` extends by the end values (fit for
        reflectances); ``"zero"`` assumes no signal outside (fit for band-limited emitters).
    what : name used in error messages.

    Returns
    -------
    ``(n_bands,)`` or ``(n_bands, k)`` float64 band averages ``(1/Δλ) ∫_band f(λ) dλ`` of the
    piecewise-linear interpolant.
    """
    wl, v, squeeze = _checked_samples(wavelengths, values, what)
    lo, hi = grid.span
    tol = 1e-9
    if wl[0] > lo + tol or wl[-1] < hi - tol:
        if extend == "refuse":
            raise SpectralError(
                f"{what}: samples cover {wl[0]:g}-{wl[-1]:g} nm but the grid {grid} needs "
                f"{lo:g}-{hi:g} nm; supply a wider spectrum or choose an extension policy "
                "('constant' or 'zero')"
            )
        if extend not in ("constant", "zero"):
            raise SpectralError(f"{what}: unknown extension policy {extend!r}; use refuse, constant or zero")
        wl, v = _extended(wl, v, lo, hi, tol, extend)
    cum = _cumulative_linear(wl, v, grid.edges)
    out = np.diff(cum, axis=0) / grid.step
    return out[:, 0] if squeeze else out


def _checked_samples(wavelengths: np.ndarray, values: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(wavelengths (n,), values (n, k), whether values was 1-D)`` float64, sorted by wavelength;
    :class:`SpectralError` for mismatched shapes, fewer than 2 samples, NaN/inf or duplicates."""
    wl = np.asarray(wavelengths, dtype=np.float64).ravel()
    v = np.asarray(values, dtype=np.float64)
    squeeze = v.ndim == 1
    v = v.reshape(len(v), -1) if v.ndim == 1 else v
    if v.ndim != 2 or v.shape[0] != wl.shape[0]:
        raise SpectralError(
            f"{what}: {wl.shape[0]} wavelengths but values of shape {np.shape(values)}; "
            "give one value row per wavelength"
        )
    if wl.shape[0] < 2:
        raise SpectralError(f"{what}: need at least 2 wavelength samples, got {wl.shape[0]}")
    if not (np.all(np.isfinite(wl)) and np.all(np.isfinite(v))):
        raise SpectralError(f"{what}: contains NaN or inf; remove or fill those samples")
    order = np.argsort(wl, kind="stable")
    wl, v = wl[order], v[order]
    if np.any(np.diff(wl) <= 0):
        raise SpectralError(f"{what}: duplicate wavelength samples; give each wavelength once")
    return wl, v, squeeze


def _extended(wl: np.ndarray, v: np.ndarray, lo: float, hi: float, tol: float,
              extend: Extension) -> tuple[np.ndarray, np.ndarray]:
    """The samples extended to cover ``[lo, hi]`` nm by ``extend`` (``"constant"``: the end values;
    ``"zero"``: zero)."""
    pad_lo = v[:1] if extend == "constant" else np.zeros_like(v[:1])
    pad_hi = v[-1:] if extend == "constant" else np.zeros_like(v[-1:])
    if wl[0] > lo + tol:
        # A zero extension steps to zero just outside the last sample, not a ramp across the gap.
        step_lo = [lo, wl[0] - 1e-9] if extend == "zero" else [lo]
        wl = np.concatenate([step_lo, wl])
        v = np.concatenate([np.repeat(pad_lo, len(step_lo), axis=0), v])
    if wl[-1] < hi - tol:
        step_hi = [wl[-1] + 1e-9, hi] if extend == "zero" else [hi]
        wl = np.concatenate([wl, step_hi])
        v = np.concatenate([v, np.repeat(pad_hi, len(step_hi), axis=0)])
    return wl, v
