"""Render benchmark: time against noise for transport cubes, and what skipping and adaptivity buy.

Three parts (``--parts``, all by default), on the seeded demo room (``renderer_jobs.demo``):

``curve`` — per image size, light group, sampling (``uniform`` spp or ``adaptive``, the default:
  ``renderer_jobs.adaptive_spp``), wavelength mode and spp: two cubes with different seeds, timed
  (wall and process CPU seconds; kernel compilation excluded by a warm-up), and their noise:

  - flat-region noise (issue 4's definition): pixels whose 3×3 neighbourhood shares normal and albedo
    AOVs; ``std(a − b)/√2/mean`` per band (median over bands) and on camera raw (cube relit by D65,
    projected through ``--sensor``), per channel R, G, B;
  - all-pixel noise against a reference cube (``--ref-factor`` × the highest spp, uniform): per pixel
    the squared relative error estimate ``((a − b)/√2 / ref)²``; ``raw_G_rms`` = RMS over pixels of the
    raw green channel, ``raw_G_block_p50/p90/p99`` = percentiles over 4×4 blocks of the local RMS
    (the worst regions), ``band_rms_median`` = median over bands of the per-band RMS;
  - ``image_mean_rel`` = image mean of raw G relative to the reference (bias check).

  Each point is ``--pairs`` seed pairs (noise variances averaged over them; times are medians).

  From the curve: the log-log slope of noise against spp and the spp / seconds to reach the thesis
  method's per-band noise (0.67 %, 21 passes × 64 spp in Cycles) by that slope.

``adaptive`` — adaptive against uniform at the same spp (same paths): noise ratios, CPU-time ratio,
  and the equal-time speed-up ``(noise_uniform/noise_adaptive)² × cpu_uniform/cpu_adaptive``.

``skip`` — light probes (``renderer_jobs.light_probe``): for every demo-room group and view, probe
  verdict and time against the cube's render time (the probe's overhead on lit groups); and for a
  dark group — a lamp inside a closed cupboard added to the room — probe time against the full
  render's, and that the full render is exactly zero (so recording it as empty changes nothing).

``background`` — what skipping pixels that see no geometry could save (for a group without a sky
  they are exactly zero): CPU time of tracing every pixel against only the pixels whose 16 AOV rays
  hit something, in an open scene (~2/3 background) and in the demo room (closed: none).

    python bench/render.py              # default: 160x120, ceiling, spp 16,32,64,128 (a few minutes, 2 cores)
    python bench/render.py --sizes 320x240,960x720 --spp 16,64,256 --groups ceiling,daylight,desk

Prints progress lines, then the JSON document last.
"""

from __future__ import annotations

import argparse
import json
import os
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


def flat_noise(a: np.ndarray, b: np.ndarray, mask: np.ndarray, raw_weights: np.ndarray) -> dict:
    """Relative noise between two renders of the same cube on flat regions (module docstring)."""
    A = a[mask].astype(np.float64)
    B = b[mask].astype(np.float64)
    mean = np.mean((A + B) / 2, axis=0)
    ok = mean > 0
    d = (A - B) / np.sqrt(2)
    band_std = np.std(d, axis=0)[ok] / mean[ok]
    mad = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    ra, rb = A @ raw_weights, B @ raw_weights
    rd = (ra - rb) / np.sqrt(2)
    rmean = np.mean((ra + rb) / 2, axis=0)
    return {"flat_band_rel_std_median": float(np.median(band_std)),
            "flat_band_rel_mad_median": float(np.median(mad[ok] / mean[ok])),
            "flat_raw_rel_std_rgb": [float(x) for x in np.std(rd, axis=0) / rmean],
            "flat_pixels": int(mask.sum())}


