"""Firefly benchmark: where the noise of generated rooms comes from, per light-group kind, and what
each suspected source costs (issue 39, "clean renders of generated rooms"; figures in
``bench/SCENES.md``, "Fireflies").

Every light group is one fixture kind (ceiling panels, pendants, tubes, strips, floor and desk lamps,
screens, daylight = sky portals + sun) rendered as its own cube, so a group's noise points at its
fixture. For each room of ``--seeds`` (generated the default way, views chosen by the probe; the
documents are cached under ``bench/out/fireflies/``, the renders' band sums too), view 0, every
group: ``render_cube`` at ``--res`` (160×120) with the default spp (64, all bands), no denoising, no
illumination cube (the transport cube is what is measured), rendered twice with render seeds 1 and
2. Per cube:

- **noise**: per lit pixel the relative difference ``d = |A − B| / (A + B)`` of the two renders' band
  sums; for independent estimates with relative standard error ``s``, ``median(d) ≈ 0.477 s``, so
  ``s ≈ median(d) / 0.477`` is reported (``rel``) with the 95th percentile of ``d / 0.477`` and the
  share of lit pixels whose ``d > 0.5``;
- **fireflies**: in each render, pixels above 10× the median of their 5×5 neighbourhood, above 4×
  the other render (what both show — an emitter or a highlight seen directly — is no firefly) and
  above 1 % of the frame's 99th percentile: their share of the lit pixels, and the share of the
  frame's light in their excess (``ff_light``) — the light a denoiser smears into blotches.

``--rng-version 2`` generates the rooms with the current code but version 2's random numbers (the
same rooms where a change draws no differently) and keeps the views version 2 chose when its
document is cached (``room-v2-rng2-<seed>.json``, written by a run of the version-2 generator):
a before/after on the same rooms, views and render seeds.

Ablations (``--ablate``, comma-separated; applied to the document): ``housing`` (tube housings →
white paint), ``tube_flat`` (tube cylinder → downward diffuser rectangle 4 cm wide) — both for
version-2 documents —, ``metal`` (every metal alpha ≥ 0.3), ``ceramic`` (glossy plastics alpha
≥ 0.25), ``glass`` (glass → diffuse white), ``glossy`` (those three), ``strip_wide`` (strips 2 →
6 cm), ``strip_away`` (strips 9 cm further from their wall), ``strip_tilt`` (facing 45° into the
room), ``strip_both``, ``glow75`` (translucent shades carry 75 % of their lamp's power, not 50 %),
``all``. ``base`` is the document unchanged. Prints one JSON object last; per-cube rows go to stderr.

``--ladder 64,256,1024``: instead, per cube, the first spp of the ladder at which its two renders
are clean (:func:`is_clean`), with CPU per render at each step: what clean renders cost by more
paths alone. ``--clean-max-spp 1024``: every cube rendered with the renderer's until-clean rule
(``RenderSettings.clean_max_spp``), two seeds, judged by the same definition, against the two plain
64-spp renders rendered in the same run (CPU ratio) and the same rule with ``--baseline``'s settings
(``no-light``: without light paths, rendered only for cubes that reached a third round — before it
both rules render the same paths; ``unguided``: without guiding or light paths; ``none``, or
``--no-unguided``: no baseline), the ``baseline_*`` figures; ``--clean-max-spp default``: the
renderer's default settings (generated rooms get the rule, capped at 1024, its late rounds light
paths or guided). ``mean_ratio_to_plain``: the rule's image mean over the plain renders' (a bias
check: 1 within noise). The other modes render exactly the spp (``clean_max_spp = 0``).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np
from illumix.renderer_jobs.clean_check import D_TO_S, is_clean, measure

OUT = Path(__file__).resolve().parent / "out" / "fireflies"
SEEDS = (9102, 9106, 9108, 9110, 9122, 9125)  # every group kind, 2-4 groups each


def room_doc(seed: int, cache: bool = True, rng_version: str | None = None) -> dict:
    """The generated document of room ``seed`` (cached as JSON by generator and rng version).

    ``rng_version``: seed the generator's random numbers as that generator version did (the current
    code, the old version's draws): the same rooms as before a fixture change, where the change
    draws no differently — a controlled before/after."""
    from illumix.scenegen import GENERATOR_VERSION
    from illumix.scenegen import generate as G

    rv = rng_version or GENERATOR_VERSION
    path = OUT / f"room-v{GENERATOR_VERSION}-rng{rv}-{seed}.json"
    if cache and path.exists():
        return json.loads(path.read_text())
    saved, G.GENERATOR_VERSION = G.GENERATOR_VERSION, rv
    try:
        doc = G.generate_doc(seed)
    finally:
        G.GENERATOR_VERSION = saved
    before = OUT / f"room-v{rv}-rng{rv}-{seed}.json"
    if rv != GENERATOR_VERSION and before.exists():  # the views the older version chose
        doc["views"] = json.loads(before.read_text())["views"]
    OUT.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return doc


def _mats_of(doc: dict, prefix: str) -> list[str]:
    return [k for k in doc["materials"] if k.startswith(prefix)]


def _ablate(doc: dict, what: str) -> dict:
    """A copy of ``doc`` with one suspected firefly source changed (see module docstring)."""
    d = copy.deepcopy(doc)
    mats, shapes = d["materials"], d["shapes"]
    if what in ("housing", "all"):
        mats["abl_white"] = {"kind": "diffuse", "reflectance": {"value": 0.8}}
        for s in shapes:
            if s["name"].startswith("tube") and s["name"].endswith("_housing"):
                s["material"] = "abl_white"
    if what in ("metal", "glossy", "all"):
        for k in _mats_of(d, "metal"):
            mats[k]["alpha"] = max(mats[k]["alpha"], 0.3)
    if what in ("ceramic", "glossy", "all"):
        for k, m in mats.items():
            if m.get("kind") == "roughplastic" and m.get("alpha", 1) < 0.25:
                m["alpha"] = 0.25
    if what in ("glass", "glossy", "all"):
        for k in _mats_of(d, "glass"):
            mats[k] = {"kind": "diffuse", "reflectance": {"value": 0.8}}
    if what in ("tube_flat", "all"):
        _flat_tubes(d)
    if what in ("strip_wide", "all"):
        for s in shapes:
            if s["name"].startswith("strip") and s.get("emitter"):
                m = np.asarray(s["transform"]["matrix"], float)
                m[:3, 1] *= 3.0  # rectangle half-size along its second axis: 1 cm → 3 cm
                s["transform"]["matrix"] = m.tolist()
    if what == "glow75":  # shades carry 75 % of their lamp's power instead of 50 %: shade ×3, all ×1/2
        lamps = {sh["name"].split("_shadeglow")[0] for sh in shapes if "_shadeglow" in sh["name"]}
        for sh in shapes:
            name = sh["name"].split("_")[0]
            if sh.get("emitter") and (name in lamps or sh["name"].split("_shadeglow")[0] in lamps):
                k = 1.5 if "_shadeglow" in sh["name"] else 0.5
                sh["emitter"] = dict(sh["emitter"], strength=sh["emitter"]["strength"] * k)
    if what in ("strip_away", "strip_both"):
        _move_strips(d, "strip_away")
    if what in ("strip_tilt", "strip_both"):
        _move_strips(d, "strip_tilt")
    return d


def _move_strips(d: dict, what: str) -> None:
    """``strip_away``: each strip 9 cm further from its wall (15 cm); ``strip_tilt``: facing 45° into
    the room instead of 17° (the wall below it further off its emitting side)."""
    for s in d["shapes"]:
        if s["name"].startswith("strip") and s.get("emitter"):
            m = np.asarray(s["transform"]["matrix"], float)
            n_wall = m[:3, 1] / np.linalg.norm(m[:3, 1])  # the rectangle's 'up': the wall normal, projected
            n_wall = n_wall * np.array([1, 0, 1])
            n_wall /= np.linalg.norm(n_wall)
            if what == "strip_away":
                m[:3, 3] += 0.09 * n_wall
            else:
                normal = np.array([0.0, -1.0, 0.0]) + n_wall
                normal /= np.linalg.norm(normal)
                up = np.cross(m[:3, 0] / np.linalg.norm(m[:3, 0]), normal)
                up *= np.sign(up @ n_wall) * np.linalg.norm(m[:3, 1])
                m[:3, 1], m[:3, 2] = up, normal
            s["transform"]["matrix"] = m.tolist()


def _flat_tubes(d: dict) -> None:
    from illumix.scenegen.parts import rect

    out = []
    for s in d["shapes"]:
        if s["name"].startswith("tube") and s["type"] == "cylinder" and s.get("emitter"):
            p0, p1 = np.asarray(s["p0"], float), np.asarray(s["p1"], float)
            c, axis = (p0 + p1) / 2, (p1 - p0)
            length = float(np.linalg.norm(axis))
            r = rect(s["name"], None, tuple(c), (0, -1, 0), tuple(axis / length), (0.04, length), emitter=s["emitter"])
            # same power: π L A — the flat diffuser emits on one side only
            r["emitter"] = dict(s["emitter"], strength=s["emitter"]["strength"] * 2 * np.pi * s["radius"] * length
                                / (0.04 * length))
            out.append(r)
        else:
            out.append(s)
    d["shapes"] = out


def kind_of(group: str) -> str:
    return group.split(":")[0]


def _renders(scene, view: str, group: str, res, seeds, tag: str) -> tuple[list, float]:
    """Band sums ``(H, W)`` of the renders of ``group`` with each render seed, and CPU s per render;
    kept under ``bench/out/fireflies/img/`` by ``tag`` (a rerun reuses them and reports their CPU)."""
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    path = OUT / "img" / f"{tag}-{scene.name}-{group}-{res[0]}x{res[1]}.npz"
    if path.exists():
        z = np.load(path, allow_pickle=True)
        return list(z["imgs"]) if z["imgs"].dtype != object else [None], float(z["cpu"])
    imgs, cpu = [], 0.0
    for s in seeds:
        c0 = time.process_time()
        r = render_cube(scene, view, group, RenderSettings(resolution=res, denoise=None, illumination=False, seed=s,
                                                           clean_max_spp=0))  # exactly the spp (no rule)
        cpu += time.process_time() - c0
        imgs.append(None if r.cube is None else np.asarray(r.cube, np.float64).sum(axis=-1))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, imgs=np.array(imgs, dtype=object if any(i is None for i in imgs) else np.float64), cpu=cpu)
    return imgs, cpu


def render_room(doc: dict, res: tuple[int, int], kinds: set[str] = frozenset(), seeds=(1, 2),
                tag: str = "base") -> list[dict]:
    """Per group of view 0 (of ``kinds`` only, if given): the measure() of two renders, CPU s per cube."""
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    view, rows = scene.views[0].name, []
    for g in [g for g in scene.group_names if not kinds or kind_of(g) in kinds]:
        imgs, cpu = _renders(scene, view, g, res, seeds, tag)
        if any(i is None for i in imgs) or not np.any(imgs[0]):
            rows.append({"room": doc["name"], "group": g, "kind": kind_of(g), "empty": True, "cpu_s": cpu / len(seeds)})
            continue
        m = measure(*imgs)
        rows.append({"room": doc["name"], "group": g, "kind": kind_of(g), "cpu_s": cpu / len(seeds), **m})
        print(f"  {doc['name']} {g}: rel {m['rel']:.3f} p95 {m['rel_p95']:.3f} ff_px {m['ff_pixels']:.4f} "
              f"ff_light {m['ff_light']:.4f} cpu {cpu / len(seeds):.1f}", file=sys.stderr, flush=True)
    return rows


def _two_renders(scene, view: str, group: str, **settings) -> tuple[list, float, list, list]:
    """Band sums ``(H, W)`` of ``group``'s cube rendered with seeds 1 and 2 (no denoising, transport
    only, ``settings`` on top), their CPU s together, each one's paths per pixel and render stats."""
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    imgs, cpu, paths, stats = [], 0.0, [], []
    for seed in (1, 2):
        c0 = time.process_time()
        st = {"clean_max_spp": 0, **settings}  # exactly the spp unless the rule is asked for
        r = render_cube(scene, view, group, RenderSettings(denoise=None, illumination=False, seed=seed, **st))
        cpu += time.process_time() - c0
        imgs.append(np.asarray(r.cube, np.float64).sum(axis=-1))
        paths.append(r.stats["paths_per_pixel"])
        stats.append(r.stats)
    return imgs, cpu, paths, stats


