"""Helpers of ``bench/denoise.py``: cached renders, composition to camera raw, the relative R/G, B/G
error (thesis eq. 4.1), pixel classes (edges, flat, fine texture), power-law fits, timing, the
shading-guide ablation filter, Open Image Denoise and the two plots. See ``bench/denoise.py``'s
docstring for what every number means."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

#: Relative R/G, B/G errors above this (%) are clipped: a test pixel with G <= 0 has no chroma.
ERR_CAP_PCT = 1e4


# ---------------------------------------------------------------------------------------------
# Renders through an .npz cache


def _cache_name(view: str, res: tuple[int, int], spp: int, seed: int, groups: Sequence[str],
                boost: tuple | None = None) -> str:
    """The cache file of a render; named by the renderer's default method too, so a change of
    default (issue 17: all-bands paths) never reads another renderer's cubes, and by the targeted
    extra paths' factor, reach and mask when boosted (``boost``: ``(mask, factor, reach)``)."""
    from illumix.renderer_jobs.render_settings import RenderSettings

    d = RenderSettings()
    method = f"{d.wavelengths}-{d.sampler}-b{d.bands_per_path}" if d.wavelengths == "all-bands" else d.wavelengths
    tag = ""
    if boost is not None:  # the mask too: it follows the guides and the denoiser's joint image
        import hashlib

        digest = hashlib.sha1(np.packbits(np.asarray(boost[0], bool)).tobytes()).hexdigest()[:8]
        tag = f"_boost{boost[1]}r{boost[2]:g}m{digest}"
    return f"{view}_{res[0]}x{res[1]}_{spp}spp_seed{seed}_{'+'.join(groups)}_{method}{tag}.npz"


def cached_render(scene, view: str, groups: str | Sequence[str], spp: int, seed: int, res: tuple[int, int],
                  cache: Path | None, log: Callable[[str], None], boost: tuple | None = None) -> dict:
    """Transport cube, illumination cube and emission of ``groups`` (one group, or several rendered
    together) at ``spp``/``seed`` with the renderer's default settings otherwise; read from
    ``cache`` when present (``cache=None``: always render, and overwrite nothing).

    Returns ``{"cube", "illumination", "emission", "cpu_s", "wall_s", "cached"}``; ``cpu_s`` is the
    process CPU time of the render when it was made (also for a cached one). ``boost``:
    ``(mask (H, W), factor, reach)`` targeted extra paths (:mod:`renderer_jobs.mitsuba.boost_paths`); None:
    plain (no pixel gets more than ``spp``). With a boost the record has ``"targeted_paths"`` too."""
    from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube

    gl = [groups] if isinstance(groups, str) else list(groups)
    path = cache / _cache_name(view, res, spp, seed, gl, boost) if cache is not None else None
    if path is not None and path.exists():
        with np.load(path) as z:
            return {"cube": z["cube"], "illumination": z["illumination"], "emission": z["emission"],
                    "cpu_s": float(z["cpu_s"]), "wall_s": float(z["wall_s"]), "cached": True,
                    **({"targeted_paths": json.loads(str(z["targeted_paths"]))} if "targeted_paths" in z.files else {})}
    w0, c0 = time.perf_counter(), time.process_time()
    settings = RenderSettings(spp=spp, seed=seed, **({"boost_factor": boost[1], "boost_reach": boost[2]}
                                                      if boost is not None else {"boost_factor": 1}))
    r = render_cube(scene, view, gl[0] if len(gl) == 1 else gl, settings,
                    boost_mask=boost[0] if boost is not None else None)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    log(f"  rendered {'+'.join(gl)} {spp} spp seed {seed}{' boosted' if boost else ''}: {cpu:.1f} s CPU, "
        f"{wall:.1f} s wall")
    out = {"cube": r.cube, "illumination": r.illumination, "emission": np.asarray(r.emission, np.float64),
           "cpu_s": cpu, "wall_s": wall, "cached": False}
    if "targeted_paths" in r.stats:
        out["targeted_paths"] = r.stats["targeted_paths"]
    if path is not None:
        _save(path, {k: (json.dumps(v) if k == "targeted_paths" else v) for k, v in out.items() if k != "cached"})
    return out


