"""Helpers of ``bench/render.py``: noise statistics of seed pairs, timing, machine info, and the
benchmark's scene variants (the demo room with a closed cupboard, an open scene, a narrow-band group)."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numpy as np


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
    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.renderer_jobs.mitsuba.light_probe import probe_group

    probe_group(scene, view, group, mr.RenderSettings(spp=32, seed=99))
    mr.render_cube(scene, view, group, mr.RenderSettings(spp=32, seed=99, wavelengths=mode,
                                                         adaptive=mode != "all-bands"))


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


NARROW_BAND = {"wavelengths": [380, 539.9, 540, 560, 560.1, 780], "values": [0, 0, 1, 1, 0, 0]}


def open_scene_doc(res: tuple[int, int]) -> dict:
    """A floor and a back wall under a ceiling panel, seen from above so that about 2/3 of the
    pixels see nothing: the case where skipping background pixels could pay."""
    from illumix.scene.demo import frame_matrix as fm

    return {"name": "open", "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.7}}},
            "shapes": [{"name": "floor", "type": "rectangle", "material": "white",
                        "transform": {"matrix": fm((0, 0, 0), (0, 1, 0), (0, 0, -1), (2, 2))}},
                       {"name": "back", "type": "rectangle", "material": "white",
                        "transform": {"matrix": fm((0, 1, -1), (0, 0, 1), (0, 1, 0), (2, 2))}},
                       {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 3.0},
                        "transform": {"matrix": fm((0, 1.9, -0.5), (0, -1, 0), (0, 0, -1), (0.4, 0.4))}}],
            "views": [{"name": "cam", "origin": (0, 1.6, 2.5), "target": (0, 1.4, -1), "fov": 60,
                       "resolution": list(res)}], "max_depth": 6}


def plot_curves(doc: dict, path: Path) -> Path | None:
    """Noise against spp and against CPU seconds (log-log), per light group: raw G RMS (solid) and
    worst-block p99 (dashed) for uniform and adaptive spp, noise-target renders as points at their
    mean spp. Returns the PNG's path, or None without matplotlib (the ``bench`` extra)."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, targets = doc.get("results", []), doc.get("noise_target", [])
    groups = sorted({r["group"] for r in rows})
    fig, axes = plt.subplots(len(groups), 2, figsize=(12, 4.5 * len(groups)), squeeze=False)
    for gi, group in enumerate(groups):
        for ax, x in zip(axes[gi], ("spp", "cpu_seconds")):
            for sampling, colour in (("uniform", "tab:blue"), ("adaptive", "tab:orange")):
                rs = sorted((r for r in rows if r["group"] == group and r["sampling"] == sampling),
                            key=lambda r: r["spp"])
                for stat, style in (("raw_G_rms", "-"), ("raw_G_block_p99", "--")):
                    ax.plot([r[x] for r in rs], [100 * r[stat] for r in rs], style, marker="o", color=colour,
                            label=f"{sampling} {stat}")
            for t in (t for t in targets if t["group"] == group):
                xv = t["mean_spp"] if x == "spp" else t["cpu_seconds"]
                for stat, marker in (("raw_G_rms", "*"), ("raw_G_block_p99", "P")):
                    ax.plot([xv], [100 * t[stat]], marker, color="tab:green", markersize=11,
                            label=f"target {t['noise_target']:g} {stat}")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("paths per pixel (mean)" if x == "spp" else "CPU seconds per cube")
            ax.set_ylabel("relative raw G noise (%)")
            ax.set_title(f"{group}, {rows[0]['size']}: noise against {'spp' if x == 'spp' else 'CPU time'}")
            ax.grid(True, which="both", alpha=0.3)
        axes[gi][0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
