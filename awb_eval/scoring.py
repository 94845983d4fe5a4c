"""Per-image scores of one gain map against the ground truth (:mod:`retarget.metrics`).

- per-pixel angular error (thesis eq. 5.1) between the method's implied illuminant ``1 / gain``
  and the GT illuminant, over the GT's valid mask: mean, median, trimean, best/worst 25 %, max
  (Hordley & Finlayson 2006's statistics, here over the pixels of one image);
- ΔE00 grid worst 25 % (thesis appendix B: 12 × 16 cells): the raw white-balanced by the method's
  gains and by the GT's, both through the same CCM (the case's) and the same exposure (the GT
  rendering's constant AEC, eq. 4.2) and the sRGB transfer function (thesis §5.2: "the same CCM
  matrix and gamma function is used as in other methods for equal comparison").

Gains are taken in the GT's convention (``max_j e_j / e_k``, renormalised so: a plug-in's overall
brightness does not count), so the grid ΔE00 measures the colour of the white balance, not exposure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.awb_eval.case import Case
from illumix.awb_eval.methods import gain_from_illuminant
from illumix.retarget.exposure import aec_gain
from illumix.retarget.isp import apply_ccm, render_srgb
from illumix.retarget.metrics import angular_error, grid_delta_e00, summary_statistics

# angular_<stat> keys of a score, in table order
ANGULAR_STATS = ("mean", "median", "trimean", "best25", "worst25", "max")


@dataclass
class Reference:
    """What every method of one case is compared with: the GT gains, exposure and sRGB."""

    gain: np.ndarray
    exposure: float
    srgb: np.ndarray


def reference(case: Case) -> Reference:
    """The GT rendering: raw × GT gain → CCM → constant AEC (eq. 4.2) → sRGB."""
    gain = gain_from_illuminant(case.illum)
    exposure = aec_gain(apply_ccm(case.raw * gain, case.ccm), method="constant")
    return Reference(gain, exposure, render_srgb(case.raw, gain, case.ccm, exposure))


def angular_error_map(case: Case, gain: np.ndarray) -> np.ndarray:
    """Per-pixel angle (degrees) between ``1 / gain`` and the GT illuminant, ``(H, W)`` float32
    (computed everywhere; only ``case.mask`` is scored)."""
    return angular_error(1.0 / np.asarray(gain, dtype=np.float64), case.illum).astype(np.float32)


def score(case: Case, gain: np.ndarray, ref: Reference) -> tuple[dict[str, float], np.ndarray]:
    """``(scores, angular error map)``: ``angular_<stat>`` over the valid pixels (degrees) and
    ``grid_de00_worst25`` (ΔE00)."""
    normalised = gain_from_illuminant(1.0 / np.asarray(gain, dtype=np.float32))
    err = angular_error_map(case, normalised)
    stats = summary_statistics(err[case.mask])
    out = {f"angular_{k}": stats[k] for k in ANGULAR_STATS}
    srgb = render_srgb(case.raw, normalised, case.ccm, ref.exposure)
    out["grid_de00_worst25"] = grid_delta_e00(ref.srgb, srgb)[0]
    return out, err
