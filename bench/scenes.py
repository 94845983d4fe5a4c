"""Scene-corpus benchmark: what generated rooms hold (objects, kinds, meshes), how mixed their light
is, what they cost to generate and render, how noisy a render is before denoising, and a contact
sheet of what they look like.

Parts (``--parts``; default ``corpus,render,sheet``):

``corpus`` — ``--corpus-rooms`` (24) rooms from seed ``--seed`` (7000: seeds no test or other bench
  uses), generated the default way (views chosen by the mixed-light probe), each also without the
  probe: CPU seconds per room both ways; per room the objects (distinct object names: furniture,
  fixtures, clutter, dressing — not walls, floors, ceilings, windows), the distinct object kinds
  over all rooms, the share of shapes that are triangle meshes (all shapes, and the objects' shapes
  alone), triangles, light groups; and, re-probing each chosen view (``scenegen.views.probe``, 48×36,
  16 spp), the fraction of views in which ≥ 2 groups each bring ≥ 5 % of the light.

``render`` — view 0 of the first ``--render-rooms`` (2) corpus rooms, every group, rendered by
  ``renderer_jobs.mitsuba.render.render_cube`` at ``--render-res`` (160×120) with the default settings
  (64 spp, all bands, the until-clean rule up to 1024 spp that generated rooms get since 2026-11-28 — the
  figures in bench/SCENES.md before that date are without it; no targeted extra paths, no denoising):
  CPU seconds per cube and per room, and
  the noise before denoising from the renderer's own per-pixel variance of the band sum
  (``CubeResult.noise``): median and 95th percentile of the relative standard error over lit pixels,
  and the share of lit pixels above 0.5 (fireflies).

``sheet`` — a contact sheet of view 0 of each corpus room at 320×240 (Mitsuba's path tracer, every
  group on, ``--sheet-spp`` (128) spp, ``renderer_jobs.mitsuba.preview``) to
  ``bench/scenes_figures/sheet.jpg``, and a line-up of every object kind to
  ``bench/scenes_figures/objects.jpg``; with the CPU seconds they took.

The earlier parts stay available: ``generate`` (``--rooms`` seeds 0…N−1 without the probe: distinct
layout hashes, generation time, what varies), ``probe`` (``--probe-rooms`` rooms: seconds and
mixed-light fractions), ``cube`` (one cube at 240×180 and 720×960 through the render jobs) and
``batch`` (``--batch-rooms`` rooms × 3 views end to end with the process pool).

Prints one JSON object last.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.render_lib import machine, timed  # noqa: E402

OUT = Path(__file__).resolve().parent / "out"
FIGURES = Path(__file__).resolve().parent / "scenes_figures"
STRUCTURE = re.compile(r"(floor|ceiling|wall|window|door)\d+$")  # shell and openings: not objects


def room_objects(doc: dict) -> tuple[set[str], list[str]]:
    """A room's objects (names) and their kinds: a shape ``chair3_mesh0`` belongs to object ``chair3``
    of kind ``chair``; clutter and dressing (``c1_cup1_…``, ``d0_frame0_…``, ``t2_vase2_…``,
    ``w0_clock0_…``) to ``c1_cup1`` of kind ``cup``; a closed door ``exit0`` is kind ``door``."""
    objects: dict[str, str] = {}
    for s in doc["shapes"]:
        parts = s["name"].split("_")
        obj, kind = (parts[0], parts[0]) if not re.match(r"[cwdt]\d+$", parts[0]) else ("_".join(parts[:2]), parts[1])
        if STRUCTURE.match(obj):
            continue
        kind = re.sub(r"\d+$", "", kind)
        objects[obj] = {"exit": "door", "panel": "ceiling-panel", "tube": "tubes"}.get(kind, kind)
    return set(objects), list(objects.values())


def _triangles(doc: dict) -> int:
    n = 0
    for s in doc["shapes"]:
        if s["type"] == "ply":
            with open(s["filename"], "rb") as f:
                head = f.read(400).split(b"end_header")[0]
            n += int(head.split(b"element face ")[1].split(b"\n")[0])
    return n


def part_corpus(seed0: int, rooms: int) -> dict:
    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.generate import GROUP_SEEN, GeneratorConfig, generate_doc
    from illumix.scenegen.views import probe

    generate_doc(seed0 + 10_000, GeneratorConfig())  # warm-up: imports, Mitsuba start, first kernels
    rows, kinds, docs = [], Counter(), []
    for seed in range(seed0, seed0 + rooms):
        _, _, cpu_fast = timed(lambda s=seed: generate_doc(s, GeneratorConfig(probe=False)))
        doc, _, cpu = timed(lambda s=seed: generate_doc(s))
        objs, k = room_objects(doc)
        kinds.update(k)
        shapes = doc["shapes"]
        obj_shapes = [s for s in shapes if not STRUCTURE.match(s["name"].split("_")[0])]
        scene = scene_from_dict(doc, source=doc["name"])
        (_, shares), _, cpu_probe = timed(lambda sc=scene: probe(sc))
        two = (shares >= GROUP_SEEN).sum(axis=1) >= 2
        rows.append({"seed": seed, "objects": len(objs), "kinds": len(set(k)), "shapes": len(shapes),
                     "mesh_share": sum(s["type"] == "ply" for s in shapes) / len(shapes),
                     "object_mesh_share": sum(s["type"] == "ply" for s in obj_shapes) / max(len(obj_shapes), 1),
                     "triangles": _triangles(doc), "groups": len(doc["light_groups"]), "views": len(doc["views"]),
                     "views_two_groups": int(two.sum()), "gen_cpu_s": cpu, "gen_cpu_s_no_probe": cpu_fast,
                     "reprobe_cpu_s": cpu_probe})
        docs.append(doc)
        print(f"  room {seed}: {len(objs)} objects, {rows[-1]['triangles']} triangles, "
              f"{rows[-1]['groups']} groups, {int(two.sum())}/{len(two)} views with >= 2 groups, {cpu:.1f} CPU s",
              file=sys.stderr, flush=True)
    col = {k: np.array([r[k] for r in rows], float) for k in rows[0]}
    views = col["views"].sum()
    global CORPUS
    CORPUS = docs
    return {"corpus_seeds": [seed0, seed0 + rooms - 1], "corpus_rooms": rooms,
            "objects_per_room_mean": round(float(col["objects"].mean()), 1),
            "objects_per_room_min_max": [int(col["objects"].min()), int(col["objects"].max())],
            "distinct_kinds": len(kinds), "kinds_per_room_mean": round(float(col["kinds"].mean()), 1),
            "kind_counts": dict(kinds.most_common()),
            "mesh_share_of_shapes": round(float(col["mesh_share"].mean()), 3),
            "mesh_share_of_object_shapes": round(float(col["object_mesh_share"].mean()), 3),
            "triangles_per_room_mean": int(col["triangles"].mean()),
            "groups_per_room": dict(Counter(int(g) for g in col["groups"])),
            "views_with_two_groups": round(float(col["views_two_groups"].sum() / views), 3),
            "gen_cpu_s_per_room": round(float(col["gen_cpu_s"].mean()), 2),
            "gen_cpu_s_per_room_no_probe": round(float(col["gen_cpu_s_no_probe"].mean()), 3)}


CORPUS: list[dict] = []


def _corpus(seed0: int, rooms: int) -> list[dict]:
    from illumix.scenegen.generate import generate_doc

    return CORPUS or [generate_doc(s) for s in range(seed0, seed0 + rooms)]


def part_render(docs: list[dict], rooms: int, res: tuple[int, int]) -> dict:
    from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube
    from illumix.scene.load import scene_from_dict

    settings = RenderSettings(resolution=res, denoise=None)
    cubes, per_room, rel_all, bright = [], [], [], []
    for doc in docs[:rooms]:
        scene = scene_from_dict(doc, source=doc["name"])
        view, room_cpu = scene.views[0].name, 0.0
        for g in scene.group_names:
            res_, _, cpu = timed(lambda gg=g, sc=scene, v=view: render_cube(sc, v, gg, settings))
            room_cpu += cpu
            if res_.noise is None:  # a group that sends no light into the view
                continue
            total, var = res_.noise[..., 0], res_.noise[..., 1]
            lit = total > 1e-3 * max(float(np.percentile(total, 99)), 1e-30)
            rel = np.sqrt(np.maximum(var[lit], 0)) / total[lit]
            rel_all.append(rel)
            bright.append(rel[total[lit] >= np.median(total[lit])] if rel.size else rel)
            uc = res_.stats.get("until_clean") or {}
            cubes.append({"room": doc["name"], "group": g, "cpu_s": round(cpu, 1),
                          "rel_noise_median": round(float(np.median(rel)), 4) if rel.size else None,
                          "paths_per_pixel": res_.stats.get("paths_per_pixel"), "until_clean": uc.get("clean")})
            print(f"  cube {doc['name']}/{view}/{g}: {cpu:.1f} CPU s", file=sys.stderr, flush=True)
        per_room.append(room_cpu)
    rel = np.concatenate(rel_all) if rel_all else np.zeros(1)
    return {"render_res": list(res), "render_spp": settings.spp, "render_cubes": cubes,
            "render_cpu_s_per_cube": round(float(np.mean([c["cpu_s"] for c in cubes])), 1),
            "render_cpu_s_per_room_one_view": round(float(np.mean(per_room)), 1),
            "noise_rel_median": round(float(np.median(rel)), 4), "noise_rel_p95": round(float(np.percentile(rel, 95)), 4),
            "noise_share_above_0_5": round(float((rel > 0.5).mean()), 4),
            "noise_rel_median_brighter_half": round(float(np.median(np.concatenate(bright))), 4) if bright else None}


def part_sheet(docs: list[dict], spp: int) -> dict:
    import cv2

    from illumix.renderer_jobs.mitsuba.preview import contact_sheet, preview_linear, to_srgb8
    from illumix.scene.load import scene_from_dict

    FIGURES.mkdir(exist_ok=True)
    tiles, c0 = [], time.process_time()
    for doc in docs:
        scene = scene_from_dict(doc, source=doc["name"])
        img = preview_linear(scene, [scene.views[0].name], resolution=(320, 240), spp=spp)[0]
        objs, _ = room_objects(doc)
        tiles.append((f"{doc['generator']['seed']}: {len(objs)} obj, {','.join(scene.group_names)}", to_srgb8(img)))
        print(f"  sheet {doc['name']}", file=sys.stderr, flush=True)
    cpu_sheet = time.process_time() - c0
    jpeg = [cv2.IMWRITE_JPEG_QUALITY, 88]  # noisy renders: a PNG would be 5 MB
    cv2.imwrite(str(FIGURES / "sheet.jpg"), cv2.cvtColor(contact_sheet(tiles, 4), cv2.COLOR_RGB2BGR), jpeg)
    c1 = time.process_time()
    cv2.imwrite(str(FIGURES / "objects.jpg"), cv2.cvtColor(object_lineup(spp), cv2.COLOR_RGB2BGR), jpeg)
    return {"sheet": "bench/scenes_figures/sheet.jpg", "sheet_rooms": len(docs), "sheet_spp": spp,
            "sheet_cpu_s": round(cpu_sheet, 1), "objects_figure": "bench/scenes_figures/objects.jpg",
            "objects_cpu_s": round(time.process_time() - c1, 1)}


LINEUP = (("table", "desk", "chair", "sofa", "cabinet", "shelf"),
          ("coffee_table", "bed", "kitchen_counter", "fridge", "oven", "washing_machine"),
          ("cup", "bowl", "bottle", "vase", "plant", "book_stack", "box"),
          ("frame", "clock", "wall_shelf", "floor_plant"))


def object_lineup(spp: int, seed: int = 5) -> np.ndarray:
    """Every furniture and clutter kind in a row on a floor against a wall, lit by a sky and a sun:
    one 960×240 strip per row of :data:`LINEUP`, the camera as far as the row needs (60° wide)."""
    from illumix.renderer_jobs.mitsuba.preview import preview_linear, to_srgb8
    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.catalog import CLUTTER, FURNITURE
    from illumix.scenegen.materials import Materials
    from illumix.scenegen.parts import place, rect

    strips = []
    for row in LINEUP:
        rng = np.random.default_rng(seed)
        mats = Materials(rng)
        shapes, x, top = [], 0.0, 0.0
        for i, kind in enumerate(row):
            item = {**FURNITURE, **CLUTTER}[kind](rng, mats, f"o{i}")
            shapes += place(item, x + item.footprint[0] / 2, -1.5 + item.footprint[1] / 2 + 0.01, 0, "")
            x += item.footprint[0] + 0.1 * item.footprint[0] + 0.05
            top = max(top, item.height)
        vertical = np.tan(np.radians(30)) * 240 / 960  # tan of half the vertical field of view
        cx, dist = x / 2, max((x / 2 + 0.35) / np.tan(np.radians(30)), (top / 2 + 0.1) / vertical)
        shapes += [rect("floor", mats.pick("paint"), (cx, 0, 0), (0, 1, 0), (0, 0, -1), (x + 30, 40)),
                   rect("back", mats.pick("paint"), (cx, 3.0, -1.5), (0, 0, 1), (0, 1, 0), (x + 30, 6)),
                   rect("sky", None, (cx, top + 2.0, dist / 2), (0, -1, 0), (0, 0, -1), (x + 4, dist + 3),
                        emitter={"group": "a", "strength": 1.0})]
        doc = {"name": "lineup", "materials": mats.docs, "shapes": shapes, "light_groups": [{"name": "a"}],
               "lights": [{"name": "sun", "type": "directional", "group": "a", "direction": [0.3, -0.8, -0.5],
                           "strength": 3.0}],
               "views": [{"name": "v", "origin": [cx, top * 0.75, -1.3 + dist], "target": [cx, top * 0.5, -1.3],
                          "fov": 60, "resolution": [960, 240]}]}
        img = preview_linear(scene_from_dict(doc, source="object line-up"), resolution=(960, 240), spp=spp)[0]
        strips.append(to_srgb8(img))
    return np.concatenate(strips, axis=0)


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
    ap.add_argument("--parts", default="corpus,render,sheet")
    ap.add_argument("--seed", type=int, default=7000)
    ap.add_argument("--corpus-rooms", type=int, default=24)
    ap.add_argument("--render-rooms", type=int, default=2)
    ap.add_argument("--render-res", default="160x120")
    ap.add_argument("--sheet-spp", type=int, default=128)
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
    rw, rh = (int(v) for v in args.render_res.split("x"))
    for name, fn in (("corpus", lambda: part_corpus(args.seed, args.corpus_rooms)),
                     ("render", lambda: part_render(_corpus(args.seed, args.corpus_rooms), args.render_rooms, (rw, rh))),
                     ("sheet", lambda: part_sheet(_corpus(args.seed, args.corpus_rooms), args.sheet_spp)),
                     ("generate", lambda: part_generate(args.rooms, args.validate_every)),
                     ("probe", lambda: part_probe(args.probe_rooms, args.sheet_rooms)),
                     ("cube", part_cube), ("batch", lambda: part_batch(args.batch_rooms, args.workers))):
        if name in parts:
            print(f"part {name} …", file=sys.stderr, flush=True)
            res.update(fn())
    print(json.dumps(res))


if __name__ == "__main__":
    main()
