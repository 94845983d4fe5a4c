"""Calibrate the until-clean rule's test of its halves (issue 39; figures in ``bench/SCENES.md``,
"The rule's test, calibrated").

``RenderSettings.clean_max_spp`` renders a cube of ``N`` paths as two independent halves of
``N / 2`` and stops adding paths when the halves pass a test. What it should predict is the
definition of clean (:mod:`renderer_jobs.clean_check`): two independent renders of ``N`` paths
compare clean. Judging the halves by that same definition is safe but dear (a cube clean at 64
spp often fails it at 32 + 32); scaling the difference by √2, as Gaussian noise would, passed a
cube that was not clean. This bench measures the right test instead of assuming one.

On rooms the rule was *not* measured on (``--seeds``, default 9130–9136; bench/fireflies.py's
rooms 9102–9125 are the held-out check), view 0, every group, 160×120, no denoising: each side
(A, B, independent seeds) rendered in rounds of 32, 32, 64, 128 spp on one loaded scene, so each
side's running average exists at 32, 64, 128 and 256 spp. For a cube of ``N`` = 64, 128, 256 the
halves are ``(A_{N/2}, B_{N/2})`` and the truth is whether ``(A_N, B_N)`` is clean. Every test of
the grid below (``d`` threshold ``t`` on the halves, the share of lit pixels above it, the halves'
firefly light) is run as the rule would run it — stop at the first ``N`` whose halves pass — and
scored by false passes (stopped at ``N`` where ``(A_N, B_N)`` is not clean) and paths spent (a cube
not stopped by 256 counts 512). ``--beyond 1024``: the cubes not clean at 256 rendered twice more at
that spp (plain, seeds 1 and 2), to see whether the rule's default cap makes them clean. Renders are cached under ``bench/out/clean_rule/``. Prints one
JSON object last; per-cube rows go to stderr.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
from illumix.renderer_jobs.clean_check import (BIG_DIFFERENCE, BIG_DIFFERENCE_SHARE_MAX, HALVES_BIG_DIFFERENCE_SHARE_MAX,
                                               is_clean, measure)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fireflies import kind_of, room_doc  # noqa: E402

OUT = Path(__file__).resolve().parent / "out" / "clean_rule"
ROUNDS = (32, 32, 64, 128)  # per side: running averages at 32, 64, 128, 256 spp
TOTALS = (64, 128, 256)
GRID = {"t": (0.5, 0.55, 0.6, 0.65, 0.7, 0.75), "share": (0.01, 0.015, 0.02, 0.03), "ff": (0.005, 0.0075, 0.01)}


def side_averages(scene, view: str, group: str, res, side: int) -> tuple[list[np.ndarray], float]:
    """One side's running band-sum averages ``(H, W)`` at 32, 64, 128, 256 spp and its CPU s."""
    from illumix.renderer_jobs.band_schedule import group_seed
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission
    from illumix.renderer_jobs.mitsuba.until_clean import SEED_STEP
    from illumix.renderer_jobs.render_settings import RenderSettings

    groups, loaded, acc, n, out = [group], {}, 0.0, 0, []
    passes, (e, _) = emitter_passes(scene, groups), group_emission(scene, group)
    c0 = time.process_time()
    for k, spp in enumerate(ROUNDS):
        seed = (group_seed(1 + side, groups) + k * SEED_STEP) % 2**32
        st = RenderSettings(spp=spp, seed=seed, resolution=res, denoise=None, illumination=False)
        cube, _, stats, _, _ = render_all_bands(scene, view, groups, passes, st, np.asarray(e, np.float64), None, loaded)
        w = stats["samples_per_band_rendered"]
        acc, n = acc + w * cube.sum(axis=-1, dtype=np.float64), n + w
        out.append(acc / n)
    return out, time.process_time() - c0


def cube_rows(doc: dict, res) -> list[dict]:
    """Per group of view 0: the measure() of the halves and of the truth at each total."""
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    view, rows = scene.views[0].name, []
    for g in scene.group_names:
        path = OUT / f"{doc['name']}-{g.replace(':', '_')}-{res[0]}x{res[1]}.npz"
        if path.exists():
            z = np.load(path)
            a, b, cpu = list(z["a"]), list(z["b"]), float(z["cpu"])
        else:
            (a, ca), (b, cb) = (side_averages(scene, view, g, res, s) for s in (0, 1))
            cpu = ca + cb
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez(path, a=np.stack(a), b=np.stack(b), cpu=cpu)
        if not np.any(a[-1]):
            continue
        row = {"room": doc["name"], "group": g, "kind": kind_of(g), "cpu_s_512_spp": round(cpu, 1), "at": {}}
        for i, n in enumerate(TOTALS):  # halves: index i (N/2); truth: index i + 1 (N)
            half, full = measure(a[i], b[i]), measure(a[i + 1], b[i + 1])
            row["at"][n] = {"half_d": half["d"], "half_ff": half["ff_light"], "clean": bool(is_clean(full)),
                            "full": {"d_above_0_5": round(full["d_above_0_5"], 4), "ff_light": round(full["ff_light"], 4)}}
        print(f"  {doc['name']} {g}: clean at " + ", ".join(f"{n}: {row['at'][n]['clean']}" for n in TOTALS)
              + f"; cpu {cpu:.0f} s", file=sys.stderr, flush=True)
        rows.append(row)
    return rows


