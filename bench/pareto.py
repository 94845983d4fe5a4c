"""Benchmark: on-demand composition time against error, versus a float64 reference (issue 7, item 1).

Knobs (what the service could hold in its cube cache and how it composes from it):

- storage dtype: ``float32-store`` (exact) vs ``float16-store`` — the store's exponent-scaled float16
  policy (``store.codec``, ≤ 2⁻¹¹ relative per value), decoded to float32 in the cache (the current
  service path);
- spectral compression ``basis-K``: a K-component basis per cube (:mod:`retarget.basis`, fitted on
  the float16-store cube), the cache holding ``(H, W, K)`` coefficients; composition projects the
  basis through the request's weights, ``(H·W, K) @ (K, 3)`` instead of ``(H·W, 63) @ (63, 3)``;
- band skipping (a narrow-band scenario; exact): skip on/off in compose, and a projection-only
  sweep of how bands are skipped (``none`` / ``gather`` columns / contiguous ``span``);
- crop (a 256² crop sliced from a cached full frame, and read cold from the store) and resize
  (``size=`` at 1/4: per-group raw resized after projection — the service path — vs the cubes
  resized first).

Errors against :func:`pareto_lib.reference` (float64 on the float32 render output; see that module
for the test cubes: measured reflectances, smooth shading, emitters, Monte-Carlo noise levels
``--noise``) over spiky-illuminant scenarios (FL11, FL2, LED-RGB1, narrow-band LEDs) and three
sensors; the worst case over scenarios × noise levels is what the tolerances are checked against.
Times: the minimum (and, beside it, the median) of ``--repeats`` interleaved runs of
:func:`retarget.compose.compose` (all outputs, the service default; also raw + gain) on two
broadband scenarios; warm = the cube representation already in the cache. On a shared machine the
minimum estimates the uncontended cost; the median shows what contention adds.

Defaults: the fastest setting whose worst-case errors are within TOLERANCES (``basis-63``, all
bands, is a control — the exact path plus a rotation — and not a candidate); settings within 5 %
of the fastest time (run-to-run noise on a shared machine) count as tied and the one with the
smaller cache footprint, then the smaller store (bytes on disk or object storage), then the faster
cold read wins (``tied_within_5pct`` lists them).

Usage: ``[OPENBLAS_NUM_THREADS=1] python bench/pareto.py [--height 480 --width 640 --repeats 5]``; progress on stderr,
plot in ``bench/out/pareto.png``, JSON last on stdout.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import pareto_lib as pl  # noqa: E402
from illumix.retarget.basis import compress  # noqa: E402
from illumix.retarget.compose import compose, group_ccms  # noqa: E402
from illumix.retarget.grid import DEFAULT_GRID  # noqa: E402
from illumix.retarget.illuminants import illuminant_spd, spd_from_samples  # noqa: E402
from illumix.retarget.reflectances import get_reflectances  # noqa: E402
from illumix.retarget.relight import band_scales, raw_weights  # noqa: E402
from illumix.retarget.sensors import get_sensor  # noqa: E402

#: gain: 0.05° is ~1/20 of the best AWB methods' median error and of dataset annotation noise;
#: raw: 0.1 % is below one 12-bit code value at mid grey (1/4096 of white ≈ 0.13 % of 0.18);
#: sRGB: p99 ΔE00 0.1 is a tenth of a just-noticeable difference (and below 8-bit rounding, which
#: the run reports as ``srgb_8bit_quantisation_de00_p99``).
TOLERANCES = {"gain_angular_deg": 0.05, "raw_p99_rel": 1e-3, "srgb_de00_p99": 0.1}
SCENARIOS = {  # name: (sensor, window illuminant, lamp illuminant)
    "D65+A/Nikon": ("Nikon 5100 (NPL)", "D65", "A"),
    "FL11+D65/Nikon": ("Nikon 5100 (NPL)", "FL11", "D65"),
    "FL2+A/Canon5DII": ("Canon_EOS_5D_Mark_II", "FL2", "A"),
    "LED-RGB1+FL11/XYZ": ("XYZ", "LED-RGB1", "FL11"),
    "narrowRGB+blueLED/Nikon": ("Nikon 5100 (NPL)", "narrow:450,530,630", "narrow:450"),
}
INTENSITIES = np.array([1.0, 0.5])
TIMED_OUTPUTS = {"all": None, "raw+gain": ("raw", "gain")}
TIMED_SCENARIOS = ("D65+A/Nikon", "FL11+D65/Nikon")


def log(msg: str) -> None:
    print(f"[bench/pareto] {msg}", file=sys.stderr, flush=True)


def spd(name: str) -> np.ndarray:
    """A library illuminant, or ``narrow:c1,c2,…``: Gaussian lines (σ 8 nm) cut to zero beyond
    ±20 nm — narrow-band LEDs with exact zeros, where band skipping applies."""
    if not name.startswith("narrow:"):
        return illuminant_spd(name)
    wl = np.arange(380.0, 781.0, 1.0)
    v = sum(np.where(abs(wl - c) <= 20, np.exp(-0.5 * ((wl - c) / 8.0) ** 2), 0.0)
            for c in map(float, name[7:].split(",")))
    return spd_from_samples(wl, v, DEFAULT_GRID, what=name)


CAMERAS = ROOT.parent / "shared" / "data" / "rawtoaces-data" / "data" / "camera"


def sensor_by_name(name: str):
    """A built-in sensor, or a rawtoaces camera from ``../shared/data`` (Nikon 5100 if absent)."""
    path = CAMERAS / f"{name}_380_780_5.json"
    if name in ("XYZ", "Nikon 5100 (NPL)") or not path.is_file():
        return get_sensor(name if name in ("XYZ", "Nikon 5100 (NPL)") else "Nikon 5100 (NPL)")
    return get_sensor(str(path))


def scenario(name: str) -> dict:
    sensor_name, *ills = SCENARIOS[name]
    sensor = sensor_by_name(sensor_name)
    illuminants = np.stack([spd(n) for n in ills])
    ccms = group_ccms(sensor, illuminants, get_reflectances("ColorChecker N Ohta")[1])
    return dict(emissions=np.ones_like(illuminants), illuminants=illuminants, intensities=INTENSITIES,
                sensor=sensor, ccms=ccms)


def stores(tmp: str, cubes: list[np.ndarray]) -> dict[str, object]:
    """The cubes written to a float32 store and to a store with the float16 policy."""
    from illumix.store import CubeMeta, CubeStore, ViewMeta

    out = {}
    for policy in ("float32", "auto"):
        st = CubeStore.open(os.path.join(tmp, policy), mode="a", dtype_policy=policy)
        st.write_view("s", "v", ViewMeta(width=cubes[0].shape[1], height=cubes[0].shape[0], fov=45.0))
        for g, c in zip(pl.GROUPS, cubes):
            st.write_cube("s", "v", g, c, CubeMeta(grid=DEFAULT_GRID.to_dict(), emission_name="flat"))
        out["float32-store" if policy == "float32" else "float16-store"] = st
    return out


def load_reps(sts: dict, ks: list[int], crop=None) -> dict[str, dict]:
    """Cache-resident representations: ``{name: {"cubes", "cold_ms", "cache_bytes_per_px"}}``."""
    reps = {}
    for name, st in sts.items():
        t = time.perf_counter()
        cubes = [st.read_cube("s", "v", g, crop=crop) for g in pl.GROUPS]
        stored = sum(st.cube_meta("s", "v", g).storage.nbytes_stored or 0 for g in pl.GROUPS)
        reps[name] = {"cubes": cubes, "cold_ms": 1e3 * (time.perf_counter() - t), "stored_bytes": stored}
    base = reps["float16-store"]
    for k in ks:
        t = time.perf_counter()
        cubes = [compress(c, k) for c in base["cubes"]]
        reps[f"basis-{k}"] = {"cubes": cubes, "cold_ms": base["cold_ms"] + 1e3 * (time.perf_counter() - t),
                              "stored_bytes": base["stored_bytes"]}
    for r in reps.values():
        h, w = r["cubes"][0].shape[:2]
        r["cache_bytes_per_px"] = sum(c.nbytes for c in r["cubes"]) / (h * w * len(r["cubes"]))
        r["stored_bytes_per_px"] = r["stored_bytes"] / (h * w * len(r["cubes"]))
    return reps


def run(cubes, sc: dict, outputs=None, **kw):
    return compose(cubes, **sc, **({} if outputs is None else {"outputs": outputs}), **kw).outputs()


def timed_ms(fn, *args, **kw) -> float:
    t = time.perf_counter()
    fn(*args, **kw)
    return 1e3 * (time.perf_counter() - t)


def interleaved(fns: dict, repeats: int) -> dict[str, dict[str, float]]:
    """Run every callable once per round, ``repeats`` rounds (so load changes on a shared machine
    hit all alike); ``{name: {"min_ms", "median_ms"}}``. The minimum estimates the uncontended cost
    and is what selection and speed-ups use; the median is reported beside it."""
    times: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(repeats):
        for k, f in fns.items():
            times[k].append(timed_ms(f))
    return {k: {"min_ms": round(min(v), 2), "median_ms": round(statistics.median(v), 2)} for k, v in times.items()}


def band_skip_sweep(cube: np.ndarray, repeats: int) -> list[dict]:
    """Projection only, one float32 cube: ``none`` / ``gather`` (copy the live columns, the old
    code) / ``span`` (slice the live bands' contiguous span, the new code) for n live bands in
    three lines (like an RGB LED)."""
    h, w, b = cube.shape
    flat = cube.reshape(h * w, b)
    rng = np.random.default_rng(0)
    rows = []
    for n in (6, 15, 30, 45, 63):
        width = n // 3  # three lines of `width` bands around bands 11, 27, 47 (450, 530, 630 nm)
        live = np.arange(b) if n >= b else np.unique(np.concatenate(
            [np.arange(c - width // 2, c - width // 2 + width) for c in (11, 27, 47)]))
        m = np.zeros((b, 3), np.float32)
        m[live] = rng.uniform(0.1, 1, (live.size, 3))
        lo, hi = int(live[0]), int(live[-1]) + 1
        t = interleaved({"none": lambda: flat @ m, "gather": lambda: flat[:, live] @ m[live],
                         "span": lambda: flat[:, lo:hi] @ m[lo:hi]}, repeats)
        rows.append({"live_bands": int(live.size), "span_bands": hi - lo,
                     **{f"{k}_ms": v["min_ms"] for k, v in t.items()}})
    return rows


def errors_phase(args, noises, ks, scs, tmp) -> tuple[dict, dict, list, list, dict]:
    """Errors of every representation × scenario × noise level; returns the last cube's data for timing."""
    errs: dict[str, list[dict]] = {}
    per: dict[str, dict] = {}
    quant = []
    for i, noise in enumerate(noises):
        log(f"test cube {args.height}×{args.width}×63, noise {noise:g}: build, store, compress")
        cubes = pl.test_cubes(args.height, args.width, noise, args.seed + i)
        sts = stores(os.path.join(tmp, f"n{i}"), cubes)
        reps = load_reps(sts, ks)
        for sname, sc in scs.items():
            ref = pl.reference(cubes, **sc)
            quant.append(pl.quantisation_de00(ref))
            for rname, rep in reps.items():
                e = pl.errors(run(rep["cubes"], sc), ref)
                errs.setdefault(rname, []).append(e)
                per.setdefault(rname, {})[f"{sname}@noise={noise:g}"] = e
            f16e = per["float16-store"][f"{sname}@noise={noise:g}"]
            log(f"  {sname}: float16-store raw p99 {f16e['raw_p99_rel']:.2e}")
    return errs, per, quant, cubes, {"stores": sts, "reps": reps}


def paths_phase(args, cubes, sts, f16, sc) -> dict:
    """Crop (warm from a cached full frame, cold from the store) and resize (after projection vs
    cubes first) on the float16-store representation, errors against float64 references."""
    paths = {}
    cx, cy, cs = args.width // 3, args.height // 3, min(256, args.height // 2, args.width // 2)
    crop_ref = pl.reference([c[cy:cy + cs, cx:cx + cs] for c in cubes], **sc)
    sliced = [c[cy:cy + cs, cx:cx + cs] for c in f16]
    t = interleaved({"warm": lambda: run(sliced, sc), "cold_read": lambda: [
        sts["float16-store"].read_cube("s", "v", g, crop=(cx, cy, cs, cs)) for g in pl.GROUPS]}, args.repeats)
    paths["crop"] = {"size": [cs, cs], "warm": t["warm"], "cold_read": t["cold_read"],
                     "errors": pl.errors(run(sliced, sc), crop_ref)}
    for f in (2, 4):
        oh, ow = args.height // f, args.width // f
        ref = pl.reference([pl.block_mean(c, f) for c in cubes], **sc)

        def after(ow=ow, oh=oh):
            return run(f16, sc, None, resize=lambda g: np.stack(
                [cv2.resize(x, (ow, oh), interpolation=cv2.INTER_AREA) for x in g]))

        def first(ow=ow, oh=oh):
            return run([cv2.resize(c, (ow, oh), interpolation=cv2.INTER_AREA) for c in f16], sc)

        t = interleaved({"after": after, "first": first}, args.repeats)
        paths[f"resize_1/{f}_raw_after_projection"] = {"size": [ow, oh], "warm": t["after"],
                                                       "errors": pl.errors(after(), ref)}
        paths[f"resize_1/{f}_cubes_first"] = {"size": [ow, oh], "warm": t["first"],
                                              "errors": pl.errors(first(), ref)}
    return paths


def main(argv: list[str] | None = None) -> dict:
    if importlib.util.find_spec("matplotlib") is None:  # checked first: the plot comes after minutes of timing
        raise SystemExit("bench/pareto.py: the plot needs matplotlib; pip install -e '.[bench]' "
                         "(bash scripts/install.sh --test includes it)")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--noise", default="0,0.0067,0.1",
                    help="per-band Monte-Carlo noise levels of the test cubes (0.0067 = the thesis renders)")
    ap.add_argument("--ks", default="3,4,6,8,12,63", help="basis sizes K")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(ROOT / "bench" / "out"))
    args = ap.parse_args(argv)
    if args.height < 64 or args.width < 64 or args.height % 4 or args.width % 4 or args.repeats < 1:
        ap.error("need --height/--width >= 64 and multiples of 4, --repeats >= 1")
    noises = [float(x) for x in args.noise.split(",")]
    ks = [int(k) for k in args.ks.split(",")]
    scs = {n: scenario(n) for n in SCENARIOS}
    with tempfile.TemporaryDirectory() as tmp:
        errs, per, quant, cubes, last = errors_phase(args, noises, ks, scs, tmp)
        reps = last["reps"]
        # Timing on the last cube (noise does not change the work) and two broadband scenarios
        # (band skipping, the only scenario-dependent work, is timed on its own below).
        log("timing: warm composition, interleaved repeats")
        fns = {}
        for s in TIMED_SCENARIOS:
            fns[("reference-float64", "all", s)] = lambda s=s: pl.reference(cubes, **scs[s])
            for r in reps:
                for o, outs in TIMED_OUTPUTS.items():
                    fns[(r, o, s)] = lambda r=r, s=s, outs=outs: run(reps[r]["cubes"], scs[s], outs)
        t = interleaved(fns, args.repeats)

        def t_of(r: str, o: str = "all", stat: str = "min_ms") -> float:
            return statistics.median([t[(r, o, s)][stat] for s in TIMED_SCENARIOS])

        log("band skipping")
        nb = "narrowRGB+blueLED/Nikon"
        f16 = reps["float16-store"]["cubes"]
        sk = interleaved({"on": lambda: run(f16, scs[nb]), "off": lambda: run(f16, scs[nb], None, skip_bands=False)},
                         args.repeats)
        sw = scs[nb]["sensor"].weights()
        live = [int(np.count_nonzero(np.any(m != 0, axis=1))) for m in
                raw_weights(band_scales(scs[nb]["illuminants"], scs[nb]["emissions"], INTENSITIES), sw)]
        band_skip = {"scenario": nb, "live_bands_per_group": live, "compose_all": sk,
                     "projection_sweep_min_ms": band_skip_sweep(f16[0], args.repeats)}
        log("crop and resize paths")
        paths = paths_phase(args, cubes, last["stores"], f16, scs["FL11+D65/Nikon"])
        paths["full_frame"] = {"size": [args.width, args.height], "warm": t[("float16-store", "all", "FL11+D65/Nikon")],
                               "cold_read_ms": round(reps["float16-store"]["cold_ms"], 1)}
    # -- summary, selection, plot -------------------------------------------------------------
    ref_ms = t_of("reference-float64")
    settings = {}
    for r, rep in reps.items():
        w = pl.worst(errs[r])
        ok = all(w[k] <= tol for k, tol in TOLERANCES.items())
        settings[r] = {"compose_all_ms": round(t_of(r), 2),
                       "compose_all_median_ms": round(t_of(r, stat="median_ms"), 2),
                       "compose_raw_gain_ms": round(t_of(r, "raw+gain"), 2),
                       "cold_read_prepare_ms": round(rep["cold_ms"], 1),
                       "cache_bytes_per_px": round(rep["cache_bytes_per_px"], 1),
                       "stored_bytes_per_px": round(rep["stored_bytes_per_px"], 1),
                       "speedup_vs_reference": round(ref_ms / t_of(r), 2),
                       "speedup_vs_float32_store": round(t_of("float32-store") / t_of(r), 3),
                       "within_tolerance": ok, "worst": {k: float(f"{v:.4g}") for k, v in w.items()}}
    # basis-63 (K = all bands) is a control: the exact path plus a rotation, not a compression.
    ok = {r: s for r, s in settings.items() if s["within_tolerance"] and r != "basis-63"}
    fastest = min(s["compose_all_ms"] for s in ok.values())
    tied = [r for r, s in ok.items() if s["compose_all_ms"] <= 1.05 * fastest]
    chosen = min(tied, key=lambda r: (settings[r]["cache_bytes_per_px"], settings[r]["stored_bytes_per_px"],
                                      settings[r]["cold_read_prepare_ms"]))
    c = settings[chosen]
    defaults = {"setting": chosen, "spectral_basis": None if not chosen.startswith("basis") else int(chosen[6:]),
                "skip_bands": True, "gain_angular_deg": c["worst"]["gain_angular_deg"],
                "raw_p99_rel": c["worst"]["raw_p99_rel"], "srgb_de00_p99": c["worst"]["srgb_de00_p99"],
                "speedup_vs_reference": c["speedup_vs_reference"], "compose_all_ms": c["compose_all_ms"],
                "tied_within_5pct": tied}
    plot_path = plot(settings, ref_ms, paths, Path(args.out))
    return {
        "benchmark": "pareto", "shape": [args.height, args.width, 63], "noise_levels": noises,
        "scenarios": {k: list(v) for k, v in SCENARIOS.items()}, "timed_scenarios": list(TIMED_SCENARIOS),
        "intensities": INTENSITIES.tolist(), "repeats": args.repeats, "tolerances": TOLERANCES,
        "srgb_8bit_quantisation_de00_p99": round(float(np.median(quant)), 4),
        "reference_float64_ms": round(ref_ms, 2), "settings": settings, "band_skip": band_skip,
        "paths": jsonable(paths), "per_scenario_errors": jsonable(per), "plot": str(plot_path),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
                    "platform": platform.platform(), "load_avg": os.getloadavg()},
        "defaults": defaults,
    }


