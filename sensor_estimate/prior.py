"""The prior over camera spectral sensitivities, learned from measured cameras.

Every measured set (rawtoaces camera JSON / CSV ``wavelength,r,g,b`` files in the folders given) is
read onto the spectral grid as band averages and scaled so the camera's green channel sums to 1 (the
relative channel gains are kept: a colour matrix states them). The prior is a Gaussian over the stacked
``(3 · n_bands)`` vector: the mean camera and the leading principal components with their variances
(Solomatov & Akkaynak 2023 use such a learned basis; a joint basis keeps how the channels co-vary).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid

#: fewer measured cameras than this cannot make a prior worth the name
MIN_CAMERAS = 8


@dataclass(frozen=True)
class MeasuredSet:
    """Measured cameras on one grid: ``names`` and ``curves`` ``(n_cameras, n_bands, 3)`` (G sums to 1)."""

    names: tuple[str, ...]
    curves: np.ndarray
    grid: SpectralGrid

    def without(self, exclude) -> MeasuredSet:
        """The set less the cameras named in ``exclude`` (case-insensitive; an unknown name is an error
        naming the close matches: leaving nothing out by a typo would make a leave-one-out dishonest)."""
        from illumix.retarget.errors import unknown_name

        drop = set()
        folded = {n.lower(): i for i, n in enumerate(self.names)}
        for name in exclude or ():
            if name.lower() not in folded:
                raise unknown_name("measured camera", name, list(self.names))
            drop.add(folded[name.lower()])
        keep = [i for i in range(len(self.names)) if i not in drop]
        return MeasuredSet(tuple(self.names[i] for i in keep), self.curves[keep], self.grid)


def normalised(curves: np.ndarray) -> np.ndarray:
    """``(…, n_bands, 3)`` curves scaled so the green channel sums to 1 (per camera)."""
    g = curves[..., 1].sum(axis=-1)[..., None, None]
    return curves / np.where(g > 0, g, 1.0)


def load_measured(folders, grid: SpectralGrid = DEFAULT_GRID) -> MeasuredSet:
    """Every camera in ``folders`` (``.json`` rawtoaces files or ``.csv`` ``wavelength,r,g,b``) whose
    samples cover the grid; the name is the file's stem (``ARRI_D21_380_780_5`` → ``ARRI_D21``)."""
    from illumix.retarget.sensors import read_sensor_file, sensor_from_samples

    names, curves = [], []
    for folder in folders:
        for f in sorted(Path(folder).glob("*")):
            if f.suffix.lower() not in (".json", ".csv"):
                continue
            try:
                wl, rgb = read_sensor_file(f)
                s = sensor_from_samples(_stem(f.stem), wl, rgb, grid)
            except SpectralError:
                continue  # unreadable, or does not cover the grid
            names.append(s.name)
            curves.append(np.asarray(s.sensitivities, np.float64))
    if len(names) < MIN_CAMERAS:
        raise SpectralError(f"a sensitivity prior needs at least {MIN_CAMERAS} measured cameras covering "
                            f"{grid.start:g}-{grid.end:g} nm; found {len(names)} in {', '.join(map(str, folders)) or 'no folder'}"
                            " (point --prior at rawtoaces camera JSON files, e.g. rawtoaces-data/data/camera)")
    return MeasuredSet(tuple(names), normalised(np.stack(curves)), grid)


def _stem(stem: str) -> str:
    import re

    return re.sub(r"_\d{3}_\d{3}_\d+$", "", stem)


@dataclass(frozen=True)
class Prior:
    """A Gaussian over stacked curves: ``mean`` ``(n_bands, 3)``, ``basis`` ``(K, n_bands, 3)``
    orthonormal components, ``variance`` ``(K,)`` of each component's coefficient, ``residual`` the
    per-element variance the components leave (what the curves vary by outside the basis)."""

    mean: np.ndarray
    basis: np.ndarray
    variance: np.ndarray
    residual: float
    cameras: tuple[str, ...]

    @property
    def n_bands(self) -> int:
        return self.mean.shape[0]

    def curves(self, coefficients: np.ndarray) -> np.ndarray:
        """``(…, n_bands, 3)`` curves of coefficients ``(…, K)``."""
        return self.mean + np.tensordot(coefficients, self.basis, axes=(-1, 0))


def learn_prior(measured: MeasuredSet, components: int = 12) -> Prior:
    """The mean camera and the ``components`` leading principal components of the measured set."""
    x = measured.curves.reshape(len(measured.names), -1)
    mean = x.mean(axis=0)
    u, s, vt = np.linalg.svd(x - mean, full_matrices=False)
    k = min(components, len(s) - 1)
    var = s[:k] ** 2 / max(len(x) - 1, 1)
    resid = float((s[k:] ** 2).sum() / max(len(x) - 1, 1) / x.shape[1])
    shape = measured.curves.shape[1:]
    return Prior(mean.reshape(shape), vt[:k].reshape(k, *shape), var, max(resid, 1e-12), measured.names)
