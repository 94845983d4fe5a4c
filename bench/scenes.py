"""Scene-corpus benchmark: how many different rooms the generator makes, how fast, how mixed their
light is, and what rendering them costs.

Four parts (``--parts``, all by default):

``generate`` — ``--rooms`` rooms (seeds 0…N−1) generated without the view probe: wall and process
  CPU seconds per room, distinct layout hashes (``scenegen.generate.layout_hash``: geometry,
  materials, lights), and what varies (layouts, windows, group kinds, shape and material counts).
  Every ``--validate-every``-th room is validated against the scene schema.

``probe`` — ``--probe-rooms`` rooms generated the default way (views chosen by the mixed-light probe
  from 12 candidates): seconds per room, and each chosen view's mixed-light fraction (lit pixels whose
  strongest group's share of the luminance is < 0.8, ``scenegen.views``): mean, quartiles, share of
  views ≥ 0.3, views that see ≥ 2 groups. A histogram goes to ``bench/out/scenes_mixed.png`` and a
  contact sheet of the first rooms' views to ``bench/out/scenes_sheet.png``.

``cube`` — one cube (room 0, its first view, its first group lit in that view) rendered at 240×180
  and at 720×960 with ``illumix render``'s default settings (64 spp, all bands, light probe,
  illumination cube, default denoiser) through the render jobs into a temporary store: the cube job's
  wall seconds, after a warm-up render at 240×180 (kernel compilation; reported separately).

``batch`` — ``--batch-rooms`` generated rooms × 3 views × every group at 240×180, default settings,
  rendered end to end by the process-pool executor with ``--workers`` (2) into a temporary store:
  wall time, cubes, and the wall time a 100-room batch would take at that rate (``batch_100_rooms_h``;
  measured directly with ``--batch-rooms 100``, which takes hours on 2 cores).

Prints one JSON object last with ``distinct_rooms``, ``gen_s_per_room``, ``mixed_fraction_mean``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.render_lib import machine, timed  # noqa: E402

OUT = Path(__file__).resolve().parent / "out"


def part_generate(rooms: int, validate_every: int) -> dict:
    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.generate import GeneratorConfig, generate_doc, layout_hash

    cfg = GeneratorConfig(probe=False)
    hashes, walls, cpus, layouts, windows, groups, shapes, mats = set(), [], [], Counter(), Counter(), Counter(), [], []
    for seed in range(rooms):
        doc, w, c = timed(lambda s=seed: generate_doc(s, cfg))
        walls.append(w)
        cpus.append(c)
        hashes.add(layout_hash(doc))
        desc = doc["description"]
        layouts[next(k for k in ("rectangular", "L-shaped", "two rooms") if k in desc)] += 1
        windows[desc.split(" window(s)")[0].rsplit(" ", 1)[-1]] += 1
        groups.update(g["name"] for g in doc["light_groups"])
        shapes.append(len(doc["shapes"]))
        mats.append(len(doc["materials"]))
        if validate_every and seed % validate_every == 0:
            scene_from_dict(doc, source=f"room {seed}")
        if seed % 100 == 99:
            print(f"  generated {seed + 1}/{rooms}", file=sys.stderr, flush=True)
    return {"rooms": rooms, "distinct_rooms": len(hashes), "gen_s_per_room": round(float(np.mean(walls)), 4),
            "gen_cpu_s_per_room": round(float(np.mean(cpus)), 4), "gen_s_p99": round(float(np.percentile(walls, 99)), 4),
            "layouts": dict(layouts), "windows": dict(sorted(windows.items())), "group_kinds": dict(groups),
            "shapes_median": int(np.median(shapes)), "materials_median": int(np.median(mats))}


def part_probe(rooms: int, sheet_rooms: int) -> dict:
    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.generate import GeneratorConfig, generate_doc

    generate_doc(10_000, GeneratorConfig())  # warm-up: Mitsuba start and first kernels
    fracs, seconds, two, docs = [], [], 0, []
    for seed in range(rooms):
        doc, w, _ = timed(lambda s=seed: generate_doc(s))
        seconds.append(w)
        text = doc["description"].split("mixed-light fraction per view ")[-1]
        fracs += [float(x) for x in text.split(", ")]
        docs.append(doc)
        print(f"  probed room {seed}: {w:.1f} s, {text}", file=sys.stderr, flush=True)
    fracs_a = np.asarray(fracs)
    out = {"probe_rooms": rooms, "views": int(fracs_a.size), "gen_with_probe_s_per_room": round(float(np.mean(seconds)), 2),
           "mixed_fraction_mean": round(float(fracs_a.mean()), 3),
           "mixed_fraction_quartiles": [round(float(q), 3) for q in np.percentile(fracs_a, [25, 50, 75])],
           "views_at_least_0_3": round(float((fracs_a >= 0.3).mean()), 3),
           "rooms_mean_below_0_3": int(sum(np.mean([float(x) for x in d["description"].split("per view ")[-1].split(", ")]) < 0.3
                                           for d in docs))}
    try:
        _plots(fracs_a, [scene_from_dict(d) for d in docs[:sheet_rooms]])
        out["plots"] = ["bench/out/scenes_mixed.png", "bench/out/scenes_sheet.png"]
    except ImportError as exc:  # matplotlib is a test extra
        out["plots"] = f"skipped: {exc}"
    return out


def _plots(fracs: np.ndarray, scenes) -> None:
    import cv2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from illumix.renderer_jobs.mitsuba.preview import contact_sheet, preview_linear, to_srgb8

    OUT.mkdir(exist_ok=True)
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(fracs, bins=20, range=(0, 1), color="#4a7")
    ax.axvline(0.3, color="k", ls="--", lw=1, label="goal: mean ≥ 0.3")
    ax.axvline(fracs.mean(), color="r", lw=1, label=f"mean {fracs.mean():.2f}")
    ax.set_xlabel("mixed-light fraction of a chosen view")
    ax.set_ylabel("views")
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "scenes_mixed.png", dpi=120)
    plt.close(fig)
    tiles = []
    for sc in scenes:
        for v, img in zip(sc.views, preview_linear(sc, resolution=(160, 120), spp=32)):
            tiles.append((f"{sc.name[5:]}/{v.name[4:]} {','.join(sc.group_names)}", to_srgb8(img)))
    cv2.imwrite(str(OUT / "scenes_sheet.png"), cv2.cvtColor(contact_sheet(tiles, 5), cv2.COLOR_RGB2BGR))


def _render(scenes, store: str, workers: int, views=None, groups=None) -> tuple[list[dict], float]:
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.renderer_jobs.mitsuba.render import RenderSettings

    p = jobs.plan(scenes, store, views=views, groups=groups)
    t0 = time.perf_counter()
    done = execute(p, store, RenderSettings(), workers=workers)
    return done, time.perf_counter() - t0


def part_cube() -> dict:
    from illumix.renderer_jobs import jobs
    from illumix.scenegen.generate import generate_scene

    scene = generate_scene(0)
    view, out = scene.views[0].name, {}

    def cube(res, group, store) -> dict:
        done, _ = _render([jobs.apply_resolution(scene, res)], store, 1, views=[view], groups=[group])
        return next(d for d in done if d["kind"] == "cube")

    with tempfile.TemporaryDirectory() as tmp:
        group = None
        for g in scene.group_names:  # warm-up (kernel compilation) on the first group lit in the view
            first = cube((240, 180), g, f"{tmp}/warm-{g}")
            if not first.get("empty"):
                group = g
                out["cube_s_first_240x180"] = round(first["seconds"], 2)
                break
        out["cube_group"] = group
        for res in ((240, 180), (720, 960)):
            if group is not None:
                print(f"  cube {res[0]}x{res[1]} …", file=sys.stderr, flush=True)
                out[f"cube_s_{res[0]}x{res[1]}"] = round(cube(res, group, f"{tmp}/{res[0]}")["seconds"], 2)
    return out


def part_batch(rooms: int, workers: int) -> dict:
    from illumix.renderer_jobs import jobs
    from illumix.scenegen.generate import GeneratorConfig, generate_scene

    cfg = GeneratorConfig(views=(3, 3))
    scenes = [jobs.apply_resolution(generate_scene(1000 + i, cfg), (240, 180)) for i in range(rooms)]
    with tempfile.TemporaryDirectory() as tmp:
        done, wall = _render(scenes, f"{tmp}/batch", workers)
    cubes = [d for d in done if d["kind"] == "cube"]
    return {"batch_rooms": rooms, "batch_views": sum(len(s.views) for s in scenes), "batch_cubes": len(cubes),
            "batch_empty_cubes": sum(bool(d.get("empty")) for d in cubes), "batch_wall_s": round(wall, 1),
            "batch_workers": workers, "batch_s_per_room": round(wall / rooms, 1),
            "batch_100_rooms_h": round(wall / rooms * 100 / 3600, 2),
            "batch_100_rooms_measured": rooms >= 100}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--parts", default="generate,probe,cube,batch")
    ap.add_argument("--rooms", type=int, default=1000)
    ap.add_argument("--validate-every", type=int, default=10)
    ap.add_argument("--probe-rooms", type=int, default=20)
    ap.add_argument("--sheet-rooms", type=int, default=4)
    ap.add_argument("--batch-rooms", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    from illumix.scenegen import GENERATOR_VERSION

    parts = [p.strip() for p in args.parts.split(",") if p.strip()]
    res: dict = {"bench": "scenes", "generator_version": GENERATOR_VERSION, **machine()}
    for name, fn in (("generate", lambda: part_generate(args.rooms, args.validate_every)),
                     ("probe", lambda: part_probe(args.probe_rooms, args.sheet_rooms)),
                     ("cube", part_cube), ("batch", lambda: part_batch(args.batch_rooms, args.workers))):
        if name in parts:
            print(f"part {name} …", file=sys.stderr, flush=True)
            res.update(fn())
    res.setdefault("distinct_rooms", None)
    res.setdefault("gen_s_per_room", None)
    res.setdefault("mixed_fraction_mean", None)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
