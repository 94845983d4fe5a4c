"""Render benchmark: time and noise of transport cubes against spp and wavelength sampling.

For the demo room (``renderer_jobs.demo.demo_room``), per image size, light group, wavelength
sampling mode (``stratified`` = this backend's default, ``random`` = Mitsuba's spectral-film
behaviour) and spp, two cubes are rendered with different seeds and compared on *flat regions*
(pixels whose 3×3 neighbourhood has the same normal and albedo AOV, i.e. interiors of uniform
planar surfaces):

- per-band noise: ``std(a − b) / √2 / mean`` per band over the flat pixels (median and mean over
  bands), and the robust version with ``1.4826 · MAD`` in place of std (insensitive to fireflies);
- projected-raw noise: the same on camera raw (cube relit by D65, projected through ``--sensor``),
  per channel R, G, B;
- time: wall seconds of one cube (kernel compilation excluded by a warm-up render).

From the noise at the highest spp, ``spp_to_thesis`` / ``seconds_to_thesis`` extrapolate (noise ∝
1/√spp) the spp and time to reach the thesis method's per-band noise (0.67 %, 21 passes × 64 spp in
Cycles). Both modes trace the same number of paths per spp, so equal spp is equal time.

    python bench/render.py                       # small default: 320x240, ceiling group, spp 16 and 64
    python bench/render.py --sizes 320x240,960x720 --spp 16,64,256 --groups ceiling,daylight

Prints progress lines, then the JSON document last.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

THESIS_BAND_NOISE = 0.0067


def flat_mask(aovs: dict[str, np.ndarray]) -> np.ndarray:
    """Pixels whose 3×3 neighbourhood shares normal and albedo (and hits geometry)."""
    n, al, m = aovs["normal"], aovs["albedo"], aovs["mask"].astype(bool)
    ok = m.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            sn = np.roll(np.roll(n, dy, 0), dx, 1)
            sa = np.roll(np.roll(al, dy, 0), dx, 1)
            ok &= np.all(np.abs(sn - n) < 1e-3, axis=-1) & np.all(np.abs(sa - al) < 1e-3, axis=-1)
            ok &= np.roll(np.roll(m, dy, 0), dx, 1)
    ok[0, :] = ok[-1, :] = ok[:, 0] = ok[:, -1] = False
    return ok


def noise_stats(a: np.ndarray, b: np.ndarray, mask: np.ndarray, raw_weights: np.ndarray) -> dict:
    """Relative noise between two renders of the same cube (see module docstring)."""
    A = a[mask].astype(np.float64)
    B = b[mask].astype(np.float64)
    mean = np.mean((A + B) / 2, axis=0)
    ok = mean > 0
    d = (A - B) / np.sqrt(2)
    band_std = np.std(d, axis=0)[ok] / mean[ok]
    mad = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    band_mad = mad[ok] / mean[ok]
    ra, rb = A @ raw_weights, B @ raw_weights
    rd = (ra - rb) / np.sqrt(2)
    rmean = np.mean((ra + rb) / 2, axis=0)
    raw_std = np.std(rd, axis=0) / rmean
    raw_mad = 1.4826 * np.median(np.abs(rd - np.median(rd, axis=0)), axis=0) / rmean
    return {"band_rel_std_median": float(np.median(band_std)), "band_rel_std_mean": float(np.mean(band_std)),
            "band_rel_mad_median": float(np.median(band_mad)),
            "raw_rel_std_rgb": [float(x) for x in raw_std], "raw_rel_mad_rgb": [float(x) for x in raw_mad],
            "flat_pixels": int(mask.sum())}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="320x240", help="WIDTHxHEIGHT list (e.g. 320x240,960x720)")
    ap.add_argument("--spp", default="16,64", help="spp list")
    ap.add_argument("--groups", default="ceiling", help="light groups of the demo room")
    ap.add_argument("--modes", default="stratified,random", help="wavelength sampling modes")
    ap.add_argument("--view", default="front")
    ap.add_argument("--sensor", default="Nikon 5100 (NPL)")
    ap.add_argument("--seed", type=int, default=0, help="demo room seed")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    args = ap.parse_args(argv)

    from renderer_jobs import demo
    from renderer_jobs import mitsuba_render as mr
    from renderer_jobs.mitsuba_variant import select_variant
    from retarget import illuminants, sensors

    variant = select_variant()
    sensor = sensors.get_sensor(args.sensor)
    w_raw = sensor.weights() * illuminants.illuminant_spd("D65")[:, None]
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    spps = [int(s) for s in args.spp.split(",")]
    groups = [g for g in args.groups.split(",") if g]
    modes = [m for m in args.modes.split(",") if m]
    rows = []
    for size in sizes:
        scene = demo.demo_room(args.seed, resolution=size)
        aovs = mr.render_aovs(scene, args.view, mr.RenderSettings())
        mask = flat_mask(aovs)
        for group in groups:
            for mode in modes:
                # Warm-up: compile this scene/group's kernels so timings are of rendering only.
                mr.render_cube(scene, args.view, group, mr.RenderSettings(spp=16, seed=99, wavelengths=mode,
                                                                           resolution=(8, 8)))
                for spp in spps:
                    t0 = time.perf_counter()
                    a = mr.render_cube(scene, args.view, group, mr.RenderSettings(spp=spp, seed=1, wavelengths=mode))
                    t = time.perf_counter() - t0
                    b = mr.render_cube(scene, args.view, group, mr.RenderSettings(spp=spp, seed=2, wavelengths=mode))
                    st = noise_stats(a.cube, b.cube, mask, w_raw)
                    row = {"size": f"{size[0]}x{size[1]}", "group": group, "mode": mode, "spp": spp,
                           "seconds": round(t, 3), "trace_seconds": a.stats["trace_s"], **st}
                    rows.append(row)
                    print(f"{row['size']:>9} {group:9s} {mode:10s} spp {spp:5d} {t:7.2f}s  band std "
                          f"{st['band_rel_std_median'] * 100:6.2f}%  band MAD {st['band_rel_mad_median'] * 100:6.2f}%  "
                          f"raw std {np.round(np.array(st['raw_rel_std_rgb']) * 100, 2)}%", flush=True)
    extrap = []
    for key in {(r["size"], r["group"], r["mode"]) for r in rows}:
        best = max((r for r in rows if (r["size"], r["group"], r["mode"]) == key), key=lambda r: r["spp"])
        for stat in ("band_rel_std_median", "band_rel_mad_median"):
            n = best[stat]
            spp_needed = best["spp"] * (n / THESIS_BAND_NOISE) ** 2
            extrap.append({"size": key[0], "group": key[1], "mode": key[2], "statistic": stat,
                           "from_spp": best["spp"], "spp_to_thesis": round(spp_needed, 1),
                           "seconds_to_thesis": round(best["seconds"] * spp_needed / best["spp"], 1)})
    doc = {"benchmark": "render", "variant": variant, "machine": platform.machine(), "python": platform.python_version(),
           "scene": f"demo-room-{args.seed}", "view": args.view, "sensor": args.sensor,
           "thesis_band_noise": THESIS_BAND_NOISE, "results": rows,
           "extrapolation": sorted(extrap, key=lambda r: (r["size"], r["group"], r["mode"], r["statistic"]))}
    text = json.dumps(doc, indent=1)
    if args.out:
        Path(args.out).write_text(text)
    print(text)
    return doc


if __name__ == "__main__":
    main()
