"""Render benchmark: time against noise for transport cubes, and what skipping and adaptivity buy.

Eight parts (``--parts``, all by default), on the seeded demo room (``scene.demo``):

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

``target`` — noise-target rendering (``RenderSettings.noise_target``, ``--targets``, per-pixel cap
  ``--target-max-spp``): mean paths per pixel, CPU time, noise against the reference, the measured
  noise of each pixel's band mean against the target (calibration), and the uniform spp and CPU time
  that reach the same raw G RMS / worst-block p99 (power law fitted to the uniform curve).

``skip`` — light probes (``renderer_jobs.mitsuba.light_probe``): for every demo-room group and view, probe
  verdict and time against the cube's render time (the probe's overhead on lit groups); and for a
  dark group — a lamp inside a closed cupboard added to the room — probe time against the full
  render's, and that the full render is exactly zero (so recording it as empty changes nothing).

``background`` — skipping pixels that cannot see geometry (for a group without a sky they are
  exactly zero; ``renderer_jobs.mitsuba.view_coverage``): render CPU time with and without the skip (uniform
  spp, so every other pixel gets the same paths either way) in an
  open scene (~2/3 background) and in the demo room (closed: nothing to skip), and that the full
  render is exactly zero in every skipped pixel.

``backends`` — Mitsuba against Cycles run the thesis way, same scenes, one run (``bench/render_backends.py``):
  CPU time, raw noise on the lit region and the image, 550 nm band noise, mean raw per region against
  a Mitsuba reference (the cross-check), and the closed-form validation on both.

``samplers`` — what each step of the all-bands renderer buys on its own (``bench/render_samplers.py``):
  4-wavelength paths against all-bands paths with each of Mitsuba's samplers, and power-weighted
  against uniform light selection, on the probe scene, the demo room and the window-lit room.

``narrowband`` — a group emitting in 5 of the 63 bands: the stratified schedule samples only those
  (``mitsuba_render.live_bands``); lit-band noise and CPU time against the full 63-band schedule.

    python bench/render.py              # default: 160x120, ceiling, spp 16,32,64,128 (a few minutes, 2 cores)
    python bench/render.py --sizes 320x240,960x720 --spp 16,64,256 --groups ceiling,daylight,desk

Prints progress lines, then the JSON document last; the curves are also plotted to ``--plot``
(default ``bench/out/render_curve.png``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]

from render_lib import (NARROW_BAND, flat_mask, flat_noise, machine, mean_of, open_scene_doc,  # noqa: E402
                        plot_curves, ref_noise, slope, timed, warm_up, with_cupboard)

THESIS_BAND_NOISE = 0.0067


def part_curve(args, scene, mr, w_raw, rows: list, targets: list, log) -> None:
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs

    aovs = render_aovs(scene, args.view, mr.RenderSettings())
    mask = flat_mask(aovs)
    for group in args.groups:
        for mode in args.modes:
            warm_up(scene, args.view, group, mode)
            ref_spp = args.ref_factor * max(args.spp)
            ref, _, ref_cpu = timed(lambda: mr.render_cube(scene, args.view, group, mr.RenderSettings(
                spp=ref_spp, seed=12345, wavelengths=mode, adaptive=False)).cube)
            log(f"  reference {group} {mode} {ref_spp} spp: {ref_cpu:.1f} s CPU")
            for sampling in args.sampling:
                if sampling == "adaptive" and mode == "all-bands":
                    continue  # adaptive spp belongs to the 4-wavelength modes
                for spp in args.spp:
                    pairs, walls, cpus = seed_pairs(args, scene, mr, group, spp=spp, wavelengths=mode,
                                                    adaptive=sampling == "adaptive")
                    flat = [flat_noise(a.cube, b.cube, mask, w_raw) for a, b in pairs]
                    vs_ref = [ref_noise(a.cube, b.cube, ref, w_raw) for a, b in pairs]
                    a = pairs[0][0]
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
            for target in args.targets:
                targets.append(measure_target(args, scene, mr, group, mode, target, ref, w_raw, log))


def seed_pairs(args, scene, mr, group: str, **settings) -> tuple[list, list[float], list[float]]:
    """``--pairs`` pairs of renders with seeds (1, 2), (3, 4), …: the pairs, wall and CPU seconds."""
    pairs, walls, cpus = [], [], []
    for pair in range(args.pairs):
        ab = []
        for seed in (1 + 2 * pair, 2 + 2 * pair):
            st = mr.RenderSettings(seed=seed, **settings)
            r, wall, cpu = timed(lambda: mr.render_cube(scene, args.view, group, st))
            ab.append(r)
            walls.append(wall)
            cpus.append(cpu)
        pairs.append(tuple(ab))
    return pairs, walls, cpus


def measure_target(args, scene, mr, group: str, mode: str, target: float, ref, w_raw, log) -> dict:
    """Noise-target rendering (``RenderSettings.noise_target``, spp capped at ``--target-max-spp``):
    paths spent, CPU time, noise against the reference, and the calibration of the target — the
    measured relative noise of each pixel's band mean (what the pilot predicts), RMS over pixels."""
    pairs, walls, cpus = seed_pairs(args, scene, mr, group, spp=args.target_max_spp, wavelengths=mode,
                                    noise_target=target)
    vs_ref, calib, stats = [], [], []
    for a, b in pairs:
        vs_ref.append(ref_noise(a.cube, b.cube, ref, w_raw))
        ya, yb = (r.cube.astype(np.float64).mean(-1) for r in (a, b))
        m = (ya + yb) / 2
        lit = m > 0
        calib.append(float(np.mean(((ya - yb)[lit] / np.sqrt(2) / m[lit]) ** 2)))
        stats += [a.stats, b.stats]
    row = {"size": f"{scene.views[0].width}x{scene.views[0].height}", "group": group, "wavelengths": mode,
           "noise_target": target, "max_spp": args.target_max_spp,
           "mean_spp": round(float(np.mean([s["spp_per_pixel"]["mean"] for s in stats])), 2),
           "pixels_at_max_spp": float(np.mean([s["noise_target"]["pixels_at_max_spp"] for s in stats])),
           "seconds": round(float(np.median(walls)), 3), "cpu_seconds": round(float(np.median(cpus)), 3),
           "band_mean_rel_rms": round(float(np.sqrt(np.mean(calib))), 5), **mean_of(vs_ref)}
    log(f"  target {target:5.3f} {group:9s} mean spp {row['mean_spp']:7.1f} ({row['pixels_at_max_spp']:.0f} px at "
        f"max)  {row['cpu_seconds']:6.2f} s CPU  band-mean noise {row['band_mean_rel_rms'] * 100:5.2f}%  "
        f"raw G rms {row['raw_G_rms'] * 100:5.2f}%  p99 {row['raw_G_block_p99'] * 100:5.2f}%")
    return row


