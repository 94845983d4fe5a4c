"""Relighting of per-group transport cubes and projection to sensor raw (DESIGN.md, "The key idea").

Light transport without fluorescence is linear in the emitted radiance at each wavelength, so a cube
``T[g]`` rendered with emission ``Ē_g`` is relit to illuminant ``Φ̄_g`` at intensity ``a_g`` by a per-band
scale, and projected through sensitivities ``C`` by a band sum::

    I(x, λ_i)   = Σ_g a_g · Φ̄_g(λ_i) / Ē_g(λ_i) · T[g](x, λ_i)
    R_{g,k}(x)  = Σ_i C_k(λ_i) · Δλ · a_g · Φ̄_g(λ_i) / Ē_g(λ_i) · T[g](x, λ_i)
    R_k(x)      = Σ_g R_{g,k}(x)

:func:`project_groups` fuses both steps into one ``(H·W, bands) @ (bands, 3)`` product per group, so
the 63-band spectral image is never materialised when only raw is wanted; bands whose weight is zero
for a group are skipped, and a group at zero intensity is not read at all.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite

_ROW_BLOCK = 1 << 18  # pixels per block when widening float16 to float32 (bounds temporaries)


def band_scales(illuminants: np.ndarray, emissions: np.ndarray, intensities: np.ndarray,
                group_names: Sequence[str] | None = None, wavelengths: np.ndarray | None = None
                ) -> np.ndarray:
    """Per-group, per-band relight factors ``a_g · Φ̄_g / Ē_g``.

    illuminants, emissions : ``(G, n_bands)`` band-averaged SPDs (any consistent units).
    intensities : ``(G,)`` non-negative scalars ``a_g``.
    Returns ``(G, n_bands)`` float64. A band where ``Ē_g = 0`` but ``a_g Φ̄_g > 0`` cannot be relit
    (the cube holds no transport there) and raises :class:`SpectralError` naming group and band.
    """
    phi = np.atleast_2d(np.asarray(illuminants, dtype=np.float64))
    emi = np.atleast_2d(np.asarray(emissions, dtype=np.float64))
    a = np.asarray(intensities, dtype=np.float64).reshape(-1)
    if not (phi.shape == emi.shape and phi.shape[0] == a.shape[0]):
        raise SpectralError(f"relight: shapes disagree: illuminants {phi.shape}, emissions "
                            f"{emi.shape}, intensities {a.shape}; need (G, bands), (G, bands), (G,)")
    if not (np.all(np.isfinite(a)) and np.all(a >= 0)):
        raise SpectralError(f"relight: intensities must be finite and >= 0, got {a.tolist()}")
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(emi))):
        raise SpectralError("relight: illuminant or emission spectra contain NaN or inf")
    # Not ``a·Φ̄ > 0``: that product underflows for a subnormal intensity (1e-320), which must be
    # refused or relit exactly like any tiny positive one.
    wanted = (a[:, None] > 0) & (phi > 0)
    dark = emi <= 0
    bad = wanted & dark
    if np.any(bad):
        g, i = map(int, np.argwhere(bad)[0])
        gname = group_names[g] if group_names is not None else f"#{g}"
        band = f"{wavelengths[i]:g} nm" if wavelengths is not None else f"band {i}"
        raise SpectralError(
            f"relight: light group {gname!r} was rendered with zero emission at {band}, where the "
            "requested illuminant has power; re-render it with flat emission or pick an illuminant "
            "that is dark there"
        )
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        scales = np.where(wanted, a[:, None] * phi / np.where(dark, 1.0, emi), 0.0)
    # Projection runs in float32: a ratio beyond its range (emission ~1e-38 of the illuminant,
    # e.g. the far tail of a Gaussian emitter) would overflow there. Refuse it here, by name.
    huge = ~(scales <= np.finfo(np.float32).max)
    if np.any(huge):
        g, i = map(int, np.argwhere(huge)[0])
        gname = group_names[g] if group_names is not None else f"#{g}"
        band = f"{wavelengths[i]:g} nm" if wavelengths is not None else f"band {i}"
        raise SpectralError(
            f"relight: light group {gname!r} was rendered with emission {emi[g, i]:.3g} at {band}, "
            f"too small to relight to the requested illuminant ({phi[g, i]:.3g} at intensity "
            f"{a[g]:.3g}: a scale beyond float32); re-render it with flat emission"
        )
    return scales


def raw_weights(scales: np.ndarray, sensor_weights: np.ndarray) -> np.ndarray:
    """``M[g, i, k] = scale[g, i] · C_k(λ_i) Δλ`` — ``(G, n_bands, 3)`` float64.

    ``sensor_weights`` is :meth:`retarget.sensors.Sensor.weights` ``(n_bands, 3)``.
    """
    return np.asarray(scales, dtype=np.float64)[:, :, None] * np.asarray(sensor_weights)[None]


def _matmul_f32(cube: np.ndarray, m: np.ndarray, bands: np.ndarray | None) -> np.ndarray:
    """``cube[..., bands] @ m`` in float32, widening float16 input block by block.

    float32 input with a band subset multiplies the contiguous *span* of the live bands (dead
    bands inside it get zero weight): a column slice is a strided view BLAS reads in place, while
    gathering the live columns copies them first — measured 1.1–8× slower than not skipping at all
    on a 480×640×63 float32 cube, where the span is as fast as or faster than no skipping
    (``python bench/pareto.py``, ``band_skip.projection_sweep_min_ms``).
    """
    h, w, n = cube.shape
    m32 = m.astype(np.float32)
    if cube.dtype == np.float32:
        lo, hi = (int(bands[0]), int(bands[-1]) + 1) if bands is not None else (0, n)
        span = np.zeros((hi - lo, m.shape[1]), np.float32)
        span[(bands if bands is not None else np.arange(n)) - lo] = m32
        if not cube.flags.c_contiguous:
            # a crop of a cached cube: one product per row reads the view in place (reshaping it
            # to (h·w, n) would copy the whole window first)
            return cube[..., lo:hi] @ span
        return (cube.reshape(h * w, n)[:, lo:hi] @ span).reshape(h, w, -1)
    flat = cube.reshape(h * w, n)
    out = np.empty((h * w, m.shape[1]), dtype=np.float32)
    for s in range(0, h * w, _ROW_BLOCK):
        block = flat[s:s + _ROW_BLOCK]
        if bands is not None:
            block = block[:, bands]
        out[s:s + _ROW_BLOCK] = block.astype(np.float32, copy=False) @ m32
    return out.reshape(h, w, -1)


def project_groups(cubes: Sequence[np.ndarray], weights: np.ndarray, *, skip_bands: bool = True
                   ) -> np.ndarray:
    """Per-group camera raw ``R_{g,k}(x)`` from transport cubes, fused relight + projection.

    cubes : G arrays ``(H, W, n_bands)`` (float16/32/64; widened to float32 block-wise).
    weights : ``(G, n_bands, 3)`` from :func:`raw_weights`.
    skip_bands : drop bands whose weights are all zero for a group (e.g. a narrow-band LED).
    Returns ``(G, H, W, 3)`` float32. Non-finite cube values are refused.
    """
    if len(cubes) != weights.shape[0]:
        raise SpectralError(f"project: {len(cubes)} cubes but weights for {weights.shape[0]} groups")
    shape = cubes[0].shape
    out = np.zeros((len(cubes), shape[0], shape[1], 3), dtype=np.float32)
    for g, cube in enumerate(cubes):
        if cube.shape != shape or cube.shape[2] != weights.shape[1]:
            raise SpectralError(f"project: cube {g} has shape {cube.shape}; expected (H, W, "
                                f"{weights.shape[1]}) matching cube 0 {shape}")
        m = weights[g]
        live = np.any(m != 0, axis=1)
        if not live.any():
            continue  # group off (zero intensity or illuminant dark under this sensor): not read
        bands = np.flatnonzero(live) if skip_bands and not live.all() else None
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite results are refused below
            out[g] = _matmul_f32(cube, m[bands] if bands is not None else m, bands)
    if not all_finite(out):
        raise SpectralError("project: a cube contains NaN or inf (or overflowed float32); "
                            "check the store with `illumix store verify`")
    return out


def relight(cubes: Sequence[np.ndarray], scales: np.ndarray) -> np.ndarray:
    """The mixed spectral image ``I(x, λ_i)`` ``(H, W, n_bands)`` float32 (only when asked for)."""
    out = np.zeros(cubes[0].shape, dtype=np.float32)
    for cube, s in zip(cubes, np.asarray(scales, dtype=np.float32)):
        if np.any(s != 0):
            out += cube.astype(np.float32, copy=False) * s
    return out


def project(spectral: np.ndarray, sensor_weights: np.ndarray) -> np.ndarray:
    """Camera raw ``R_k = Σ_i C_k Δλ · I(λ_i)`` of a spectral image ``(H, W, n)`` → ``(H, W, 3)``."""
    return _matmul_f32(spectral, np.asarray(sensor_weights), None)
