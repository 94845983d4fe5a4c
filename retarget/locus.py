"""The Planckian and CIE daylight loci in a camera's own chromaticity plane (r/g, b/g).

A colour-constancy engineer plots white points as ``R/G`` against ``B/G`` of the camera raw: the
sensor white point (eq. 3.2, ``w_k = Σ_i C_k Φ̄(λ_i) Δλ``, G = 1) of a blackbody at temperature T
traces the Planckian locus of *that* sensor, which is where AWB algorithms search. The loci here are
those white points for blackbodies (Planck's law, ``blackbody:K``) and CIE D-series daylight
(``daylight:K``) on the sensor's spectral grid, exactly as the service computes a group's white point.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from illumix.retarget import illuminants as ill
from illumix.retarget.grid import SpectralGrid

#: temperatures of the plotted loci, kelvin: steps that grow with temperature (the white point moves
#: less per kelvin as T rises) and that include the values worth labelling (2000, 3000, 5000, 6500 K…)
_STEPS = ((1500, 3000, 100), (3000, 6000, 250), (6000, 10000, 500), (10000, 20001, 2000))
PLANCKIAN_KELVIN = tuple(float(k) for lo, hi, step in _STEPS for k in range(lo, hi, step))
DAYLIGHT_KELVIN = tuple(k for k in PLANCKIAN_KELVIN if k >= 4000)


@lru_cache(maxsize=16)
def _spds(kind: str, kelvins: tuple[float, ...], grid: SpectralGrid) -> np.ndarray:
    return np.stack([ill.illuminant_spd(f"{kind}:{k:g}", grid) for k in kelvins])


def locus(sensor_weights: np.ndarray, grid: SpectralGrid, kind: str = "blackbody") -> tuple[np.ndarray, np.ndarray]:
    """``(kelvins (n,), white points (n, 3))`` with G = 1 of ``kind`` (``"blackbody"`` or
    ``"daylight"``) illuminants on a sensor with ``sensor_weights`` ``(bands, 3)`` = ``C_k Δλ``.

    Temperatures whose white point has a non-positive channel on this sensor (it sees no R or B of
    them) are left out rather than refused: a locus is a curve to draw, not a request.
    """
    kelvins = PLANCKIAN_KELVIN if kind == "blackbody" else DAYLIGHT_KELVIN
    rgb = _spds(kind, tuple(kelvins), grid) @ np.asarray(sensor_weights, dtype=np.float64)
    ok = np.all(rgb > 0, axis=1) & np.all(np.isfinite(rgb), axis=1)
    return np.asarray(kelvins, dtype=np.float64)[ok], rgb[ok] / rgb[ok, 1:2]