# --baseline: the rule with these settings, in the same run (bench/SCENES.md); "no-light" is rendered
# only for cubes whose rule reached a third round (before it, the two rules render the same paths)
BASELINES = {"unguided": {"guide_paths": False, "light_paths": False}, "no-light": {"light_paths": False}}


def spp_to_clean(doc: dict, res: tuple[int, int], ladder: list[int], tag: str) -> list[dict]:
    """Per group of view 0: render it at each spp of ``ladder`` in turn (two seeds each, fresh paths)
    until the two renders are :func:`is_clean`: the spp that got there and the CPU per render at each
    step — what "clean before denoising" costs by more paths alone (``--ladder``)."""
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    view, rows = scene.views[0].name, []
    for g in scene.group_names:
        row: dict = {"room": doc["name"], "group": g, "steps": [], "clean_at": None}
        for spp in ladder:
            if spp == 64:  # the default: the renders the base measurement keeps
                imgs, cpu = _renders(scene, view, g, res, (1, 2), tag)
            else:
                imgs, cpu, _, _ = _two_renders(scene, view, g, resolution=res, spp=spp)
            if any(i is None for i in imgs) or not np.any(imgs[0]):
                break
            m = measure(*imgs)
            row["steps"].append({"spp": spp, "rel": round(m["rel"], 3), "d_above_0_5": round(m["d_above_0_5"], 4),
                                 "ff_light": round(m["ff_light"], 4), "cpu_s": round(cpu / 2, 1)})
            if is_clean(m):
                row["clean_at"] = spp
                break
        print(f"  {doc['name']} {g}: clean at {row['clean_at']} spp; {row['steps']}", file=sys.stderr, flush=True)
        rows.append(row)
    return rows