def compare_target(rows: list, targets: list) -> list:
    """Each noise-target row against uniform spp at the same noise: the uniform spp (and CPU time)
    that reaches the same raw G RMS / worst-block p99, from the power law fitted to the uniform curve
    (``extrapolated`` when outside its spp range)."""
    out = []
    for t in targets:
        u = sorted((r for r in rows if r["sampling"] == "uniform" and all(
            r[k] == t[k] for k in ("size", "group", "wavelengths"))), key=lambda r: r["spp"])
        if len(u) < 2:
            continue
        sp = np.log([r["spp"] for r in u])
        cpu_fit = np.polyfit(sp, np.log([r["cpu_seconds"] for r in u]), 1)
        d = {k: t[k] for k in ("size", "group", "wavelengths", "noise_target", "mean_spp", "cpu_seconds")}
        for stat in ("raw_G_rms", "raw_G_block_p99"):
            fit = np.polyfit(sp, np.log([r[stat] for r in u]), 1)
            log_spp = (np.log(t[stat]) - fit[1]) / fit[0]
            spp_u = float(np.exp(log_spp))
            d[f"uniform_spp_same_{stat}"] = round(spp_u, 1)
            d[f"paths_saving_{stat}"] = round(spp_u / t["mean_spp"], 3)
            d[f"equal_noise_speedup_{stat}"] = round(float(np.exp(np.polyval(cpu_fit, log_spp))) / t["cpu_seconds"], 3)
            d[f"extrapolated_{stat}"] = bool(not u[0]["spp"] <= spp_u <= u[-1]["spp"])
        out.append(d)
    return out


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
        d["paths_ratio"] = round(r.get("spp_per_pixel", {}).get("mean", r["spp"]) / r["spp"], 4)
        d["equal_time_speedup_raw_G_rms"] = round((u["raw_G_rms"] / r["raw_G_rms"]) ** 2 / d["cpu_ratio"], 3)
        d["equal_time_speedup_raw_G_block_p99"] = round(
            (u["raw_G_block_p99"] / r["raw_G_block_p99"]) ** 2 / d["cpu_ratio"], 3)
        d["image_mean_rel_adaptive"] = r["image_mean_rel"]
        d["image_mean_rel_uniform"] = u["image_mean_rel"]
        out.append(d)
    return out