def _save(path: Path, arrays: dict) -> None:
    """``np.savez`` through a temporary file: an interrupted run leaves no half-written cache."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(path)


def multijitter_count(n: int) -> int:
    """The samples per pixel Mitsuba's ``multijitter`` sampler renders when asked for ``n``: an
    ``r × ⌈n/r⌉`` grid with ``r = ⌊√n⌋`` (checked against Mitsuba for n = 1…299; e.g. 21–23 → 24,
    32 → 35)."""
    r = int(np.sqrt(n))
    while r * r > n:
        r -= 1
    return r * -(-n // r)


def exact_spp_bracket(target: float, sets: int = 4) -> tuple[int, int]:
    """The largest spp ≤ ``target`` and the smallest ≥ it that split into ``sets`` band sets the
    renderer's default sampler (multijitter) renders exactly."""
    from illumix.renderer_jobs.render_settings import RenderSettings

    assert RenderSettings().sampler == "multijitter", "exact_spp_bracket knows multijitter's rule only"
    ok = [n for n in range(1, int(target / sets) + 64) if multijitter_count(n) == n]
    lo = max([n for n in ok if n * sets <= target], default=ok[0])
    hi = min(n for n in ok if n * sets >= target)
    return lo * sets, hi * sets


def cached_aovs(scene, view: str, res: tuple[int, int], seed: int, aov_spp: int, cache: Path | None,
                log: Callable[[str], None], straddle: bool = True) -> dict:
    """The view's geometry AOVs (``render_aovs``, ``aov_spp`` jittered primary rays per pixel), cached.
    ``straddle``: with the ``straddle`` AOV, traced again alone when the cache's was made by another
    rule (the guides' AOVs; the clean ones for pixel classes need none)."""
    from illumix.renderer_jobs.mitsuba import denoise_guides as dg
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs
    from illumix.renderer_jobs.mitsuba.render import RenderSettings

    path = cache / f"{view}_{res[0]}x{res[1]}_aovs_seed{seed}_aovspp{aov_spp}.npz" if cache is not None else None
    rule = np.float64([dg.STRADDLE_RAYS, dg.STRADDLE_COS, dg.STRADDLE_LOG_DEPTH, dg.FLAT_LOG_DEPTH, dg.FLAT_DEGREES])
    if path is not None and path.exists():
        with np.load(path) as z:
            cached = {k: z[k] for k in z.files} if "albedo_bands" in z.files else None  # older: render again
        if cached is not None and straddle and not np.array_equal(cached.get("straddle_rule"), rule):
            from illumix.renderer_jobs.mitsuba.trace import Tracer

            cached["straddle"], cached["straddle_rule"] = dg.straddle(Tracer(scene, view, None, res)), rule
            _save(path, cached)
        if cached is not None:
            return cached
    c0 = time.process_time()
    aovs = render_aovs(scene, view, RenderSettings(spp=64, seed=seed, aov_spp=aov_spp,
                                                   **({} if straddle else {"boost_factor": 1})))
    aovs["cpu_s"] = np.float64(time.process_time() - c0)
    if straddle:
        aovs["straddle_rule"] = rule
    log(f"  rendered AOVs ({aov_spp} rays per pixel): {aovs['cpu_s']:.1f} s CPU")
    if path is not None:
        _save(path, aovs)
    return aovs


