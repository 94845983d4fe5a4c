"""Spectral compression of a transport cube by a per-cube K-component basis (issue 7, item 1).

A transport cube ``T(x, λ_i)`` ``(H, W, B)`` is approximated in a K-dimensional subspace of band
space spanned by orthonormal rows ``V`` ``(K, B)``::

    T(x, ·) ≈ c(x) · V,       c(x) = T(x, ·) · Vᵀ   (coefficients, (H, W, K): orthogonal projection)

``V`` is the top-K right singular vectors of a pixel subsample of the cube whose spectra are first
scaled to unit L2 norm (so the basis fits spectral *shapes*, not the few brightest pixels; an
uncentred SVD, because a subspace through the origin is what the linear relight needs). This is
the truncated Karhunen–Loève / PCA representation of spectra (Maloney 1986; Parkkinen, Hallikainen
& Jaaskelainen 1989: natural reflectances need ~8 components).

Relighting and projection are linear in ``T``, so the fused relight + projection of
:func:`retarget.relight.project_groups` runs in the subspace::

    R_{g,k}(x) = Σ_i T(x, λ_i) M_g[i, k]  ≈  Σ_j c_j(x) (V M_g)[j, k]          (H·W, K) @ (K, 3)

instead of ``(H·W, B) @ (B, 3)``. The error is the residual ``r = T − c V`` projected through
``M_g``: zero for ``K = B``, otherwise it depends on the cube (render noise is not in a low-rank
subspace) and on the request (a spiky illuminant weights single bands of ``r`` heavily) —
``bench/pareto.py`` measures it against a float64 reference.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite
from illumix.retarget.projected import Projected
from illumix.retarget.relight import project_groups

#: Pixels sampled for the basis fit (plenty for 63 bands; the 63 × 63 Gram matrix takes ~30 ms).
DEFAULT_SAMPLE = 1 << 16
_ROW_BLOCK = 1 << 17  # pixels per block when computing coefficients (bounds temporaries)


@dataclass(frozen=True)
class BasisCube:
    """A transport cube held as coefficients on a spectral basis.

    coefficients : ``(H, W, K)`` float32, the cube's values projected on the basis rows
    (same radiometric units as the cube).
    basis : ``(K, B)`` float64 with orthonormal rows (``basis @ basis.T = I_K``).
    Quacks like a cube where :func:`project_groups_any` needs it: ``shape`` is ``(H, W, B)`` and
    ``[y0:y1, x0:x1]`` slices a crop (a view of the coefficients).
    """

    coefficients: np.ndarray
    basis: np.ndarray

    def __post_init__(self) -> None:
        c, v = self.coefficients, self.basis
        if c.ndim != 3 or v.ndim != 2 or c.shape[2] != v.shape[0] or v.shape[0] > v.shape[1]:
            raise SpectralError(f"basis cube: coefficients {c.shape} and basis {v.shape} do not fit "
                                "(need (H, W, K) and (K, B) with K <= B)")

    @property
    def k(self) -> int:
        return int(self.basis.shape[0])

    @property
    def shape(self) -> tuple[int, int, int]:
        h, w, _ = self.coefficients.shape
        return (h, w, int(self.basis.shape[1]))

    @property
    def nbytes(self) -> int:
        return int(self.coefficients.nbytes + self.basis.nbytes)

    def __getitem__(self, key) -> BasisCube:
        if not (isinstance(key, tuple) and len(key) == 2 and all(isinstance(s, slice) for s in key)):
            raise TypeError("a BasisCube is cropped with cube[y0:y1, x0:x1]")
        return BasisCube(self.coefficients[key], self.basis)

    def project(self, weights: np.ndarray) -> np.ndarray:
        """``Σ_i T̂(x, λ_i) weights[i, k]`` for ``weights`` ``(B, C)`` → ``(H, W, C)`` float32."""
        m = np.asarray(weights, dtype=np.float64)
        if m.shape[0] != self.basis.shape[1]:
            raise SpectralError(f"basis cube: weights have {m.shape[0]} bands, the basis {self.basis.shape[1]}")
        reduced = (self.basis @ m).astype(np.float32)  # (K, C): the basis seen by the request
        h, w, k = self.coefficients.shape
        flat = self.coefficients.reshape(h * w, k)  # a copy only for a cropped (strided) view
        return (flat @ reduced).reshape(h, w, m.shape[1])

    def reconstruct(self) -> np.ndarray:
        """The approximated cube ``c · V`` ``(H, W, B)`` float32 (for tests and diagnostics)."""
        h, w, k = self.coefficients.shape
        return (self.coefficients.reshape(h * w, k) @ self.basis.astype(np.float32)).reshape(h, w, -1)


def fit_basis(cube: np.ndarray, k: int, *, sample: int = DEFAULT_SAMPLE, seed: int = 0) -> np.ndarray:
    """The top-``k`` spectral basis ``(k, B)`` float64 (orthonormal rows) of a cube ``(H, W, B)``.

    SVD of up to ``sample`` pixel spectra (drawn without replacement with ``seed``; all pixels if
    fewer), each scaled to unit L2 norm; all-zero pixels are left out. A cube with fewer than ``k``
    independent spectra still gets ``k`` orthonormal rows (the remaining singular vectors).
    """
    if cube.ndim != 3:
        raise SpectralError(f"fit_basis: need a cube (H, W, B), got shape {cube.shape}")
    h, w, b = cube.shape
    if not 1 <= k <= b:
        raise SpectralError(f"fit_basis: K must be in 1..{b} (the number of bands), got {k}")
    flat = cube.reshape(h * w, b)
    rng = np.random.default_rng(seed)
    idx = np.arange(h * w) if h * w <= sample else np.sort(rng.choice(h * w, sample, replace=False))
    x = flat[idx].astype(np.float64)
    if not np.all(np.isfinite(x)):
        raise SpectralError("fit_basis: the cube contains NaN or inf")
    norm = np.linalg.norm(x, axis=1)
    x = x[norm > 0] / norm[norm > 0, None]
    if x.shape[0] == 0:
        return np.eye(b)[:k]  # an all-dark cube: any basis represents it exactly
    # Right singular vectors of x = eigenvectors of the Gram matrix xᵀx (B × B), by decreasing
    # eigenvalue; eigh returns a full orthonormal set even when x has rank < k. (30× faster than
    # an SVD of the n × B sample; the Gram's squared condition number only affects the trailing,
    # discarded components.)
    _, vecs = np.linalg.eigh(x.T @ x)
    return np.ascontiguousarray(vecs[:, ::-1][:, :k].T)


def compress(cube: np.ndarray, k: int, *, sample: int = DEFAULT_SAMPLE, seed: int = 0,
             basis: np.ndarray | None = None) -> BasisCube:
    """A :class:`BasisCube` of ``cube`` ``(H, W, B)`` (float16/32/64) with ``k`` components.

    ``basis`` ``(K, B)`` (orthonormal rows) skips the fit. Coefficients are computed in float32
    block by block: ``c = T Vᵀ``. Non-finite cube values are refused.
    """
    v = fit_basis(cube, k, sample=sample, seed=seed) if basis is None else np.asarray(basis, np.float64)
    h, w, b = cube.shape
    if v.ndim != 2 or v.shape[1] != b:
        raise SpectralError(f"compress: basis {v.shape} does not match the cube's {b} bands")
    flat = cube.reshape(h * w, b)
    vt32 = v.T.astype(np.float32)
    coef = np.empty((h * w, v.shape[0]), np.float32)
    for s in range(0, h * w, _ROW_BLOCK):
        coef[s:s + _ROW_BLOCK] = flat[s:s + _ROW_BLOCK].astype(np.float32, copy=False) @ vt32
    if not np.all(np.isfinite(coef)):
        raise SpectralError("compress: the cube contains NaN or inf (or overflows float32)")
    return BasisCube(coef.reshape(h, w, -1), v)


def project_groups_any(cubes: Sequence[np.ndarray | BasisCube], weights: np.ndarray, *,
                       skip_bands: bool = True) -> np.ndarray:
    """:func:`retarget.relight.project_groups` for cubes that may be :class:`BasisCube` or
    :class:`retarget.projected.Projected`.

    cubes : G arrays ``(H, W, B)`` or basis cubes of that shape; weights : ``(G, B, 3)``.
    Returns ``(G, H, W, 3)`` float32; a group whose weights are all zero is not read.
    """
    if not any(isinstance(c, (BasisCube, Projected)) for c in cubes):
        return project_groups(cubes, weights, skip_bands=skip_bands)
    if len(cubes) != weights.shape[0]:
        raise SpectralError(f"project: {len(cubes)} cubes but weights for {weights.shape[0]} groups")
    shape = tuple(cubes[0].shape)
    out = np.zeros((len(cubes), shape[0], shape[1], 3), dtype=np.float32)
    for g, cube in enumerate(cubes):
        if tuple(cube.shape) != shape or shape[2] != weights.shape[1]:
            raise SpectralError(f"project: cube {g} has shape {cube.shape}; expected (H, W, "
                                f"{weights.shape[1]}) matching cube 0 {shape}")
        if not np.any(weights[g] != 0):
            continue
        if isinstance(cube, Projected):
            with np.errstate(invalid="ignore", over="ignore"):
                cube.project(weights[g], out=out[g])
        elif isinstance(cube, BasisCube):
            with np.errstate(invalid="ignore", over="ignore"):
                out[g] = cube.project(weights[g])
        else:
            out[g] = project_groups([cube], weights[g:g + 1], skip_bands=skip_bands)[0]
    # a cached projection was checked when it was computed, and its scale is finite (band_scales):
    # only a product with a cube (or a basis) can bring a NaN or inf here
    if not all(isinstance(c, Projected) for c in cubes) and not all_finite(out):
        raise SpectralError("project: a cube contains NaN or inf (or overflowed float32); "
                            "check the store with `illumix store verify`")
    return out
