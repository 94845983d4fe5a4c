"""Reflectance library: sets of spectral reflectances by name or CSV file, on a spectral grid.

Sets
----
- ``ColorChecker N Ohta``, ``BabelColor Average`` — ColorChecker Classic, 24 patches in chart order
  (1 = dark skin … 24 = black), from colour-science's ``SDS_COLOURCHECKERS``;
- ``TCS CIE 1995`` (14), ``TCS CIE 2024`` — CIE test colour samples (``colour.quality``);
- ``CQS 9.0`` / ``CQS 7.4`` — NIST Colour Quality Scale samples VS1–VS15;
- ``CIE 2017`` — the 99 test colour samples of CIE 224:2017 (colour fidelity index);
- a path to a CSV file (first column wavelength, one column per sample).

Reflectances are extended by their end values where they do not cover the grid (a reflectance is a
slowly varying material property; the edges of the visible range carry little weight).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import colour
import numpy as np
from colour.quality import datasets as quality_data

from retarget.ccm_methods import DEFAULT_TRAINING_SET  # noqa: F401  (callers import it from here)
from retarget.errors import SpectralError, UnknownName, unknown_name
from retarget.grid import DEFAULT_GRID, SpectralGrid, resample
from retarget.tables import read_csv_table


def _sets() -> dict[str, dict]:
    return {
        "ColorChecker N Ohta": colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"],
        "BabelColor Average": colour.SDS_COLOURCHECKERS["BabelColor Average"],
        "TCS CIE 1995": quality_data.SDS_TCS["CIE 1995"],
        "TCS CIE 2024": quality_data.SDS_TCS["CIE 2024"],
        "CQS 9.0": quality_data.SDS_VS["NIST CQS 9.0"],
        "CQS 7.4": quality_data.SDS_VS["NIST CQS 7.4"],
    }


def set_names() -> list[str]:
    return [*_sets(), "CIE 2017"]


def get_reflectances(name: str, grid: SpectralGrid = DEFAULT_GRID) -> tuple[list[str], np.ndarray]:
    """``(sample_names, reflectances (n_samples, n_bands) float64)`` for a set name or CSV path."""
    if name in set_names():
        names, r = _cached_set(name, grid)
        return list(names), r.copy()
    if Path(name).is_file():
        wl, v, cols = read_csv_table(name, what=f"reflectance file {name!r}")
        return cols, _validate(resample(wl, v, grid, extend="constant", what=name).T, name)
    err = unknown_name("reflectance set", name, set_names())
    raise UnknownName(f"{err} (sets: {', '.join(set_names())}; or a CSV file: wavelength, one column per sample)")


@lru_cache(maxsize=32)
def _cached_set(name: str, grid: SpectralGrid) -> tuple[tuple[str, ...], np.ndarray]:
    if name == "CIE 2017":
        from colour.quality.cfi2017 import load_TCS_CIE2017

        msds = load_TCS_CIE2017(colour.SpectralShape(380, 780, 5))
        names, wl, values = list(msds.labels), msds.wavelengths, msds.values
    else:
        sds = _sets()[name]
        names = list(sds.keys())
        # Samples of one set may be tabulated on different wavelengths: resample each.
        r = np.stack([resample(sds[n].wavelengths, sds[n].values, grid, extend="constant",
                               what=f"reflectance {name!r}/{n!r}") for n in names])
        return tuple(names), _validate(r, name)
    r = resample(wl, values, grid, extend="constant", what=f"reflectance set {name!r}").T
    return tuple(names), _validate(r, name)


def _validate(r: np.ndarray, name: str) -> np.ndarray:
    if not np.all(np.isfinite(r)):
        raise SpectralError(f"reflectances {name!r}: contain NaN or inf")
    return np.clip(r, 0.0, None)