def cached_direct(scene, view: str, group: str, res: tuple[int, int], seed: int, cache: Path | None,
                  log: Callable[[str], None]) -> dict:
    """A group's direct-light guide, the light glass keeps from each pixel, the guide's own noise
    and the light as the camera sees it (``renderer_jobs.mitsuba.denoise_guides.direct_guide(behind_glass=True)``),
    cached: ``{"direct", "behind", "noise", "seen"}`` ``(H, W)`` and ``"cpu_s"``."""
    from illumix.renderer_jobs.mitsuba.denoise_guides import DIRECT_SAMPLES, direct_guide

    name = f"{view}_{res[0]}x{res[1]}_direct_{group}_seed{seed}_n{DIRECT_SAMPLES}x2_glass_seen.npz"
    path = cache / name if cache is not None else None
    keys = ("direct", "behind", "noise", "seen")
    if path is not None and path.exists():
        with np.load(path) as z:
            return {**{k: z[k] for k in keys}, "cpu_s": float(z["cpu_s"])}
    c0 = time.process_time()
    g = direct_guide(scene, view, group, res, seed, behind_glass=True)
    out = {"direct": g.direct, "behind": g.behind, "noise": g.noise, "seen": g.seen, "cpu_s": time.process_time() - c0}
    log(f"  traced the direct-light guide of {group}: {out['cpu_s']:.2f} s CPU")
    if path is not None:
        _save(path, out)
    return out


def group_guides(guides, direct: dict):
    """``guides`` with a group's :func:`cached_direct` record (its direct light, what glass keeps, the
    guide's noise and the light as seen). No cube noise: the direct-light test's fixed tolerance
    (the renderer's noise-aware one is measured by ``bench/fidelity.py``)."""
    return guides.with_direct(direct["direct"], direct.get("behind"), direct.get("noise"), direct.get("seen"))


def run_denoise(cube: np.ndarray, guides, name: str, direct: dict | None, kind: str = "transport") -> np.ndarray:
    """``retarget.denoise.denoise`` with the group's direct-light guides (a :func:`cached_direct`
    record) where the method takes them."""
    from illumix.retarget.denoise import denoise, method_guides

    return denoise(cube, group_guides(guides, direct) if "direct" in method_guides(name) else guides, name, kind=kind)


def mean_render(renders: Sequence[dict]) -> dict:
    """The mean of independent renders of the same groups (cube and illumination)."""
    return {"cube": np.mean([r["cube"] for r in renders], axis=0, dtype=np.float64).astype(np.float32),
            "illumination": np.mean([r["illumination"] for r in renders], axis=0,
                                    dtype=np.float64).astype(np.float32),
            "emission": renders[0]["emission"]}


# ---------------------------------------------------------------------------------------------
# Composition to camera raw


def composition_weights(sensor: str, illuminants: Sequence[str] | None, emissions: Sequence[np.ndarray]
                        ) -> np.ndarray:
    """``M (G, bands, 3)`` float32 of ``raw = Σ_g cube_g @ M_g``: each group relit to its illuminant
    (``retarget.relight``, intensity 1), projected through the sensor. ``illuminants=None``: every
    group as rendered (its own emission, i.e. scale 1)."""
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.relight import band_scales, raw_weights
    from illumix.retarget.sensors import get_sensor

    s = get_sensor(sensor)
    em = np.stack([np.asarray(e, np.float64) for e in emissions])
    spd = em if illuminants is None else np.stack([illuminant_spd(n, s.grid) for n in illuminants])
    return raw_weights(band_scales(spd, em, np.ones(len(em))), s.weights()).astype(np.float32)


def compose(cubes: Sequence[np.ndarray], m: np.ndarray) -> np.ndarray:
    """``Σ_g cube_g @ M_g`` → ``(H, W, 3)`` float32 camera raw."""
    h, w, nb = cubes[0].shape
    return sum(np.asarray(c, np.float32).reshape(-1, nb) @ mg for c, mg in zip(cubes, m)).reshape(h, w, 3)


# ---------------------------------------------------------------------------------------------
# Errors


