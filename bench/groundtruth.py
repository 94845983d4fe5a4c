"""Ground truth under coloured bounce light: the formula (thesis eq. 3.3) against the physical one.

Renders, with the default renderer settings, into a fresh store:

- ``demo``: the demo room (seed 0), pair ``A,D65`` on its first two groups (daylight, ceiling);
- ``bounce``: a scene made for it — a grey (flat 0.5) box and floor and a glossy grey ball beside a
  saturated coloured wall, a flat 0.8 ceiling, one ceiling lamp, lit by D65;
- ``control``: the demo room with every material flat 0.5 (no coloured bounce light), where the two
  ground truths must agree within noise: rendered twice (seeds 0 and 1), the angle between the two
  renders' physical white points (/√2) is the noise the agreement is judged against.

For each scene, view and sensor (``--sensors``, default Sony ILCE-9 and Nikon D810 from
``../shared/data``), the service composes the sample in-process twice (``gt=physical`` and
``gt=formula``). *Neutral* pixels are those whose served ``reflectance`` spectrum (transport /
illumination) is flat within 3 % over 420–680 nm and above 5 %, inside the ground-truth ``mask``.
Their raw, white-balanced with the served gain, should be neutral: the error is its angle to
(1, 1, 1) in camera RGB, in degrees (median and p95 over the neutral pixels of all views and
sensors). Also measured: the angle between the two ground truths' white points on the same pixels,
and the CPU time of rendering a cube with its illumination cube against the transport cube alone.

Error maps: ``bench/out/groundtruth_<scene>.png``. Prints a JSON object last with
``{"physical": {"median_deg", "p95_deg"}, "formula": {"median_deg", "p95_deg"}, ...}`` (over the
``demo`` and ``bounce`` scenes). Usage: ``python bench/groundtruth.py [--resolution 160x120 --spp 64]``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]
CAMERAS = ROOT.parent / "shared" / "data" / "rawtoaces-data" / "data" / "camera"
OUT = ROOT / "bench" / "out"


def log(msg: str) -> None:
    print(f"[bench/groundtruth] {msg}", file=sys.stderr, flush=True)


def cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def bounce_scene(resolution: tuple[int, int]) -> dict:
    """A grey box and floor beside a saturated coloured wall under one ceiling lamp."""
    from illumix.scene import demo

    flat = lambda v: {"kind": "diffuse", "reflectance": {"value": v}}  # noqa: E731
    mats = {"grey": flat(0.5), "ceiling": flat(0.8), "dark": flat(0.3),
            "grey_gloss": {"kind": "roughplastic", "reflectance": {"value": 0.5}, "alpha": 0.25},
            "green": {"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "index": 13}}}
    fm = demo.frame_matrix
    shapes = [
        {"name": "floor", "type": "rectangle", "material": "grey", "transform": {"matrix": fm((0, 0, 0), (0, 1, 0), (0, 0, -1), (4, 4))}},
        {"name": "ceiling", "type": "rectangle", "material": "ceiling", "transform": {"matrix": fm((0, 2.5, 0), (0, -1, 0), (0, 0, 1), (4, 4))}},
        {"name": "wall_green", "type": "rectangle", "material": "green", "transform": {"matrix": fm((-2, 1.25, 0), (1, 0, 0), (0, 1, 0), (4, 2.5))}},
        {"name": "wall_back", "type": "rectangle", "material": "grey", "transform": {"matrix": fm((0, 1.25, -2), (0, 0, 1), (0, 1, 0), (4, 2.5))}},
        {"name": "wall_right", "type": "rectangle", "material": "dark", "transform": {"matrix": fm((2, 1.25, 0), (-1, 0, 0), (0, 1, 0), (4, 2.5))}},
        {"name": "box", "type": "cube", "material": "grey", "transform": {"matrix": demo.box_matrix((-1.3, 0.4, -0.6), (0.4, 0.4, 0.4))}},
        {"name": "ball", "type": "sphere", "material": "grey_gloss", "center": (-0.9, 0.35, 0.6), "radius": 0.35},
        {"name": "lamp", "type": "rectangle", "emitter": {"group": "lamp", "strength": 6.0},
         "transform": {"matrix": fm((0.6, 2.48, 0.2), (0, -1, 0), (0, 0, -1), (0.6, 0.6))}},
    ]
    return {"name": "bounce", "materials": mats, "shapes": shapes, "lights": [],
            "light_groups": [{"name": "lamp", "emission": "flat"}],
            "views": [{"name": "cam", "origin": (0.8, 1.4, 3.4), "target": (-1.0, 0.8, -1.0), "fov": 60,
                       "resolution": tuple(resolution)}], "max_depth": 6}


def control_scene(resolution: tuple[int, int]) -> dict:
    from illumix.scene import demo

    doc = demo.demo_room_dict(0, resolution, name="control")
    for m in doc["materials"].values():
        m.clear()
        m.update({"kind": "diffuse", "reflectance": {"value": 0.5}})
    return doc


def render(docs: list[dict], store: str, spp: int, seed: int = 0) -> float:
    """Render the scenes into ``store`` (default settings); returns the wall time."""
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.scene.load import scene_from_dict

    t = time.perf_counter()
    scenes = [scene_from_dict(d, source=d["name"]) for d in docs]
    execute(jobs.plan(scenes, store), store, RenderSettings(spp=spp, seed=seed))
    return time.perf_counter() - t


def noise_deg(store: str, a: str, b: str, sensor: str, params: dict) -> dict:
    """Noise of the physical white point: the angle between two renders (other seed) of one scene,
    over √2 (both are noisy), on the pixels valid in both."""
    from illumix.service.app import create_app
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    ctx = create_app(CubeStore.open(store, mode="r"), cache_mb=2048).state.ctx
    out = []
    for view in ctx.store.views(a):
        s = [build_sample(SampleSpec(scene=n, view=view, sensor=sensor, seed=0, outputs="illum,mask", **params), ctx)[0]
             for n in (a, b)]
        ok = s[0]["mask"] & s[1]["mask"]
        out.append(angle(s[0]["illum"], s[1]["illum"])[ok] / np.sqrt(2))
    return summary(np.concatenate(out))


def cost_ratio(doc: dict, spp: int, repeats: int = 2) -> dict:
    """CPU time of a cube with its illumination cube over the transport cube alone, per group
    (interleaved repeats after a warm-up, so JIT compilation and load changes hit both alike)."""
    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.scene.load import scene_from_dict

    scene = scene_from_dict(doc, source=doc["name"])
    view = scene.views[0].name
    out = {}
    for g in scene.group_names:
        times = {False: [], True: []}
        for rep in range(repeats + 1):
            for ill in (False, True):
                c0 = cpu_s()
                mr.render_cube(scene, view, g, mr.RenderSettings(spp=spp, seed=rep, illumination=ill))
                if rep:
                    times[ill].append(cpu_s() - c0)
        out[g] = round(float(np.median(times[True]) / np.median(times[False])), 3)
    return out


def angle_to_neutral(rgb: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(rgb, axis=-1) * np.sqrt(3.0)
    return np.degrees(np.arccos(np.clip(rgb.sum(-1) / np.where(n > 0, n, 1), -1, 1)))


def angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def measure(store: str, scene: str, sensors: list[str], params: dict) -> dict:
    """Per (view, sensor): neutral-pixel errors under both ground truths, and their maps."""
    from illumix.service.app import create_app
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    ctx = create_app(CubeStore.open(store, mode="r"), cache_mb=2048).state.ctx
    wl = None
    errs = {"physical": [], "formula": []}
    between, maps = [], []
    for view in ctx.store.views(scene):
        for sensor in sensors:
            base = dict(scene=scene, view=view, sensor=sensor, seed=0, **params)
            phys, meta = build_sample(SampleSpec(**base, outputs="raw,gain,illum,mask,reflectance", gt="physical"), ctx)
            form, _ = build_sample(SampleSpec(**base, outputs="gain,illum", gt="formula"), ctx)
            if wl is None:
                from illumix.retarget.grid import SpectralGrid

                wl = SpectralGrid.from_dict(meta["grid"]).wavelengths
            r = phys["reflectance"][..., (wl >= 420) & (wl <= 680)]
            neutral = phys["mask"] & (r.min(-1) > 0.05) & (r.max(-1) <= 1.03 * r.min(-1))
            e_phys = angle_to_neutral(phys["raw"] * phys["gain"])
            e_form = angle_to_neutral(phys["raw"] * form["gain"])
            errs["physical"].append(e_phys[neutral])
            errs["formula"].append(e_form[neutral])
            between.append(angle(phys["illum"], form["illum"])[phys["mask"]])
            maps.append((f"{view} / {sensor}", np.where(neutral, e_phys, np.nan),
                         np.where(neutral, e_form, np.nan)))
    stats = {k: summary(np.concatenate(v)) for k, v in errs.items()}
    stats["between_deg"] = summary(np.concatenate(between))
    stats["neutral_pixels"] = int(sum(len(v) for v in errs["physical"]))
    return stats | {"_maps": maps, "_errs": errs}


def summary(x: np.ndarray) -> dict:
    if not x.size:
        return {"median_deg": None, "p95_deg": None, "n": 0}
    return {"median_deg": round(float(np.median(x)), 4), "p95_deg": round(float(np.percentile(x, 95)), 4),
            "n": int(x.size)}


def plot(name: str, maps: list) -> str | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    OUT.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(maps), 2, figsize=(8, 2.8 * len(maps)), squeeze=False)
    vmax = max(5.0, max(float(np.nanmax(m[2])) if np.isfinite(m[2]).any() else 0 for m in maps))
    cmap = matplotlib.colormaps["magma"].copy()
    cmap.set_bad("0.8")  # grey: not a neutral surface
    for row, (title, ep, ef) in zip(axes, maps):
        for ax, img, gt in zip(row, (ep, ef), ("physical", "formula")):
            im = ax.imshow(img, cmap=cmap, vmin=0, vmax=vmax)
            ax.set_title(f"{title}: {gt} GT, median {np.nanmedian(img):.2f}°", fontsize=8)
            ax.axis("off")
    fig.colorbar(im, ax=axes.ravel().tolist(), label="neutral surface after WB: angle to neutral (°)")
    path = OUT / f"groundtruth_{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", default="160x120")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--sensors", default="Sony_ILCE-9,Nikon_D810")
    ap.add_argument("--cost-spp", type=int, default=32, help="spp of the cost measurement renders")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.resolution.lower().split("x"))
    os.environ["ILLUMIX_SENSOR_PATH"] = str(CAMERAS)  # the service names them by file stem
    sensors = args.sensors.split(",")
    from illumix.scene import demo

    docs = {"demo": demo.demo_room_dict(0, res, name="demo"), "bounce": bounce_scene(res),
            "control": control_scene(res)}
    lighting = {"demo": {"pair": "A,D65"}, "bounce": {"illuminants": "D65"}, "control": {"pair": "A,D65"}}
    result: dict = {"bench": "groundtruth", "resolution": list(res), "spp": args.spp,
                    "sensors": sensors}
    with tempfile.TemporaryDirectory() as tmp:
        store = str(Path(tmp) / "store")
        log(f"rendering {', '.join(docs)} at {args.resolution}, {args.spp} spp …")
        result["render_s"] = round(render(list(docs.values()), store, args.spp), 1)
        render([control_scene(res) | {"name": "control_b"}], store, args.spp, seed=1)
        scenes = {}
        for name in docs:
            log(f"measuring {name} …")
            m = measure(store, name, sensors, lighting[name])
            m["plot"] = plot(name, m.pop("_maps"))
            scenes[name] = m
        scenes["control"]["noise_deg"] = noise_deg(store, "control", "control_b", sensors[0], lighting["control"])
    errs = {k: np.concatenate([np.concatenate(scenes[s]["_errs"][k]) for s in ("demo", "bounce")])
            for k in ("physical", "formula")}
    for s in scenes.values():
        s.pop("_errs")
    log("cost: a cube with its illumination cube against the transport cube alone (CPU time) …")
    cost = {name: cost_ratio(docs[name], args.cost_spp) for name in ("demo", "bounce")}
    result.update({"physical": summary(errs["physical"]), "formula": summary(errs["formula"]),
                   "scenes": scenes, "illumination_cost_ratio": cost,
                   "illumination_cost_ratio_max": max(v for c in cost.values() for v in c.values())})
    print(json.dumps(result))


if __name__ == "__main__":
    main()
