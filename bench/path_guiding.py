"""Path guiding, or light paths, at equal paths (issue 39; figures in ``bench/SCENES.md``, "Path
guiding" and "Light paths").

What :mod:`renderer_jobs.mitsuba.path_guide` buys per path and per CPU second, apart from the
until-clean rule that uses it (``bench/fireflies.py --clean-max-spp default`` measures the rule).
For each room of ``--seeds`` (generated rooms, cached as in ``bench/fireflies.py``; the default
rooms 9140–9143 are held out: the guide's settings were chosen on rooms 9131 and 9135), view 0,
every group: the cube rendered at ``--spp`` (160×120, all bands, no denoising, transport only)
plain and guided (the guide learnt for the cube, its training included in the CPU), each with
render seeds 1 and 2. Per cube: relative noise (``rel``, from the two renders' differences, as
:func:`renderer_jobs.clean_check.measure`), share of lit pixels 3:1 apart, firefly light, CPU per
render, whether the two are clean, the image mean's ratio guided / plain (a bias check), and the
efficiency ``(rel_plain / rel_guided)² / (cpu_guided / cpu_plain)``: how many times fewer CPU
seconds the guided cube needs for the same noise. ``--kind light``: light paths
(:mod:`renderer_jobs.mitsuba.light_paths`, with their camera-path complement) in place of guided
ones, on the cubes that may take them (lamps, a sun through windows: ``band_render.light_paths_apply``).
``--against guided``: compared with guided paths instead of plain ones; ``--kinds daylight``: only groups
of those kinds; ``--pass without``: one emitter pass alone (``without``: lamps and a sun; ``only``: sky
portals), e.g. a daylight cube's sun. Prints one JSON object last; per-cube rows go to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from illumix.renderer_jobs.clean_check import is_clean, measure

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fireflies import kind_of, room_doc  # noqa: E402


def _pair(scene, view: str, group: str, res, spp: int, kind: str, passes: str = "all") -> tuple[list, float]:
    """Band sums ``(H, W)`` of the cube (its emitter pass ``passes`` alone, unless "all") rendered with
    seeds 1 and 2, and CPU s per render."""
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission
    from illumix.renderer_jobs.render_settings import RenderSettings

    e = np.asarray(group_emission(scene, group)[0], np.float64)
    todo = [p for p in emitter_passes(scene, [group]) if passes in ("all", p)]
    imgs, cpu = [], 0.0
    for seed in (1, 2):
        st = RenderSettings(resolution=res, spp=spp, seed=seed, denoise=None, illumination=False, clean_max_spp=0)
        c0 = time.process_time()
        cube = render_all_bands(scene, view, [group], todo, st, e, None, None, kind)[0]
        cpu += time.process_time() - c0
        imgs.append(np.asarray(cube, np.float64).sum(axis=-1))
    return imgs, cpu / 2


def cube_row(scene, group: str, res, spp: int, other: str = "guided", against: str = "plain",
             passes: str = "all") -> dict | None:
    from illumix.renderer_jobs.mitsuba.band_render import light_paths_apply
    from illumix.renderer_jobs.mitsuba.render import emitter_passes

    view = scene.views[0].name
    row: dict = {"room": scene.name, "group": group}
    if other == "light" and not light_paths_apply(scene, [group]):
        return None
    if passes not in ("all", *emitter_passes(scene, [group])):
        return None
    row["against"], row["passes"] = against, passes
    for kind in (against, other):
        imgs, cpu = _pair(scene, view, group, res, spp, kind, passes)
        if not np.any(imgs[0]):
            return None
        m = measure(*imgs)
        row[kind] = {"rel": round(m["rel"], 4), "d_above_0_5": round(m["d_above_0_5"], 4),
                     "ff_light": round(m["ff_light"], 4), "clean": is_clean(m), "cpu_s": round(cpu, 2),
                     "mean": float(np.mean(imgs))}
    p, g = row[against], row[other]
    row["mean_ratio"] = round(g["mean"] / p["mean"], 4)
    row["efficiency"] = round((p["rel"] / g["rel"]) ** 2 / (g["cpu_s"] / p["cpu_s"]), 3)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="9140,9141,9142,9143")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--res", default="160x120")
    ap.add_argument("--kind", default="guided", choices=["guided", "light"], help="what is compared with plain paths")
    ap.add_argument("--against", default="plain", choices=["plain", "guided"], help="the paths --kind is compared with")
    ap.add_argument("--kinds", default="", help="only groups of these kinds (comma-separated), e.g. daylight")
    ap.add_argument("--pass", dest="passes", default="all", choices=["all", "without", "only"],
                    help="one emitter pass alone: 'without' (lamps, a sun), 'only' (sky portals)")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.res.split("x"))
    kinds = {k for k in args.kinds.split(",") if k}
    from illumix.scene.load import scene_from_dict

    rows = []
    for seed in args.seeds.split(","):
        doc = room_doc(int(seed))
        scene = scene_from_dict(doc, source=doc["name"])
        for g in [g for g in scene.group_names if not kinds or kind_of(g) in kinds]:
            row = cube_row(scene, g, res, args.spp, args.kind, args.against, args.passes)
            if row:
                rows.append(row)
                print(f"  {row}", file=sys.stderr, flush=True)
    eff = np.array([r["efficiency"] for r in rows])
    k = args.kind
    out = {"bench": "path_guiding", "kind": k, "seeds": args.seeds, "spp": args.spp, "res": list(res), "cubes": len(rows),
           "efficiency_median": round(float(np.median(eff)), 3),
           "efficiency_geomean": round(float(np.exp(np.mean(np.log(eff)))), 3),
           "efficiency_min": round(float(eff.min()), 3), "efficiency_max": round(float(eff.max()), 3),
           "against": args.against, "pass": args.passes,
           f"clean_{args.against}": sum(r[args.against]["clean"] for r in rows), f"clean_{k}": sum(r[k]["clean"] for r in rows),
           f"cpu_s_{args.against}": round(sum(r[args.against]["cpu_s"] for r in rows), 1),
           f"cpu_s_{k}": round(sum(r[k]["cpu_s"] for r in rows), 1),
           "mean_ratio_mean": round(float(np.mean([r["mean_ratio"] for r in rows])), 4), "rows": rows}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