def rel_chroma_err(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per pixel ``|c_x − c_ref| / |c_ref| × 100`` (%) with ``c = (R/G, B/G)`` (thesis eq. 4.1);
    pixels where the test's G is not positive get :data:`ERR_CAP_PCT`."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cx = np.stack([x[..., 0] / x[..., 1], x[..., 2] / x[..., 1]], -1).astype(np.float64)
        cr = np.stack([ref[..., 0] / ref[..., 1], ref[..., 2] / ref[..., 1]], -1).astype(np.float64)
        e = np.linalg.norm(cx - cr, axis=-1) / np.linalg.norm(cr, axis=-1) * 100.0
    return np.minimum(np.nan_to_num(e, nan=ERR_CAP_PCT, posinf=ERR_CAP_PCT), ERR_CAP_PCT)


def err_summary(err: np.ndarray, mask: np.ndarray) -> dict:
    """Median and 99.3rd percentile (%) of an error map over ``mask``."""
    e = err[mask]
    if not e.size:
        return {"median_rel_pct": None, "p99_3_rel_pct": None, "pixels": 0}
    return {"median_rel_pct": round(float(np.median(e)), 4), "p99_3_rel_pct": round(float(np.percentile(e, 99.3)), 4),
            "pixels": int(e.size)}


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (°) between RGB vectors per pixel; NaN where either is zero."""
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    ok = (na > 0) & (nb > 0)
    c = np.where(ok, (a * b).sum(-1) / np.where(ok, na * nb, 1.0), np.nan)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def angle_summary(ang: np.ndarray, mask: np.ndarray) -> dict:
    a = ang[mask]
    a = a[np.isfinite(a)]
    if not a.size:
        return {"median": None, "p99": None, "pixels": 0}
    return {"median": round(float(np.median(a)), 4), "p99": round(float(np.percentile(a, 99)), 4),
            "pixels": int(a.size)}


def floor_corrected(e: float | None, floor: float) -> float | None:
    """``√(e² − floor²)``: the error against the truth if test and reference errors add in quadrature
    (independent, Rayleigh-like chroma errors); None when ``e ≤ floor``."""
    if e is None or e <= floor:
        return None
    return round(float(np.sqrt(e * e - floor * floor)), 4)


# ---------------------------------------------------------------------------------------------
# Pixel classes


def flat_pixels(aovs: dict, valid: np.ndarray, albedo_tol: float = 0.03) -> np.ndarray:
    """Pixels whose 3×3 neighbourhood shares normal and hit (``bench/render_lib.flat_mask`` with the
    albedo test switched off) and whose albedo differs from every neighbour's by less than
    ``albedo_tol`` in R, G and B, ``& valid``. ``flat_mask``'s own albedo test (1e-3) is meant for
    exact albedos; the albedo AOV is a Monte-Carlo estimate over wavelengths (noise ≈ 0.003 at 1024
    rays per pixel, ≈ 0.05 at 16), so here it is tested with a tolerance on a many-ray AOV."""
    from render_lib import flat_mask

    geo = flat_mask({"normal": aovs["normal"], "mask": aovs["mask"], "albedo": np.zeros_like(aovs["albedo"])})
    al = aovs["albedo"]
    ok = np.ones(valid.shape, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ok &= np.all(np.abs(np.roll(np.roll(al, dy, 0), dx, 1) - al) < albedo_tol, axis=-1)
    return geo & ok & valid


def texture_mask(albedo: np.ndarray, valid: np.ndarray, std_threshold: float = 0.05,
                 density: float = 0.75) -> tuple[np.ndarray, np.ndarray]:
    """Fine-texture pixels and the colour chart among them.

    A pixel is *busy* when the local standard deviation of the albedo AOV over 5×5 (the largest of
    R, G, B) exceeds ``std_threshold``; *texture* = pixels whose 9×9 neighbourhood is more than
    ``density`` busy (a lone material edge fills about half of it, the chart's 24 patches nearly all
    of it). The chart is texture's largest connected component. Both ``& valid``."""
    from scipy.ndimage import label, uniform_filter

    a = albedo.astype(np.float64)
    mu = uniform_filter(a, (5, 5, 1))
    sd = np.sqrt(np.maximum(uniform_filter(a * a, (5, 5, 1)) - mu * mu, 0.0)).max(-1)
    busy = sd > std_threshold
    tex = (uniform_filter(busy.astype(np.float64), 9) > density) & valid
    lab, n = label(tex)
    if n == 0:
        return tex, tex
    sizes = np.bincount(lab.ravel())[1:]
    return tex, lab == (1 + int(np.argmax(sizes)))


def bbox(mask: np.ndarray) -> list[int] | None:
    """``[x0, y0, x1, y1]`` (inclusive) of a mask's pixels."""
    ys, xs = np.nonzero(mask)
    return [int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())] if ys.size else None


