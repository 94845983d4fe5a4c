"""Reflectance library: sets of spectral reflectances by name or CSV file, on a spectral grid.

Sets
----
- ``ColorChecker N Ohta``, ``BabelColor Average`` — ColorChecker Classic, 24 patches in chart order
  (1 = dark skin … 24 = black), from colour-science's ``SDS_COLOURCHECKERS``;
- ``TCS CIE 1995`` (14), ``TCS CIE 2024`` — CIE test colour samples (``colour.quality``);
- ``CQS 9.0`` / ``CQS 7.4`` — NIST Colour Quality Scale samples VS1–VS15;
- ``CIE 2017`` — the 99 test colour samples of CIE 224:2017 (colour fidelity index);
- measured object sets from ISETCam's data (:data:`ISETCAM_SETS`; Vrhel, Gershon & Iwan 1994, 400–700 nm
  at 10 nm): ``Vrhel Objects`` (170), its subsets ``Vrhel Nature`` (79), ``Vrhel Food`` (27),
  ``Vrhel Clothes`` (41), and ``DuPont Paint`` (120), ``Munsell Vrhel`` (64), plus the ``Gretag SG``
  chart (140, 380–730 nm). They are read from the ``isetcam-spectra`` folder found through
  ``ILLUMIX_ISETCAM_PATH`` or beside the repository (``../shared/data/isetcam-spectra``); values are
  clipped to ``[0, 1]`` (a reflectance);
- a path to a CSV file (first column wavelength, one column per sample).

Reflectances are extended by their end values where they do not cover the grid (a reflectance is a
slowly varying material property; the edges of the visible range carry little weight).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import colour
import numpy as np
from colour.quality import datasets as quality_data

from illumix.retarget.ccm_methods import DEFAULT_TRAINING_SET  # noqa: F401  (callers import it from here)
from illumix.retarget.errors import SpectralError, UnknownName, unknown_name
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid, resample
from illumix.retarget.tables import read_csv_table


def _sets() -> dict[str, dict]:
    return {
        "ColorChecker N Ohta": colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"],
        "BabelColor Average": colour.SDS_COLOURCHECKERS["BabelColor Average"],
        "TCS CIE 1995": quality_data.SDS_TCS["CIE 1995"],
        "TCS CIE 2024": quality_data.SDS_TCS["CIE 2024"],
        "CQS 9.0": quality_data.SDS_VS["NIST CQS 9.0"],
        "CQS 7.4": quality_data.SDS_VS["NIST CQS 7.4"],
    }


ISETCAM_SETS = {
    "Vrhel Objects": "surfaces__reflectances__Objects_Vhrel.csv",
    "Vrhel Nature": "surfaces__reflectances__Nature_Vhrel.csv",
    "Vrhel Food": "surfaces__reflectances__Food_Vhrel.csv",
    "Vrhel Clothes": "surfaces__reflectances__Clothes_Vhrel.csv",
    "DuPont Paint": "surfaces__reflectances__DupontPaintChip_Vhrel.csv",
    "Munsell Vrhel": "surfaces__reflectances__MunsellSamples_Vhrel.csv",
    "Gretag SG": "surfaces__reflectances__gretagDigitalColorSG.csv",
}


def isetcam_dir() -> Path | None:
    """The ``isetcam-spectra`` folder: ``$ILLUMIX_ISETCAM_PATH``, else ``../shared/data/isetcam-spectra``
    beside the repository or the working directory; None when absent."""
    env = os.environ.get("ILLUMIX_ISETCAM_PATH")
    candidates = [Path(env)] if env else []
    candidates += [Path(__file__).resolve().parents[2] / "shared/data/isetcam-spectra",
                   Path.cwd().parent / "shared/data/isetcam-spectra"]
    for c in candidates:
        if (c / "csv").is_dir():
            return c
    return None


def set_names() -> list[str]:
    return [*_sets(), "CIE 2017", *ISETCAM_SETS]


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
    if name in ISETCAM_SETS:
        root = isetcam_dir()
        if root is None:
            raise SpectralError(f"reflectance set {name!r} is read from ISETCam's data, which was not found: "
                                "set ILLUMIX_ISETCAM_PATH to the isetcam-spectra folder (it holds csv/)")
        wl, v, _ = read_csv_table(str(root / "csv" / ISETCAM_SETS[name]), what=f"reflectance set {name!r}")
        r = np.clip(resample(wl, v, grid, extend="constant", what=f"reflectance set {name!r}").T, 0.0, 1.0)
        return tuple(f"{name} {i:03d}" for i in range(r.shape[0])), _validate(r, name)
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
