"""Colour-correction matrices per sensor × illuminant (thesis §3.2 "CCM"; DESIGN.md "Ground truth").

A CCM maps *white-balanced* camera raw to linear sRGB. For illuminant Φ and a reflectance training
set ``S_n``:

- camera raw ``ρ_n = Σ_i C(λ_i) Φ̄(λ_i) S_n(λ_i) Δλ``, white-balanced by the raw of the perfect
  reflector ``ρ_w`` (so white becomes ``(1, 1, 1)``);
- target ``t_n`` = linear sRGB of the same reflectance *as seen under Φ by an observer adapted to
  Φ*: CIE 1931 XYZ under Φ (white Y = 1), chromatically adapted from Φ's white to sRGB's D65 white
  by colour-science's ``chromatic_adaptation`` (``cat``, default Von Kries with CAT02), then the
  sRGB matrix;
- ``M = argmin Σ_n ‖M ρ̂_n − t_n‖²`` subject to ``M (1, 1, 1)ᵀ = (1, 1, 1)ᵀ`` (white preserving), each
  row solved on the constraint's null space by least squares (robust to near-degenerate sensors).

The fit's quality is reported as CIEDE2000 between ``M ρ̂_n`` (``M`` rounded to float32, as served) and
``t_n`` in CIELAB (D65), and by ``M``'s condition number (bounded by :mod:`retarget.conditioning`).
Methods are dispatched by name through :data:`CCM_METHODS` (case-insensitive, with aliases; defined
in :mod:`retarget.ccm_methods`):
``method="White Preserving"`` (default; alias ``"wp"``) or ``"Unconstrained"`` (alias
``"Least Squares"``).

colour-science is imported on first use, not at import.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from illumix.retarget.ccm_methods import CCM_METHODS
from illumix.retarget.conditioning import ccm_condition
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import SpectralGrid, resample


@dataclass(frozen=True)
class CCMFit:
    """A fitted CCM: ``matrix`` ``(3, 3)`` (rows = sRGB R, G, B) and per-sample CIEDE2000."""

    matrix: np.ndarray
    delta_e00: np.ndarray = field(repr=False)

    @property
    def delta_e00_mean(self) -> float:
        return float(np.mean(self.delta_e00))

    @property
    def delta_e00_max(self) -> float:
        return float(np.max(self.delta_e00))

    @property
    def condition(self) -> float:
        """The matrix's 2-norm condition number (see :mod:`retarget.conditioning`)."""
        return ccm_condition(self.matrix)


@lru_cache(maxsize=1)
def _srgb():
    """``(colour module, sRGB colourspace, D65 white XYZ)``, loaded once on first use."""
    import colour

    space = colour.RGB_COLOURSPACES["sRGB"]
    return colour, space, colour.xy_to_XYZ(space.whitepoint)


@lru_cache(maxsize=16)
def _cmfs(grid: SpectralGrid) -> np.ndarray:
    import colour

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return resample(cmfs.wavelengths, cmfs.values, grid) * grid.step


def target_linear_srgb(spd: np.ndarray, reflectances: np.ndarray, grid: SpectralGrid,
                       cat: str = "CAT02") -> np.ndarray:
    """Adapted linear-sRGB targets ``(N, 3)`` of reflectances ``(N, n_bands)`` under ``spd``."""
    colour, srgb, d65 = _srgb()
    cmf = _cmfs(grid)
    white = spd @ cmf
    if white[1] <= 0:
        raise SpectralError("CCM: the illuminant has no luminance on the grid")
    xyz = (reflectances * spd) @ cmf / white[1]
    xyz_adapted = colour.chromatic_adaptation(xyz, white / white[1], d65,
                                              method="Von Kries", transform=cat)
    return colour.XYZ_to_RGB(xyz_adapted, srgb, apply_cctf_encoding=False)


def linear_srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of linear sRGB ``(..., 3)``."""
    colour, srgb, _ = _srgb()
    xyz = colour.RGB_to_XYZ(rgb, srgb, apply_cctf_decoding=False)
    return colour.XYZ_to_Lab(xyz, srgb.whitepoint)


def _solve(a: np.ndarray, t: np.ndarray, white_preserving: bool) -> np.ndarray:
    if not white_preserving:
        return np.linalg.lstsq(a, t, rcond=None)[0].T
    # m_r = 1/3·(1,1,1) + N z with N spanning {v : 1·v = 0}: the constraint holds for every z.
    null = np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, -1.0]])
    base = np.full(3, 1.0 / 3.0)
    z = np.linalg.lstsq(a @ null, t - (a @ base)[:, None], rcond=None)[0]
    return (base[:, None] + null @ z).T


def fit_ccm(sensor_weights: np.ndarray, spd: np.ndarray, reflectances: np.ndarray, grid: SpectralGrid,
            *, method: str = "White Preserving", cat: str = "CAT02") -> CCMFit:
    """Fit the CCM of one sensor × illuminant (see module docstring).

    sensor_weights : ``(n_bands, 3)`` ``C_k Δλ``; spd : ``(n_bands,)``; reflectances ``(N, n_bands)``.
    """
    white_preserving = CCM_METHODS[method]
    r = np.asarray(reflectances, dtype=np.float64)
    if r.ndim != 2 or r.shape[0] < 3:
        raise SpectralError(f"CCM: need at least 3 training reflectances, got shape {r.shape}")
    cw = np.asarray(sensor_weights, dtype=np.float64)
    raw_white = spd @ cw
    if np.any(raw_white <= 0):
        raise SpectralError("CCM: the illuminant gives no response in some sensor channel")
    raw = (r * spd) @ cw / raw_white
    target = target_linear_srgb(spd, r, grid, cat)
    m = _solve(raw, target, white_preserving)
    if not np.all(np.isfinite(m)):
        raise SpectralError("CCM: the fit is degenerate (sensor channels are linearly dependent)")
    colour = _srgb()[0]
    # The error of the matrix as it is served (float32 maps), not of the float64 solution: for an
    # ill-conditioned fit (huge, cancelling entries) only the former shows how wrong it is.
    with np.errstate(over="ignore", invalid="ignore"):  # an entry beyond float32 serves as inf: its ΔE is NaN
        served = m.astype(np.float32).astype(np.float64)
        de = colour.delta_E(linear_srgb_to_lab(raw @ served.T), linear_srgb_to_lab(target), method="CIE 2000")
    return CCMFit(matrix=m, delta_e00=np.asarray(de, dtype=np.float64))
