"""Benchmark: one sample, end to end — relight + raw + gain map + CCM map + sRGB (issue 2, item 8).

A synthetic two-group scene (default 720×960×63, the thesis's image size and band count): smooth
random illumination fields per light group ("window" lit by D65, "lamp" by A at half intensity)
times per-pixel reflectances mixed smoothly from the ColorChecker. Flat unit emission, as the
renderer stores cubes.

Timed paths (median of ``--repeats`` runs each):

- ``fused_float32`` / ``fused_float16``: :func:`retarget.compose.compose` with every output, on
  float32 and float16 cubes (float16 is how the store keeps them).
- ``naive_float32``: the baseline a direct port of the thesis pipeline would run — materialise the
  63-band mixed spectral image with :func:`retarget.relight.relight`, :func:`project` it, materialise
  and project each group's spectral image again for the weights, then the same ground truth and ISP.

Accuracy is reported beside speed: the fused path against the naive one, and float16 input
against float32, as max |ΔsRGB| and grid CIEDE2000 (thesis appendix B).
Peak memory per path is tracemalloc's peak (numpy reports its buffers to tracemalloc) during one
extra, untimed call, over what was allocated before it; ``maxrss_mb`` is the process's high-water mark.

Usage: ``python bench/compose.py [--repeats 3] [--height 720] [--width 960]``. Progress goes to
stderr; the JSON result is the last line on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from illumix.retarget import groundtruth as gt  # noqa: E402
from illumix.retarget.compose import compose, group_ccms  # noqa: E402
from illumix.retarget.illuminants import illuminant_spd  # noqa: E402
from illumix.retarget.isp import apply_ccm, render_srgb  # noqa: E402
from illumix.retarget.exposure import aec_gain  # noqa: E402
from illumix.retarget.metrics import grid_delta_e00  # noqa: E402
from illumix.retarget.reflectances import get_reflectances  # noqa: E402
from illumix.retarget.relight import band_scales, project, project_groups, raw_weights, relight  # noqa: E402
from illumix.retarget.sensors import get_sensor  # noqa: E402

GROUPS = ("window", "lamp")
ILLUMINANTS = ("D65", "A")
INTENSITIES = np.array([1.0, 0.5])


def log(msg: str) -> None:
    print(f"[bench/compose] {msg}", file=sys.stderr, flush=True)


def smooth_field(rng: np.random.Generator, h: int, w: int, coarse: tuple[int, int] = (6, 8)) -> np.ndarray:
    """A smooth positive random field ``(H, W)``: bilinear upsampling of a coarse random grid."""
    c = rng.uniform(0.0, 1.0, coarse)
    ys = np.linspace(0, coarse[0] - 1, h)
    xs = np.linspace(0, coarse[1] - 1, w)
    y0 = np.minimum(ys.astype(int), coarse[0] - 2)
    x0 = np.minimum(xs.astype(int), coarse[1] - 2)
    ty = (ys - y0)[:, None]
    tx = (xs - x0)[None, :]
    top = c[y0][:, x0] * (1 - tx) + c[y0][:, x0 + 1] * tx
    bottom = c[y0 + 1][:, x0] * (1 - tx) + c[y0 + 1][:, x0 + 1] * tx
    return top * (1 - ty) + bottom * ty


def synthetic_scene(h: int, w: int, seed: int = 0) -> list[np.ndarray]:
    """Two transport cubes ``(H, W, 63)`` float32: illumination field × mixed reflectance."""
    rng = np.random.default_rng(seed)
    palette = get_reflectances("ColorChecker N Ohta")[1]  # (24, 63)
    picks = rng.choice(len(palette), 6, replace=False)
    alpha = np.stack([smooth_field(rng, h, w, (12, 16)) ** 4 for _ in picks], axis=-1)
    alpha /= alpha.sum(axis=-1, keepdims=True)
    reflectance = (alpha.reshape(-1, len(picks)) @ palette[picks]).astype(np.float32).reshape(h, w, -1)
    cubes = []
    for g in range(len(GROUPS)):
        field = (0.05 + 2.0 * smooth_field(rng, h, w) ** 2).astype(np.float32)
        cubes.append(reflectance * field[..., None])
    return cubes


def naive(cubes, emissions, illuminants, sensor, ccms):
    """Materialise spectral images (mixed and per group), project, then ground truth + ISP."""
    scales = band_scales(illuminants, emissions, INTENSITIES)
    sw = sensor.weights()
    raw = project(relight(cubes, scales), sw)
    group_raw = np.stack([project(relight([c], scales[g:g + 1]), sw) for g, c in enumerate(cubes)])
    weights, _mask = gt.illuminant_weights(group_raw[..., 1])
    wps = gt.white_points(sw, illuminants)
    gain = gt.gain_map(gt.mixed_white_point(weights, wps))
    ccm = gt.ccm_map(weights, ccms)
    exposure = aec_gain(apply_ccm(raw * gain, ccm), method="constant")
    return {"raw": raw, "gain": gain, "ccm": ccm, "srgb": render_srgb(raw, gain, ccm, exposure)}


def fused(cubes, emissions, illuminants, sensor, ccms):
    return compose(cubes, emissions=emissions, illuminants=illuminants, intensities=INTENSITIES,
                   sensor=sensor, ccms=ccms, group_names=GROUPS).outputs()


def stages(cubes, emissions, illuminants, sensor, ccms) -> dict[str, float]:
    """One instrumented pass through the steps compose() runs, in its order (seconds each)."""
    t = {}
    t0 = time.perf_counter()
    scales = band_scales(illuminants, emissions, INTENSITIES)
    group_raw = project_groups(cubes, raw_weights(scales, sensor.weights()))
    raw = group_raw.sum(axis=0)
    t["relight_project_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    weights, _ = gt.illuminant_weights(group_raw[..., 1])
    t["weights_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    gain = gt.gain_map(gt.mixed_white_point(weights, gt.white_points(sensor.weights(), illuminants)))
    t["gain_map_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ccm = gt.ccm_map(weights, ccms)
    t["ccm_map_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    render_srgb(raw, gain, ccm, aec_gain(apply_ccm(raw * gain, ccm), method="constant"))
    t["aec_srgb_s"] = time.perf_counter() - t0
    return {k: round(v, 4) for k, v in t.items()}


def timed(fn, repeats: int, *args) -> tuple[list[float], dict]:
    times, out = [], None
    for i in range(repeats):
        t0 = time.perf_counter()
        out = fn(*args)
        times.append(time.perf_counter() - t0)
        log(f"  {fn.__name__} run {i + 1}/{repeats}: {times[-1]:.3f} s")
    return times, out


def peak_mb(fn, *args) -> float:
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    fn(*args)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return round((peak - base) / 2**20, 1)


def summary(times: list[float]) -> dict:
    med = statistics.median(times)
    return {"median_s": round(med, 4), "min_s": round(min(times), 4), "max_s": round(max(times), 4),
            "images_per_s": round(1.0 / med, 3), "runs": len(times)}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per path (median reported)")
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--sensor", default="Nikon 5100 (NPL)", help="sensor name or camera file")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.height < 12 or args.width < 16:
        ap.error("need --repeats >= 1 and an image of at least 12×16 (the grid ΔE00 cells)")

    log(f"building a {args.height}×{args.width}×63 two-group scene (seed {args.seed})")
    t0 = time.perf_counter()
    cubes32 = synthetic_scene(args.height, args.width, args.seed)
    cubes16 = [c.astype(np.float16) for c in cubes32]
    build_s = time.perf_counter() - t0
    sensor = get_sensor(args.sensor)
    illuminants = np.stack([illuminant_spd(n, sensor.grid) for n in ILLUMINANTS])
    emissions = np.ones_like(illuminants)
    t0 = time.perf_counter()
    ccms = group_ccms(sensor, illuminants, get_reflectances("ColorChecker N Ohta", sensor.grid)[1])
    ccm_fit_s = time.perf_counter() - t0
    common = (emissions, illuminants, sensor, ccms)

    fused(cubes32, *common)  # warm-up: caches, BLAS threads, page faults
    log("fused float32")
    t32, out32 = timed(fused, args.repeats, cubes32, *common)
    log("fused float16")
    t16, out16 = timed(fused, args.repeats, cubes16, *common)
    log("naive float32 (materialised spectral images)")
    tnv, outnv = timed(naive, args.repeats, cubes32, *common)
    log("stage breakdown and peak memory")
    stage = stages(cubes32, *common)
    mem = {"fused_float32": peak_mb(fused, cubes32, *common),
           "fused_float16": peak_mb(fused, cubes16, *common),
           "naive_float32": peak_mb(naive, cubes32, *common)}

    def srgb_error(a: dict, b: dict) -> dict:
        score, _ = grid_delta_e00(a["srgb"], b["srgb"])
        return {"max_abs_srgb": float(np.max(np.abs(a["srgb"] - b["srgb"]))),
                "max_rel_raw": float(np.max(np.abs(a["raw"] - b["raw"]) / np.maximum(np.abs(b["raw"]), 1e-12))),
                "grid_delta_e00_worst25": round(score, 6)}

    result = {
        "benchmark": "compose",
        "shape": [args.height, args.width, int(cubes32[0].shape[2])],
        "groups": [f"{g}={i}@{a:g}" for g, i, a in zip(GROUPS, ILLUMINANTS, INTENSITIES)],
        "sensor": sensor.name,
        "outputs": sorted(out32),
        "fused_float32": summary(t32),
        "fused_float16": summary(t16),
        "naive_float32": summary(tnv),
        "speedup_fused_vs_naive": round(statistics.median(tnv) / statistics.median(t32), 2),
        "speedup_float16_vs_naive": round(statistics.median(tnv) / statistics.median(t16), 2),
        "stages_float32_s": stage,
        "peak_mem_mb": mem,
        "cube_mb": {"float32": round(sum(c.nbytes for c in cubes32) / 2**20, 1),
                    "float16": round(sum(c.nbytes for c in cubes16) / 2**20, 1)},
        "error_fused_vs_naive": srgb_error(out32, outnv),
        "error_float16_vs_float32": srgb_error(out16, out32),
        "setup_s": {"scene": round(build_s, 3), "ccm_fit": round(ccm_fit_s, 4)},
        "maxrss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "machine": {"python": platform.python_version(), "numpy": np.__version__,
                    "cpus": os.cpu_count(), "platform": platform.platform()},
    }
    return result


if __name__ == "__main__":
    res = main()
    log(f"fused float32 {res['fused_float32']['images_per_s']} img/s, float16 "
        f"{res['fused_float16']['images_per_s']} img/s, naive {res['naive_float32']['images_per_s']} img/s "
        f"(×{res['speedup_fused_vs_naive']})")
    print(json.dumps(res))