# ---------------------------------------------------------------------------------------------
# Power law (error against spp)


def power_fit(spps: Sequence[float], errs: Sequence[float]) -> tuple[float, float] | None:
    """Least-squares ``log err = slope · log spp + intercept`` → ``(slope, intercept)``."""
    x, y = np.asarray(spps, float), np.asarray(errs, float)
    ok = (x > 0) & (y > 0) & np.isfinite(y)
    if ok.sum() < 2:
        return None
    s, b = np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)
    return float(s), float(b)


def equivalent_spp(spps: Sequence[float], errs: Sequence[float], target: float | None) -> dict:
    """The spp at which the fitted power law reaches ``target``; ``extrapolated`` when outside the
    measured spp range."""
    fit = power_fit(spps, errs)
    if fit is None or target is None or target <= 0 or fit[0] >= 0:
        return {"spp": None, "slope": fit[0] if fit else None, "extrapolated": None}
    m = float(np.exp((np.log(target) - fit[1]) / fit[0]))
    return {"spp": round(m, 1), "slope": round(fit[0], 4),
            "extrapolated": bool(not min(spps) <= m <= max(spps))}


# ---------------------------------------------------------------------------------------------
# Timing


def best_ms(fn: Callable[[], object], repeats: int = 3) -> float:
    """Best of ``repeats`` wall-clock runs (time.perf_counter), in ms."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return round(best * 1e3, 2)


def upsample_nearest(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Nearest-neighbour resize of an ``(H, W, …)`` array to ``shape`` (synthetic large guides)."""
    h, w = a.shape[:2]
    ys = np.arange(shape[0]) * h // shape[0]
    xs = np.arange(shape[1]) * w // shape[1]
    return a[ys][:, xs]


# ---------------------------------------------------------------------------------------------
# Ablation: the domain transform with a shading channel in its joint image


def shading_joint(guides, shading_u: np.ndarray, sigma_albedo: float, sigma_normal: float,
                  sigma_shading: float, prefilter_sigma: float) -> np.ndarray:
    """Joint image ``(H, W, 4)`` of the ablation: albedo G / σa, (albedo R − B) / σa, the
    ``dt-guides`` normal channel (with its emitter/background offsets) / σn, and
    ``log(S + ε)/σs`` with ``S`` the summed illumination image ``shading_u`` pre-filtered by the
    default ``dt-guides`` operator and ``ε = 10⁻³ max S``. OpenCV takes at most 4 channels, so the
    three albedo channels become two."""
    from illumix.retarget.denoise import dt_filter, dt_guide_image

    g = dt_guide_image(guides, sigma_albedo, sigma_normal)
    s = dt_filter(shading_u[..., None].astype(np.float32), dt_guide_image(guides, 0.05, 0.2),
                  prefilter_sigma)[..., 0]
    s = np.log(np.maximum(s, 0.0) + 1e-3 * s.max())
    return np.stack([g[..., 1], g[..., 0] - g[..., 2], g[..., 3], s / sigma_shading], -1).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Intel Open Image Denoise (not linear: only on the composed raw)


def oidn(raw: np.ndarray, albedo: np.ndarray, normal: np.ndarray, clean_aux: bool) -> np.ndarray:
    """``pyoidn.denoise`` (RT filter, HDR, quality high) of a raw image with albedo and normal."""
    import pyoidn

    def c32(x):
        return np.ascontiguousarray(x, np.float32)

    return pyoidn.denoise(c32(raw), c32(np.clip(albedo, 0, 1)), c32(np.clip(normal, -1, 1)), hdr=True,
                          clean_aux=clean_aux, quality="high")


