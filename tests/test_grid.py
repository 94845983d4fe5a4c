"""Spectral grid and band-integrated resampling (issue 2, item 2) against closed forms and quadrature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from independent import band_average_fine, fine_lattice, interp
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid, resample

# ---------------------------------------------------------------------------------------- the grid


def test_default_grid_is_the_thesis_grid():
    g = DEFAULT_GRID
    assert g.n_bands == 63
    assert g.wavelengths[0] == 395.0 and g.wavelengths[-1] == 705.0
    np.testing.assert_array_equal(np.diff(g.wavelengths), 5.0)
    assert g.edges.shape == (64,)
    assert g.span == (392.5, 707.5)
    np.testing.assert_array_equal(0.5 * (g.edges[1:] + g.edges[:-1]), g.wavelengths)


def test_grid_round_trips_through_dict_and_is_hashable():
    g = SpectralGrid(400, 700, 10)
    assert SpectralGrid.from_dict(g.to_dict()) == g
    assert g.n_bands == 31
    assert len({g, SpectralGrid(400.0, 700.0, 10.0)}) == 1  # usable as an lru_cache key
    assert "31 bands" in str(g)


@pytest.mark.parametrize("args", [(400, 700, 0), (400, 700, -5), (700, 400, 5), (400, 703, 5)])
def test_invalid_grids_are_refused(args):
    with pytest.raises(SpectralError, match="invalid spectral grid"):
        SpectralGrid(*args)


# ------------------------------------------------------------------------------- closed forms


@pytest.mark.parametrize("grid", [DEFAULT_GRID, SpectralGrid(400, 700, 10), SpectralGrid(380, 780, 1)])
def test_linear_spectrum_band_average_is_its_centre_value(grid):
    # The average of a linear function over a symmetric interval is its value at the centre.
    # The interpolant of a linear function's samples is the function itself, so this is exact
    # up to float rounding (values ~1e3, cumulative sums ~1e5: 1e-9 relative is generous).
    wl = np.arange(300.0, 831.0, 7.0)
    f = lambda x: 3.0 * x - 200.0  # noqa: E731
    out = resample(wl, f(wl), grid)
    np.testing.assert_allclose(out, f(grid.wavelengths), rtol=1e-9)


def test_quadratic_spectrum_matches_closed_form_plus_interpolation_offset():
    # f(λ) = λ², tabulated every h = 0.5 nm. Exact band average: (b³ − a³) / (3 (b − a)).
    # The piecewise-linear interpolant of a convex quadratic lies above it; on each knot interval
    # the mean overshoot is f''·h²/12 = h²/6, and the band edges (multiples of 2.5 nm) are knots,
    # so the interpolant's band average is exactly closed form + h²/6.
    h = 0.5
    wl = np.arange(390.0, 710.0 + h / 2, h)
    out = resample(wl, wl**2, DEFAULT_GRID)
    a, b = DEFAULT_GRID.edges[:-1], DEFAULT_GRID.edges[1:]
    exact = (b**3 - a**3) / (3 * (b - a))
    np.testing.assert_allclose(out, exact + h * h / 6, rtol=1e-11)
    # and it is *not* point sampling: the centre values differ from the band averages by Δλ²/12.
    assert np.all(np.abs(out - DEFAULT_GRID.wavelengths**2) > 2.0)


def test_matches_scipy_quad_of_the_interpolant_on_an_irregular_table():
    rng = np.random.default_rng(7)
    wl = np.sort(np.concatenate([[385.0, 715.0], rng.uniform(385, 715, 60)]))
    v = rng.uniform(0, 2, wl.size) ** 3  # rough, spiky
    out = resample(wl, v, DEFAULT_GRID)

    def f(x):
        return np.interp(x, wl, v)

    ref = []
    for lo, hi in zip(DEFAULT_GRID.edges[:-1], DEFAULT_GRID.edges[1:]):
        knots = wl[(wl > lo) & (wl < hi)]
        val, err = integrate.quad(f, lo, hi, points=knots if knots.size else None, limit=200,
                                  epsabs=1e-13, epsrel=1e-12)
        ref.append(val / (hi - lo))
    # quad with the knots as break points integrates each linear piece to ~1e-14 relative.
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-12)


def test_matches_fine_trapezoid_reference_on_colour_science_d65():
    import colour

    sd = colour.SDS_ILLUMINANTS["D65"]
    out = resample(sd.wavelengths, sd.values, DEFAULT_GRID)
    x = fine_lattice()
    ref = band_average_fine(interp(sd.wavelengths, sd.values, x))
    # The 5 nm knots lie on the 0.05 nm lattice: the trapezoid rule is exact for the interpolant.
    np.testing.assert_allclose(out, ref, rtol=1e-10)


def test_narrow_line_inside_a_band_is_integrated_not_missed():
    # A 1 nm wide triangular emission line (area 0.5) centred at 551.3 nm lies inside the
    # 550 nm band [547.5, 552.5]: its average there is area / Δλ = 0.1; every other band is dark.
    wl = np.array([380.0, 550.8, 551.3, 551.8, 720.0])
    v = np.array([0.0, 0.0, 1.0, 0.0, 0.0])
    out = resample(wl, v, DEFAULT_GRID)
    i550 = int(np.flatnonzero(DEFAULT_GRID.wavelengths == 550.0)[0])
    assert out[i550] == pytest.approx(0.1, rel=1e-12)
    assert np.count_nonzero(out) == 1
    # point sampling at the band centres would see nothing at all
    assert np.interp(DEFAULT_GRID.wavelengths, wl, v).max() == 0.0
    assert out.sum() * DEFAULT_GRID.step == pytest.approx(0.5, rel=1e-12)


def test_line_on_a_band_edge_is_split_between_the_two_bands():
    wl = np.array([380.0, 552.0, 552.5, 553.0, 720.0])
    v = np.array([0.0, 0.0, 1.0, 0.0, 0.0])
    out = resample(wl, v, DEFAULT_GRID)
    i = int(np.flatnonzero(DEFAULT_GRID.wavelengths == 550.0)[0])
    # area 0.5 in total, 0.25 on each side of 552.5 nm → 0.05 average in each band
    assert out[i] == pytest.approx(0.05, rel=1e-12)
    assert out[i + 1] == pytest.approx(0.05, rel=1e-12)
    assert np.count_nonzero(out) == 2


def test_total_power_is_conserved():
    rng = np.random.default_rng(3)
    wl = np.concatenate([[392.5], np.sort(rng.uniform(393, 707, 200)), [707.5]])
    v = rng.exponential(1.0, wl.size)
    out = resample(wl, v, DEFAULT_GRID)
    # Σ f̄_i Δλ is the exact integral of the interpolant over the span = trapezoid on its knots.
    assert out.sum() * DEFAULT_GRID.step == pytest.approx(np.trapezoid(v, wl), rel=1e-12)


def test_multi_column_equals_column_by_column_and_order_is_irrelevant():
    rng = np.random.default_rng(11)
    wl = np.arange(380.0, 781.0, 4.0)
    v = rng.uniform(0, 1, (wl.size, 3))
    both = resample(wl, v, DEFAULT_GRID)
    assert both.shape == (63, 3)
    for k in range(3):
        np.testing.assert_array_equal(both[:, k], resample(wl, v[:, k], DEFAULT_GRID))
    perm = rng.permutation(wl.size)
    np.testing.assert_allclose(resample(wl[perm], v[perm], DEFAULT_GRID), both, rtol=1e-15)


# ----------------------------------------------------------------------------------- coverage


def test_spectrum_not_covering_the_grid_is_refused_by_default():
    wl = np.arange(400.0, 701.0, 10.0)
    with pytest.raises(SpectralError, match=r"400-700 nm.*392\.5-707\.5 nm.*extension policy"):
        resample(wl, np.ones_like(wl), DEFAULT_GRID, what="my spectrum")
    # Covering the span exactly (the band edges, not just the centres) is enough.
    wl2 = np.array([392.5, 707.5])
    np.testing.assert_allclose(resample(wl2, np.ones(2), DEFAULT_GRID), 1.0)
    with pytest.raises(SpectralError, match="392.5-707.5"):
        resample(np.array([395.0, 705.0]), np.ones(2), DEFAULT_GRID)


def test_constant_extension_holds_the_end_values():
    wl = np.arange(400.0, 701.0, 10.0)
    out = resample(wl, wl.copy(), DEFAULT_GRID, extend="constant")  # f(λ) = λ on [400, 700]
    assert out[0] == pytest.approx(400.0, rel=1e-12)  # [392.5, 397.5]: all extension
    # [397.5, 402.5]: 2.5 nm at 400 plus ∫_400^402.5 λ dλ = (402.5² − 400²)/2 = 1003.125
    assert out[1] == pytest.approx((2.5 * 400 + 1003.125) / 5, rel=1e-12)
    assert out[-1] == pytest.approx(700.0, rel=1e-12)
    # Reference: np.interp holds the end values outside the samples, exactly this policy.
    ref = band_average_fine(interp(wl, wl, fine_lattice()))
    np.testing.assert_allclose(out, ref, rtol=1e-11)


def test_zero_extension_steps_to_zero_outside_the_samples():
    wl = np.arange(400.0, 701.0, 10.0)
    out = resample(wl, np.ones_like(wl), DEFAULT_GRID, extend="zero")
    assert out[0] == 0.0
    # [397.5, 402.5] is covered for 2.5 of its 5 nm; the 1e-9 nm step ramp adds < 1e-9 relative.
    assert out[1] == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(out[2:-2], 1.0, rtol=1e-12)
    assert out[-2] == pytest.approx(0.5, abs=1e-9)  # [697.5, 702.5]
    assert out[-1] == 0.0


def test_unknown_extension_policy_is_refused():
    wl = np.arange(400.0, 701.0, 10.0)
    with pytest.raises(SpectralError, match="unknown extension policy"):
        resample(wl, np.ones_like(wl), DEFAULT_GRID, extend="mirror")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "wl, v, message",
    [
        (np.array([380.0, 500.0, 500.0, 780.0]), np.ones(4), "duplicate"),
        (np.array([380.0, 500.0, 780.0]), np.array([1.0, np.nan, 1.0]), "NaN or inf"),
        (np.array([380.0, np.inf, 780.0]), np.ones(3), "NaN or inf"),
        (np.array([380.0, 500.0, 780.0]), np.ones(4), "3 wavelengths"),
        (np.array([500.0]), np.ones(1), "at least 2"),
        (np.array([380.0, 500.0, 780.0]), np.ones((3, 2, 2)), "3 wavelengths"),
    ],
)
def test_bad_tables_are_refused_with_a_clear_message(wl, v, message):
    with pytest.raises(SpectralError, match=message):
        resample(wl, v, DEFAULT_GRID)
