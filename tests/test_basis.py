"""retarget.basis against independent computations: float64 einsum projections, numpy's SVD
(Eckart–Young residual), exact recovery of low-rank cubes, and compose() parity."""

from __future__ import annotations

import numpy as np
import pytest

from illumix.retarget.basis import BasisCube, compress, fit_basis, project_groups_any
from illumix.retarget.compose import compose, group_ccms
from illumix.retarget.errors import SpectralError
from illumix.retarget.illuminants import illuminant_spd
from illumix.retarget.reflectances import get_reflectances
from illumix.retarget.sensors import get_sensor

PALETTE = get_reflectances("ColorChecker N Ohta")[1]  # (24, 63)
B = PALETTE.shape[1]


def low_rank_cube(rank: int, h: int = 20, w: int = 30, seed: int = 0) -> np.ndarray:
    """A cube whose spectra are non-negative mixtures of ``rank`` measured reflectances."""
    rng = np.random.default_rng(seed)
    mix = rng.uniform(0, 1, (h, w, rank)) * 10.0 ** rng.uniform(-3, 2, (h, w, 1))
    return (mix @ PALETTE[:rank]).astype(np.float32)


def einsum_raw(cube: np.ndarray, m: np.ndarray) -> np.ndarray:
    return np.einsum("hwb,bk->hwk", cube.astype(np.float64), np.asarray(m, np.float64))


@pytest.mark.parametrize("rank", [1, 3, 8])
def test_a_cube_of_rank_k_is_recovered_exactly_with_k_components(rank):
    cube = low_rank_cube(rank)
    bc = compress(cube, rank)
    assert bc.shape == cube.shape and bc.k == rank and bc.coefficients.dtype == np.float32
    np.testing.assert_allclose(bc.basis @ bc.basis.T, np.eye(rank), atol=1e-12)
    scale = np.abs(cube).max(axis=-1, keepdims=True)
    assert np.max(np.abs(bc.reconstruct() - cube) / scale) < 1e-5
    m = get_sensor("Nikon 5100 (NPL)").weights() * illuminant_spd("FL11")[:, None]
    ref = einsum_raw(cube, m)
    got = bc.project(m)
    assert got.shape == (*cube.shape[:2], 3) and got.dtype == np.float32
    assert np.max(np.abs(got - ref) / np.abs(ref).max(axis=-1, keepdims=True)) < 1e-5


def test_full_basis_projection_equals_the_direct_projection():
    rng = np.random.default_rng(1)
    cube = rng.lognormal(0, 1, (16, 12, B)).astype(np.float32)  # full rank, noisy
    m = rng.uniform(0, 1, (B, 3))
    got = compress(cube, B).project(m)
    np.testing.assert_allclose(got, einsum_raw(cube, m), rtol=2e-5)


def test_basis_spans_the_leading_singular_subspace_and_residual_meets_eckart_young():
    rng = np.random.default_rng(2)
    cube = low_rank_cube(12, seed=3) * rng.lognormal(0, 0.05, (20, 30, B)).astype(np.float32)
    x = cube.reshape(-1, B).astype(np.float64)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    _, sv, vt = np.linalg.svd(x, full_matrices=False)  # independent: LAPACK SVD of the sample
    for k in (2, 5, 9):
        v = fit_basis(cube, k)
        np.testing.assert_allclose(v.T @ v, vt[:k].T @ vt[:k], atol=1e-8)  # same projector
        resid = x - (x @ v.T) @ v
        assert np.sum(resid ** 2) == pytest.approx(np.sum(sv[k:] ** 2), rel=1e-8)


def test_crops_of_a_basis_cube_project_like_crops_of_the_cube():
    cube = low_rank_cube(24, seed=4)
    bc = compress(cube, B)
    m = np.random.default_rng(5).uniform(0, 1, (B, 3))
    crop = bc[3:11, 7:29]
    assert crop.shape == (8, 22, B)
    np.testing.assert_allclose(crop.project(m), einsum_raw(cube[3:11, 7:29], m), rtol=2e-5, atol=1e-6)
    with pytest.raises(TypeError):
        bc[3]


def test_compose_accepts_basis_cubes_and_matches_the_array_path():
    sensor = get_sensor("Nikon 5100 (NPL)")
    ill = np.stack([illuminant_spd("FL11"), illuminant_spd("A")])
    ccms = group_ccms(sensor, ill, PALETTE)
    cubes = [low_rank_cube(24, seed=s) for s in (6, 7)]
    cubes[1][:2] = 0.0  # rows with no light from either group
    cubes[0][:2] = 0.0
    kw = dict(emissions=np.ones_like(ill), illuminants=ill, intensities=np.array([1.0, 0.3]),
              sensor=sensor, ccms=ccms)
    a = compose(cubes, **kw)
    b = compose([compress(c, B) for c in cubes], **kw)
    np.testing.assert_allclose(b.raw, a.raw, rtol=1e-4, atol=1e-6 * float(a.raw.max()))
    np.testing.assert_allclose(b.gain, a.gain, rtol=1e-4)
    np.testing.assert_array_equal(b.mask, a.mask)
    # a mixed list (one basis cube, one array) and a switched-off basis group also work
    c = compose([compress(cubes[0], B), cubes[1]], **{**kw, "intensities": np.array([1.0, 0.0])})
    assert np.all(np.isfinite(c.raw)) and np.all(c.weights[..., 1][c.mask] == 0)


def test_refusals_are_spectral_errors():
    cube = low_rank_cube(3)
    with pytest.raises(SpectralError, match="K must be"):
        fit_basis(cube, 0)
    with pytest.raises(SpectralError, match="K must be"):
        fit_basis(cube, B + 1)
    bad = cube.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(SpectralError, match="NaN"):
        compress(bad, 3, sample=10**9)
    with pytest.raises(SpectralError, match="do not fit"):
        BasisCube(np.zeros((2, 2, 4), np.float32), np.eye(B)[:3])
    with pytest.raises(SpectralError, match="bands"):
        compress(cube, 3).project(np.ones((B - 1, 3)))
    with pytest.raises(SpectralError, match="shape"):
        project_groups_any([compress(cube, 3), np.zeros((2, 2, B), np.float32)], np.ones((2, B, 3)))


def test_an_all_dark_cube_compresses_to_zeros():
    bc = compress(np.zeros((4, 5, B), np.float32), 6)
    assert not bc.coefficients.any()
    np.testing.assert_allclose(bc.basis @ bc.basis.T, np.eye(6))
    assert not bc.project(np.ones((B, 3))).any()