def ref_noise(a: np.ndarray, b: np.ndarray, ref: np.ndarray, raw_weights: np.ndarray) -> dict:
    """All-pixel relative noise of a seed pair against a reference cube (module docstring)."""
    from scipy.ndimage import uniform_filter

    a, b, ref = (x.astype(np.float64) for x in (a, b, ref))
    ra, rb, rr = a @ raw_weights, b @ raw_weights, ref @ raw_weights
    lit = rr[..., 1] > 1e-6 * rr[..., 1].max()
    eg = np.where(lit, ((ra - rb)[..., 1] / np.sqrt(2) / np.where(lit, rr[..., 1], 1)) ** 2, 0.0)
    blk = np.sqrt(uniform_filter(eg, 4)[::4, ::4])
    okb = ref > 1e-3 * ref.mean()
    eb = np.where(okb, ((a - b) / np.sqrt(2) / np.where(okb, ref, 1)) ** 2, np.nan)
    band_rms = np.sqrt(np.nanmean(eb.reshape(-1, eb.shape[-1]), axis=0))
    return {"raw_G_rms": float(np.sqrt(eg[lit].mean())),
            "raw_G_block_p50": float(np.percentile(blk, 50)), "raw_G_block_p90": float(np.percentile(blk, 90)),
            "raw_G_block_p99": float(np.percentile(blk, 99)),
            "band_rms_median": float(np.nanmedian(band_rms)),
            "image_mean_rel": float(((ra + rb)[..., 1].mean() / 2) / rr[..., 1].mean() - 1)}


def mean_of(dicts: list[dict]) -> dict:
    """Noise statistics averaged over seed pairs (variances averaged, then the root taken)."""
    out = {}
    for k, v in dicts[0].items():
        vals = np.asarray([d[k] for d in dicts], dtype=float)
        if k.startswith(("raw_G", "flat_band_rel_std", "flat_raw_rel_std", "band_rms")):
            out[k] = np.sqrt(np.mean(vals ** 2, axis=0)).tolist()
        elif k == "flat_pixels":
            out[k] = int(v)
        else:
            out[k] = np.mean(vals, axis=0).tolist()
    return out


