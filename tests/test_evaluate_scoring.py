"""Per-image scores (:mod:`awb_eval.scoring`) against independent computations: the angle between
two illuminants by the dot-product formula, and the ΔE00 grid through colour-science's own sRGB
encoding, Lab conversion and CIEDE2000 on hand-made 2×2-pixel cells (float64 references; the
scoring path renders in float32, so ΔE00 agrees to 1e-3 and angles to 1e-4°)."""

from __future__ import annotations

import colour
import numpy as np

from illumix.awb_eval.case import Case
from illumix.awb_eval.methods import gain_from_illuminant
from illumix.awb_eval.scoring import reference, score

H, W = 24, 32  # 12 × 16 cells of 2 × 2 pixels


def make_case(illum=(0.6, 1.0, 0.5)) -> Case:
    rng = np.random.default_rng(1)
    raw = (rng.uniform(0.05, 0.6, (H, W, 3)) * np.array(illum)).astype(np.float32)
    ccm = np.array([[1.6, -0.5, -0.1], [-0.2, 1.5, -0.3], [0.0, -0.4, 1.4]], np.float32)
    return Case("c", "X", raw=raw, illum=np.broadcast_to(np.float32(illum), (H, W, 3)).copy(),
                mask=np.ones((H, W), bool), mixture=np.ones((H, W, 1), np.float32),
                white_points=np.array([illum], np.float64), ccm=ccm)


def angle(a, b) -> float:
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return float(np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b))))


def test_angular_error_of_a_uniform_estimate():
    case = make_case()
    ref = reference(case)
    estimate = np.array([0.7, 1.0, 0.45])
    gain = gain_from_illuminant(np.broadcast_to(np.float32(estimate), (H, W, 3)))
    s, _err = score(case, gain, ref)
    expect = angle(estimate, case.illum[0, 0])
    assert abs(s["angular_mean"] - expect) < 1e-4 and abs(s["angular_worst25"] - expect) < 1e-4
    # a gain map's overall scale is not its colour: 3× the gains score the same
    s3, _ = score(case, 3 * gain, ref)
    assert s3 == s
    # the ground truth itself
    s0, _ = score(case, ref.gain, ref)
    assert s0["angular_max"] < 1e-3 and s0["grid_de00_worst25"] == 0.0


def test_grid_de00_against_colour_science():
    case = make_case()
    ref = reference(case)
    estimate = np.array([0.5, 1.0, 0.7])
    gain = gain_from_illuminant(np.broadcast_to(np.float32(estimate), (H, W, 3)))
    s, _ = score(case, gain, ref)

    def srgb(g):
        linear = np.einsum("ij,hwj->hwi", case.ccm.astype(np.float64), case.raw * np.asarray(g, np.float64)) * ref.exposure
        return colour.cctf_encoding(np.clip(linear, 0, 1), function="sRGB")

    def cells(img):
        return img.reshape(12, 2, 16, 2, 3).mean(axis=(1, 3))

    def lab(img):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(img), colour.RGB_COLOURSPACES["sRGB"].whitepoint)

    de = colour.delta_E(lab(cells(srgb(ref.gain))), lab(cells(srgb(gain))), method="CIE 2000").ravel()
    worst = np.sort(de)[-48:].mean()  # 25 % of 192 cells
    assert abs(s["grid_de00_worst25"] - worst) < 1e-3 and worst > 1.0
