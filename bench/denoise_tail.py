"""Where the default denoiser's p99.3 tail is, and why: ``bench/denoise.py``'s renders (read from its
cache), the tail pixels of (a) the bias-only error (the default method applied to the reference's
own cubes) and (b) the default test (64 spp, boosted as the renderer's default), each pixel counted
under the first cause of this list that it has:

1. ``behind_glass``: a shadow ray of either group's direct-light guide is blocked by glass only (a
   dielectric, followed straight through: ``direct_light(behind_glass=True)``), within 1 pixel —
   where the glass may focus light that the guide shows as a shadow (a caustic);
2. ``metal_or_glass``: the pixel itself has no diffuse reflectance (the can, the glass ball);
3. ``near_light``: within 3 pixels of an emitter or background (sky) pixel;
4. ``glossy_ball``: the rough-plastic ball (its first hit, the pixel centre);
5. ``shadow_edge``: the direct guide of either group steps by more than ``sigma_direct`` in log
   to a 3×3 neighbour;
6. ``geometry_edge``: a 3×3 neighbour's normal differs by more than 0.05 (1 − cos) or its depth by
   more than 8 %;
7. ``material_edge``: a 3×3 neighbour's clean (1024-ray) albedo differs by more than 0.03;
8. ``other``.

Also the tail's pixels per shape (the centre ray's first hit). Picture: ``bench/out/denoise_tail_<view>.png``
(bias-only and test error maps, the tail pixels coloured by cause). JSON last on stdout.

Usage::

    python bench/denoise_tail.py --view corner      # after python bench/denoise.py --view corner (its cache)
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]

import denoise as bd  # noqa: E402
import denoise_lib as dl  # noqa: E402

CAUSES = ("behind_glass", "metal_or_glass", "near_light", "glossy_ball", "shadow_edge", "geometry_edge",
          "material_edge", "other")
COLOURS = ("#ff00ff", "#00ffff", "#ffff00", "#ff8000", "#ff0000", "#00ff00", "#4080ff", "#ffffff")


def _any_neighbour(a: np.ndarray, pred) -> np.ndarray:
    """``(H, W)`` bool: ``pred(a, a shifted to a 3×3 neighbour)`` for any of the 8 (edge replicated)."""
    from illumix.retarget.denoise_filters import _shifted

    out = np.zeros(a.shape[:2], bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                out |= pred(a, _shifted(a, dy, dx))
    return out


def shape_ids(scene, view: str, res) -> tuple[np.ndarray, list[str]]:
    """``(H, W)`` int: index into the returned shape names of each pixel centre's first hit (−1: none)."""
    from illumix.renderer_jobs.mitsuba.trace import Tracer, camera_rays

    t = Tracer(scene, view, None, res)
    mi, dr = t.mi, t.dr
    pix = np.arange(t.width * t.height)
    ray = camera_rays(mi, t.sensor, t.width, t.height, pix, np.full((len(pix), 2), 0.5, np.float32),
                      np.full((len(pix), 4), 550, np.float32), differential=False)
    si = t.ms.ray_intersect(ray)
    out = np.full(len(pix), -1)
    names = []
    for k, s in enumerate(t.ms.shapes()):
        m = si.is_valid() & (si.shape == mi.ShapePtr(s))
        dr.eval(m)
        out[np.asarray(m, bool)] = k
        names.append(s.id().removeprefix("shape_") or f"walls_{k}")  # Mitsuba merges meshes of one material
    return out.reshape(t.height, t.width), names


def causes(R: dict, guides, scene, args, behind: dict) -> tuple[dict, np.ndarray, list[str]]:
    """Every cause's ``(H, W)`` mask (before the first-match rule), the shape ids and names."""
    from illumix.retarget.denoise import method_params
    from illumix.retarget.denoise_classes import GLASS_MARGIN, GLASS_SHARE, _dilate

    p = method_params("dt-irradiance")[1]
    ids, names = shape_ids(scene, args.view, args.res)
    light = ~guides.hit | guides.emitter
    logd = [np.log(R["direct"][g]["direct"] + 1e-3 * R["direct"][g]["direct"].max()) for g in R["direct"]]
    z = np.log(np.maximum(guides.depth, 1e-3))
    clean = R["clean_aovs"]["albedo_bands"]
    glass_frac = [guides.with_direct(R["direct"][g]["direct"], behind[g]).behind_glass for g in behind]
    return {
        "behind_glass": _dilate(np.any([f > GLASS_SHARE for f in glass_frac], axis=0), GLASS_MARGIN),
        "metal_or_glass": guides.hit & ~guides.emitter & (guides.albedo_bands.max(axis=-1) < p["albedo_floor"]),
        "near_light": _dilate(light, 3) & ~light,
        "glossy_ball": ids == names.index("ball") if "ball" in names else np.zeros(ids.shape, bool),
        "shadow_edge": np.any([_any_neighbour(d, lambda a, b: np.abs(a - b) > p["sigma_direct"]) for d in logd], 0),
        "geometry_edge": _any_neighbour(guides.normal, lambda a, b: 1 - (a * b).sum(-1) > 0.05)
        | _any_neighbour(z, lambda a, b: np.abs(a - b) > 0.08),
        "material_edge": _any_neighbour(clean, lambda a, b: np.abs(a - b).max(-1) > 0.03),
    }, ids, names


