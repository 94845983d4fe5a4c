"""Sensor library: camera spectral sensitivities by name or file, on a spectral grid.

Names
-----
- ``XYZ`` — the CIE 1931 2° standard observer as a sensor (x̄, ȳ, z̄ as "R, G, B");
- colour-science's measured cameras (``MSDS_CAMERA_SENSITIVITIES``, e.g. ``Nikon 5100 (NPL)``);
- every ``*.json`` (rawtoaces camera JSON) and ``*.csv`` (``wavelength,r,g,b``) file in the folders
  listed in the environment variable ``ILLUMIX_SENSOR_PATH`` (``os.pathsep``-separated), named by
  the file stem without a ``_380_780_5``-style range suffix (``Nikon_D810``);
- a path to such a file;
- names registered at run time (uploads), passed in as ``extra``.

Validation: finite, non-negative, covers the grid, no all-zero channel on the grid.
Normalisation: divided by the largest sensitivity over all channels and bands (peak = 1); only
ratios between channels matter to colour, and exposure sets the absolute level.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import colour
import numpy as np

from illumix.retarget.errors import SpectralError, unknown_name
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid, resample
from illumix.retarget.tables import read_csv_table, read_rawtoaces_camera

XYZ = "XYZ"
_RANGE_SUFFIX = re.compile(r"_\d{3}_\d{3,4}_\d+$")


@dataclass(frozen=True)
class Sensor:
    """A camera's spectral sensitivities on a grid.

    ``sensitivities`` is ``(n_bands, 3)`` float64 band averages for channels R, G, B (peak 1).
    """

    name: str
    grid: SpectralGrid
    sensitivities: np.ndarray = field(repr=False)
    source: str = "builtin"

    def weights(self) -> np.ndarray:
        """``C_k(λ_i) · Δλ`` as ``(n_bands, 3)``: multiply a band-average spectrum to get raw."""
        return self.sensitivities * self.grid.step


def sensor_dirs() -> list[Path]:
    raw = os.environ.get("ILLUMIX_SENSOR_PATH", "")
    return [Path(p) for p in raw.split(os.pathsep) if p]


def _dir_sensors() -> dict[str, Path]:
    """``name → file`` of the sensors in ILLUMIX_SENSOR_PATH. Listed again only when the path or a
    folder's modification time changes (the service resolves a sensor name on every request)."""
    dirs = sensor_dirs()
    stamp = []
    for d in dirs:
        try:
            stamp.append((str(d), d.stat().st_mtime_ns))
        except OSError:
            stamp.append((str(d), None))
    return _list_dirs(tuple(stamp))


def sensor_file(name: str) -> Path | None:
    """The ILLUMIX_SENSOR_PATH file of a sensor name, or None."""
    return _dir_sensors().get(name)


@lru_cache(maxsize=8)
def _list_dirs(stamp: tuple[tuple[str, int | None], ...]) -> dict[str, Path]:
    found: dict[str, Path] = {}
    for d, mtime in stamp:
        if mtime is not None and Path(d).is_dir():
            for f in sorted(Path(d).iterdir()):
                if f.suffix.lower() in (".json", ".csv"):
                    found.setdefault(_RANGE_SUFFIX.sub("", f.stem), f)
    return found


_CAMERAS = tuple(colour.MSDS_CAMERA_SENSITIVITIES.keys())  # a CanonicalMapping slugifies on every .keys()


@lru_cache(maxsize=1024)
def _is_camera(name: str) -> bool:
    return name in colour.MSDS_CAMERA_SENSITIVITIES  # case-insensitive matching, remembered


def builtin_names() -> list[str]:
    """All sensor names known without uploads: XYZ, colour-science cameras, ILLUMIX_SENSOR_PATH files."""
    return [XYZ, *_CAMERAS, *_dir_sensors()]


def availability(grid: SpectralGrid = DEFAULT_GRID) -> tuple[list[str], dict[str, str]]:
    """``(usable names, {unusable name: why})`` of the built-in sensors on ``grid``.

    Some measured cameras do not cover the whole grid (``Sigma SDMerill (NPL)`` stops at 680 nm);
    listing them as usable would promise samples that are always refused.
    """
    return _availability(grid, tuple(sorted((n, str(p)) for n, p in _dir_sensors().items())))