# ---------------------------------------------------------------------------------------------
# Plots


def _show(x: np.ndarray, scale: float) -> np.ndarray:
    return np.clip(np.maximum(x, 0) / scale, 0, 1) ** (1 / 2.2)


def plot_maps(path: Path, ref: np.ndarray, und: np.ndarray, den: np.ndarray, e_und: np.ndarray, e_den: np.ndarray,
              e_floor: np.ndarray, valid: np.ndarray, titles: dict) -> str | None:
    """2×3: reference / undenoised / denoised raw (gamma 2.2, same scale), and their relative
    R/G, B/G error maps plus the reference's own floor map (grey: not a valid pixel)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    wb = ref[valid].mean(0)
    wb = wb[1] / wb  # grey-world white balance of the reference, applied to all three images
    scale = float(np.percentile(ref[..., 1][valid], 99)) * 1.2
    cmap = matplotlib.colormaps["viridis"].copy()
    cmap.set_bad("0.75")
    fig, ax = plt.subplots(2, 3, figsize=(15, 8.2))
    for a, img, t in zip(ax[0], (ref, und, den), ("reference", "undenoised", "denoised")):
        a.imshow(_show(img * wb, scale))
        a.set_title(titles[t], fontsize=9)
    for a, e, t in zip(ax[1], (e_und, e_den, e_floor), ("err_undenoised", "err_denoised", "err_floor")):
        im = a.imshow(np.where(valid, e, np.nan), cmap=cmap, vmin=0, vmax=8)
        a.set_title(titles[t], fontsize=9)
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    fig.colorbar(im, ax=ax[1].tolist(), label="relative R/G, B/G error (%)", shrink=0.9)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return str(path)


def plot_curve(path: Path, curve: list[dict], denoised: dict, floor: dict, goals: dict, spp: int,
               fits: dict) -> str | None:
    """Undenoised error against spp (median, p99.3; log-log, with the fitted power laws), the
    denoised points at ``spp`` and their equivalent spp, the reference floor and the goals."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(8, 5.5))
    xs = np.array([c["spp"] for c in curve], float)
    eqs = [d[f"equivalent_{k}"] for d in denoised.values() for k in ("median_rel_pct", "p99_3_rel_pct")
           if d.get(f"equivalent_{k}")]
    lo, hi = min([xs.min(), *eqs]) / 1.2, max([xs.max(), *eqs]) * 1.2
    for stat, colour, label in (("median_rel_pct", "tab:blue", "median"), ("p99_3_rel_pct", "tab:red", "p99.3")):
        ax.plot(xs, [c[stat] for c in curve], "o-", color=colour, label=f"undenoised {label}")
        fit = fits.get(stat)
        if fit:
            xx = np.geomspace(lo, hi, 50)
            ax.plot(xx, np.exp(fit["intercept"]) * xx ** fit["slope"], ":", color=colour,
                    label=f"fit {label}: slope {fit['slope']:.2f}")
        for name, d in denoised.items():
            ax.plot([spp], [d[stat]], "*" if d.get("default") else "P", color=colour, markersize=12,
                    markeredgecolor="k", label=f"{d['label']} {label} @ {spp} spp")
            m = d.get(f"equivalent_{stat}")
            if m:
                ax.plot([spp, m], [d[stat]] * 2, "--", color=colour, alpha=0.5)
                ax.plot([m], [d[stat]], "o", mfc="none", color=colour)
        ax.axhline(floor[stat], color=colour, alpha=0.4, lw=4, label=f"reference floor {label}")
        ax.axhline(goals[stat], color=colour, alpha=0.8, lw=1, ls="-.", label=f"goal {label}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("paths per pixel")
    ax.set_ylabel("relative R/G, B/G error against the reference (%)")
    ax.set_title("undenoised error against spp, and the denoised point at the default spp", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return str(path)


def dumps(doc: dict) -> str:
    return json.dumps(doc, indent=1)
