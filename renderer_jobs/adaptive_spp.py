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

The budget's normalisation ``Σ√v`` would still couple a pixel to itself through the 24 neighbours
whose windows contain it; :func:`allocate` re-estimates those neighbours without the pixel, and
rounds with a seed-only random number, so no count depends on its own pixel's samples. Measured
with a heavy-tailed synthetic tracer on a 6×5 film (30 000 renders): a global normalisation biased
pixels by −0.3 … −0.4 % (z = −5); this one by |bias| < 0.1 % (|z| ≤ 1), as :func:`to_target` (a
per-pixel rule) does.

``v`` is quantised to quarter-octaves first (and ``v < 1e-6`` — e.g. a lamp seen directly — counts as
0), so a cube rendered with another emission spectrum (a relit one) gets the same allocation as the
flat one, path for path, up to a float-rounding coincidence.

Measured (``bench/render.py --parts curve,adaptive``, demo room, equal paths): 2–18 % lower RMS
relative raw noise and 10–26 % lower noise in the worst 1 % regions, more under harder light; see
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


def _variance(S1: np.ndarray, S2: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Relative variance per path from pooled sums of ``Y``, ``Y²`` over ``N`` paths (elementwise);
    0 where no path saw light or the relative spread is below ``V_FLOOR``."""
    N = np.where(N > 0, N, np.inf)
    m = S1 / N
    var = np.maximum(S2 / N - m * m, 0.0)
    v = np.where(m > 0, var / np.where(m > 0, m * m, 1.0), 0.0)
    return np.where(v > V_FLOOR, v, 0.0)


def relative_variance(s1: np.ndarray, s2: np.ndarray, n: int | np.ndarray, window: int = WINDOW) -> np.ndarray:
    """Per-pixel relative variance per path ``(H, W)`` from per-pixel pilot sums of ``Y`` and ``Y²``
    ``(H, W)`` over ``n`` paths (one number, or ``(H, W)``: 0 for pixels that traced none), pooled
    over the neighbourhood without the pixel (module docstring); 0 where the neighbourhood saw no
    light or a relative spread below ``V_FLOOR``."""
    s1 = np.asarray(s1, dtype=np.float64)
    n_map = np.broadcast_to(np.asarray(n, dtype=np.float64), s1.shape)
    return _variance(_window_sum(s1, window), _window_sum(np.asarray(s2, dtype=np.float64), window),
                     _window_sum(np.ascontiguousarray(n_map), window))


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


def _normalisation_without(s1: np.ndarray, s2: np.ndarray, n_map: np.ndarray, w: np.ndarray,
                           act: np.ndarray) -> np.ndarray:
    """``S(x)`` ``(H, W)``: ``Σ_y √v(y)`` over the active pixels with every ``v(y)`` whose window
    contains ``x`` recomputed without ``x``'s pilot — the normalisation as it would be had ``x``
    traced nothing, so that ``x``'s count cannot depend on ``x``'s own samples."""
    r = WINDOW // 2
    h, wd = s1.shape
    S1, S2, N = (_window_sum(a, WINDOW) for a in (s1, s2, n_map))
    pads = [np.pad(a, r, mode="constant") for a in (S1, S2, N, w, act.astype(np.float64))]
    near_old = np.zeros_like(w)
    near_new = np.zeros_like(w)
    for dy in range(WINDOW):
        for dx in range(WINDOW):
            if dy == r and dx == r:
                continue
            S1y, S2y, Ny, wy, ay = (p[dy:dy + h, dx:dx + wd] for p in pads)  # neighbour y = x + (dy−r, dx−r)
            near_old += wy
            near_new += np.where(ay > 0, np.sqrt(quantised(_variance(S1y - s1, S2y - s2, Ny - n_map))), 0.0)
    return w.sum() - near_old + near_new


def allocate(s1: np.ndarray, s2: np.ndarray, n: int | np.ndarray, spp: int, pilot: int, cap: float = CAP, *,
             seed: int = 0, active: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Paths per pixel ``(H, W)`` int64, and the relative variance ``v`` ``(H, W)`` it came from,
    for a fixed budget: from per-pixel pilot sums ``s1``, ``s2`` of ``Y``, ``Y²`` over ``n`` paths
    (as :func:`relative_variance`), every active pixel gets the pilot plus
    ``a(x) = extra · √v(x) / S(x)`` of the ``extra = (spp − pilot) · n_active`` remaining paths, at
    most ``cap · spp``; inactive pixels (``active``, bool ``(H, W)``, default all) get 0.

    ``S(x)`` is ``Σ√v`` with the neighbours that see ``x`` re-estimated without ``x``
    (:func:`_normalisation_without`), and ``a(x)`` is rounded up or down with a probability drawn
    from ``seed`` alone, so ``n(x)`` depends on no sample of ``x`` and ``E[n(x)] = pilot + a(x)``.
    The total is the budget up to that rounding, ``x``'s own pull on ``S`` and the cap's excess
    (which is not handed on): within 1 % in ``tests/test_render_adaptive.py``."""
    s1 = np.asarray(s1, dtype=np.float64)
    s2 = np.asarray(s2, dtype=np.float64)
    n_map = np.ascontiguousarray(np.broadcast_to(np.asarray(n, dtype=np.float64), s1.shape))
    v = relative_variance(s1, s2, n_map)
    act = np.ones(s1.shape, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    extra = (spp - pilot) * int(act.sum())
    w = np.where(act, np.sqrt(quantised(v)), 0.0)
    if extra <= 0 or not np.any(w > 0):
        return np.where(act, spp, 0).astype(np.int64), v
    norm = _normalisation_without(s1, s2, n_map, w, act)
    a = np.divide(extra * w, norm, out=np.zeros_like(w), where=(w > 0) & (norm > 0))
    a = np.minimum(a, max(cap * spp - pilot, 0))
    u = np.random.default_rng([seed & 0xFFFFFFFF, 0xA110C]).random(s1.shape)
    return np.where(act, pilot + np.floor(a + u).astype(np.int64), 0), v