def until_clean(doc: dict, res: tuple[int, int], max_spp: int | None, baseline: str | None = "no-light",
                kinds: set[str] = frozenset()) -> list[dict]:
    """Per group of view 0 (of ``kinds`` only, if given): two renders (seeds 1, 2) with ``RenderSettings.clean_max_spp = max_spp``
    (None: unset, the renderer's default; the renderer adds paths until its own halves are clean): whether the two are clean by
    :func:`is_clean`, the paths each used, the kinds of its rounds and CPU per render (``--clean-max-spp``).
    In the same run, as baselines: two plain 64-spp renders (``plain``) and the rule with ``baseline``'s
    settings (:data:`BASELINES`; ``"baseline"`` in the row)."""
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    view, rows = scene.views[0].name, []

    def judged(imgs, cpu, paths=None) -> dict:
        m = measure(*imgs)
        out = {"clean": is_clean(m), "rel": round(m["rel"], 3), "d_above_0_5": round(m["d_above_0_5"], 4),
               "ff_light": round(m["ff_light"], 4), "cpu_s": round(cpu / 2, 1)}
        return out if paths is None else {"paths_per_pixel": paths, **out}

    for g in [g for g in scene.group_names if not kinds or kind_of(g) in kinds]:
        plain, plain_cpu, _, _ = _two_renders(scene, view, g, resolution=res)  # the baseline, same run
        if not np.any(plain[0]):
            continue
        row = {"room": doc["name"], "group": g}
        imgs, cpu, paths, stats = _two_renders(scene, view, g, resolution=res, clean_max_spp=max_spp)
        mine = judged(imgs, cpu, paths)
        row.update(mine)
        row["kinds"] = [st.get("until_clean", {}).get("kinds") for st in stats]
        row["light_weight"] = [st.get("until_clean", {}).get("light_weight") for st in stats]
        if baseline == "no-light" and all(k is None or len(k) <= 2 for k in row["kinds"]):
            row["baseline"] = {**mine, "same_renders": True}
        elif baseline:
            row["baseline"] = judged(*_two_renders(scene, view, g, resolution=res, clean_max_spp=max_spp,
                                                   **BASELINES[baseline])[:3])
        row["mean_ratio_to_plain"] = round(float(np.mean(imgs) / max(np.mean(plain), 1e-30)), 4)
        row["plain"] = judged(plain, plain_cpu)
        rows.append(row)
        print(f"  {rows[-1]}", file=sys.stderr, flush=True)
    return rows


