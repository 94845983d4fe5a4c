"""Conditioning bounds of a sensor × illuminant projection: refuse what has no meaningful ground truth.

Two numbers decide whether a sensor ``C`` and an illuminant ``Φ̄`` give a usable white balance and
colour correction (thesis §3.2; DESIGN.md "Ground truth"):

- the **white-balance gain** ``max_k ρ_k / min_k ρ_k`` of the white point ``ρ_k = Σ_i C_k Φ̄ Δλ``
  (eq. 3.2): the factor the weakest raw channel is multiplied by. Beyond :data:`MAX_WHITE_GAIN` that
  channel sees (almost) nothing of the light; every gain, and every CCM fitted from it, amplifies
  rounding and noise rather than signal (a sensor whose blue curve is 1e-12 × normal gives 1e12);
- the **2-norm condition number** ``σ_max / σ_min`` of the fitted CCM (:mod:`retarget.ccm`). Under
  a (nearly) monochromatic light every reflectance has (nearly) the same raw colour, the least-squares
  fit is rank-deficient and its matrix is arbitrary (|ccm| 1e12 for power only in 392–393 nm) while
  its training-set error looks tiny (0.007 ΔE00): the error alone cannot tell. Beyond
  :data:`MAX_CCM_CONDITION` relative errors in raw (float32 ≈ 6e-8, render noise ≫ that) are
  amplified past anything a ground truth may claim.

Measured range (``tests/test_conditioning.py`` re-checks a subset on every run) over every tabulated
built-in illuminant (colour-science ``SDS_ILLUMINANTS`` that cover 395–705 nm: 52) × every sensor
usable on the default grid (XYZ, Nikon 5100 (NPL), the 52 rawtoaces cameras): gain 1.0014–10.2 and
condition 1.76–5.6 (both worst for XYZ × HP1), fit ΔE00 mean 0.005–1.67, max ≤ 6.4. The parametric
illuminants reach further: ``blackbody:1000`` gain ≤ 230, condition ≤ 41; ``blackbody:500`` (the
documented lower end) gain ≤ 1.2e4, condition ≤ 1.01e4; ``daylight:`` stays inside the tabulated
range. So the bounds keep ≥ 10× margin over every built-in pair and ≥ 1e4× over the tabulated ones.
What they refuse: a line only 1 nm wide (conditions 1.7e12–3e16, or a zero channel); a blue curve
1e-12 × normal (gain ~1e12); a 552 nm line 1e12 above its floor through XYZ (condition 2.8e5; through
the Nikon 3.7e4, still served); a sensor whose G is R to 1e-9 (condition 3.5e9).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError

#: Largest white-balance gain (strongest / weakest white-point channel) a pair may need.
MAX_WHITE_GAIN = 1e6
#: Largest 2-norm condition number of a CCM that is served.
MAX_CCM_CONDITION = 1e5
#: Sensors an uploaded illuminant must be well-conditioned through: the CIE 1931 observer (what
#: every camera approximates) and the measured camera that ships with colour-science.
REFERENCE_SENSORS = ("XYZ", "Nikon 5100 (NPL)")
#: Illuminants an uploaded sensor must be well-conditioned under: daylight and tungsten, the two
#: ends of ordinary lighting.
REFERENCE_ILLUMINANTS = ("D65", "A")

_CHANNELS = ("red", "green", "blue")
# What is wrong and how to fix it, by who is to blame: an upload of either, or a stored pair.
_WHY = {
    "illuminant": ("the illuminant has almost no power where the sensor's {ch} channel sees",
                   "give a broadband SPD (power across 400-700 nm)"),
    "sensor": ("the sensor's {ch} curve is almost zero where the illuminant has power",
               "check the sensor file's {ch} column (its scale and order)"),
    "pair": ("the illuminant has almost no power where this sensor's {ch} channel sees (or that channel "
             "is nearly blind)", "use a broadband illuminant or another sensor"),
}
_WHY_CCM = {
    "illuminant": ("under this light the sensor sees (nearly) fewer than three independent colours, so no "
                   "stable CCM exists", "give a broadband SPD (power across 400-700 nm)"),
    "sensor": ("the sensor's channels are (nearly) linearly dependent", "check that the file's three "
               "curves are the camera's distinct R, G, B sensitivities"),
    "pair": ("under this light this sensor sees (nearly) fewer than three independent colours (a "
             "narrow-band illuminant or dependent channels)", "use a broadband illuminant or another sensor"),
}


@dataclass(frozen=True)
class Conditioning:
    """How well one sensor × illuminant is conditioned, and how well its CCM fits.

    white_rgb : ``(3,)`` raw of the perfect reflector (sensor units; only ratios matter);
    white_gain : ``max / min`` of it (inf for a zero channel); condition : the CCM's 2-norm
    condition number (``None`` before a fit, inf for a singular one); delta_e00_mean / _max : the
    CIEDE2000 of the CCM as served (float32) over its training set (:func:`retarget.ccm.fit_ccm`).
    """

    white_rgb: tuple[float, float, float]
    white_gain: float
    condition: float | None = None
    delta_e00_mean: float | None = None
    delta_e00_max: float | None = None

    def meta(self) -> dict:
        """The JSON fields a sample's ``meta`` states for this pair's CCM."""
        return {"ccm_fit_delta_e00_mean": self.delta_e00_mean, "ccm_fit_delta_e00_max": self.delta_e00_max,
                "ccm_condition_number": self.condition, "white_balance_gain": self.white_gain}


def white_gains(sensor_weights: np.ndarray, spds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(white rgb (G, 3), gains (G,))`` of ``(G, n_bands)`` SPDs through ``(n_bands, 3)`` weights
    ``C_k Δλ``; a gain is inf where a channel is zero (or negative)."""
    rgb = np.atleast_2d(np.asarray(spds, np.float64)) @ np.asarray(sensor_weights, np.float64)
    low, high = rgb.min(axis=1), rgb.max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        gains = np.where(low > 0, high / np.where(low > 0, low, 1.0), np.inf)
    return rgb, gains


