"""Is a cube clean before denoising? Two independent renders of it compared (issue 39).

A cube is *clean* when the light in its fireflies is below 0.5 % of its light and fewer than 1 % of
its lit pixels differ between the two renders by more than 3:1 (``d = |A − B| / (A + B) > 0.5``):
isolated errors that large are what a denoiser spreads into blotches rather than averages away; the
median noise is left to the denoiser (bench/SCENES.md, "Fireflies"). Used by bench/fireflies.py
and, through :func:`halves_clean`, by the renderer's ``clean_max_spp`` rule
(:mod:`renderer_jobs.mitsuba.until_clean`).
"""

from __future__ import annotations

import numpy as np

D_TO_S = 0.4769  # median |N(0, √2 s)| / 2 = 0.4769 s: median(d) → relative standard error
FIREFLY_LIGHT_MAX = 0.005
BIG_DIFFERENCE = 0.5
BIG_DIFFERENCE_SHARE_MAX = 0.01
# The until-clean rule's test of a cube's two halves (each half the paths): up to 2 % of lit pixels
# 3:1 apart. bench/clean_rule.py on rooms 9130–9136 (18 cubes, 64–256 spp): halves of cubes whose two
# full renders are clean ≤ 2.5 %, of cubes not clean ≥ 3.4 %; no false pass at 1–3 %, the paths
# 5696 (1 %, the full-render test), 5632 (2 %), 5312 (3 %, the oracle's). 3 % then passed room 9125's
# floor lamp at 256 spp on bench/fireflies.py's rooms, where two 256-spp renders are not clean: 2 %.
HALVES_BIG_DIFFERENCE_SHARE_MAX = 0.02


def firefly_stats(img: np.ndarray, other: np.ndarray, lit: np.ndarray) -> tuple[float, float]:
    """``(share of lit pixels that are fireflies, share of the frame's light in their excess)`` of an
    ``(H, W)`` render given an independent render ``other`` of the same cube: pixels above 10× their
    5×5 median, above 4× the other render (so that what both renders show — an emitter or a highlight
    seen directly — is not counted) and above 1 % of the 99th percentile; the excess is over the
    larger of that median and the other render."""
    from scipy.ndimage import median_filter

    med = median_filter(img, size=5, mode="nearest")
    floor = 0.01 * max(float(np.percentile(img, 99)), 1e-30)
    ff = (img > 10 * med) & (img > 4 * other) & (img > floor)
    total = float(img.sum())
    excess = (img - np.maximum(med, other))[ff].sum()
    return float(ff[lit].mean()) if lit.any() else 0.0, float(excess / total) if total > 0 else 0.0


def measure(a: np.ndarray, b: np.ndarray) -> dict:
    """Noise and firefly figures of two independent ``(H, W)`` renders."""
    mean = (a + b) / 2
    lit = mean > 1e-3 * max(float(np.percentile(mean, 99)), 1e-30)
    d = np.abs(a - b)[lit] / np.maximum(a + b, 1e-30)[lit]
    fa, fb = firefly_stats(a, b, lit), firefly_stats(b, a, lit)
    return {"lit": int(lit.sum()), "d": d, "rel": float(np.median(d) / D_TO_S) if d.size else None,
            "rel_p95": float(np.percentile(d, 95) / D_TO_S) if d.size else None,
            "d_above_0_5": float((d > BIG_DIFFERENCE).mean()) if d.size else 0.0,
            "ff_pixels": (fa[0] + fb[0]) / 2, "ff_light": (fa[1] + fb[1]) / 2}


def is_clean(m: dict) -> bool:
    """The definition above, on a :func:`measure` result."""
    return m["ff_light"] < FIREFLY_LIGHT_MAX and m["d_above_0_5"] < BIG_DIFFERENCE_SHARE_MAX


def halves_clean(m: dict) -> bool:
    """Whether a cube whose two halves gave :func:`measure` result ``m`` is clean (their average, twice
    each half's paths): the firefly test as above, and :data:`HALVES_BIG_DIFFERENCE_SHARE_MAX`."""
    return m["ff_light"] < FIREFLY_LIGHT_MAX and m["d_above_0_5"] < HALVES_BIG_DIFFERENCE_SHARE_MAX