def part_skip(args, scene_doc: dict, mr, log) -> list:
    from illumix.renderer_jobs.mitsuba.light_probe import probe_group
    from illumix.renderer_jobs.mitsuba.scene_dict import scene_bounds
    from illumix.scene.load import scene_from_dict

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


def part_narrowband(args, scene_doc: dict, mr, log) -> dict:
    """The ceiling group given a 540–560 nm emission: the schedule samples only its 5 emitting bands.
    Against the full 63-band schedule (the flat cube × the emission: the same cube in expectation,
    and exactly what a 63-band schedule renders), per-band relative noise of the lit bands (RMS over
    pixels, two seeds) and CPU time at the same spp."""
    from illumix.renderer_jobs.band_schedule import live_bands
    from illumix.renderer_jobs.mitsuba.scene_dict import group_emission
    from illumix.scene.load import scene_from_dict

    doc = json.loads(json.dumps(scene_doc, default=list))
    flat_scene = scene_from_dict(doc)
    next(g for g in doc["light_groups"] if g["name"] == "ceiling")["emission"] = NARROW_BAND
    narrow_scene = scene_from_dict(doc)
    out = {"group": "ceiling", "emission": "540-560 nm box", "spp": args.skip_spp}
    e = np.asarray(group_emission(narrow_scene, "ceiling")[0])  # the narrow cube's emission, per band
    for label, scene in (("emitting_bands_only", narrow_scene), ("all_63_bands", flat_scene)):
        warm_up(scene, args.view, "ceiling")
        (pair,), _, cpus = seed_pairs(argparse.Namespace(pairs=1, view=args.view), scene, mr, "ceiling",
                                      spp=args.skip_spp)
        live = live_bands(e)
        a, b = (r.cube[..., live].astype(np.float64) * (1.0 if label == "emitting_bands_only" else e[live])
                for r in pair)
        m = (a + b) / 2
        rel = np.sqrt(np.mean(((a - b) / np.sqrt(2))[m > 0] ** 2 / m[m > 0] ** 2))
        out[label] = {"band_rel_rms": round(float(rel), 4), "cpu_seconds": round(float(np.median(cpus)), 3)}
    n, f = out["emitting_bands_only"], out["all_63_bands"]
    out["noise_ratio"] = round(n["band_rel_rms"] / f["band_rel_rms"], 3)
    out["equal_noise_speedup"] = round((f["band_rel_rms"] / n["band_rel_rms"]) ** 2 * f["cpu_seconds"]
                                       / n["cpu_seconds"], 1)
    log(f"  narrow-band ceiling: lit-band noise {f['band_rel_rms'] * 100:.1f} % (63-band schedule) -> "
        f"{n['band_rel_rms'] * 100:.1f} % (emitting bands only), CPU {f['cpu_seconds']:.2f} -> "
        f"{n['cpu_seconds']:.2f} s: {out['equal_noise_speedup']}x at equal noise")
    return out