def beyond(doc: dict, rows: list[dict], res, spp: int) -> None:
    """Rows of ``doc`` not clean at 256 get ``row["beyond"]``: two plain renders at ``spp`` measured."""
    from fireflies import _two_renders
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    for row in [r for r in rows if r["room"] == doc["name"] and not r["at"][TOTALS[-1]]["clean"]]:
        path = OUT / f"{doc['name']}-{row['group'].replace(':', '_')}-{res[0]}x{res[1]}-plain{spp}.npz"
        if path.exists():
            z = np.load(path)
            imgs, cpu = list(z["imgs"]), float(z["cpu"])
        else:
            imgs, cpu, _, _ = _two_renders(scene, scene.views[0].name, row["group"], resolution=res, spp=spp)
            np.savez(path, imgs=np.stack(imgs), cpu=cpu)
        m = measure(*imgs)
        row["beyond"] = {"spp": spp, "clean": bool(is_clean(m)), "d_above_0_5": round(m["d_above_0_5"], 4),
                         "ff_light": round(m["ff_light"], 4), "rel": round(m["rel"], 3), "cpu_s": round(cpu / 2, 1)}
        print(f"  {doc['name']} {row['group']} at {spp}: {row['beyond']}", file=sys.stderr, flush=True)


def passes(at: dict, t: float, share: float, ff: float) -> bool:
    return float((at["half_d"] > t).mean()) < share and at["half_ff"] < ff


def score(rows: list[dict], t: float, share: float, ff: float) -> dict:
    """The rule run with this test: false passes and paths per pixel spent, summed over the cubes."""
    false, paths, stops = 0, 0, []
    for r in rows:
        stop = next((n for n in TOTALS if passes(r["at"][n], t, share, ff)), None)
        stops.append(stop)
        paths += stop or 2 * TOTALS[-1]
        false += stop is not None and not r["at"][stop]["clean"]
    return {"t": t, "share": share, "ff": ff, "false_passes": false, "paths": paths, "stops": stops}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="9130,9131,9132,9133,9134,9135,9136")
    ap.add_argument("--res", default="160x120")
    ap.add_argument("--beyond", type=int, default=0, help="cubes not clean at 256: two renders at this spp")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.res.split("x"))
    docs = [room_doc(int(s)) for s in args.seeds.split(",")]
    rows = [r for doc in docs for r in cube_rows(doc, res)]
    for doc in docs if args.beyond else ():
        beyond(doc, rows, res, args.beyond)
    # the oracle: the first total whose two full renders are clean
    oracle = sum(next((n for n in TOTALS if r["at"][n]["clean"]), 2 * TOTALS[-1]) for r in rows)
    grid = [score(rows, *p) for p in itertools.product(*GRID.values())]
    safe = sorted((g for g in grid if g["false_passes"] == 0), key=lambda g: (g["paths"], -g["share"], g["t"]))
    full_test = score(rows, BIG_DIFFERENCE, BIG_DIFFERENCE_SHARE_MAX, 0.005)  # the halves judged as two renders
    adopted = score(rows, BIG_DIFFERENCE, HALVES_BIG_DIFFERENCE_SHARE_MAX, 0.005)  # clean_check.halves_clean
    result = {"bench": "clean_rule", "res": list(res), "seeds": args.seeds, "cubes": len(rows),
              "clean_at": {n: sum(r["at"][n]["clean"] for r in rows) for n in TOTALS},
              "paths_oracle": oracle, "full_render_test": full_test, "adopted_test": adopted, "best_safe": safe[:5],
              "cheapest_any": sorted(grid, key=lambda g: g["paths"])[:3],
              "cubes_rows": [{"room": r["room"], "group": r["group"],
                              "clean": {n: r["at"][n]["clean"] for n in TOTALS},
                              "full": {n: r["at"][n]["full"] for n in TOTALS}, "beyond": r.get("beyond")}
                             for r in rows]}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
