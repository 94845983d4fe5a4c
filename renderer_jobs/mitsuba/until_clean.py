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
as two renders of ``spp / 2`` instead.

``guided``: the rounds from the ``GUIDE_FROM_ROUND``-th on take some bounces from a path guide learnt
for the cube (:mod:`renderer_jobs.mitsuba.path_guide`): light that only rare paths find (a lamp in the
next room) is what keeps a cube from being clean at 2 × spp, and that is what guiding finds more often.
A cube clean by its second round never pays for the guide (its training and its dearer paths cost
about as much as that round: bench/SCENES.md, "Path guiding").

Combining: within the plain rounds and within the guided rounds, each round weighs by its rendered
samples. Between the two kinds the weights are inverse to each kind's variance, measured from its own
halves over the whole frame (one number per kind, from thousands of pixels, so the weights hardly
depend on any pixel's own noise): each kind is an unbiased estimate, so the result is too.
bench/SCENES.md measures on generated rooms what the rule buys.
"""

from __future__ import annotations

import numpy as np
from illumix.renderer_jobs.clean_check import halves_clean, measure

SEED_STEP = 1_000_003  # round k renders with seed + k·SEED_STEP: independent paths
GUIDE_FROM_ROUND = 3  # rounds 1 and 2 (spp, then as many again) plain; guided after


def render_until_clean(render_once, settings, halves: bool = True, guided: bool = False
                       ) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None]:
    """``render_once(settings, guided) -> (cube, illum, stats, noise, halves)`` (band_render.render_all_bands
    bound to the scene) called in rounds as above; returns the combined ``(cube, illum, stats, noise)``.
    ``halves``: whether render_once returns them (band_render.sets_give_halves); else two renders.
    ``guided``: the rounds from ``GUIDE_FROM_ROUND`` on are guided (module docstring)."""
    rounds: list[tuple] = []
    kinds: list[bool] = []  # whether each round was guided

    def one(spp: int, guide: bool = False) -> tuple:
        seed = (settings.seed + len(rounds) * SEED_STEP) % 2**32
        rounds.append(render_once(settings.model_copy(update={"spp": spp, "seed": seed}), guide))
        kinds.append(guide)
        return rounds[-1]

    if not halves:
        return _by_two_renders(one, settings)
    one(settings.spp)
    total = settings.spp
    while True:
        w = round_weights(rounds, kinds)
        m = measure(*np.moveaxis(_weighted(rounds, w, lambda r: r[4]), -1, 0))
        clean = halves_clean(m)
        if clean or 2 * total > settings.clean_max_spp:
            return _combine(rounds, w, m, clean, kinds)
        one(total, guided and len(rounds) + 1 >= GUIDE_FROM_ROUND)
        total *= 2


def _by_two_renders(one, settings) -> tuple:
    """The rule with each half its own render (rounds alternate between the two sides)."""
    per_side = settings.spp // 2
    sides = ([one(per_side)], [one(per_side)])
    while True:
        m = measure(*(_weighted(side, _by_samples(side), lambda r: r[0].sum(axis=-1, dtype=np.float64))
                      for side in sides))
        clean = halves_clean(m)
        if clean or 4 * per_side > settings.clean_max_spp:
            results = sides[0] + sides[1]
            return _combine(results, _by_samples(results), m, clean, [False] * len(results))
        for side in sides:
            side.append(one(per_side))
        per_side *= 2


def _by_samples(results: list[tuple]) -> np.ndarray:
    w = np.array([r[2]["samples_per_band_rendered"] for r in results], np.float64)
    return w / w.sum()


def round_weights(results: list[tuple], kinds: list[bool]) -> np.ndarray:
    """Each round's weight (module docstring): by samples within its kind, and the two kinds
    inverse to the variance of each kind's estimate, from the spread of its halves over the frame."""
    kinds = np.asarray(kinds, bool)
    if kinds.all() or not kinds.any():
        return _by_samples(results)
    w = np.zeros(len(results))
    inv_var = {}
    for kind in (False, True):
        idx = np.flatnonzero(kinds == kind)
        share = _by_samples([results[i] for i in idx])
        h = sum(s * np.asarray(results[i][4], np.float64) for s, i in zip(share, idx))
        var = float(np.mean((h[..., 0] - h[..., 1]) ** 2)) / 4  # of the mean of the two halves
        inv_var[kind] = 1.0 / var if var > 0 else 0.0
        w[idx] = share
    if not inv_var[False] and not inv_var[True]:
        return _by_samples(results)
    total = inv_var[False] + inv_var[True]
    for kind in (False, True):
        w[kinds == kind] *= inv_var[kind] / total
    return w


def _weighted(results: list[tuple], w: np.ndarray, pick) -> np.ndarray:
    return sum(wi * np.asarray(pick(r), np.float64) for wi, r in zip(w, results))


def _combine(results: list[tuple], w: np.ndarray, m: dict, clean: bool, kinds: list[bool]) -> tuple:
    cube = _weighted(results, w, lambda r: r[0]).astype(np.float32)
    illum = None if results[0][1] is None else _weighted(results, w, lambda r: r[1]).astype(np.float32)
    noise = None
    if results[0][3] is not None:  # the mean of estimates and the variance of that mean (weights squared)
        n1 = sum(wi * wi * r[3][..., 1].astype(np.float64) for wi, r in zip(w, results))
        noise = np.stack([_weighted(results, w, lambda r: r[3][..., 0]), n1], -1).astype(np.float32)
    stats = dict(results[0][2])
    for key in ("load_s", "trace_s", "total_s"):
        stats[key] = round(sum(r[2][key] for r in results), 4)
    for key in ("nonfinite_samples", "paths_per_pixel", "samples_per_band", "paths_per_pixel_rendered",
                "samples_per_band_rendered"):
        stats[key] = int(sum(r[2][key] for r in results))
    stats["until_clean"] = {"rounds": len(results), "clean": bool(clean), "rel_noise": m["rel"],
                            "d_above_0_5": round(m["d_above_0_5"], 5), "firefly_light": round(m["ff_light"], 5)}
    guided = [r[2]["guided"] for r, k in zip(results, kinds) if k and "guided" in r[2]]
    if guided:
        stats["until_clean"]["guided_rounds"] = int(sum(kinds))
        stats["until_clean"]["guided_weight"] = round(float(w[np.asarray(kinds, bool)].sum()), 4)
        stats["until_clean"]["guide"] = guided[0]["learnt"]
    return cube, illum, stats, noise
