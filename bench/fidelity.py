"""Fidelity gate: is what ``/sample`` serves by default ever worse than the plain render, on scenes
nobody tuned the defaults on?

    python bench/fidelity.py [--quick | --tuning] [--scenes a,b] [--cache DIR] [--reuse] [--figures DIR]

Renders the held-out corpus (:mod:`fidelity_corpus`: adversarial scene files, the example scene at
640×480, procedural rooms from unused seeds, an OBJ import) with the defaults twice and once at
≥ 16× the paths, then measures with the service's own composition (:mod:`fidelity_metrics`).
Prints one JSON object last:

- ``n_scenes``; ``max_mean_shift_pct`` — worst change of a group's frame sum, default against
  ``denoise=none``, of the operator (on the reference's cubes: its expectation; goal ≤ 0.5), and
  ``max_mean_shift_pct_per_render`` (on each production render: noise included — a firefly where
  the filter's column sum is not 1 moves the sum);
- ``biased_pixel_pct`` — pixels whose default-served output (raw, the illumination spectrum, illum,
  gain, mixture, weights, sRGB) is biased beyond 3σ of the render's own noise, the bias taken from
  the operator on the reference (goal ≤ 0.3); ``biased_pixel_pct_two_renders`` the same from two
  renders' mean, with ``biased_pixel_pct_plain`` (that test on the plain render: its floor); the
  share per output;
- ``denoised_worse_pct`` — (scene, pixel class) pairs where the default's error exceeds the plain
  render's (goal 0);
- ``rg_bg`` — relative R/G, B/G error median / p99.3 (%) of the composed raw, per scene and over the
  corpus (goal ≤ 0.5 / 2.5), default and plain;
- ``goals_met`` and per-scene details. ``--figures`` writes one PNG per scene (error maps).
Results: ``bench/FIDELITY.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fidelity_corpus as fc  # noqa: E402
import fidelity_metrics as fm  # noqa: E402

GOALS = {"max_mean_shift_pct": 0.5, "biased_pixel_pct": 0.3, "denoised_worse_pct": 0.0,
         "rg_bg_median_pct": 0.5, "rg_bg_p99_3_pct": 2.5}


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def measure_scene(entry: fc.Entry, cache: Path, reuse: bool, redenoise: bool = False) -> dict:
    from illumix_client.local import LocalClient

    t0 = time.perf_counter()
    log(f"{entry.name}: {entry.what} ({entry.resolution[0]}x{entry.resolution[1]})")
    b = fc.build(entry, cache, log, reuse=reuse, redenoise=redenoise)
    scene, view = b["scene"], fc.view_of(b["scene"])
    groups = list(b["prod_paths"])
    clients = {"P1": LocalClient(str(b["prod"][0])), "P2": LocalClient(str(b["prod"][1])), "R": LocalClient(str(b["ref"])),
               "O": LocalClient(str(b["ref_op"]))}
    lit_all = scene.group_names
    got = fm.fetch(clients, scene.name, view, lit_all)
    tests, shifts = {}, {}
    for req, served in got.items():
        for out in ("raw", "illumination", "illum", "gain", "mixture", "weights", "srgb"):
            if out not in served["R"]:
                continue
            arrs = [served[k][out] for k in ("D1", "D2", "N1", "N2", "R", "O")]
            masks = [served[k]["mask"] for k in ("D1", "D2", "N1", "N2", "R", "O")]
            valid = np.ones(arrs[0].shape[:2], bool) if out == "raw" else np.logical_and.reduce(masks)
            tests[f"{req}/{out}"] = fm.bias_test(*arrs, valid)
        if req.startswith("group:") and req[6:] in groups:
            shifts[req[6:]] = {"operator": max(fm.mean_shift_pct(served["O"][k], served["R"][k]) for k in ("raw", "illumination")),
                               "render": max(fm.mean_shift_pct(served[d][k], served[n][k]) for k in ("raw", "illumination")
                                             for d, n in (("D1", "N1"), ("D2", "N2")))}
    mix = got["mix"]
    ref_illum = sum(got[f"group:{g}"]["R"]["illumination"] for g in lit_all)
    classes = fm.pixel_classes(str(b["prod"][0]), scene, view, ref_illum)
    worse = fm.worse_by_class(mix["D1"]["raw"], mix["N1"]["raw"], mix["R"]["raw"], classes)
    valid = mix["R"]["mask"] & mix["D1"]["mask"]
    e_def = fm.chroma_errors(mix["D1"]["raw"], mix["R"]["raw"], valid)
    e_plain = fm.chroma_errors(mix["N1"]["raw"], mix["R"]["raw"], valid)
    for c in clients.values():
        c.close()
    pct = lambda e, q: round(float(np.percentile(e, q)), 4) if e.size else None  # noqa: E731
    return {"name": entry.name, "what": entry.what, "resolution": list(entry.resolution), "groups": groups,
            "prod_paths_per_pixel": {g: round(v, 1) for g, v in b["prod_paths"].items()}, "ref_spp": b["ref_spp"],
            "render_cpu_s": round(b["cpu_s"], 1),
            "mean_shift_pct": {g: {k: round(x, 4) for k, x in v.items()} for g, v in shifts.items()},
            "bias": {k: {kk: vv for kk, vv in v.items() if kk != "map"} for k, v in tests.items()},
            "classes": worse,
            "rg_bg": {"default": {"median": pct(e_def, 50), "p99_3": pct(e_def, 99.3)},
                      "plain": {"median": pct(e_plain, 50), "p99_3": pct(e_plain, 99.3)}},
            "_maps": {"bias_raw": tests["mix/raw"]["map"], "ref_raw": mix["R"]["raw"], "def_raw": mix["D1"]["raw"],
                      "err_def": _rel(mix["D1"]["raw"], mix["R"]["raw"]), "err_plain": _rel(mix["N1"]["raw"], mix["R"]["raw"])},
            "_errors": (e_def, e_plain), "seconds": round(time.perf_counter() - t0, 1)}


def _rel(a: np.ndarray, r: np.ndarray) -> np.ndarray:
    g = np.maximum(r[..., 1], 1e-3 * max(float(r[..., 1].max()), 1e-30))
    return 100 * np.abs(a - r)[..., 1] / g


def summarise(scenes: list[dict]) -> dict:
    tot = sum(v["pixels"] for s in scenes for v in s["bias"].values())
    biased = sum(v["biased"] for s in scenes for v in s["bias"].values())
    two = sum(v["biased_two_renders"] for s in scenes for v in s["bias"].values())
    plain = sum(v["biased_plain"] for s in scenes for v in s["bias"].values())
    per_out: dict = {}
    for s in scenes:
        for k, v in s["bias"].items():
            o = per_out.setdefault(k.split("/")[1], [0, 0])
            o[0] += v["biased"]
            o[1] += v["pixels"]
    pairs = [(s["name"], c) for s in scenes for c, v in s["classes"].items()]
    worse = [f"{s['name']}/{c}" for s in scenes for c, v in s["classes"].items() if v["worse"]]
    e_def = np.concatenate([s["_errors"][0] for s in scenes])
    e_plain = np.concatenate([s["_errors"][1] for s in scenes])
    out = {
        "n_scenes": len(scenes),
        "max_mean_shift_pct": round(max(v["operator"] for s in scenes for v in s["mean_shift_pct"].values()), 4),
        "max_mean_shift_pct_per_render": round(max(v["render"] for s in scenes for v in s["mean_shift_pct"].values()), 4),
        "biased_pixel_pct": round(100 * biased / max(tot, 1), 4),
        "biased_pixel_pct_two_renders": round(100 * two / max(tot, 1), 4),
        "biased_pixel_pct_plain": round(100 * plain / max(tot, 1), 4),
        "biased_pixel_pct_by_output": {k: round(100 * a / max(b, 1), 4) for k, (a, b) in per_out.items()},
        "denoised_worse_pct": round(100 * len(worse) / max(len(pairs), 1), 2),
        "denoised_worse": worse,
        "rg_bg": {"default": {"median": round(float(np.median(e_def)), 4), "p99_3": round(float(np.percentile(e_def, 99.3)), 4)},
                  "plain": {"median": round(float(np.median(e_plain)), 4),
                            "p99_3": round(float(np.percentile(e_plain, 99.3)), 4)}},
    }
    out["goals"] = GOALS
    out["goals_met"] = {
        "max_mean_shift_pct": out["max_mean_shift_pct"] <= GOALS["max_mean_shift_pct"],
        "biased_pixel_pct": out["biased_pixel_pct"] <= GOALS["biased_pixel_pct"],
        "denoised_worse_pct": out["denoised_worse_pct"] <= GOALS["denoised_worse_pct"],
        "rg_bg_median_pct": out["rg_bg"]["default"]["median"] <= GOALS["rg_bg_median_pct"],
        "rg_bg_p99_3_pct": out["rg_bg"]["default"]["p99_3"] <= GOALS["rg_bg_p99_3_pct"]}
    return out


def figure(scene: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = scene["_maps"]
    top = max(float(np.percentile(m["ref_raw"], 99)), 1e-30)  # one display scale for both: raw, gamma 1/2.2
    fig, ax = plt.subplots(1, 5, figsize=(15, 2.8))
    for k, (key, title) in enumerate((("ref_raw", "reference raw"), ("def_raw", "served by default"))):
        ax[k].imshow(np.clip(m[key] / top, 0, 1) ** (1 / 2.2))
        ax[k].set_title(title)
    im = ax[2].imshow(m["bias_raw"], vmin=0, vmax=6, cmap="magma")
    ax[2].set_title("|bias| / sigma, raw (>3: biased)")
    fig.colorbar(im, ax=ax[2], fraction=0.046)
    for k, (key, title) in enumerate((("err_def", "|error| % G, default"), ("err_plain", "|error| % G, plain"))):
        im = ax[3 + k].imshow(m[key], vmin=0, vmax=10, cmap="viridis")
        ax[3 + k].set_title(title)
        fig.colorbar(im, ax=ax[3 + k], fraction=0.046)
    for a in ax:
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(f"{scene['name']}: {scene['what']} ({scene['resolution'][0]}x{scene['resolution'][1]})")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=70)
    plt.close(fig)


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the suite's two small scenes only")
    ap.add_argument("--tuning", action="store_true", help="the demo room's views the defaults were chosen on, instead")
    ap.add_argument("--scenes", default=None, help="comma-separated corpus names (default: all)")
    ap.add_argument("--cache", default=str(Path.home() / ".cache" / "illumix" / "fidelity"),
                    help="where the stores are kept (the references are reused between runs)")
    ap.add_argument("--reuse", action="store_true", help="reuse complete production stores too (same code only)")
    ap.add_argument("--redenoise", action="store_true", help="with --reuse: denoise the reused production renders "
                    "again with today's denoiser (from their saved guides), to measure a change to it")
    ap.add_argument("--figures", default=None, help="write one PNG of error maps per scene into this folder")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse(argv)
    entries = fc.QUICK if args.quick else fc.TUNING if args.tuning else fc.ENTRIES
    if args.scenes:
        entries = tuple(fc.entry_named(n.strip(), entries) for n in args.scenes.split(","))
    cache = Path(args.cache) / ("quick" if args.quick else "tuning" if args.tuning else "corpus")
    scenes = [measure_scene(e, cache, args.reuse, args.redenoise) for e in entries]
    if args.figures:
        for s in scenes:
            figure(s, Path(args.figures) / f"fidelity_{s['name']}.png")
    out = summarise(scenes)
    out["scenes"] = [{k: v for k, v in s.items() if not k.startswith("_")} for s in scenes]
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=1))