def summarise(rows: list[dict]) -> dict:
    """Per group kind and pooled: noise from the pooled d, mean firefly shares, CPU."""
    out = {}
    full = [r for r in rows if not r.get("empty")]
    for kind in sorted({r["kind"] for r in full}) + ["all"]:
        sel = [r for r in full if kind in ("all", r["kind"])]
        d = np.concatenate([r["d"] for r in sel])
        out[kind] = {"cubes": len(sel), "rel": round(float(np.median(d) / D_TO_S), 4),
                     "rel_p95": round(float(np.percentile(d, 95) / D_TO_S), 4),
                     "d_above_0_5": round(float((d > 0.5).mean()), 4),
                     "ff_pixels": round(float(np.mean([r["ff_pixels"] for r in sel])), 5),
                     "ff_light": round(float(np.mean([r["ff_light"] for r in sel])), 5),
                     "ff_light_max": round(float(np.max([r["ff_light"] for r in sel])), 5)}
    rooms = {r["room"] for r in rows}
    out["cpu_s_per_cube"] = round(float(np.mean([r["cpu_s"] for r in rows])), 2)
    out["cpu_s_per_room_one_view"] = round(sum(r["cpu_s"] for r in rows) / max(len(rooms), 1), 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default=",".join(map(str, SEEDS)))
    ap.add_argument("--res", default="160x120")
    ap.add_argument("--ablate", default="base")
    ap.add_argument("--kinds", default="", help="only groups of these kinds (comma-separated; every mode but --ladder)")
    ap.add_argument("--no-cache", action="store_true", help="regenerate the rooms")
    ap.add_argument("--rng-version", default=None, help="seed the rooms as this generator version did")
    ap.add_argument("--ladder", default="", help="e.g. 64,256,1024: per cube, the spp that makes it clean")
    ap.add_argument("--clean-max-spp", default="", help="render with the renderer's until-clean rule up to this "
                    "many spp; 'default': the renderer's default settings (the rule's default cap on generated rooms)")
    ap.add_argument("--baseline", default="no-light", choices=[*BASELINES, "none"], help="with --clean-max-spp: "
                    "the rule also rendered without light paths (no-light) or without guiding and light paths "
                    "(unguided), or not (none)")
    ap.add_argument("--no-unguided", action="store_true", help="the same as --baseline none")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.res.split("x"))
    kinds = {k for k in args.kinds.split(",") if k}
    from illumix.scenegen import GENERATOR_VERSION as version

    docs = [room_doc(int(s), not args.no_cache, args.rng_version) for s in args.seeds.split(",")]
    version = f"{version}-rng{args.rng_version or version}"
    result = {"bench": "fireflies", "res": list(res), "seeds": args.seeds}
    if args.clean_max_spp:
        cap = None if args.clean_max_spp == "default" else int(args.clean_max_spp)
        baseline = None if args.no_unguided or args.baseline == "none" else args.baseline
        rows = [r for doc in docs for r in until_clean(doc, res, cap, baseline, kinds)]
        u = result["until_clean"] = {"max_spp": args.clean_max_spp, "cubes": len(rows),
                                     "clean": sum(r["clean"] for r in rows),
                                     "cpu_s": round(sum(r["cpu_s"] for r in rows), 1),
                                     "plain_clean": sum(r["plain"]["clean"] for r in rows),
                                     "plain_cpu_s": round(sum(r["plain"]["cpu_s"] for r in rows), 1)}
        u["cpu_ratio"] = round(u["cpu_s"] / max(u["plain_cpu_s"], 1e-9), 2)
        u["mean_paths_ratio"] = round(float(np.mean([np.mean(r["paths_per_pixel"]) / 64 for r in rows])), 2)
        u["mean_ratio_to_plain"] = round(float(np.mean([r["mean_ratio_to_plain"] for r in rows])), 4)
        if baseline:
            u["baseline"] = baseline
            u["baseline_clean"] = sum(r["baseline"]["clean"] for r in rows)
            u["baseline_cpu_s"] = round(sum(r["baseline"]["cpu_s"] for r in rows), 1)
            u["baseline_cpu_ratio"] = round(u["baseline_cpu_s"] / max(u["plain_cpu_s"], 1e-9), 2)
            u["baseline_mean_paths_ratio"] = round(float(np.mean([np.mean(r["baseline"]["paths_per_pixel"]) / 64
                                                                  for r in rows])), 2)
        u["rows"] = rows
        print(json.dumps(result))
        return
    if args.ladder:
        ladder = [int(v) for v in args.ladder.split(",")]
        rows = [r for doc in docs for r in spp_to_clean(doc, res, ladder, f"v{version}-base")]
        steps = {spp: sum(1 for r in rows if r["clean_at"] is not None and r["clean_at"] <= spp) for spp in ladder}
        result["ladder"] = {"cubes": len(rows), "clean_by_spp": steps,
                            "cpu_s_default": round(sum(r["steps"][0]["cpu_s"] for r in rows if r["steps"]), 1),
                            # more paths kept where the cube is not clean yet: the last step's CPU per cube
                            "cpu_s_until_clean": round(sum(r["steps"][-1]["cpu_s"] for r in rows if r["steps"]), 1),
                            "rows": rows}
        print(json.dumps(result))
        return
    for what in args.ablate.split(","):
        print(f"ablation {what} …", file=sys.stderr, flush=True)
        rows = []
        for doc in docs:
            if not kinds or any(kind_of(g["name"]) in kinds for g in doc["light_groups"]):
                rows += render_room(doc if what == "base" else _ablate(doc, what), res, kinds, tag=f"v{version}-{what}")
        result[what] = summarise(rows) if rows else {}
        print(json.dumps({what: result[what]}), file=sys.stderr, flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
