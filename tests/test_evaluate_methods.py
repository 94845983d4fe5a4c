"""AWB methods (:mod:`awb_eval.statistical`, :mod:`awb_eval.methods`) against hand-computed cases.

Each estimate is compared with an independent float64 computation of its defining equation (van de
Weijer et al. 2007, eq. 10) or a closed form. Tolerances: the methods work in float64 and return
float32 gains, so 1e-5 relative (a few float32 ulps) is the bound; the Gaussian derivative filters
have exact moments up to order 2, so on quadratic polynomials they match the closed form to float64
rounding (1e-9).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from illumix.awb_eval.case import Case
from illumix.awb_eval.method_names import AWB_METHODS, DEFAULT_METHODS
from illumix.awb_eval.methods import awb_gain_map, statistical_gain, weighted_average_gain
from illumix.awb_eval.statistical import derivative_magnitude, grid_estimates, illuminant_map
from illumix.retarget.errors import SpectralError, UnknownName

RNG = np.random.default_rng(3)


def expected_gain(e: np.ndarray) -> np.ndarray:
    """Thesis eq. 3.3 for one illuminant estimate: max_j e_j / e_k."""
    e = np.asarray(e, np.float64)
    return e.max() / e


def textured(h: int = 40, w: int = 56, colour=(0.8, 0.5, 0.3)) -> np.ndarray:
    """A random grey-texture image under a coloured light."""
    return (RNG.uniform(0.05, 1.0, (h, w, 1)) * np.array(colour)).astype(np.float32)


def test_gray_world_is_the_channel_mean():
    raw = RNG.uniform(0.0, 1.0, (30, 40, 3)).astype(np.float32) * np.float32([2.0, 1.0, 0.5])
    gain = statistical_gain(raw, "Gray World")
    assert gain.shape == (30, 40, 3)
    np.testing.assert_allclose(gain, np.broadcast_to(expected_gain(raw.astype(np.float64).mean(axis=(0, 1))),
                                                     gain.shape), rtol=1e-5)


def test_gray_world_on_a_known_mean():
    # two flat halves: mean = ((0.2, 0.4, 0.6) + (0.6, 0.4, 0.2)) / 2 = (0.4, 0.4, 0.4) → unit gains
    raw = np.empty((10, 20, 3), np.float32)
    raw[:, :10], raw[:, 10:] = (0.2, 0.4, 0.6), (0.6, 0.4, 0.2)
    np.testing.assert_allclose(statistical_gain(raw, "gray world")[0, 0], [1, 1, 1], rtol=1e-6)


def test_white_patch_is_the_channel_max():
    raw = textured()
    raw[3, 4] = (5.0, 1.0, 2.0)  # the brightest of each channel, not one pixel's colour in general
    raw[7, 9, 1] = 4.0
    gain = awb_gain_map(raw, "max-RGB")
    np.testing.assert_allclose(gain[0, 0], expected_gain([5.0, 4.0, 2.0]), rtol=1e-6)


def test_shades_of_gray_is_the_p6_norm():
    raw = RNG.uniform(0.0, 1.0, (25, 35, 3)).astype(np.float32)
    x = raw.reshape(-1, 3).astype(np.float64)
    e = np.linalg.norm(x, ord=6, axis=0)  # (Σ x^6)^{1/6}: the mean's N^{-1/6} is a common scale
    np.testing.assert_allclose(awb_gain_map(raw, "SoG")[5, 5], expected_gain(e), rtol=1e-5)
    # p overrides: p = 1 is Gray World
    np.testing.assert_allclose(statistical_gain(raw, "Shades of Gray", p=1), statistical_gain(raw, "GW"), rtol=1e-6)


@pytest.mark.parametrize("method, order", [("Gray Edge", 1), ("2nd Order Gray Edge", 2)])
def test_gray_edge_on_a_gradient_image(method, order):
    # f_c = a_c · xⁿ + b_c: every derivative of order n is a_c times the same function of x, so the
    # estimate is ∝ a (whatever the Gaussian and the border do), while the offsets b fool Gray World.
    h, w = 48, 64
    x = np.arange(w, dtype=np.float64)[None, :, None] / w
    a, b = np.array([0.2, 0.5, 0.9]), np.array([3.0, 0.5, 0.1])
    raw = np.broadcast_to(a * x ** order + b, (h, w, 3)).astype(np.float32)
    np.testing.assert_allclose(statistical_gain(raw, method)[10, 10], expected_gain(a), rtol=1e-4)
    assert not np.allclose(statistical_gain(raw, "Gray World")[10, 10], expected_gain(a), rtol=1e-2)


def test_derivative_magnitudes_against_closed_forms():
    # Gaussian smoothing of a polynomial of degree ≤ 2 changes only its constant term
    # (x² * G_σ = x² + σ²), so in the interior: |∇(x² + y²)| = 2√(x² + y²),
    # √(f_xx² + 4 f_xy² + f_yy²) = 2√2 for x² + y² and 2 for x·y.
    h, w, s = 60, 60, 2.0
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) / 10.0
    inner = (slice(15, 45), slice(15, 45))
    for f, order, expect in ((x ** 2 + y ** 2, 1, 2 * np.hypot(x, y)), (x ** 2 + y ** 2, 2, np.full_like(x, 2 * math.sqrt(2))),
                             (x * y, 2, np.full_like(x, 2.0))):
        img = np.repeat(f[..., None], 3, axis=2)
        got = derivative_magnitude(img, order, s)[..., 0] * (10.0 ** order)  # pixels → units of x
        np.testing.assert_allclose(got[inner], expect[inner], rtol=1e-9)


def test_patch_wise_on_a_two_half_image():
    h, w = 20, 40
    c1, c2 = np.array([0.9, 0.6, 0.2]), np.array([0.3, 0.6, 0.9])
    raw = textured(h, w, (1, 1, 1))
    raw[:, : w // 2] *= c1.astype(np.float32)
    raw[:, w // 2:] *= c2.astype(np.float32)
    gain = statistical_gain(raw, "Patch Gray World", grid=(1, 2), interpolation="nearest")
    np.testing.assert_allclose(gain[:, : w // 2], np.broadcast_to(expected_gain(c1), (h, w // 2, 3)), rtol=1e-5)
    np.testing.assert_allclose(gain[:, w // 2:], np.broadcast_to(expected_gain(c2), (h, w // 2, 3)), rtol=1e-5)
    # bilinear: the cell estimates sit at the cell centres and are held beyond the outer ones
    smooth = statistical_gain(raw, "Patch Gray World", grid=(1, 2))
    np.testing.assert_allclose(smooth[:, :10], np.broadcast_to(expected_gain(c1), (h, 10, 3)), rtol=1e-5)
    np.testing.assert_allclose(smooth[:, 30:], np.broadcast_to(expected_gain(c2), (h, 10, 3)), rtol=1e-5)
    # between the centres (x = 9.5 … 29.5) the illuminant chromaticity is interpolated linearly
    e1, e2 = c1 / c1.sum(), c2 / c2.sum()
    mid = illuminant_map(np.stack([e1, e2])[None], (h, w))[0, 19]
    np.testing.assert_allclose(mid, e1 + (19 - 9.5) / 20 * (e2 - e1), rtol=1e-5)


def test_patch_wise_default_grid_and_empty_cells():
    raw = textured(40, 40)
    valid = np.ones((40, 40), bool)
    valid[:20, :20] = False  # that cell has no usable pixel: it takes the global estimate
    cells, total = grid_estimates(raw, grid=(2, 2), valid=valid)
    np.testing.assert_allclose(cells[0, 0], total)
    assert statistical_gain(raw, "patch-gw").shape == (40, 40, 3)


def test_degenerate_images_give_finite_neutral_gains():
    black = np.zeros((16, 16, 3), np.float32)
    for name in ("Gray World", "White Patch", "Gray Edge", "Patch Gray Edge"):
        np.testing.assert_array_equal(awb_gain_map(black, name), np.ones((16, 16, 3), np.float32))
    flat = np.full((16, 16, 3), 0.5, np.float32)  # no edges at all
    np.testing.assert_array_equal(awb_gain_map(flat, "GE2"), np.ones((16, 16, 3), np.float32))


def test_weighted_average_is_the_mean_mixture_of_white_points():
    h, w = 12, 16
    share = np.tile(np.linspace(0, 1, w, dtype=np.float32), (h, 1))
    mixture = np.stack([share, 1 - share], axis=-1)
    mask = np.ones((h, w), bool)
    mask[:, :4] = False  # only valid pixels count
    wps = np.array([[0.5, 1.0, 1.6], [1.4, 1.0, 0.6]])
    case = Case("c", "A,D65", raw=np.ones((h, w, 3), np.float32), illum=(mixture @ wps).astype(np.float32),
                mask=mask, mixture=mixture, white_points=wps, ccm=np.eye(3, dtype=np.float32))
    s = share[:, 4:].mean()
    np.testing.assert_allclose(weighted_average_gain(case)[0, 0], expected_gain(s * wps[0] + (1 - s) * wps[1]), rtol=1e-5)
    np.testing.assert_allclose(awb_gain_map(case.raw, "GT", truth=case), np.asarray(
        [[expected_gain(v) for v in row] for row in case.illum]), rtol=1e-6)
    with pytest.raises(SpectralError, match="reads the ground truth"):
        awb_gain_map(case.raw, "Weighted Average")


def test_weighted_average_is_the_explorers_baseline(monkeypatch):
    """One implementation of the thesis' single white point: the evaluator's Weighted Average goes
    through :mod:`retarget.global_wb` (the web explorer's and the DNG's), with the same numbers."""
    from illumix.retarget import global_wb

    h, w = 6, 8
    share = np.tile(np.linspace(0, 1, w, dtype=np.float32), (h, 1))
    mixture = np.stack([share, 1 - share], axis=-1)
    wps = np.array([[0.5, 1.0, 1.6], [1.4, 1.0, 0.6]])
    case = Case("c", "A,D65", raw=np.ones((h, w, 3), np.float32), illum=(mixture @ wps).astype(np.float32),
                mask=np.ones((h, w), bool), mixture=mixture, white_points=wps, ccm=np.eye(3, dtype=np.float32))
    calls = []
    real = global_wb.global_white_point
    monkeypatch.setattr(global_wb, "global_white_point", lambda *a: calls.append(a) or real(*a))
    expected = global_wb.render_global(case.raw, real(global_wb.frame_shares(mixture, case.mask), wps), np.eye(3))
    got = global_wb.render_global(case.raw * weighted_average_gain(case), np.ones(3), np.eye(3))
    assert len(calls) == 1
    np.testing.assert_allclose(got, expected, atol=1e-6)
    # no valid pixel: nothing to weight by, every light counts the same
    case.mask[:] = False
    case.mixture = np.zeros_like(mixture)
    np.testing.assert_allclose(weighted_average_gain(case)[0, 0], expected_gain(wps.mean(axis=0)), rtol=1e-6)


def test_registry_names_aliases_and_case():
    canon = AWB_METHODS.canonical
    assert canon("grey world") == canon("GW") == canon("gray-world") == "Gray World"
    assert canon("max-RGB") == canon("MAXRGB") == canon("white_patch") == "White Patch"
    assert canon("sog") == "Shades of Gray"
    assert canon("GE1") == canon("grey edge") == canon("1st order gray edge") == "Gray Edge"
    assert canon("ge2") == canon("second-order gray edge") == "2nd Order Gray Edge"
    assert canon("patch max-rgb") == "Patch White Patch" and canon("Patch GE2") == "Patch 2nd Order Gray Edge"
    assert canon("gt") == "Ground Truth" and canon("wa") == "Weighted Average"
    assert all(m in AWB_METHODS for m in DEFAULT_METHODS)
    with pytest.raises(UnknownName, match="did you mean 'Gray World'"):
        canon("Gray Wrld")


def test_bad_parameters_are_one_line_errors():
    raw = textured()
    with pytest.raises(SpectralError, match="does not fit"):
        statistical_gain(raw, "Patch Gray World", grid=(100, 2))
    with pytest.raises(SpectralError, match="sigma > 0"):
        statistical_gain(raw, "Gray Edge", sigma=0)
    with pytest.raises(SpectralError, match="p must be >= 1"):
        statistical_gain(raw, "Shades of Gray", p=0.5)
    with pytest.raises(SpectralError, match="not a statistical"):
        statistical_gain(raw, "Ground Truth")
