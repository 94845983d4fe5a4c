"""A synthetic spectral transport cube that looks like a path-traced render (benchmarks, tests).

Not random noise: a room-like image of regions with smooth reflectance spectra (walls, floor,
objects, a 4×6 chart), smooth shading from two point-like lamps with soft shadows (down to
``shadow`` × the mean), a mild spatially varying spectral tint (inter-reflections), a directly
visible emitter ``emitter`` × the mean, and Monte-Carlo-like multiplicative noise: log-normal with
relative std ``noise`` per band (≈ 10 % per 5 nm band for Mitsuba's default spectral sampling) plus
rare fireflies (``firefly_rate`` of values × 30).
"""

from __future__ import annotations

import numpy as np

from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid


def _reflectances(rng: np.random.Generator, k: int, wl: np.ndarray) -> np.ndarray:
    """``k`` smooth reflectance spectra ``(k, B)`` in [0.03, 0.9]: sigmoids plus Gaussian bumps."""
    t = (wl - wl[0]) / (wl[-1] - wl[0])
    out = np.empty((k, wl.size))
    for i in range(k):
        base = rng.uniform(0.05, 0.5)
        edge = rng.uniform(0.2, 0.8)
        rise = rng.uniform(-0.5, 0.5) / (1 + np.exp(-(t - edge) / rng.uniform(0.03, 0.15)))
        bump = rng.uniform(0, 0.4) * np.exp(-0.5 * ((t - rng.uniform(0, 1)) / rng.uniform(0.05, 0.2)) ** 2)
        out[i] = np.clip(base + rise + bump, 0.03, 0.9)
    return out


def synthetic_cube(height: int = 720, width: int = 960, grid: SpectralGrid = DEFAULT_GRID, seed: int = 0,
                   noise: float = 0.10, emitter: float = 2e5, shadow: float = 1e-4,
                   firefly_rate: float = 2e-4) -> np.ndarray:
    """A ``(height, width, grid.n_bands)`` float32 cube, non-negative, relative units (the lit diffuse
    part has mean 1; the emitter is ``emitter``, the darkest shadows about ``shadow``)."""
    rng = np.random.default_rng(seed)
    wl = grid.wavelengths
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    u, v = xx / width, yy / height
    # Regions: back wall, side wall, floor, 6 random boxes, a 4x6 chart.
    labels = np.where(v > 0.65, 2, np.where(u < 0.15 + 0.2 * v, 1, 0)).astype(np.int32)
    n_lab = 3
    for _ in range(6):
        x0, y0 = rng.uniform(0.1, 0.8), rng.uniform(0.3, 0.8)
        w, h = rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2)
        labels[(u > x0) & (u < x0 + w) & (v > y0) & (v < y0 + h)] = n_lab
        n_lab += 1
    cx0, cy0, pw = 0.55, 0.35, 0.035
    for r in range(4):
        for c in range(6):
            m = (u > cx0 + c * pw) & (u < cx0 + (c + 0.85) * pw) & (v > cy0 + r * pw * 1.33) & \
                (v < cy0 + (r + 0.85) * pw * 1.33)
            labels[m] = n_lab
            n_lab += 1
    refl = _reflectances(rng, n_lab, wl).astype(np.float32)
    # Shading: two lamps, 1/r^2 with a soft floor of ambient light, soft shadows.
    shade = np.full((height, width), 0.02, np.float32)
    for lx, ly, p in ((0.3, 0.1, 1.0), (0.8, 0.2, 0.6)):
        shade += p * 0.05 / ((u - lx) ** 2 + (v - ly) ** 2 + 0.05)
    for _ in range(3):
        sx, sy, r = rng.uniform(0.1, 0.9), rng.uniform(0.5, 0.95), rng.uniform(0.05, 0.12)
        d = np.sqrt((u - sx) ** 2 + ((v - sy) * 1.5) ** 2) / r
        shade *= 1 - (1 - shadow ** 0.5) / (1 + np.exp(np.minimum((d - 1) * 12, 60)))
    corner = np.sqrt(u ** 2 + (1 - v) ** 2)
    shade *= np.where(corner < 0.12, shadow ** 0.5 * (0.2 + corner / 0.12), 1).astype(np.float32)
    tint = (1 + 0.25 * np.sin(3 * u + 2 * v)[..., None] * ((wl - 550) / 160)[None, None, :]).astype(np.float32)
    cube = refl[labels] * shade[..., None] * tint
    cube /= cube.mean()
    # Directly visible emitter (a lamp shade / window patch): flat unit emission x strength.
    ey, ex = int(0.08 * height), int(0.28 * width)
    cube[ey:ey + max(2, height // 40), ex:ex + max(2, width // 25)] = emitter
    # Monte-Carlo noise: log-normal with relative std `noise`, plus fireflies.
    s = np.float32(np.sqrt(np.log1p(noise ** 2)))
    for r0 in range(0, height, 64):
        blk = cube[r0:r0 + 64]
        z = rng.standard_normal(blk.shape, dtype=np.float32)
        blk *= np.exp(s * z - s * s / 2)
        fire = rng.random(blk.shape, dtype=np.float32) < firefly_rate
        blk[fire] *= 30
    return cube
