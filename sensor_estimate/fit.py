"""Spectral sensitivities from a camera's colour matrices (DNG ``ColorMatrix1/2``), under a learned prior.

A DNG colour matrix ``M`` maps CIE XYZ to camera RGB for surfaces lit by its calibration illuminant
``E`` (Adobe's convention: rows R, G, B; scaled so the illuminant's white, Y = 1, has its largest
camera channel at 1). For reflectances ``R`` (columns) the camera sees ``Sᵀ diag(E) R`` and the
matrix predicts ``α M Xᵀ diag(E) R`` (``X`` the CIE 1931 observer, ``α`` the unknown overall scale).
With the curves ``S = μ + Σ_k c_k B_k`` under the prior (:mod:`sensor_estimate.prior`), that is
linear in ``(c, α)``: a Gaussian linear model, solved in closed form with the posterior covariance of
``c`` (the estimate's uncertainty). Several matrices (``ColorMatrix1`` and ``2``) add their rows.

The model noise ``σ`` scales with the part of a camera's responses no 3×3 matrix of XYZ explains (its
departure from the Luther condition), taken from the prior's own mean camera — never from the camera
being estimated (:data:`NOISE_SCALE`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.sensor_estimate.prior import Prior

#: the fit's reflectances: colour-science's ColorChecker (what DNG matrices are made from)
FIT_REFLECTANCES = "ColorChecker N Ohta"
#: ``σ`` = this × the mean camera's Luther residual. Chosen on the even-indexed measured cameras
#: (leave-one-out from synthetic D65 matrices, mean white-point error: × 0.1 → 0.68°, × 0.2 → 0.63°,
#: × 0.3 → 0.68°, × 1 → 1.25°), reported on the odd-indexed ones (bench/SENSORS.md)
NOISE_SCALE = 0.2
#: a chart photo's model noise: the patch means' relative error (sensor noise, the chart's reflectances
#: against the library's, flare). Chosen on the even-indexed cameras from synthetic chart photos (x 0.01 ->
#: 0.64 deg, 0.02 -> 0.56, 0.03 -> 0.56, 0.1 -> 0.82: bench/sensors.py), reported on the odd ones
CHART_NOISE = 0.02


def reflectance_columns(name: str, grid) -> np.ndarray:
    """``(n_bands, N)`` reflectances of a library set (``get_reflectances`` gives ``(N, n_bands)``)."""
    from illumix.retarget.reflectances import get_reflectances

    return np.asarray(get_reflectances(name, grid)[1], np.float64).T


def xyz_observer(grid) -> np.ndarray:
    """``(n_bands, 3)`` CIE 1931 2° colour matching functions, band averages on ``grid``."""
    from illumix.retarget.sensors import get_sensor

    return np.asarray(get_sensor("XYZ", grid).sensitivities, np.float64)


def colour_matrix(curves: np.ndarray, spd: np.ndarray, reflectances: np.ndarray, observer: np.ndarray) -> np.ndarray:
    """The DNG-convention ``ColorMatrix`` ``(3, 3)`` (XYZ → camera) of ``curves`` ``(n_bands, 3)`` under
    illuminant ``spd`` ``(n_bands,)``: least squares over ``reflectances`` ``(n_bands, N)``, scaled so
    the illuminant's white (Y = 1) has its largest camera channel at 1."""
    lit = spd[:, None] * reflectances
    cam, xyz = curves.T @ lit, observer.T @ lit
    m = np.linalg.lstsq(xyz.T, cam.T, rcond=None)[0].T
    white = observer.T @ spd
    white = white / white[1]
    return m / (m @ white).max()


@dataclass(frozen=True)
class Estimate:
    """Curves ``(n_bands, 3)`` (green sums to 1, non-negative), ``samples`` ``(n, n_bands, 3)`` drawn from
    the posterior (before clipping), the posterior covariance of the prior coefficients, and the
    relative residual of the matrices' relation."""

    curves: np.ndarray
    samples: np.ndarray
    covariance: np.ndarray
    residual: float


def _design(prior: Prior, matrix: np.ndarray, spd: np.ndarray, reflectances: np.ndarray, observer: np.ndarray):
    """``(J, r0, t)``: the rows ``vec(Sᵀ diag(E) R)`` = ``r0 + J c`` and the matrix's prediction ``t``."""
    lit = spd[:, None] * reflectances  # (n_bands, N)
    r0 = (prior.mean.T @ lit).ravel()
    jac = np.stack([(b.T @ lit).ravel() for b in prior.basis], axis=1)  # (3N, K)
    t = (matrix @ (observer.T @ lit)).ravel()
    return jac, r0, t


def _dng_scaled(m: np.ndarray, spd: np.ndarray, observer: np.ndarray) -> np.ndarray:
    """``m`` scaled as DNG states it (the illuminant's white, Y = 1, at max camera channel 1; a DNG's
    own matrices are already): the fit weighs each matrix by its responses' size, so any input scale
    (1e-300 or 1e300 entries) gives the same estimate."""
    m = m / np.abs(m).max()
    white = observer.T @ spd
    peak = np.max(m @ (white / white[1]))
    if not peak > 0:
        raise SpectralError("the colour matrix maps the illuminant's white to no positive camera channel: check the "
                            "nine numbers' signs and order (rows R, G, B; XYZ -> camera)")
    return m / peak


