"""Illuminant library: relative SPDs by name, on a spectral grid.

Names
-----
- every entry of colour-science's ``SDS_ILLUMINANTS`` (A, D50…D75, FL1…FL12, FL3.x, HP1…HP5,
  LED-B1…LED-V2, ISO 7589 …);
- ``blackbody:<K>`` — Planck's law at K kelvin (500 ≤ K ≤ 50000);
- ``daylight:<K>`` — CIE D-series daylight at correlated colour temperature K (4000 ≤ K ≤ 25000),
  via colour-science's ``CCT_to_xy_CIE_D`` and ``sd_CIE_illuminant_D_series`` (CIE 15:2004);
- a path to a CSV file ``wavelength,value``;
- names registered at run time (uploads), passed in as ``extra``.

Normalisation
-------------
Every illuminant is scaled *photometrically*: its luminance on the grid equals that of the
equal-energy spectrum of value 1 (``Σ Φ̄ ȳ Δλ = Σ 1 · ȳ Δλ``, CIE 1931 2° ȳ). A transport cube rendered
with flat unit emission and relit by any illuminant at intensity 1 therefore keeps its luminance, so
intensity ratios between light groups are illuminance ratios.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import colour
import numpy as np

from illumix.retarget.errors import SpectralError, unknown_name
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid, resample
from illumix.retarget.tables import read_csv_table

PARAMETRIC = {"blackbody": (500.0, 50000.0), "daylight": (4000.0, 25000.0)}
_FINE = colour.SpectralShape(300, 830, 1)


def builtin_names() -> list[str]:
    """colour-science's tabulated illuminants (the parametric forms are not enumerable)."""
    return list(_BUILTIN)


_BUILTIN = tuple(colour.SDS_ILLUMINANTS.keys())  # a CanonicalMapping slugifies its keys on every call


@lru_cache(maxsize=1024)
def is_builtin(name: str) -> bool:
    """``name in colour.SDS_ILLUMINANTS`` (its case-insensitive matching), remembered: the service
    asks it several times per request and each answer slugifies every key."""
    return name in colour.SDS_ILLUMINANTS


@lru_cache(maxsize=64)
def _luminance_weights(grid: SpectralGrid) -> np.ndarray:
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return resample(cmfs.wavelengths, cmfs.values[:, 1], grid)


def normalise(spd: np.ndarray, grid: SpectralGrid, what: str = "illuminant") -> np.ndarray:
    """Scale band averages ``(n_bands,)`` to the luminance of the unit equal-energy spectrum."""
    ybar = _luminance_weights(grid)
    lum = float(np.dot(spd, ybar))
    if not np.isfinite(lum) or lum <= 0:
        raise SpectralError(f"{what}: has no luminance on the grid {grid} (all zero or negative there)")
    return spd * (float(ybar.sum()) / lum)


def _parametric(kind: str, arg: str) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = PARAMETRIC[kind]
    try:
        kelvin = float(arg.lower().removesuffix("k"))
    except ValueError:
        raise SpectralError(f"illuminant '{kind}:{arg}': temperature must be a number in kelvin, "
                            f"e.g. {kind}:6500") from None
    if not lo <= kelvin <= hi:
        raise SpectralError(f"illuminant '{kind}:{arg}': {kelvin:g} K is outside {lo:g}-{hi:g} K")
    if kind == "blackbody":
        sd = colour.sd_blackbody(kelvin, _FINE)
    else:
        # CIE D-series CCTs use the old c2 = 1.4380e-2 m·K: daylight:6500 is D65 (6504 K today).
        xy = colour.temperature.CCT_to_xy_CIE_D(kelvin * 1.4388 / 1.4380)
        sd = colour.sd_CIE_illuminant_D_series(xy).align(colour.SpectralShape(300, 830, 5))
    return sd.wavelengths, sd.values


def illuminant_samples(name: str, extra: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Raw tabulated samples ``(wavelengths (n,), values (n,))`` of a named illuminant."""
    if extra and name in extra:
        return extra[name]
    if is_builtin(name):
        sd = colour.SDS_ILLUMINANTS[name]
        return sd.wavelengths, sd.values
    kind, sep, arg = name.partition(":")
    if sep and kind.lower() in PARAMETRIC:
        return _parametric(kind.lower(), arg.strip())
    if name.lower().endswith(".csv") or Path(name).is_file():
        wl, v, _ = read_csv_table(name, columns=1, what=f"illuminant file {name!r}")
        return wl, v[:, 0]
    known = builtin_names() + [f"{k}:<K>" for k in PARAMETRIC] + list(extra or {})
    raise unknown_name("illuminant", name, known)


def illuminant_spd(name: str, grid: SpectralGrid = DEFAULT_GRID,
                   extra: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> np.ndarray:
    """Normalised band-averaged SPD ``(n_bands,)`` float64 of a named illuminant on ``grid``.

    Negative samples are refused; an SPD must cover the grid (no silent extension: an emitter with
    no data at a band is not known to be dark there).
    """
    builtin = is_builtin(name) or name.partition(":")[0].lower() in PARAMETRIC
    if builtin and not (extra and name in extra):
        return _cached_spd(name, grid).copy()
    wl, v = illuminant_samples(name, extra)
    return spd_from_samples(wl, v, grid, what=f"illuminant {name!r}")


def spd_from_samples(wl: np.ndarray, values: np.ndarray, grid: SpectralGrid, what: str = "SPD") -> np.ndarray:
    """Validate, band-average and normalise a tabulated SPD (see module docstring)."""
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise SpectralError(f"{what}: contains NaN or inf; an SPD must be finite numbers")
    if np.any(values < 0):
        raise SpectralError(f"{what}: has negative power at {np.asarray(wl)[values < 0][0]:g} nm; "
                            "an SPD must be non-negative")
    peak = float(values.max()) if values.size else 0.0
    if peak > 0 and not 1e-100 < peak < 1e100:
        # An SPD is relative: scaling it to peak 1 first keeps values like 1e-320 or 1e308 from
        # under- or overflowing the band integrals and the luminance sum.
        values = values / peak
    return normalise(resample(wl, values, grid, what=what), grid, what)


@lru_cache(maxsize=512)
def _cached_spd(name: str, grid: SpectralGrid) -> np.ndarray:
    wl, v = illuminant_samples(name)
    return spd_from_samples(wl, v, grid, what=f"illuminant {name!r}")