def part_background(args, size, mr, log) -> list:
    """Background-pixel skip (``renderer_jobs.mitsuba.view_coverage``): render time with and without it, the
    pixels skipped, and that the full render is exactly zero in every skipped pixel."""
    from illumix.scene import demo
    from illumix.scene.load import scene_from_dict
    from illumix.renderer_jobs.mitsuba.view_coverage import covered_pixels

    out = []
    for name, scene, view, group in (("open floor + wall", scene_from_dict(open_scene_doc(size)), "cam", "lamp"),
                                     ("demo room", demo.demo_room(args.seed, resolution=size), "front", "ceiling")):
        cov = covered_pixels(scene, view)
        warm_up(scene, view, group)
        cpus: dict[bool, list[float]] = {False: [], True: []}
        full = None
        for rep in range(3):  # median of three (CPU time of a ~1 s render jitters by ~20 %)
            for on in (False, True):
                r, _, c = timed(lambda: mr.render_cube(scene, view, group, mr.RenderSettings(
                    spp=args.skip_spp, seed=1 + rep, skip_background=on, wavelengths="stratified")))
                cpus[on].append(c)
                if not on:
                    full = r
        cpu_full, cpu_skip = float(np.median(cpus[False])), float(np.median(cpus[True]))
        skipped = np.zeros(full.cube.shape[:2], bool) if cov is None else ~cov
        row = {"scene": name, "skipped_fraction": round(float(skipped.mean()), 3),
               "cpu_seconds_full": round(cpu_full, 3), "cpu_seconds_with_skip": round(cpu_skip, 3),
               "saving": round(1 - cpu_skip / cpu_full, 3),
               "full_render_zero_in_skipped_pixels": bool(np.all(full.cube[skipped] == 0))}
        out.append(row)
        log(f"  background {name}: {row['skipped_fraction'] * 100:.0f} % of pixels skipped, CPU "
            f"{cpu_full:.2f} s -> {cpu_skip:.2f} s ({row['saving'] * 100:.0f} % saved); full render zero there: "
            f"{row['full_render_zero_in_skipped_pixels']}")
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="curve,adaptive,target,skip,background,narrowband,samplers,backends",
                    help="curve, adaptive, target, skip, background, narrowband")
    ap.add_argument("--sizes", default="160x120", help="WIDTHxHEIGHT list (e.g. 320x240,960x720)")
    ap.add_argument("--spp", default="16,32,64,128", help="spp list")
    ap.add_argument("--groups", default="ceiling", help="light groups of the demo room")
    ap.add_argument("--modes", default="stratified", help="wavelength sampling modes (stratified,random)")
    ap.add_argument("--sampling", default="uniform,adaptive", help="uniform and/or adaptive spp")
    ap.add_argument("--ref-factor", type=int, default=4, help="reference spp = this × the highest spp")
    ap.add_argument("--pairs", type=int, default=2, help="seed pairs per point (noise averaged over them)")
    ap.add_argument("--skip-spp", type=int, default=64, help="spp of the renders the probes are compared with")
    ap.add_argument("--targets", default="0.1,0.05",
                    help="noise targets to measure (part target; relative noise of a pixel's spectral sum)")
    ap.add_argument("--target-max-spp", type=int, default=1024, help="per-pixel spp cap of the noise-target renders")
    ap.add_argument("--view", default="front")
    ap.add_argument("--sensor", default="Nikon 5100 (NPL)")
    ap.add_argument("--seed", type=int, default=0, help="demo room seed")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    root = Path(__file__).resolve().parents[1]
    ap.add_argument("--bench-scenes", default=str(root.parent / "shared" / "bench-scenes"),
                    help="folder of the benchmark scenes (part backends: probe.yaml)")
    ap.add_argument("--backends-sensor", default=str(root.parent / "shared" / "data" / "rawtoaces-data" / "data"
                                                     / "camera" / "Nikon_D810_380_780_5.json"),
                    help="sensor of part backends (issue 17 measured with the Nikon D810)")
    ap.add_argument("--probe-size", default="240x180", help="probe scene resolution (part backends)")
    ap.add_argument("--demo-size", default="160x120", help="demo room resolution (part backends)")
    ap.add_argument("--samplers-sizes", default="120x90,80x60",
                    help="probe and demo-room resolutions of part samplers (half of part backends': 13 configurations)")
    ap.add_argument("--backends-ref-spp", type=int, default=512, help="Mitsuba reference spp (part backends)")
    ap.add_argument("--plot", default="bench/out/render_curve.png", help="PNG of noise against spp and CPU time")
    args = ap.parse_args(argv)
    args.spp = [int(s) for s in args.spp.split(",")]
    args.probe_size = [int(v) for v in args.probe_size.lower().split("x")]
    args.demo_size = [int(v) for v in args.demo_size.lower().split("x")]
    args.samplers_sizes = [[int(v) for v in s.lower().split("x")] for s in args.samplers_sizes.split(",")]
    args.groups = [g for g in args.groups.split(",") if g]
    args.modes = [m for m in args.modes.split(",") if m]
    args.sampling = [s for s in args.sampling.split(",") if s]
    parts = {p for p in args.parts.split(",") if p}
    args.targets = [float(t) for t in args.targets.split(",") if t] if "target" in parts else []

    from illumix.scene import demo
    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.renderer_jobs.mitsuba.variant import select_variant
    from illumix.retarget import illuminants, sensors

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
    if parts & {"curve", "adaptive", "target"}:
        targets: list = []
        for size in sizes:
            part_curve(args, demo.demo_room(args.seed, resolution=size), mr, w_raw, rows, targets, log)
        doc["results"] = rows
        doc["curve"] = summarise_curve(rows)
        if "adaptive" in parts:
            doc["adaptive_vs_uniform"] = compare_adaptive(rows)
        if targets:
            doc["noise_target"] = targets
            doc["noise_target_vs_uniform"] = compare_target(rows, targets)
    if "skip" in parts:
        doc["skip"] = part_skip(args, demo.demo_room_dict(args.seed, resolution=sizes[0]), mr, log)
    if "background" in parts:
        doc["background"] = part_background(args, sizes[0], mr, log)
    if "narrowband" in parts:
        doc["narrowband"] = part_narrowband(args, demo.demo_room_dict(args.seed, resolution=sizes[0]), mr, log)
    if "samplers" in parts:
        from render_samplers import part_samplers

        doc["samplers"] = part_samplers(args, log)
    if "backends" in parts:
        from illumix.scene.blender_env import find_blender_python

        if find_blender_python(required=False) is None:
            doc["backends"] = {"skipped": "Blender (bpy) not installed: bash scripts/install.sh --blender"}
        else:
            from render_backends import part_backends

            doc["backends"] = part_backends(args, log)
            doc["vs_thesis"] = doc["backends"]["vs_thesis"]
    if rows:
        png = plot_curves(doc, Path(args.plot))
        doc["plot"] = str(png) if png else None
        log(f"  plot: {png}" if png else "  plot skipped: matplotlib missing (pip install -e '.[bench]')")
    doc["total_seconds"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(doc, indent=1)
    if args.out:
        Path(args.out).write_text(text)
    print(text)
    return doc


if __name__ == "__main__":
    main()
