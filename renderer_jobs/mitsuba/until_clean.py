"""Render a cube until it is clean before denoising (issue 39): ``RenderSettings.clean_max_spp``.

The cube is rendered as two independent halves of ``spp`` (other seeds). While the halves disagree
as a noisy cube does (:mod:`renderer_jobs.clean_check`: each half judged as a whole render would
be, so the cube, with twice a half's paths, is clean with a margin — judging the halves with ``d``
scaled by √2 instead passed room 9125's floor lamp at 256 spp, where two 256-spp renders are not
clean), both halves get as many paths again, up to ``clean_max_spp`` per pixel in all. The cube is the average of every round weighted by its
rendered samples: each round is an unbiased estimate, so the result is too, and a cube that is clean
at once costs what ``spp`` costs. bench/SCENES.md measures on generated rooms what the rule buys.
"""

from __future__ import annotations

import numpy as np
from illumix.renderer_jobs.clean_check import is_clean, measure

SEED_STEP = 1_000_003  # round k renders with seed + k·SEED_STEP: independent paths


def render_until_clean(render_once, settings) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None]:
    """``render_once(settings) -> (cube, illum, stats, noise)`` (band_render.render_all_bands bound
    to the scene) called in rounds as above; returns the combined ``(cube, illum, stats, noise)``."""
    half = settings.spp // 2
    rounds: list[tuple[int, tuple]] = []

    def one(spp: int, side: int) -> None:
        seed = (settings.seed + len(rounds) * SEED_STEP) % 2**32
        rounds.append((side, render_once(settings.model_copy(update={"spp": spp, "seed": seed}))))

    def side_sum(side: int) -> np.ndarray:
        mine = [r for s, r in rounds if s == side]
        w = np.array([r[2]["samples_per_band_rendered"] for r in mine], np.float64)
        return sum(wi * r[0].sum(axis=-1, dtype=np.float64) for wi, r in zip(w / w.sum(), mine))

    one(half, 0)
    one(half, 1)
    per_side = half
    while True:
        m = measure(side_sum(0), side_sum(1))
        clean = is_clean(m)
        if clean or 4 * per_side > settings.clean_max_spp:
            break
        one(per_side, 0)
        one(per_side, 1)
        per_side *= 2
    return _combine([r for _, r in rounds], m, clean)


def _combine(results: list[tuple], m: dict, clean: bool) -> tuple:
    w = np.array([r[2]["samples_per_band_rendered"] for r in results], np.float64)
    w /= w.sum()
    cube = sum(wi * r[0].astype(np.float64) for wi, r in zip(w, results)).astype(np.float32)
    illum = (None if results[0][1] is None
             else sum(wi * r[1].astype(np.float64) for wi, r in zip(w, results)).astype(np.float32))
    noise = None
    if results[0][3] is not None:  # the mean of estimates and the variance of that mean
        n0 = sum(wi * r[3][..., 0].astype(np.float64) for wi, r in zip(w, results))
        n1 = sum(wi * wi * r[3][..., 1].astype(np.float64) for wi, r in zip(w, results))
        noise = np.stack([n0, n1], -1).astype(np.float32)
    stats = dict(results[0][2])
    for key in ("load_s", "trace_s", "total_s"):
        stats[key] = round(sum(r[2][key] for r in results), 4)
    for key in ("nonfinite_samples", "paths_per_pixel", "samples_per_band", "paths_per_pixel_rendered",
                "samples_per_band_rendered"):
        stats[key] = int(sum(r[2][key] for r in results))
    stats["until_clean"] = {"rounds": len(results), "clean": bool(clean), "rel_noise": m["rel"],
                            "d_above_0_5": round(m["d_above_0_5"], 5), "firefly_light": round(m["ff_light"], 5)}
    return cube, illum, stats, noise