@lru_cache(maxsize=8)
def _availability(grid: SpectralGrid, files: tuple[tuple[str, str], ...]) -> tuple[list[str], dict[str, str]]:
    usable, unusable = [], {}
    for name in builtin_names():
        try:
            get_sensor(name, grid)
            usable.append(name)
        except SpectralError as exc:
            unusable[name] = str(exc)
    return usable, unusable


def read_sensor_file(path: str | Path | bytes, *, fmt: str | None = None, what: str | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Samples ``(wavelengths (n,), rgb (n, 3))`` from a rawtoaces JSON or ``wavelength,r,g,b`` CSV.

    ``fmt`` is ``"json"`` or ``"csv"``; guessed from the suffix or content when omitted.
    """
    what = what or f"sensor file {str(path)[:80]!r}"
    if fmt is None:
        if isinstance(path, bytes):
            fmt = "json" if path.lstrip()[:1] == b"{" else "csv"
        else:
            fmt = "json" if str(path).lower().endswith(".json") else "csv"
    if fmt == "json":
        wl, rgb, _ = read_rawtoaces_camera(path, what=what)
    else:
        wl, rgb, _ = read_csv_table(path, columns=3, what=what)
    return wl, rgb


def sensor_from_samples(name: str, wl: np.ndarray, rgb: np.ndarray, grid: SpectralGrid = DEFAULT_GRID,
                        source: str = "user") -> Sensor:
    """Validate, band-average and normalise tabulated sensitivities (see module docstring)."""
    what = f"sensor {name!r}"
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.ndim != 2 or rgb.shape[1] != 3:
        raise SpectralError(f"{what}: need 3 channels (R, G, B), got shape {rgb.shape}")
    if not np.all(np.isfinite(rgb)):
        raise SpectralError(f"{what}: contains NaN or inf")
    if np.any(rgb < 0):
        bad = np.asarray(wl)[np.any(rgb < 0, axis=1)][0]
        raise SpectralError(f"{what}: negative sensitivity at {bad:g} nm; sensitivities must be >= 0")
    if rgb.size and not 1e-100 < rgb.max() < 1e100:
        rgb = rgb / rgb.max()  # relative curves: keep 1e-320 or 1e308 inputs inside float64's range
    s = resample(wl, rgb, grid, what=what)
    peak = s.max(axis=0)
    if np.any(peak <= 0):
        ch = "RGB"[int(np.argmin(peak))]
        raise SpectralError(f"{what}: channel {ch} is all zero on the grid {grid}")
    return Sensor(name=name, grid=grid, sensitivities=s / peak.max(), source=source)


def get_sensor(name: str, grid: SpectralGrid = DEFAULT_GRID,
               extra: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> Sensor:
    """Look a sensor up by name (see module docstring) or load it from a file path."""
    if extra and name in extra:
        wl, rgb = extra[name]
        return sensor_from_samples(name, wl, rgb, grid, source="uploaded")
    if name == XYZ or _is_camera(name):
        return _cached_builtin(name, grid)
    files = _dir_sensors()
    if name in files:
        return _cached_file(str(files[name]), name, grid)
    if Path(name).is_file():
        return _cached_file(str(Path(name).resolve()), _RANGE_SUFFIX.sub("", Path(name).stem), grid)
    if name.lower().endswith((".json", ".csv")):
        raise SpectralError(f"sensor file {name!r} does not exist; check the path")
    raise unknown_name("sensor", name, builtin_names() + list(extra or {}))


@lru_cache(maxsize=64)
def _cached_builtin(name: str, grid: SpectralGrid) -> Sensor:
    if name == XYZ:
        msds = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
        src = "CIE 1931 2 Degree Standard Observer"
    else:
        msds = colour.MSDS_CAMERA_SENSITIVITIES[name]
        src = "colour-science MSDS_CAMERA_SENSITIVITIES"
    return sensor_from_samples(name, msds.wavelengths, msds.values, grid, source=src)


@lru_cache(maxsize=128)
def _cached_file(path: str, name: str, grid: SpectralGrid) -> Sensor:
    wl, rgb = read_sensor_file(path)
    return sensor_from_samples(name, wl, rgb, grid, source=path)
