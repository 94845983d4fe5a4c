"""Adaptive sampling: where a fixed path budget goes, from a pilot's per-pixel variance.

Every pixel first gets ``pilot`` paths (16 on the 63-band grid: every band sampled once). From the
pilot, the relative variance per path of the pixel's spectral sum is estimated as

    v(x) = Var[Y] / E[Y]²,   Y = Σ_j L_j / Ē(λ_j)   (the path's 4 wavelengths, per unit emission)

over the pilot paths of the ``window × window`` neighbourhood of ``x`` **without x itself** (and
only neighbours inside the image), so the number of paths a pixel gets does not depend on its own
samples and its estimate stays unbiased (including a pixel's own pilot biased the image mean by
−0.1 … −0.2 % in ``bench/render.py``). The remaining ``(spp − pilot) · n_pixels`` paths are
distributed ``∝ √v`` — the allocation that minimises the mean relative variance Σ v/n over the
image — with no pixel above ``cap · spp``.

One coupling is left in this fixed-budget mode: the normalisation Σ√v over the image includes the
24 neighbours whose windows contain ``x``, so ``x``'s samples move its own share by O(24/N) of
themselves. With a heavy-tailed synthetic tracer on a 6×5 film (N = 30) that biased pixels by
−0.3 … −0.4 % (30 000 renders); the effect scales as 1/N, i.e. ~1e-5 at 160×120, far below the
noise. :func:`to_target` (``noise_target``) is a per-pixel rule and has no such coupling
(measured: |bias| < 0.1 % at z < 1 on the same film).
``v`` is quantised to quarter-octaves first (and ``v < 1e-6`` — e.g. a lamp seen directly — counts as
0), so a cube rendered with another emission spectrum (a relit one) gets the same allocation as the
flat one, path for path, up to a float-rounding coincidence.

Measured (``bench/render.py --parts curve,adaptive``, demo room, equal paths): 0–19 % lower RMS
relative raw noise and 6–26 % lower noise in the worst 1 % regions, more under harder light; see
``bench/RENDER_PERF.md``.
"""

from __future__ import annotations

import numpy as np

WINDOW = 5
CAP = 8.0
QUANT = 4  # steps per octave of v
V_FLOOR = 1e-6  # relative variance per path below this (0.1 % relative std) needs no extra paths


def pilot_spp(n_bands: int) -> int:
    """Pilot paths per pixel: enough for one wavelength sample in every band (4 per path)."""
    return -(-n_bands // 4)


def _window_sum(a: np.ndarray, window: int) -> np.ndarray:
    """Sum over the ``window × window`` neighbourhood of each pixel without the pixel itself, over
    the neighbours inside the image only (replicating the edge would copy a border pixel into its
    own window: its path count would depend on its own samples, biasing it by +2 … +3 % in a
    corner), added in a fixed order: a region of zeros sums to exactly zero (a running-sum filter
    leaves ±1e-17 residues there, which would read as huge relative variances)."""
    r = window // 2
    pad = np.pad(a, r, mode="constant")
    out = np.zeros_like(a)
    h, w = a.shape
    for dy in range(window):
        for dx in range(window):
            if dy != r or dx != r:
                out += pad[dy:dy + h, dx:dx + w]
    return out


def relative_variance(s1: np.ndarray, s2: np.ndarray, n: int, window: int = WINDOW) -> np.ndarray:
    """Per-pixel relative variance per path ``(H, W)`` from per-pixel pilot sums of ``Y`` and ``Y²``
    ``(H, W)`` over ``n`` paths each, pooled over the neighbourhood without the pixel (module
    docstring); 0 where the neighbourhood saw no light or a relative spread below ``V_FLOOR``."""
    s1 = np.asarray(s1, dtype=np.float64)
    N = n * _window_sum(np.ones_like(s1), window)  # pilot paths of the in-image neighbours
    N = np.where(N > 0, N, np.inf)                 # a 1×1 film has none: v = 0
    m = _window_sum(s1, window) / N
    var = np.maximum(_window_sum(np.asarray(s2, dtype=np.float64), window) / N - m * m, 0.0)
    v = np.where(m > 0, var / np.where(m > 0, m * m, 1.0), 0.0)
    return np.where(v > V_FLOOR, v, 0.0)


def quantised(v: np.ndarray) -> np.ndarray:
    """``v`` rounded to quarter-octaves (0 stays 0), float64 of the same shape: float rounding
    differences between a flat and a relit render do not change an allocation made from it."""
    flat = np.asarray(v, dtype=np.float64)
    out = np.zeros(flat.shape)
    pos = flat > 0
    out[pos] = np.exp2(np.round(np.log2(flat[pos]) * QUANT) / QUANT)
    return out


def to_target(v: np.ndarray, target: float, pilot: int, max_spp: int) -> np.ndarray:
    """Paths per pixel (same shape as ``v``, int64) for a relative noise ``target`` of each pixel's
    spectral sum: ``n = ⌈v / target²⌉`` (relative std with ``n`` paths is ``√(v/n)``), at least the
    pilot, at most ``max_spp``. Pixels whose neighbourhood saw no light or no spread (``v = 0``)
    keep the pilot."""
    if not 0 < target < 1:
        raise ValueError(f"noise target {target} must lie in (0, 1) (a relative standard deviation)")
    need = np.ceil(quantised(v) / (target * target))
    return np.clip(need, pilot, max(max_spp, pilot)).astype(np.int64)


def predicted_noise(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Predicted relative std ``√(v/n)`` of each pixel's spectral sum with ``n`` paths (0 where v = 0)."""
    return np.sqrt(quantised(v) / np.maximum(n, 1))


def allocate(v: np.ndarray, spp: int, pilot: int, cap: float = CAP) -> np.ndarray:
    """Paths per pixel (same shape as ``v``, int64, each ≥ ``pilot``, ≤ ``cap · spp`` where possible),
    summing to exactly ``spp · v.size``: the pilot plus the rest ∝ √v (module docstring)."""
    flat = np.asarray(v, dtype=np.float64).ravel()
    npix = flat.size
    extra = (spp - pilot) * npix
    w = np.sqrt(quantised(flat))
    if extra <= 0 or not np.any(w > 0):
        return np.full(v.shape, spp, dtype=np.int64)
    n = w / w.sum() * extra
    limit = max(cap * spp - pilot, 0)
    for _ in range(16):  # clip at the cap, hand the excess to the others (∝ √v, else evenly)
        over = n > limit
        if not over.any():
            break
        excess = (n[over] - limit).sum()
        n[over] = limit
        free = n < limit
        if not free.any():
            break
        wf = w[free]
        n[free] += excess * (wf / wf.sum() if wf.sum() > 0 else 1.0 / free.sum())
    ni = np.floor(n).astype(np.int64)
    rem = int(extra - ni.sum())
    if rem > 0:
        ni[np.argsort(-(n - ni), kind="stable")[:rem]] += 1
    return (pilot + ni).reshape(v.shape)