def ccm_condition(matrix: np.ndarray) -> float:
    """The 2-norm condition number of a ``(3, 3)`` CCM (inf when singular or not finite)."""
    m = np.asarray(matrix, np.float64)
    if not np.all(np.isfinite(m)):
        return float("inf")
    c = float(np.linalg.cond(m))
    return c if np.isfinite(c) else float("inf")


def check_white(white_rgb: np.ndarray, gain: float, sensor: str, illuminant: str, blame: str = "pair") -> None:
    """:class:`SpectralError` (one line: what, where, why, fix) when ``gain`` exceeds
    :data:`MAX_WHITE_GAIN`; ``blame`` is ``"illuminant"``, ``"sensor"`` (an upload) or ``"pair"``."""
    if gain <= MAX_WHITE_GAIN:
        return
    rgb = np.asarray(white_rgb, np.float64)
    weak, strong = _CHANNELS[int(np.argmin(rgb))], _CHANNELS[int(np.argmax(rgb))]
    ratio = max(float(rgb.min()), 0.0) / float(rgb.max()) if rgb.max() > 0 else 0.0
    why, fix = (s.format(ch=weak) for s in _WHY[blame])
    raise SpectralError(f"illuminant {illuminant!r} through sensor {sensor!r}: its white point's {weak} channel "
                        f"is {ratio:.2g} of its {strong} (limit {1 / MAX_WHITE_GAIN:.0e}, a white-balance gain of "
                        f"{MAX_WHITE_GAIN:.0e}): {why}; {fix}")


def check_ccm(condition: float, sensor: str, illuminant: str, blame: str = "pair") -> None:
    """:class:`SpectralError` (one line) when a CCM's condition number exceeds :data:`MAX_CCM_CONDITION`."""
    if condition <= MAX_CCM_CONDITION:
        return
    why, fix = _WHY_CCM[blame]
    raise SpectralError(f"illuminant {illuminant!r} through sensor {sensor!r}: its colour-correction matrix has "
                        f"condition number {condition:.2g} (limit {MAX_CCM_CONDITION:.0e}): {why}; {fix}")


def require(q: Conditioning, sensor: str, illuminant: str, blame: str = "pair") -> Conditioning:
    """``q`` when both bounds hold, else the :class:`SpectralError` of the first that does not."""
    check_white(np.asarray(q.white_rgb), q.white_gain, sensor, illuminant, blame)
    if q.condition is not None:
        check_ccm(q.condition, sensor, illuminant, blame)
    return q