def model_noise(prior: Prior, spds: list[np.ndarray], reflectances: np.ndarray, observer: np.ndarray) -> float:
    """Relative RMS of the mean camera's responses no 3×3 matrix of XYZ explains (module docstring)."""
    out = []
    for spd in spds:
        lit = spd[:, None] * reflectances
        cam, xyz = prior.mean.T @ lit, observer.T @ lit
        m = np.linalg.lstsq(xyz.T, cam.T, rcond=None)[0].T
        out.append(np.sqrt(np.mean((cam - m @ xyz) ** 2)) / np.sqrt(np.mean(cam ** 2)))
    return float(max(NOISE_SCALE * np.mean(out), 1e-5))


def estimate(prior: Prior, matrices: list[tuple[np.ndarray, np.ndarray]], reflectances: np.ndarray,
             observer: np.ndarray, samples: int = 64, seed: int = 0) -> Estimate:
    """The posterior of the curves given ``matrices`` ``[(ColorMatrix (3, 3), its illuminant (n_bands,))]``."""
    if not matrices:
        raise SpectralError("give at least one colour matrix")
    blocks, consts, targets = [], [], []
    for m, spd in matrices:
        m = np.asarray(m, np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise SpectralError(f"a colour matrix is 3x3 finite numbers (rows R, G, B), got {m.shape}")
        if not np.any(m) or abs(np.linalg.det(m / np.abs(m).max())) < 1e-9:
            raise SpectralError("the colour matrix is singular (its rows are not independent): check the "
                                "nine numbers and their order (rows R, G, B; XYZ -> camera)")
        m = _dng_scaled(m, np.asarray(spd, np.float64), observer)
        jac, r0, t = _design(prior, m, np.asarray(spd, np.float64), reflectances, observer)
        scale = np.sqrt(np.mean(t ** 2))
        blocks.append(jac / scale)
        consts.append(r0 / scale)
        targets.append(t / scale)
    sigma = model_noise(prior, [np.asarray(s, np.float64) for _, s in matrices], reflectances, observer)
    return _solve(prior, blocks, consts, targets, sigma, samples, seed)


def estimate_from_patches(prior: Prior, photos: list[tuple[np.ndarray, np.ndarray]], reflectances: np.ndarray,
                          noise: float | None = None, samples: int = 64, seed: int = 0) -> Estimate:
    """The posterior of the curves given chart photos ``[(patch means (P, 3), illuminant spd (n_bands,))]``
    (linear camera RGB, any exposure), the patches' ``reflectances`` ``(n_bands, P)``: for each photo
    ``Sᵀ diag(E) R = α · responses`` (its own unknown exposure ``α``), noise ``noise`` relative to the
    responses' RMS (default :data:`CHART_NOISE`)."""
    if not photos:
        raise SpectralError("give at least one chart photo")
    blocks, consts, targets = [], [], []
    for responses, spd in photos:
        responses = np.asarray(responses, np.float64)
        if responses.shape == (reflectances.shape[1], 3) and np.all(np.isfinite(responses)) and responses.max() > 0:
            responses = responses / responses.max()  # exposure is the free α: any scale stays finite
        if responses.shape != (reflectances.shape[1], 3) or not np.all(np.isfinite(responses)):
            raise SpectralError(f"chart: need {reflectances.shape[1]} finite RGB patch means, got {responses.shape}")
        if np.any(responses.max(axis=0) <= 0):
            raise SpectralError("chart: a channel reads zero on every patch; is the photo exposed and the chart in it?")
        lit = np.asarray(spd, np.float64)[:, None] * reflectances
        jac = np.stack([(b.T @ lit).T.ravel() for b in prior.basis], axis=1)
        r0 = (prior.mean.T @ lit).T.ravel()
        t = responses.ravel()
        s0, st = np.sqrt(np.mean(r0 ** 2)), np.sqrt(np.mean(t ** 2))  # residuals relative to the responses
        blocks.append(jac / s0)
        consts.append(r0 / s0)
        targets.append(t / st)
    return _solve(prior, blocks, consts, targets, CHART_NOISE if noise is None else noise, samples, seed)


def _solve(prior: Prior, blocks, consts, targets, sigma: float, n_samples: int, seed: int) -> Estimate:
    """Gaussian linear model in ``(c, α_1 … α_m)``: ``r0 + J c − α t ≈ 0`` with noise ``σ`` (relative to
    each matrix's responses), ``c ~ N(0, diag(variance))``, a flat prior on the scales ``α``."""
    k, m = len(prior.variance), len(blocks)
    rows = sum(b.shape[0] for b in blocks)
    a = np.zeros((rows, k + m))
    y = np.zeros(rows)
    at = 0
    for i, (jac, r0, t) in enumerate(zip(blocks, consts, targets)):
        n = jac.shape[0]
        a[at:at + n, :k] = jac
        a[at:at + n, k + i] = -t
        y[at:at + n] = -r0
        at += n
    prec = a.T @ a / sigma ** 2
    prec[:k, :k] += np.diag(1.0 / prior.variance)
    rhs = a.T @ y / sigma ** 2
    cov = np.linalg.pinv(prec, hermitian=True)
    z = cov @ rhs
    c, cov_c = z[:k], cov[:k, :k]
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(cov_c))):
        raise SpectralError("the estimate is not finite: the inputs are degenerate (check the matrices or the chart)")
    rng = np.random.default_rng(seed)
    draws = rng.multivariate_normal(c, (cov_c + cov_c.T) / 2, size=n_samples, method="eigh")
    curves = _clean(prior.curves(c))
    fitted = a @ z
    resid = float(np.sqrt(np.mean((fitted - y) ** 2)))
    return Estimate(curves, prior.curves(draws), cov_c, resid)


def _clean(curves: np.ndarray) -> np.ndarray:
    """Non-negative, green summing to 1."""
    from illumix.sensor_estimate.prior import normalised

    return normalised(np.maximum(curves, 0.0))