def slope(xs, ys) -> float | None:
    """Least-squares slope of log y against log x."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    ok = (xs > 0) & (ys > 0)
    return float(np.polyfit(np.log(xs[ok]), np.log(ys[ok]), 1)[0]) if ok.sum() >= 2 else None


def timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"machine": platform.machine(), "cpu": cpu, "cpus": os.cpu_count(), "python": platform.python_version(),
            "load_average_at_start": [round(x, 2) for x in os.getloadavg()]}


def warm_up(scene, view: str, group: str, mode: str = "stratified") -> None:
    """Compile the Mitsuba kernels of (view, group) at the film size that is timed (kernels are
    specific to the film size): a probe and a small render, so timings are of rendering only."""
    from renderer_jobs import mitsuba_render as mr
    from renderer_jobs.light_probe import probe_group

    probe_group(scene, view, group, mr.RenderSettings(spp=32, seed=99))
    mr.render_cube(scene, view, group, mr.RenderSettings(spp=32, seed=99, wavelengths=mode, adaptive=True))


def with_cupboard(scene_doc: dict, lo: np.ndarray, hi: np.ndarray) -> dict:
    """The demo room plus a closed cupboard in the back-left corner with a bulb inside (group ``cupboard``)."""
    c = [float(lo[0]) + 0.35, 0.3, float(lo[2]) + 0.35]
    doc = json.loads(json.dumps(scene_doc, default=list))
    doc["materials"]["cupboard_wood"] = {"kind": "diffuse", "reflectance": {"value": 0.45}}
    doc["shapes"].append({"name": "cupboard", "type": "cube", "material": "cupboard_wood",
                          "transform": {"scale": [0.25, 0.3, 0.25], "translate": c}})
    doc["lights"].append({"name": "cupboard_bulb", "type": "point", "group": "cupboard", "position": c,
                          "strength": 5.0})
    doc["light_groups"].append({"name": "cupboard", "description": "a bulb inside a closed cupboard"})
    return doc


def part_curve(args, scene, mr, w_raw, rows: list, log) -> None:
    aovs = mr.render_aovs(scene, args.view, mr.RenderSettings())
    mask = flat_mask(aovs)
    for group in args.groups:
        for mode in args.modes:
            warm_up(scene, args.view, group, mode)
            ref_spp = args.ref_factor * max(args.spp)
            ref, _, ref_cpu = timed(lambda: mr.render_cube(scene, args.view, group, mr.RenderSettings(
                spp=ref_spp, seed=12345, wavelengths=mode, adaptive=False)).cube)
            log(f"  reference {group} {mode} {ref_spp} spp: {ref_cpu:.1f} s CPU")
            for sampling in args.sampling:
                for spp in args.spp:
                    walls, cpus, flat, vs_ref = [], [], [], []
                    for pair in range(args.pairs):
                        st = [mr.RenderSettings(spp=spp, seed=s, wavelengths=mode, adaptive=sampling == "adaptive")
                              for s in (1 + 2 * pair, 2 + 2 * pair)]
                        a, wall, cpu = timed(lambda: mr.render_cube(scene, args.view, group, st[0]))
                        b, wall2, cpu2 = timed(lambda: mr.render_cube(scene, args.view, group, st[1]))
                        walls += [wall, wall2]
                        cpus += [cpu, cpu2]
                        flat.append(flat_noise(a.cube, b.cube, mask, w_raw))
                        vs_ref.append(ref_noise(a.cube, b.cube, ref, w_raw))
                    wall, cpu = float(np.median(walls)), float(np.median(cpus))
                    row = {"size": f"{scene.views[0].width}x{scene.views[0].height}", "group": group,
                           "wavelengths": mode, "sampling": sampling, "spp": spp, "seconds": round(wall, 3),
                           "cpu_seconds": round(cpu, 3), "trace_seconds": a.stats["trace_s"],
                           "paths_per_cpu_second": round(a.cube.shape[0] * a.cube.shape[1] * spp / cpu),
                           "seed_pairs": args.pairs, **mean_of(flat), **mean_of(vs_ref)}
                    if "spp_per_pixel" in a.stats:
                        row["spp_per_pixel"] = a.stats["spp_per_pixel"]
                    rows.append(row)
                    log(f"{row['size']:>9} {group:9s} {mode:10s} {sampling:8s} spp {spp:4d} {wall:6.2f}s "
                        f"({cpu:6.2f} CPU)  flat band {row['flat_band_rel_std_median'] * 100:5.1f}%  "
                        f"raw G rms {row['raw_G_rms'] * 100:5.2f}%  p99 {row['raw_G_block_p99'] * 100:5.2f}%  "
                        f"band rms {row['band_rms_median'] * 100:5.1f}%")


def summarise_curve(rows: list) -> list:
    out = []
    for key in sorted({(r["size"], r["group"], r["wavelengths"], r["sampling"]) for r in rows}):
        rs = sorted((r for r in rows if (r["size"], r["group"], r["wavelengths"], r["sampling"]) == key),
                    key=lambda r: r["spp"])
        sp = [r["spp"] for r in rs]
        best = rs[-1]
        doc = {"size": key[0], "group": key[1], "wavelengths": key[2], "sampling": key[3],
               "slope_raw_G_rms_vs_spp": slope(sp, [r["raw_G_rms"] for r in rs]),
               "slope_band_rms_vs_spp": slope(sp, [r["band_rms_median"] for r in rs]),
               "slope_cpu_seconds_vs_spp": slope(sp, [r["cpu_seconds"] for r in rs])}
        for stat in ("flat_band_rel_std_median", "band_rms_median"):
            n = best[stat]
            need = best["spp"] * (n / THESIS_BAND_NOISE) ** 2
            doc[f"spp_to_thesis_by_{stat}"] = round(need, 1)
            doc[f"cpu_seconds_to_thesis_by_{stat}"] = round(best["cpu_seconds"] * need / best["spp"], 1)
        out.append(doc)
    return out


def compare_adaptive(rows: list) -> list:
    out = []
    for r in rows:
        if r["sampling"] != "adaptive":
            continue
        u = next((x for x in rows if x["sampling"] == "uniform" and all(
            x[k] == r[k] for k in ("size", "group", "wavelengths", "spp"))), None)
        if u is None:
            continue
        d = {k: r[k] for k in ("size", "group", "wavelengths", "spp")}
        for stat in ("raw_G_rms", "raw_G_block_p50", "raw_G_block_p90", "raw_G_block_p99", "band_rms_median",
                     "flat_band_rel_std_median"):
            d[f"{stat}_ratio"] = round(r[stat] / u[stat], 4)
        d["cpu_ratio"] = round(r["cpu_seconds"] / u["cpu_seconds"], 3)
        d["equal_time_speedup_raw_G_rms"] = round((u["raw_G_rms"] / r["raw_G_rms"]) ** 2 / d["cpu_ratio"], 3)
        d["equal_time_speedup_raw_G_block_p99"] = round(
            (u["raw_G_block_p99"] / r["raw_G_block_p99"]) ** 2 / d["cpu_ratio"], 3)
        d["image_mean_rel_adaptive"] = r["image_mean_rel"]
        d["image_mean_rel_uniform"] = u["image_mean_rel"]
        out.append(d)
    return out


def part_skip(args, scene_doc: dict, mr, log) -> list:
    from renderer_jobs.light_probe import probe_group
    from renderer_jobs.mitsuba_scene import scene_bounds
    from renderer_jobs.scene_load import scene_from_dict

    base = scene_from_dict(scene_doc)
    scene = scene_from_dict(with_cupboard(scene_doc, *scene_bounds(base)))
    spp = args.skip_spp
    out = []
    for view in (v.name for v in scene.views):
        for group in scene.group_names:
            st = mr.RenderSettings(spp=spp, seed=1)
            warm_up(scene, view, group)
            probe, pw, pc = timed(lambda: probe_group(scene, view, group, st))
            cube, rw, rc = timed(lambda: mr.render_cube(scene, view, group, st).cube)
            row = {"view": view, "group": group, "spp": spp, "probe_lit": probe.lit, "probe_paths": probe.paths,
                   "probe_budget": probe.budget, "probe_seconds": round(pw, 4), "probe_cpu_seconds": round(pc, 4),
                   "render_seconds": round(rw, 3), "render_cpu_seconds": round(rc, 3),
                   "probe_cpu_fraction_of_render": round(pc / rc, 4),
                   "render_exactly_zero": bool(not (cube.max() > 0)), "render_max": float(cube.max())}
            out.append(row)
            log(f"  probe {view:6s} {group:9s} lit={probe.lit!s:5s} {probe.paths:7d}/{probe.budget} paths "
                f"{pc:6.3f} s CPU = {pc / rc * 100:5.2f}% of the render ({rc:.2f} s CPU); "
                f"render all zero: {row['render_exactly_zero']}")
    return out


def open_scene_doc(res: tuple[int, int]) -> dict:
    """A floor and a back wall under a ceiling panel, seen from above so that about 2/3 of the
    pixels see nothing: the case where skipping background pixels could pay."""
    from renderer_jobs.demo import frame_matrix as fm

    return {"name": "open", "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.7}}},
            "shapes": [{"name": "floor", "type": "rectangle", "material": "white",
                        "transform": {"matrix": fm((0, 0, 0), (0, 1, 0), (0, 0, -1), (2, 2))}},
                       {"name": "back", "type": "rectangle", "material": "white",
                        "transform": {"matrix": fm((0, 1, -1), (0, 0, 1), (0, 1, 0), (2, 2))}},
                       {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 3.0},
                        "transform": {"matrix": fm((0, 1.9, -0.5), (0, -1, 0), (0, 0, -1), (0.4, 0.4))}}],
            "views": [{"name": "cam", "origin": (0, 1.6, 2.5), "target": (0, 1.4, -1), "fov": 60,
                       "resolution": list(res)}], "max_depth": 6}


def part_background(args, size, mr, log) -> list:
    """CPU time of tracing every pixel against tracing only pixels whose camera rays hit geometry
    (for a group without a sky the others are exactly zero): what a background skip could save."""
    from renderer_jobs import demo
    from renderer_jobs.mitsuba_trace import Tracer
    from renderer_jobs.scene_load import scene_from_dict

    out = []
    for name, scene, view, group in (("open floor + wall", scene_from_dict(open_scene_doc(size)), "cam", "lamp"),
                                     ("demo room", demo.demo_room(args.seed, resolution=size), "front", "ceiling")):
        hit = mr.render_aovs(scene, view, mr.RenderSettings(aov_spp=16))["mask"].ravel()
        tracers = [Tracer(scene, view, [group], None)]
        st = mr.RenderSettings(spp=args.skip_spp, seed=1, adaptive=False)
        cpu = {}
        for rep in range(2):  # the first round compiles
            for label, pixels in (("all", np.arange(hit.size)), ("hit", np.flatnonzero(hit))):
                blocks = mr._PathBlocks(tracers, st, np.ones(scene.spectral_grid.n_bands))
                pix = np.repeat(pixels, st.spp)
                s = np.tile(np.arange(st.spp), len(pixels))
                c0 = time.process_time()
                for a in range(0, len(pix), st.max_lanes):
                    blocks.trace(pix[a:a + st.max_lanes], s[a:a + st.max_lanes], a)
                cpu[label] = time.process_time() - c0
        row = {"scene": name, "background_fraction": round(float(1 - hit.mean()), 3),
               "cpu_seconds_all_pixels": round(cpu["all"], 3), "cpu_seconds_hit_pixels": round(cpu["hit"], 3),
               "possible_saving": round(1 - cpu["hit"] / cpu["all"], 3)}
        out.append(row)
        log(f"  background {name}: {row['background_fraction'] * 100:.0f} % of pixels see nothing; tracing "
            f"them costs {row['possible_saving'] * 100:.0f} % of the render")
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="curve,adaptive,skip,background",
                    help="curve, adaptive, skip, background")
    ap.add_argument("--sizes", default="160x120", help="WIDTHxHEIGHT list (e.g. 320x240,960x720)")
    ap.add_argument("--spp", default="16,32,64,128", help="spp list")
    ap.add_argument("--groups", default="ceiling", help="light groups of the demo room")
    ap.add_argument("--modes", default="stratified", help="wavelength sampling modes (stratified,random)")
    ap.add_argument("--sampling", default="uniform,adaptive", help="uniform and/or adaptive spp")
    ap.add_argument("--ref-factor", type=int, default=4, help="reference spp = this × the highest spp")
    ap.add_argument("--pairs", type=int, default=2, help="seed pairs per point (noise averaged over them)")
    ap.add_argument("--skip-spp", type=int, default=64, help="spp of the renders the probes are compared with")
    ap.add_argument("--view", default="front")
    ap.add_argument("--sensor", default="Nikon 5100 (NPL)")
    ap.add_argument("--seed", type=int, default=0, help="demo room seed")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    args = ap.parse_args(argv)
    args.spp = [int(s) for s in args.spp.split(",")]
    args.groups = [g for g in args.groups.split(",") if g]
    args.modes = [m for m in args.modes.split(",") if m]
    args.sampling = [s for s in args.sampling.split(",") if s]
    parts = {p for p in args.parts.split(",") if p}

    from renderer_jobs import demo
    from renderer_jobs import mitsuba_render as mr
    from renderer_jobs.mitsuba_variant import select_variant
    from retarget import illuminants, sensors

    def log(msg: str) -> None:
        print(msg, flush=True)

    t0 = time.perf_counter()
    variant = select_variant()
    w_raw = sensors.get_sensor(args.sensor).weights() * illuminants.illuminant_spd("D65")[:, None]
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    rows: list = []
    doc: dict = {"benchmark": "render", "variant": variant, **machine(),
                 "threads": os.environ.get("DRJIT_NUM_THREADS", "all"), "scene": f"demo-room-{args.seed}",
                 "view": args.view, "sensor": args.sensor, "thesis_band_noise": THESIS_BAND_NOISE}
    if parts & {"curve", "adaptive"}:
        for size in sizes:
            part_curve(args, demo.demo_room(args.seed, resolution=size), mr, w_raw, rows, log)
        doc["results"] = rows
        doc["curve"] = summarise_curve(rows)
        if "adaptive" in parts:
            doc["adaptive_vs_uniform"] = compare_adaptive(rows)
    if "skip" in parts:
        doc["skip"] = part_skip(args, demo.demo_room_dict(args.seed, resolution=sizes[0]), mr, log)
    if "background" in parts:
        doc["background"] = part_background(args, sizes[0], mr, log)
    doc["total_seconds"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(doc, indent=1)
    if args.out:
        Path(args.out).write_text(text)
    print(text)
    return doc


if __name__ == "__main__":
    main()