def jsonable(x):
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, float):
        return float(f"{x:.4g}")
    return x


def plot(settings: dict, ref_ms: float, paths: dict, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2, 2, figsize=(13, 9))
    axes = axes.ravel()
    for ax, key in zip(axes, ("raw_p99_rel", "gain_angular_deg", "srgb_de00_p99")):
        for name, s in settings.items():
            y = max(s["worst"][key], 1e-9)
            ax.scatter(s["compose_all_ms"], y, c="tab:green" if s["within_tolerance"] else "tab:red", zorder=3)
            ax.annotate(name, (s["compose_all_ms"], y), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.scatter(ref_ms, 1e-9, marker="*", s=120, c="k")
        ax.annotate("float64 reference", (ref_ms, 1e-9), fontsize=7, xytext=(-40, 6), textcoords="offset points")
        ax.axhline(TOLERANCES[key], ls="--", c="gray", lw=1)
        ax.set(yscale="log", xlabel="warm compose time, full frame, all outputs (ms, min of interleaved repeats)",
               ylabel="worst case over scenarios × noise levels", title=f"{key} (tolerance dashed)")
        ax.grid(alpha=0.3)
    ax = axes[3]
    names = list(paths)
    ax.barh(range(len(names)), [paths[n]["warm"]["min_ms"] for n in names], color="tab:blue")
    ax.set_yticks(range(len(names)), [f"{n} {paths[n]['size'][0]}×{paths[n]['size'][1]}" for n in names], fontsize=7)
    for i, n in enumerate(names):
        e = paths[n].get("errors")
        ax.annotate(f"raw p99 {e['raw_p99_rel']:.1e}" if e else "", (paths[n]["warm"]["min_ms"], i), fontsize=7,
                    xytext=(3, -3), textcoords="offset points")
    ax.set(xlabel="warm compose time (ms), float16-store cubes, FL11+D65", title="crop and resize paths")
    fig.suptitle("illumix composition: time vs error against a float64 reference "
                 "(green: within tolerance, red: outside)")
    fig.tight_layout()
    path = out / "pareto.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    res = main()
    d = res["defaults"]
    log(f"defaults: {d['setting']} (gain {d['gain_angular_deg']:.3g}°, raw p99 {d['raw_p99_rel']:.3g}, "
        f"×{d['speedup_vs_reference']} vs float64 reference)")
    print(json.dumps(res))