def first_cause(masks: dict, pixels: np.ndarray) -> np.ndarray:
    """``(H, W)`` int: the index in :data:`CAUSES` of each pixel's first cause (−1 outside ``pixels``)."""
    out = np.full(pixels.shape, -1)
    left = pixels.copy()
    for k, c in enumerate(CAUSES):
        m = left & masks.get(c, True)
        out[m] = k
        left &= ~m
    return out


def plot(path: Path, maps: dict, tails: dict, valid: np.ndarray) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    fig, ax = plt.subplots(2, 2, figsize=(12, 8.4))
    cmap = matplotlib.colormaps["viridis"].copy()
    cmap.set_bad("0.75")
    for a, (title, e) in zip(ax[0], maps.items()):
        im = a.imshow(np.where(valid, e, np.nan), cmap=cmap, vmin=0, vmax=8)
        a.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax[0].tolist(), label="relative R/G, B/G error (%)", shrink=0.9)
    for a, (title, t) in zip(ax[1], tails.items()):
        a.imshow(np.where(valid, 0.35, 0.1), cmap="gray", vmin=0, vmax=1)
        a.imshow(np.ma.masked_less(t, 0), cmap=ListedColormap(COLOURS), vmin=-0.5, vmax=len(CAUSES) - 0.5,
                 interpolation="nearest")
        a.set_title(title, fontsize=9)
    handles = [plt.Line2D([], [], marker="s", ls="", color=c, label=n) for c, n in zip(COLOURS, CAUSES)]
    fig.legend(handles=handles, loc="lower center", ncol=len(CAUSES), fontsize=8)
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--view", default="corner")
    ap.add_argument("--resolution", default="160x120")
    own, rest = ap.parse_known_args(argv)
    args = bd.parse(["--view", own.view, "--resolution", own.resolution, *rest])
    from illumix.scene.demo import demo_room
    from illumix.retarget.denoise import DEFAULT_METHOD, Guides

    scene = demo_room(args.room, args.res)
    R = bd.render_all(args, scene, bd.cache_dir(args))
    groups = [g for g, _ in bd.PAIR]
    guides = Guides.from_aovs(R["aovs"])
    if args.boost_factor <= 1:  # the renderer uses the straddle guide only with the targeted extra paths
        guides = replace(guides, straddle=None)
    M = dl.composition_weights(args.sensor, [i for _, i in bd.PAIR], [R["test"][g]["emission"] for g in groups])
    ref = bd.reference(R, M, guides)
    valid = ref["valid"]
    behind = {g: R["direct"][g]["behind"] for g in groups}
    masks, ids, names = causes(R, guides, scene, args, behind)

    def raw(cubes):
        return dl.compose([dl.run_denoise(cubes[g]["cube"], guides, DEFAULT_METHOD, R["direct"][g])
                           for g in groups], M)

    errs = {"bias_only": dl.rel_chroma_err(raw(ref["cubes"]), ref["raw"]),
            "test": dl.rel_chroma_err(raw(R["test"]), ref["raw"])}
    doc: dict = {"room": args.room, "view": args.view, "valid_pixels": int(valid.sum()),
                 "cause_pixels_in_view": {c: int((m & valid).sum()) for c, m in masks.items()}}
    tails = {}
    for k, e in errs.items():
        p = float(np.percentile(e[valid], 99.3))
        tail = valid & (e >= p)
        fc = first_cause(masks, tail)
        tails[f"{k}: tail (>= p99.3 {p:.2f} %) by first cause"] = fc
        shapes = np.bincount(ids[tail] + 1, minlength=len(names) + 1)
        doc[k] = {**dl.err_summary(e, valid), "tail_pixels": int(tail.sum()),
                  "by_first_cause": {c: int((fc == i).sum()) for i, c in enumerate(CAUSES)},
                  "by_shape": {n: int(s) for n, s in zip(["(none)", *names], shapes) if s},
                  "tail_also_in_bias_tail": None}
    bias_tail, test_tail = (t >= 0 for t in tails.values())
    doc["test"]["tail_also_in_bias_tail"] = int((bias_tail & test_tail).sum())
    path = bd.OUT / f"denoise_tail_{args.view}{f'_room{args.room}' if args.room else ''}.png"
    plot(path, {f"bias only (filter on the reference): p99.3 {doc['bias_only']['p99_3_rel_pct']:.2f} %":
                errs["bias_only"], f"test (64 spp, boosted): p99.3 {doc['test']['p99_3_rel_pct']:.2f} %": errs["test"]},
         tails, valid)
    doc["plot"] = str(path.relative_to(ROOT))
    text = dl.dumps(doc)
    print(text)
    return doc


if __name__ == "__main__":
    main()
