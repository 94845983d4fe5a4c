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

Late rounds (from the ``GUIDE_FROM_ROUND``-th on) are where a cube is noisy because its light
arrives by rare camera paths (a lamp lighting the ceiling, a lamp in the next room). With ``light``
(a lamp's cube, or a sun's through windows: :func:`renderer_jobs.mitsuba.band_render.light_paths_apply`), the first
late round is split in two: half its paths traced from the lights (**light paths**,
:mod:`renderer_jobs.mitsuba.light_paths`), half from the camera; each later round is of the kind —
light or camera paths — whose late rounds have given the least variance per CPU second (each kind's
variance from its own halves over the frame, :func:`next_kind`): a cube lit by bounces goes on
tracing from its light, one whose camera paths do better goes back to them, having spent half a
round to find out. Camera paths in late rounds are ``guided`` when allowed: some bounces from a path
guide learnt for the cube (:mod:`renderer_jobs.mitsuba.path_guide`). A cube clean by its second round never pays for either
(bench/SCENES.md, "Light paths" and "Path guiding").

Combining: within each kind of round (plain, guided, light), each round weighs by its rendered
samples. Between the kinds the weights are inverse to each kind's variance, measured from its own
halves over the whole frame (one number per kind, from thousands of pixels, so the weights hardly
depend on any pixel's own noise): each kind is an unbiased estimate, so the result is too.
bench/SCENES.md measures on generated rooms what the rule buys.
"""

from __future__ import annotations

import time

import numpy as np
from illumix.renderer_jobs.clean_check import FIREFLY_LIGHT_MAX, halves_clean, measure

SEED_STEP = 1_000_003  # round k renders with seed + k·SEED_STEP: independent paths
GUIDE_FROM_ROUND = 3  # rounds 1 and 2 (spp, then as many again) plain; guided or light paths after
KINDS = ("plain", "guided", "light")


def render_until_clean(render_once, settings, halves: bool = True, guided: bool = False, light: bool = False
                       ) -> tuple[np.ndarray, np.ndarray | None, dict, np.ndarray | None]:
    """``render_once(settings, kind) -> (cube, illum, stats, noise, halves)`` (band_render.render_all_bands
    bound to the scene; ``kind`` one of :data:`KINDS`) called in rounds as above; returns the combined
    ``(cube, illum, stats, noise)``. ``halves``: whether render_once returns them
    (band_render.sets_give_halves); else two renders. ``guided``, ``light``: the kinds the rounds from
    ``GUIDE_FROM_ROUND`` on may take (module docstring; neither: plain)."""
    rounds: list[tuple] = []
    kinds: list[str] = []
    cpu: list[float] = []

    def one(spp: int, kind: str = "plain") -> tuple:
        seed = (settings.seed + len(rounds) * SEED_STEP) % 2**32
        c0 = time.process_time()
        rounds.append(render_once(settings.model_copy(update={"spp": spp, "seed": seed}), kind))
        # what a further round of this kind would cost: a guide is learnt once, not every round
        cpu.append(time.process_time() - c0 - rounds[-1][2].get("guided", {}).get("learn_cpu_s", 0.0))
        kinds.append(kind)
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
            return _combine(rounds, w, m, clean, kinds, cpu)
        camera = "guided" if guided else "plain"
        if len(rounds) + 1 < GUIDE_FROM_ROUND:
            one(total)
        elif light and "light" not in kinds:  # the first late round: half light, half camera paths
            one(total // 2, "light")
            one(total - total // 2, camera)
        else:
            one(total, next_kind(rounds, kinds, cpu, camera) if light else camera)
        total *= 2


def next_kind(rounds: list[tuple], kinds: list[str], cpu: list[float], camera: str) -> str:
    """``"light"`` or ``camera``: the one whose late rounds (from ``GUIDE_FROM_ROUND``, where the two
    started on equal paths) have given the least variance per CPU second — each kind's variance from
    its own halves over the frame (:func:`kind_variance`), times its CPU seconds. The first two rounds
    do not count: from fewer paths, a variance misses more of the rare large paths, which would
    flatter them. Light paths whose halves show fireflies (more than
    :data:`~renderer_jobs.clean_check.FIREFLY_LIGHT_MAX` of the light in them) when the camera
    paths' do not are not taken whatever their variance: a heavy tail not yet drawn makes a variance
    look small (room 9135's daylight: light paths taken for their variance ended 1.4 % dark and
    noisier than camera paths alone)."""
    eff, ff = {}, {}
    for kind in ("light", camera):
        idx = [i for i, k in enumerate(kinds) if k == kind and i >= GUIDE_FROM_ROUND - 1]
        h = kind_halves(rounds, idx)
        var = _halves_variance(h)
        eff[kind] = 1.0 / (var * max(sum(cpu[i] for i in idx), 1e-9)) if var > 0 else np.inf
        ff[kind] = measure(h[..., 0], h[..., 1])["ff_light"] >= FIREFLY_LIGHT_MAX
    if ff["light"] and not ff[camera]:
        return camera
    return "light" if eff["light"] > eff[camera] else camera


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
            return _combine(results, _by_samples(results), m, clean, ["plain"] * len(results), None)
        for side in sides:
            side.append(one(per_side))
        per_side *= 2


def _by_samples(results: list[tuple]) -> np.ndarray:
    w = np.array([r[2]["samples_per_band_rendered"] for r in results], np.float64)
    return w / w.sum()


def kind_halves(results: list[tuple], idx: list[int]) -> np.ndarray:
    """``(H, W, 2)``: the two halves of the estimate that rounds ``idx`` make together (by samples)."""
    share = _by_samples([results[i] for i in idx])
    return sum(s * np.asarray(results[i][4], np.float64) for s, i in zip(share, idx))


def kind_variance(results: list[tuple], idx: list[int]) -> float:
    """The frame-mean variance of the estimate that rounds ``idx`` make together (weighted by samples):
    from the spread of its two halves (:func:`kind_halves`), ``mean((h0 − h1)²) / 4`` (of their mean)."""
    return _halves_variance(kind_halves(results, idx))


def _halves_variance(h: np.ndarray) -> float:
    return float(np.mean((h[..., 0] - h[..., 1]) ** 2)) / 4


def round_weights(results: list[tuple], kinds: list[str]) -> np.ndarray:
    """Each round's weight (module docstring): by samples within its kind, and the kinds inverse to
    the variance of each kind's estimate (:func:`kind_variance`)."""
    present = sorted(set(kinds))
    if len(present) == 1:
        return _by_samples(results)
    w = np.zeros(len(results))
    inv_var = {}
    for kind in present:
        idx = [i for i, k in enumerate(kinds) if k == kind]
        var = kind_variance(results, idx)
        inv_var[kind] = 1.0 / var if var > 0 else 0.0
        w[idx] = _by_samples([results[i] for i in idx])
    total = sum(inv_var.values())
    if not total:
        return _by_samples(results)
    for kind in present:
        w[[k == kind for k in kinds]] *= inv_var[kind] / total
    return w


def _weighted(results: list[tuple], w: np.ndarray, pick) -> np.ndarray:
    return sum(wi * np.asarray(pick(r), np.float64) for wi, r in zip(w, results))


def _combine(results: list[tuple], w: np.ndarray, m: dict, clean: bool, kinds: list[str], cpu) -> tuple:
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
                "samples_per_band_rendered", "light_path_sets"):
        stats[key] = int(sum(r[2].get(key, 0) for r in results))
    stats["light_paths"] = stats["light_path_sets"] > 0
    stats["until_clean"] = {"rounds": len(results), "clean": bool(clean), "rel_noise": m["rel"],
                            "d_above_0_5": round(m["d_above_0_5"], 5), "firefly_light": round(m["ff_light"], 5),
                            "kinds": list(kinds)}
    if cpu is not None:
        stats["until_clean"]["cpu_s"] = [round(c, 3) for c in cpu]
    is_kind = {k: np.array([x == k for x in kinds]) for k in KINDS}
    # the guide is learnt by the first round that uses it: a guided round, or a light round's pass
    # that keeps to camera paths (a window's sky portal)
    learnt = [r[2]["guided"]["learnt"] for r in results if r[2].get("guided", {}).get("learnt")]
    if is_kind["guided"].any():
        stats["until_clean"]["guided_rounds"] = int(is_kind["guided"].sum())
        stats["until_clean"]["guided_weight"] = round(float(w[is_kind["guided"]].sum()), 4)
    if learnt:
        stats["until_clean"]["guide"] = learnt[0]
    if is_kind["light"].any():
        stats["until_clean"]["light_rounds"] = int(is_kind["light"].sum())
        stats["until_clean"]["light_weight"] = round(float(w[is_kind["light"]].sum()), 4)
    return cube, illum, stats, noise
