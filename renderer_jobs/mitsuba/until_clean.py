"""Render a cube until it is clean before denoising (issue 39): ``RenderSettings.clean_max_spp``,
on by default for generated rooms (:meth:`RenderSettings.clean_cap`).

The cube is rendered at ``spp``; its even and odd band sets (each with its own paths) give two
independent estimates of its band sum, each from half the paths (``halves`` of
:func:`renderer_jobs.mitsuba.band_render.render_all_bands`). While they fail
:func:`renderer_jobs.clean_check.halves_clean` (fireflies, or more than 2 % of lit pixels 3:1 apart:
calibrated by bench/clean_rule.py so that the halves pass where two full renders of the cube would
first be clean), the cube gets as many paths again (other seeds), up to ``clean_max_spp`` per pixel in
all; the rounds share one loaded scene. A cube that is clean at once costs exactly what ``spp`` costs.
Where the band sets are not an even number (a group emitting in few bands), the halves are rendered
as two renders of ``spp / 2`` instead. The cube is the average of every round weighted by its
rendered samples: each round is an unbiased estimate, so the result is too. bench/SCENES.md measures
on generated rooms what the rule buys.
"""

from __future__ import annotations

import numpy as np
from illumix.renderer_jobs.clean_check import halves_clean, measure

SEED_STEP = 1_000_003  # round k renders with seed + k·SEED_STEP: independent paths


def render_until_clean(render_once, settings, halves: bool = True
                       ) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None]:
    """``render_once(settings) -> (cube, illum, stats, noise, halves)`` (band_render.render_all_bands
    bound to the scene) called in rounds as above; returns the combined ``(cube, illum, stats, noise)``.
    ``halves``: whether render_once returns them (band_render.sets_give_halves); else two renders."""
    rounds: list[tuple] = []

    def one(spp: int) -> tuple:
        seed = (settings.seed + len(rounds) * SEED_STEP) % 2**32
        rounds.append(render_once(settings.model_copy(update={"spp": spp, "seed": seed})))
        return rounds[-1]

    if not halves:
        return _by_two_renders(one, settings)
    one(settings.spp)
    total = settings.spp
    while True:
        m = measure(*np.moveaxis(_weighted(rounds, lambda r: r[4]), -1, 0))
        clean = halves_clean(m)
        if clean or 2 * total > settings.clean_max_spp:
            return _combine(rounds, m, clean)
        one(total)
        total *= 2


def _by_two_renders(one, settings) -> tuple:
    """The rule with each half its own render (rounds alternate between the two sides)."""
    per_side = settings.spp // 2
    sides = ([one(per_side)], [one(per_side)])
    while True:
        m = measure(*(_weighted(side, lambda r: r[0].sum(axis=-1, dtype=np.float64)) for side in sides))
        clean = halves_clean(m)
        if clean or 4 * per_side > settings.clean_max_spp:
            return _combine(sides[0] + sides[1], m, clean)
        for side in sides:
            side.append(one(per_side))
        per_side *= 2


def _weighted(results: list[tuple], pick) -> np.ndarray:
    w = np.array([r[2]["samples_per_band_rendered"] for r in results], np.float64)
    return sum(wi * np.asarray(pick(r), np.float64) for wi, r in zip(w / w.sum(), results))


def _combine(results: list[tuple], m: dict, clean: bool) -> tuple:
    cube = _weighted(results, lambda r: r[0]).astype(np.float32)
    illum = None if results[0][1] is None else _weighted(results, lambda r: r[1]).astype(np.float32)
    noise = None
    if results[0][3] is not None:  # the mean of estimates and the variance of that mean (weights squared)
        w = np.array([r[2]["samples_per_band_rendered"] for r in results], np.float64)
        w /= w.sum()
        n1 = sum(wi * wi * r[3][..., 1].astype(np.float64) for wi, r in zip(w, results))
        noise = np.stack([_weighted(results, lambda r: r[3][..., 0]), n1], -1).astype(np.float32)
    stats = dict(results[0][2])
    for key in ("load_s", "trace_s", "total_s"):
        stats[key] = round(sum(r[2][key] for r in results), 4)
    for key in ("nonfinite_samples", "paths_per_pixel", "samples_per_band", "paths_per_pixel_rendered",
                "samples_per_band_rendered"):
        stats[key] = int(sum(r[2][key] for r in results))
    stats["until_clean"] = {"rounds": len(results), "clean": bool(clean), "rel_noise": m["rel"],
                            "d_above_0_5": round(m["d_above_0_5"], 5), "firefly_light": round(m["ff_light"], 5)}
    return cube, illum, stats, noise
