"""Denoising benchmark: the guide-only linear denoisers of ``retarget.denoise`` against a converged
reference, on the demo room's mixed-illuminant composition.

Scene and composition
---------------------
The demo room (seed 0), view ``--view`` (front) at ``--resolution`` (160×120), rendered in-process
with the renderer's default settings (all-bands paths since issue 17, illumination cubes),
each render cached as ``.npz`` under ``bench/out/denoise-cache/`` by (view, resolution, spp, seed,
groups, the default renderer method) (``--no-cache`` renders again and writes nothing). The *test* is group ``daylight`` relit
by illuminant A plus group ``ceiling`` relit by D65 (desk off), projected to camera raw through the
sensor ``--sensor`` (Nikon 5100 (NPL)): ``raw = Σ_g T_g @ M_g`` with ``M_g`` from
``retarget.relight.band_scales``/``raw_weights``. Seeds: test ``--seed`` (0; also its direct-light
guides' seed, as in the renderer) at ``--spp`` (64), error curve 1, 2, … (one per extra spp),
reference ``100 … 100+K−1``, the thesis protocol's mixed render 5, the equal-path uniform renders 7.

Reference and its own floor
---------------------------
The reference is the mean of K = ``--ref-seeds`` (4) independent renders at ``--ref-spp`` (1024)
per group (``reference_spp`` = K × ref-spp = 4096, 64× the test). A reference carries noise of its
own: two independent 1024-spp renders differ by about 0.7 % median, so no error below that could be
seen against a single one. The floor is measured from the reference's two halves A (seeds
100 … 100+K/2−1) and B (the rest): the map ``err(A, B)`` (raw of A against raw of B, same metric)
has the noise of A and B added, i.e. twice the noise of the full mean ``(A + B)/2``; the reported
floor is ``err(A, B)/2`` — the error the full reference itself has against the truth
(``reference_floor_{median,p99_3}_rel_pct``; ``err(A, B)`` itself is under
``reference_floor.halves_*``, ``err(A, B)/√2`` would be the floor of one half). A test with error
``e`` against the truth measures ≈ ``√(e² + floor²)`` against the reference (errors of independent
renders add in quadrature), so ``*_floor_corrected`` = ``√(measured² − floor²)`` estimates the
error against the truth (None when measured ≤ floor).

The metric (thesis eq. 4.1)
---------------------------
Per pixel, ``c = (R/G, B/G)`` of camera raw; ``err = |c_x − c_ref| / |c_ref| × 100 %``. Valid
pixels: the AOV hit mask, not an emitter, reference G > 10⁻⁴ × its maximum. Reported: the median
and the 99.3rd percentile over valid pixels (``median_rel_pct``, ``p99_3_rel_pct``). Goals: median
≤ 0.5 %, p99.3 ≤ 2.5 % of the default method against the reference (``goal_met``; as measured,
floor included).

Guides and pixel classes
------------------------
Guides: ``Guides.from_aovs`` of the view's AOVs at ``--aov-spp`` (16) rays per pixel, seed 0. The
albedo AOV is a Monte-Carlo estimate over wavelengths (each ray samples one wavelength per 100-nm
band), so at 16 rays it is noisy (``guide_noise.albedo_rms_vs_clean``). Pixel classes come from a
*clean* AOV set at ``--clean-aov-spp`` (1024) rays: *flat* = 3×3 neighbourhood with the same normal
and hit (``render_lib.flat_mask``) and albedo within 0.03 of every neighbour; *edges* = valid and
not flat (geometry and material edges, curved surfaces). ``render_lib.flat_mask`` itself (albedo
within 1e-3) is reported as ``classes.render_lib_flat_mask_pixels``: with a sampled albedo it keeps
only the spectrally flat ceiling. *Texture*: 9×9 neighbourhoods more than 75 % "busy" (5×5 local
std of the clean albedo > 0.05); *chart*: its largest connected component (the ColorChecker; its
bounding box is reported).

What is reported (JSON keys)
----------------------------
1. ``methods.<name>`` for ``none`` and every method of ``DENOISE_METHODS`` at default parameters
   (``describe``): each group's 64-spp transport cube denoised separately (``denoise(cube, guides,
   method)``), then composed; ``median_rel_pct``/``p99_3_rel_pct`` against the reference (and their
   floor-corrected values), per class (``edges``, ``flat``, ``texture``, ``chart``),
   ``projection_commutes_max_rel`` (``max|D(raw) − raw(D(T))| / max|raw|``: the linearity check).
   Top level: ``default_method`` and its ``median_rel_pct``/``p99_3_rel_pct``,
   ``undenoised_*`` (= ``none``), ``reference_floor_*``, ``reference_spp``, ``goal_*``.
2. ``thesis_protocol`` (thesis Fig. 4.1): the sum of the two single-group renders at ``--spp``, each
   as rendered (its own emission, scale 1), against ONE render of both groups together at
   ``--thesis-factor`` (16) × ``--spp`` (seed 5), undenoised and denoised (default method; all under
   ``denoised_by_method``), beside the thesis' 1.8 / 9.43 % and 0.9 / 4.89 %. Also the same test
   against the K-seed mean reference composed as rendered (``vs_mean_reference``), and
   ``single_reference_floor_estimate`` = ``err(seed 100, seed 101)/√2`` of two single-group
   ``--ref-spp`` renders composed as rendered: the floor a single 16× reference has.
3. ``equivalent_spp_factor``: undenoised renders at ``--curve-spp`` (64, 128, 256, 512; 64 is the
   test render, the others seeds 1, 2, 3 — never the reference's seeds), a power law
   ``log err = a log spp + b`` fitted to their median errors, solved for the default method's
   median error at ``--spp``: ``M``; factor = ``M / spp``; ``extrapolated`` when ``M`` lies outside
   the measured spp range. Same for the p99.3 (``equivalent_spp_factor_p99_3``), per method
   (``equivalent_spp.<method>``), and with floor-corrected errors (``*_floor_corrected``: the
   reference floor flattens the undenoised curve at high spp, which makes the plain fit's slope
   shallower and ``M`` larger). ``undenoised_spp_to_goal``: the same power law solved for the goals.
4. ``bias``: image mean of raw G over valid pixels, relative to the reference's, for the undenoised
   and every method; ``noise_of_mean_rel`` = the expected noise of the undenoised image mean,
   ``√Σ(x − ref)² / N / mean(ref)`` (pixels are independent); ``reference_noise_of_mean_rel`` =
   ``√Σ(A − B)² / (2N) / mean(ref)``; ``filter_shift_rel`` = denoised mean / undenoised mean − 1:
   the same paths before and after, so this is the filter's own bias (energy moved between regions
   of different size), free of render noise.
5. ``gain_angle_deg``: the physical ground truth's white point is the illumination cubes composed the
   same way, ``U_rgb = Σ_g U_g @ M_g``; the angle (°) between the test's and the reference's
   ``U_rgb`` per pixel, undenoised and with the U cubes denoised by the default method (every
   method under ``by_method``), median and p99 on ``edges`` and ``flat``; ``reference_floor`` is
   ``angle(U_A, U_B)/2``.
6. ``cost_ms_per_cube``: wall ms (time.perf_counter, best of ``--cost-repeats``) of ``denoise`` of
   one 63-band cube per method, at the test size (the real cube and guides) and at
   ``--cost-size`` (960×720: random data, the AOVs resized nearest-neighbour as guides);
   ``cost_ms_request_alternative``: denoising 3-channel projected raw on request instead, per
   method and OIDN, on a 256×256 crop with a 48-pixel halo (352×352) and the full ``--cost-size``
   frame. ``render_cpu_s_per_cube``: process CPU seconds of rendering each group's cube (with its
   illumination cube) at ``--spp``, as measured when rendered (``from_cache`` says if this run read
   it back).
7. ``worse_than_undenoised``: fraction of valid pixels, on edges and on flat pixels, where the
   denoised error exceeds the undenoised one (per method), and the errors on the fine-texture and
   chart regions.
8. ``ablation_shading_guide`` (not an offered method): the DT filter with a joint image of albedo G,
   albedo R − B, the normal channel and ``log(shading)/0.4``, shading = the sum over all the view's
   groups and bands of their own ``--spp`` illumination cubes, pre-filtered by ``dt-guides``. Linear
   and relight-exact, but its weights carry the render's noise (not "noise-free guides").
8b. ``tail_diagnosis``: the default method applied to the reference's own cubes (``bias_only``: the
   error smoothing alone makes), and at the test's tail pixels (error ≥ its p99.3) the median of
   that bias-only error beside the undenoised and denoised errors there, with the tail's classes
   (``bench/denoise_tail.py`` counts those pixels by cause and draws them).
9. ``oidn``: Intel Open Image Denoise (``pyoidn``, RT filter, HDR) on the composed raw with albedo
   and normal (not linear, so not on cubes), aux images prefiltered (``clean_aux=False``: the albedo
   AOV is noisy) and not (``clean_aux_true``); ``{"available": false, "why": …}`` without it.
10. ``guide_noise``: every method again with the clean (``--clean-aov-spp``) guides, and the albedo
    AOV's RMS deviation from the clean one per R, G, B.
11. Plots: ``bench/out/denoise_maps.png`` (reference / undenoised / denoised raw, and their error
    maps beside the reference's floor map) and ``bench/out/denoise_curve.png`` (error against spp).
12. ``targeted_paths``: the test renders are boosted as the renderer's default is (``--boost-factor``,
    ``--boost-reach``; :mod:`renderer_jobs.mitsuba.boost_paths`: pixels whose reach, from the AOVs and the
    group's direct-light guide alone, exceeds the threshold get factor × ``--spp``). Part 1 measures
    the boosted renders (desk, for the ablation only, stays plain); the error curve's ``--spp`` point and
    the references are plain. Here: the default method on the plain renders, on the boosted ones and
    on plain uniform renders at the two spp (seed 7) that bracket the boost's total paths and that the
    sampler renders exactly (multijitter rounds e.g. 21 per set up to 24), with ``per_group`` pixel
    fractions and extra-path fractions; ``uniform_equal_paths_estimate`` scales the plain errors by
    ``(1 + extra)^-½``.

Usage::

    python bench/denoise.py              # default: 160x120, 64 spp, reference 4 × 1024 spp (~10 min on 2 vCPUs; ~1.5 min cached)
    python bench/denoise.py --quick      # smoke test: 64x48, reference 2 × 256 spp, curve 64/128 (~1-2 min)

Progress lines go to stderr; the JSON object is printed last on stdout (also ``--out FILE``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]

import denoise_lib as dl  # noqa: E402
from render_lib import flat_mask, machine  # noqa: E402

OUT = ROOT / "bench" / "out"
PAIR = (("daylight", "A"), ("ceiling", "D65"))  # group → illuminant of the main composition (desk off)
TEST_SEED, REF_SEED0, MIXED_SEED, AOV_SEED, UNIFORM_SEED = 0, 100, 5, 0, 7
THESIS = {"undenoised": {"median_rel_pct": 1.8, "p99_3_rel_pct": 9.43},
          "denoised": {"median_rel_pct": 0.9, "p99_3_rel_pct": 4.89}}
GOALS = {"median_rel_pct": 0.5, "p99_3_rel_pct": 2.5}
STATS = ("median_rel_pct", "p99_3_rel_pct")


def log(msg: str) -> None:
    print(f"[bench/denoise] {msg}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------
# Renders


def curve_seed(args, spp: int) -> int:
    """The error curve's seed at ``spp``: the test's at ``--spp``, else 1, 2, … in spp order."""
    others = [s for s in args.curve_spp if s != args.spp]
    return args.seed if spp == args.spp else 1 + others.index(spp)


def render_all(args, scene, cache: Path | None) -> dict:
    """Every render the benchmark uses (through the cache): AOVs, the test cubes of all the view's
    groups at ``--spp`` (desk only feeds the ablation's shading), the error curve, the thesis
    protocol's mixed render and the K reference seeds."""
    from illumix.renderer_jobs.mitsuba.boost_paths import boost_mask
    from illumix.retarget.denoise import DEFAULT_METHOD, Guides

    groups = [g for g, _ in PAIR]

    def render(grp, spp, seed):
        return dl.cached_render(scene, args.view, grp, spp, seed, args.res, cache, log)

    log(f"AOVs ({args.aov_spp} and {args.clean_aov_spp} rays per pixel)")
    aovs = dl.cached_aovs(scene, args.view, args.res, AOV_SEED, args.aov_spp, cache, log)
    clean = dl.cached_aovs(scene, args.view, args.res, AOV_SEED, args.clean_aov_spp, cache, log, straddle=False)
    direct = {g: dl.cached_direct(scene, args.view, g, args.res, args.seed, cache, log) for g in groups}
    log(f"test renders at {args.spp} spp, seed {args.seed}" + (f", boosted x{args.boost_factor} where reach > "
                                                               f"{args.boost_reach}" if args.boost_factor > 1 else ""))
    plain = {g: render(g, args.spp, args.seed) for g in scene.group_names}
    test = dict(plain)
    if args.boost_factor > 1:  # the renderer's default: targeted extra paths from the guides alone
        for g in groups:
            mask = boost_mask(dl.group_guides(Guides.from_aovs(aovs), direct[g]), DEFAULT_METHOD,
                              args.boost_reach)
            test[g] = dl.cached_render(scene, args.view, g, args.spp, args.seed, args.res, cache, log,
                                       boost=(mask, args.boost_factor, args.boost_reach))
    curve = {}
    for spp in args.curve_spp:
        log(f"error curve: {spp} spp, seed {curve_seed(args, spp)}")
        curve[spp] = ({g: plain[g] for g in groups} if spp == args.spp  # undenoised, plain: never boosted
                      else {g: render(g, spp, curve_seed(args, spp)) for g in groups})
    uniform = None
    if args.boost_factor > 1:
        extra = float(np.mean([test[g]["targeted_paths"]["extra_paths_fraction"] for g in groups]))
        lo, hi = dl.exact_spp_bracket(args.spp * (1 + extra), sets=4)
        log(f"equal-path uniform baselines: {lo} and {hi} spp (the boost: +{100 * extra:.1f} % paths), seed {UNIFORM_SEED}")
        uniform = {"extra_paths_fraction": extra,
                   "renders": {spp: {g: render(g, spp, UNIFORM_SEED) for g in groups} for spp in (lo, hi)}}
    mixed_spp = args.thesis_factor * args.spp
    log(f"thesis protocol: both groups in one render at {mixed_spp} spp, seed {MIXED_SEED}")
    mixed = render(groups, mixed_spp, MIXED_SEED)
    refs = []
    for k in range(args.ref_seeds):
        log(f"reference seed {k + 1}/{args.ref_seeds} ({args.ref_spp} spp, seed {REF_SEED0 + k})")
        refs.append({g: render(g, args.ref_spp, REF_SEED0 + k) for g in groups})
    return {"aovs": aovs, "clean_aovs": clean, "test": test, "plain": plain, "uniform": uniform, "curve": curve,
            "mixed": mixed, "refs": refs, "mixed_spp": mixed_spp, "direct": direct}


def targeted_paths(args, R: dict, guides, M: np.ndarray, ref: dict, classes: dict, method: str) -> dict:
    """Part 12: the default method on the plain test renders, on the boosted ones (the renderer's
    default) and on uniform renders at the two spp that bracket the same total of paths (``--spp`` ×
    (1 + the boost's extra fraction); spp the sampler renders exactly, :func:`denoise_lib.exact_spp_bracket`),
    against the reference; plus the equal-path estimate of a noise-limited tail,
    ``plain × √(spp / (spp·(1 + extra)))``. The renders without the extra paths are denoised
    without the ``straddle`` guide, as the renderer does (``denoise_guides.uses_straddle``)."""
    groups = [g for g, _ in PAIR]
    if R["uniform"] is None:
        return {"boost_factor": args.boost_factor, "applied": False}

    unboosted = replace(guides, straddle=None)  # the renderer uses it only with the extra paths

    def measure(renders: dict, boosted: bool = False) -> dict:
        raw = dl.compose([dl.run_denoise(renders[g]["cube"], guides if boosted else unboosted, method, R["direct"][g])
                          for g in groups], M)
        und = dl.compose([renders[g]["cube"] for g in groups], M)
        s = dl.err_summary(dl.rel_chroma_err(raw, ref["raw"]), classes["all"])
        u = dl.err_summary(dl.rel_chroma_err(und, ref["raw"]), classes["all"])
        return {"median_rel_pct": s["median_rel_pct"], "p99_3_rel_pct": s["p99_3_rel_pct"],
                "undenoised_median_rel_pct": u["median_rel_pct"], "undenoised_p99_3_rel_pct": u["p99_3_rel_pct"]}

    extra = R["uniform"]["extra_paths_fraction"]
    out = {"boost_factor": args.boost_factor, "boost_reach": args.boost_reach, "applied": True, "method": method,
           "per_group": {g: R["test"][g]["targeted_paths"] for g in groups},
           "extra_paths_fraction": round(extra, 5), "plain": measure(R["plain"]), "boosted": measure(R["test"], boosted=True),
           "uniform_equal_paths": [{"spp": spp, "extra_paths_fraction": round(spp / args.spp - 1, 4),
                                    "seed": UNIFORM_SEED, **measure(r)} for spp, r in R["uniform"]["renders"].items()]}
    scale = (1 + extra) ** -0.5
    out["uniform_equal_paths_estimate"] = {k: round(out["plain"][k] * scale, 4)
                                           for k in ("median_rel_pct", "p99_3_rel_pct")}
    for k, row in [("plain", out["plain"]), ("boosted", out["boosted"]),
                   *((f"uniform {u['spp']} spp", u) for u in out["uniform_equal_paths"])]:
        log(f"  {k:20s} median {row['median_rel_pct']:.3f} %  p99.3 {row['p99_3_rel_pct']:.3f} %")
    return out


def den(R: dict, g: str, guides, name: str, kind: str = "transport") -> np.ndarray:
    """Group ``g``'s test cube (``kind``: transport or illumination) denoised by ``name``."""
    return dl.run_denoise(R["test"][g]["cube" if kind == "transport" else "illumination"], guides, name,
                          R["direct"][g] if g in R["direct"] else None, kind)


# ---------------------------------------------------------------------------------------------
# Measurements


def class_summaries(err: np.ndarray, classes: dict) -> dict:
    """Error summary over every pixel class."""
    return {name: dl.err_summary(err, mask) for name, mask in classes.items()}


def measure_methods(args, R: dict, guides, M: np.ndarray, ref: dict, classes: dict) -> dict:
    """Part 1 (and 4, 5, 7): each method's denoised test cubes, composed, against the reference."""
    from illumix.retarget.denoise import DENOISE_METHODS, denoise, describe, method_guides

    groups = [g for g, _ in PAIR]
    valid = classes["all"]
    out, maps = {}, {}
    u_ref = ref["u_rgb"]
    for name in ["none", *DENOISE_METHODS.names]:
        t0 = time.perf_counter()
        if name == "none":
            T = [R["test"][g]["cube"] for g in groups]
            U = [R["test"][g]["illumination"] for g in groups]
        else:
            T = [den(R, g, guides, name) for g in groups]
            U = [den(R, g, guides, name, "illumination") for g in groups]
        raw = dl.compose(T, M)
        err = dl.rel_chroma_err(raw, ref["raw"])
        s = dl.err_summary(err, valid)
        row = {**({"describe": describe(name)} if name != "none" else {}), **s,
               **{f"{k}_floor_corrected": dl.floor_corrected(s[k], ref["floor"][k]) for k in STATS},
               "classes": class_summaries(err, {k: v for k, v in classes.items() if k != "all"}),
               "mean_G_rel": float(raw[..., 1][valid].mean() / ref["raw"][..., 1][valid].mean() - 1)}
        ang = dl.angle_deg(dl.compose(U, M), u_ref)
        row["gain_angle_deg"] = {c: dl.angle_summary(ang, classes[c]) for c in ("edges", "flat")}
        if name != "none" and "direct" not in method_guides(name):  # one operator for all groups and bands
            und = [R["test"][g]["cube"] for g in groups]
            proj = sum(denoise(dl.compose([c], M[i:i + 1]), guides, name) for i, c in enumerate(und))
            row["projection_commutes_max_rel"] = float(np.abs(proj - raw).max() / np.abs(raw).max())
        out[name] = row
        maps[name] = {"raw": raw, "err": err}
        log(f"  {name:14s} median {s['median_rel_pct']:.3f} %  p99.3 {s['p99_3_rel_pct']:.3f} %  "
            f"gain angle edges/flat median {row['gain_angle_deg']['edges']['median']}/"
            f"{row['gain_angle_deg']['flat']['median']}°  ({time.perf_counter() - t0:.1f} s)")
    return {"rows": out, "maps": maps}


def reference(R: dict, M: np.ndarray, guides) -> dict:
    """The K-seed mean reference (raw and ``U_rgb``), its halves and the valid-pixel mask."""
    groups = [g for g, _ in PAIR]
    K = len(R["refs"])
    full = {g: dl.mean_render([r[g] for r in R["refs"]]) for g in groups}
    half_a = {g: dl.mean_render([r[g] for r in R["refs"][:K // 2]]) for g in groups}
    half_b = {g: dl.mean_render([r[g] for r in R["refs"][K // 2:]]) for g in groups}

    def raw(d, key="cube"):
        return dl.compose([d[g][key] for g in groups], M)

    ref = {"raw": raw(full), "u_rgb": raw(full, "illumination"), "raw_a": raw(half_a), "raw_b": raw(half_b),
           "u_a": raw(half_a, "illumination"), "u_b": raw(half_b, "illumination"), "cubes": full}
    g = ref["raw"][..., 1]
    ref["valid"] = guides.hit & ~guides.emitter & (g > 1e-4 * g.max())
    return ref


def reference_floor(ref: dict, classes: dict) -> dict:
    """``err(A, B)/2``: the full reference's own error (module docstring)."""
    halves = dl.rel_chroma_err(ref["raw_a"], ref["raw_b"])
    ref["floor_map"] = halves / 2
    h = dl.err_summary(halves, classes["all"])
    f = dl.err_summary(ref["floor_map"], classes["all"])
    ang = dl.angle_deg(ref["u_a"], ref["u_b"]) / 2
    return {"median_rel_pct": f["median_rel_pct"], "p99_3_rel_pct": f["p99_3_rel_pct"],
            "halves_median_rel_pct": h["median_rel_pct"], "halves_p99_3_rel_pct": h["p99_3_rel_pct"],
            "definition": "err(A, B)/2 with A, B the means of the first and second half of the reference seeds: "
                          "the noise of the full mean (A+B)/2; err(A, B)/sqrt(2) would be that of one half",
            "classes": {c: dl.err_summary(ref["floor_map"], classes[c]) for c in ("edges", "flat", "texture", "chart")},
            "gain_angle_deg": {c: dl.angle_summary(ang, classes[c]) for c in ("edges", "flat")}}


def thesis_protocol(args, R: dict, guides, sensor: str, ref: dict, method: str) -> dict:
    """Part 2: Σ single-group renders as rendered vs one mixed render at 16× spp (thesis Fig. 4.1)."""
    from illumix.retarget.denoise import DENOISE_METHODS

    groups = [g for g, _ in PAIR]
    Mas = dl.composition_weights(sensor, None, [R["test"][g]["emission"] for g in groups])
    Mmix = dl.composition_weights(sensor, None, [R["mixed"]["emission"]])
    mixed = dl.compose([R["mixed"]["cube"]], Mmix)
    g = mixed[..., 1]
    valid = guides.hit & ~guides.emitter & (g > 1e-4 * g.max())
    mean_ref = dl.compose([ref["cubes"][gr]["cube"] for gr in groups], Mas)
    out = {"reference": f"one render of {'+'.join(groups)} at {R['mixed_spp']} spp (seed {MIXED_SEED})",
           "composition": "each group as rendered (its own emission, scale 1)", "thesis": THESIS,
           "valid_pixels": int(valid.sum())}
    by = {}
    for name in ["none", *DENOISE_METHODS.names]:
        T = [R["test"][gr]["cube"] if name == "none" else den(R, gr, guides, name) for gr in groups]
        raw = dl.compose(T, Mas)
        by[name] = {"vs_mixed": dl.err_summary(dl.rel_chroma_err(raw, mixed), valid),
                    "vs_mean_reference": dl.err_summary(dl.rel_chroma_err(raw, mean_ref), ref["valid"])}
    out["undenoised"] = by["none"]["vs_mixed"]
    out["denoised"] = by[method]["vs_mixed"]
    out["denoised_by_method"] = {k: v["vs_mixed"] for k, v in by.items() if k != "none"}
    out["vs_mean_reference"] = {"undenoised": by["none"]["vs_mean_reference"],
                                "denoised": by[method]["vs_mean_reference"],
                                "denoised_by_method": {k: v["vs_mean_reference"] for k, v in by.items() if k != "none"}}
    if len(R["refs"]) >= 2:
        a, b = (dl.compose([r[gr]["cube"] for gr in groups], Mas) for r in R["refs"][:2])
        e = dl.rel_chroma_err(a, b) / np.sqrt(2)
        out["single_reference_floor_estimate"] = {
            **dl.err_summary(e, valid), "definition": f"err(seed {REF_SEED0}, seed {REF_SEED0 + 1})/sqrt(2), "
            f"two {args.ref_spp}-spp single-group renders composed as rendered: one such render's own error"}
    log(f"  thesis protocol: undenoised {out['undenoised']['median_rel_pct']}/{out['undenoised']['p99_3_rel_pct']} %, "
        f"{method} {out['denoised']['median_rel_pct']}/{out['denoised']['p99_3_rel_pct']} % "
        f"(thesis 1.8/9.43 -> 0.9/4.89)")
    return out


def error_curve(args, R: dict, M: np.ndarray, ref: dict) -> list[dict]:
    """Undenoised error against the reference at every curve spp (its own seed)."""
    groups = [g for g, _ in PAIR]
    rows = []
    for spp, cubes in R["curve"].items():
        raw = dl.compose([cubes[g]["cube"] for g in groups], M)
        s = dl.err_summary(dl.rel_chroma_err(raw, ref["raw"]), ref["valid"])
        rows.append({"spp": spp, "seed": curve_seed(args, spp), **s,
                     "cpu_s": round(sum(cubes[g]["cpu_s"] for g in groups), 2)})
        log(f"  curve {spp:5d} spp: median {s['median_rel_pct']:.3f} %  p99.3 {s['p99_3_rel_pct']:.3f} %")
    return rows


def equivalents(args, curve: list[dict], rows: dict, floor: dict) -> dict:
    """Part 3: the spp at which the undenoised power law reaches each method's error (plain and
    floor-corrected)."""
    spps = [c["spp"] for c in curve]
    out = {}
    for name, row in rows.items():
        if name == "none":
            continue
        d = {}
        for k in STATS:
            plain = dl.equivalent_spp(spps, [c[k] for c in curve], row[k])
            corr_curve = [dl.floor_corrected(c[k], floor[k]) for c in curve]
            ok = [(s, e) for s, e in zip(spps, corr_curve) if e is not None]
            corr = dl.equivalent_spp([s for s, _ in ok], [e for _, e in ok], dl.floor_corrected(row[k], floor[k])) \
                if len(ok) >= 2 else {"spp": None, "slope": None, "extrapolated": None}
            d[k] = {**plain, "factor": round(plain["spp"] / args.spp, 3) if plain["spp"] else None,
                    "floor_corrected": {**corr, "factor": round(corr["spp"] / args.spp, 3) if corr["spp"] else None}}
        out[name] = d
    return out


def bias(R: dict, rows: dict, maps: dict, ref: dict) -> dict:
    """Part 4: image-mean shifts of raw G (module docstring)."""
    v = ref["valid"]
    r = ref["raw"][..., 1][v].astype(np.float64)
    x = maps["none"]["raw"][..., 1][v].astype(np.float64)
    n, mean = r.size, r.mean()
    ab = (ref["raw_a"][..., 1] - ref["raw_b"][..., 1])[v].astype(np.float64)
    out = {"reference_mean_G": float(mean), "undenoised_rel": float(x.mean() / mean - 1),
           "noise_of_mean_rel": float(np.sqrt(np.sum((x - r) ** 2)) / n / mean),
           "reference_noise_of_mean_rel": float(np.sqrt(np.sum(ab ** 2)) / (2 * n) / mean), "methods": {}}
    for name in rows:
        if name == "none":
            continue
        d = maps[name]["raw"][..., 1][v].astype(np.float64)
        out["methods"][name] = {"rel": float(d.mean() / mean - 1), "filter_shift_rel": float(d.mean() / x.mean() - 1),
                                "in_noise_units": float((d.mean() / mean - 1) / out["noise_of_mean_rel"])}
    return out


def worse(rows: dict, maps: dict, classes: dict) -> dict:
    """Part 7: where denoising makes the error larger than the undenoised's."""
    e0 = maps["none"]["err"]
    out = {}
    for name, m in maps.items():
        if name == "none":
            continue
        w = m["err"] > e0
        out[name] = {**{f"fraction_{c}": round(float(w[classes[c]].mean()), 4) if classes[c].any() else None
                        for c in ("all", "edges", "flat", "texture", "chart")},
                     **{c: {"undenoised": rows["none"]["classes"][c], "denoised": rows[name]["classes"][c]}
                        for c in ("texture", "chart")}}
    return out


def ablation(R: dict, guides, M: np.ndarray, ref: dict, classes: dict) -> dict:
    """Part 8: the DT with a shading channel in its joint image (module docstring)."""
    from illumix.retarget.denoise import denoise, dt_filter, dt_guide_image, method_params

    groups = [g for g, _ in PAIR]
    p = method_params("dt-guides")[1]  # the default parameters
    T = [R["test"][g]["cube"] for g in groups]
    same = dt_filter(T[0], dt_guide_image(guides, p["sigma_albedo"], p["sigma_normal"]), p["sigma_spatial"],
                     p["iterations"])
    check = float(np.abs(same - denoise(T[0], guides, "dt-guides")).max())
    shading = sum(R["test"][g]["illumination"].sum(-1, dtype=np.float64) for g in R["test"])
    joint = dl.shading_joint(guides, shading, p["sigma_albedo"], p["sigma_normal"], 0.4, p["sigma_spatial"])
    out = {"groups_in_shading": list(R["test"]), "sigma_albedo": p["sigma_albedo"], "sigma_normal": p["sigma_normal"],
           "sigma_shading": 0.4, "iterations": p["iterations"], "dt_joint_equals_dt_guides_max_abs_diff": check,
           "rows": []}
    for ss in (4.0, 8.0):
        raw = dl.compose([dt_filter(t, joint, ss, p["iterations"]) for t in T], M)
        err = dl.rel_chroma_err(raw, ref["raw"])
        row = {"sigma_spatial": ss, **dl.err_summary(err, classes["all"]),
               "classes": class_summaries(err, {k: classes[k] for k in ("edges", "flat", "chart")})}
        out["rows"].append(row)
        log(f"  ablation shading guide, sigma_spatial {ss:g}: median {row['median_rel_pct']:.3f} %  "
            f"p99.3 {row['p99_3_rel_pct']:.3f} %")
    return out


def tail_diagnosis(R: dict, guides, M: np.ndarray, ref: dict, maps: dict, classes: dict, method: str) -> dict:
    """Part 9: is the default method's tail bias or left-over noise? The filter applied to the
    reference's own cubes (``bias_only``: what smoothing alone does to a nearly noise-free image)
    against the reference, and at the test's tail pixels (error ≥ its p99.3) the median of that
    bias-only error beside the undenoised error there, with the tail's pixel classes."""
    groups = [g for g, _ in PAIR]
    cubes = [dl.run_denoise(ref["cubes"][g]["cube"], guides, method, R["direct"][g]) for g in groups]
    bias_err = dl.rel_chroma_err(dl.compose(cubes, M), ref["raw"])
    err, valid = maps[method]["err"], classes["all"]
    tail = valid & (err >= np.percentile(err[valid], 99.3))
    return {"bias_only": dl.err_summary(bias_err, valid), "tail_pixels": int(tail.sum()),
            "tail_median_bias_only_rel_pct": round(float(np.median(bias_err[tail])), 4),
            "tail_median_undenoised_rel_pct": round(float(np.median(maps["none"]["err"][tail])), 4),
            "tail_median_denoised_rel_pct": round(float(np.median(err[tail])), 4),
            "tail_by_class": {c: int((tail & classes[c]).sum()) for c in ("edges", "flat", "texture", "chart")}}


def oidn_part(args, R: dict, guides, aovs: dict, M: np.ndarray, ref: dict, classes: dict) -> dict:
    """Part 9: Open Image Denoise on the composed raw (albedo + normal aux)."""
    try:
        import pyoidn  # noqa: F401 - only whether it imports
    except Exception as exc:  # noqa: BLE001 - any import failure means "not available"
        return {"available": False, "why": repr(exc)}
    groups = [g for g, _ in PAIR]
    raw = dl.compose([R["test"][g]["cube"] for g in groups], M)
    out = {"available": True, "filter": "RT, hdr=True, quality=high, albedo+normal AOVs"}
    for clean in (False, True):
        try:
            den = dl.oidn(raw, aovs["albedo"], aovs["normal"], clean)
        except Exception as exc:  # noqa: BLE001
            return {"available": False, "why": repr(exc)}
        err = dl.rel_chroma_err(den, ref["raw"])
        s = {**dl.err_summary(err, classes["all"]),
             "classes": class_summaries(err, {k: classes[k] for k in ("edges", "flat", "chart")})}
        if clean:
            out["clean_aux_true"] = s
        else:
            out.update(s, clean_aux=False)
    log(f"  OIDN: median {out['median_rel_pct']:.3f} %  p99.3 {out['p99_3_rel_pct']:.3f} %  "
        f"(clean_aux: {out['clean_aux_true']['median_rel_pct']:.3f} / {out['clean_aux_true']['p99_3_rel_pct']:.3f} %)")
    return out


def guide_noise(R: dict, aovs: dict, clean: dict, M: np.ndarray, ref: dict, classes: dict, args,
                straddle: np.ndarray | None) -> dict:
    """Part 10: the methods with clean (many-ray) guides, and the albedo AOV's noise (``straddle``:
    the test's, a geometric flag that averaging more rays does not change)."""
    from illumix.retarget.denoise import DENOISE_METHODS, Guides

    groups = [g for g, _ in PAIR]
    v = classes["all"]
    d = (aovs["albedo"] - clean["albedo"])[v]
    out = {"aov_spp": args.aov_spp, "clean_aov_spp": args.clean_aov_spp,
           "albedo_rms_vs_clean_rgb": [round(float(x), 4) for x in np.sqrt(np.mean(d ** 2, axis=0))], "methods": {}}
    gclean = replace(Guides.from_aovs(clean), straddle=straddle)
    for name in DENOISE_METHODS.names:
        raw = dl.compose([den(R, g, gclean, name) for g in groups], M)
        err = dl.rel_chroma_err(raw, ref["raw"])
        out["methods"][name] = {**dl.err_summary(err, v),
                                "classes": class_summaries(err, {k: classes[k] for k in ("edges", "flat", "chart")})}
        s = out["methods"][name]
        log(f"  clean guides ({args.clean_aov_spp} rays) {name}: median {s['median_rel_pct']:.3f} %  "
            f"p99.3 {s['p99_3_rel_pct']:.3f} %")
    return out


def cost(args, R: dict, guides, aovs: dict) -> dict:
    """Part 6: wall ms per 63-band cube and per 3-channel request (best of ``--cost-repeats``)."""
    from illumix.retarget.denoise import DENOISE_METHODS, Guides, denoise

    rep = args.cost_repeats
    cube = R["test"][PAIR[0][0]]["cube"]
    small = f"{args.res[0]}x{args.res[1]}"
    big_w, big_h = args.cost_size
    big = f"{big_w}x{big_h}"
    crop = 256 + 2 * 48
    direct = R["direct"][PAIR[0][0]]["direct"]  # the test cube's group's own

    def synth(shape):
        return Guides(*(dl.upsample_nearest(np.asarray(x), shape) for x in
                        (aovs["albedo"], aovs["normal"], aovs["depth"], aovs["mask"], aovs["emitter"],
                         aovs["albedo_bands"], direct)))

    guides = guides.with_direct(direct)
    rng = np.random.default_rng(0)
    big_cube = rng.random((big_h, big_w, cube.shape[-1]), dtype=np.float32)
    gbig, gcrop = synth((big_h, big_w)), synth((crop, crop))
    raw_big = rng.random((big_h, big_w, 3), dtype=np.float32)
    raw_crop = rng.random((crop, crop, 3), dtype=np.float32)
    per_cube, request = {}, {}
    for name in DENOISE_METHODS.names:
        per_cube[name] = {small: dl.best_ms(lambda: denoise(cube, guides, name), rep),
                          big: dl.best_ms(lambda: denoise(big_cube, gbig, name), rep)}
        # on request there is no per-band albedo to divide a 3-channel raw by: the same filter undivided
        request[name] = {f"{crop}x{crop}": dl.best_ms(lambda: denoise(raw_crop, gcrop, name, "illumination"), rep),
                         big: dl.best_ms(lambda: denoise(raw_big, gbig, name, "illumination"), rep)}
        log(f"  cost {name}: {per_cube[name]} ms per cube, {request[name]} ms per raw request")
    try:
        al, nr = (dl.upsample_nearest(aovs[k], s) for k, s in (("albedo", (crop, crop)), ("normal", (crop, crop))))
        alb, nrb = (dl.upsample_nearest(aovs[k], (big_h, big_w)) for k in ("albedo", "normal"))
        request["oidn"] = {f"{crop}x{crop}": dl.best_ms(lambda: dl.oidn(raw_crop, al, nr, False), rep),
                           big: dl.best_ms(lambda: dl.oidn(raw_big, alb, nrb, False), rep)}
        log(f"  cost oidn: {request['oidn']} ms per raw request")
    except Exception as exc:  # noqa: BLE001 - OIDN is optional
        request["oidn"] = {"available": False, "why": repr(exc)}
    groups = [g for g, _ in PAIR]
    render = {g: {"cpu_s": round(R["test"][g]["cpu_s"], 2), "wall_s": round(R["test"][g]["wall_s"], 2),
                  "from_cache": R["test"][g]["cached"]} for g in groups}
    guide_cpu = {"direct_light_cpu_s_per_group": {g: round(R["direct"][g]["cpu_s"], 3) for g in groups},
                 "aov_pass_cpu_s": round(float(aovs["cpu_s"]), 2) if "cpu_s" in aovs else None,
                 "note": "the direct-light guide per group and the AOV pass (with albedo_bands) per view; "
                         "from the run that made the cache"}
    return {"cost_ms_per_cube": per_cube, "cost_ms_request_alternative": request, "guide_cost": guide_cpu,
            "render_cpu_s_per_cube": {"spp": args.spp, "includes": "transport + illumination cube", **render},
            "timing": f"wall ms, time.perf_counter, best of {rep}; {big} and the {crop}x{crop} crop: random data, "
                      "the view's AOVs resized nearest-neighbour as guides"}


# ---------------------------------------------------------------------------------------------


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=64, help="spp of the test renders")
    ap.add_argument("--seed", type=int, default=TEST_SEED,
                    help="seed of the test renders and their direct-light guides (not one of the other renders')")
    ap.add_argument("--ref-spp", type=int, default=1024, help="spp of each reference seed")
    ap.add_argument("--ref-seeds", type=int, default=4, help="independent reference renders averaged (even, >= 2)")
    ap.add_argument("--resolution", default="160x120")
    ap.add_argument("--view", default="front")
    ap.add_argument("--sensor", default="Nikon 5100 (NPL)")
    ap.add_argument("--curve-spp", default="64,128,256,512", help="spp of the undenoised error curve")
    ap.add_argument("--thesis-factor", type=int, default=16, help="the thesis protocol's mixed render: this x --spp")
    ap.add_argument("--aov-spp", type=int, default=16, help="rays per pixel of the guide AOVs")
    ap.add_argument("--clean-aov-spp", type=int, default=1024, help="rays per pixel of the AOVs for pixel classes")
    ap.add_argument("--cost-size", default="960x720", help="large size of the cost measurement")
    ap.add_argument("--cost-repeats", type=int, default=3)
    ap.add_argument("--boost-factor", type=int, default=None,
                    help="targeted extra paths of the test renders (default: the renderer's, 8; 1 = off)")
    ap.add_argument("--boost-reach", type=float, default=None, help="their reach threshold (default: the renderer's)")
    ap.add_argument("--room", type=int, default=0,
                    help="the procedural demo room's seed (0: the room the defaults were chosen on; another seed "
                         "is a room they have not seen; its renders are cached in a folder of their own)")
    ap.add_argument("--no-cache", action="store_true", help="render everything again (and cache nothing)")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: 64x48, reference 2 x 256 spp, curve 64/128, thesis factor 4")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    args = ap.parse_args(argv)
    if args.quick:
        args.resolution, args.ref_seeds, args.ref_spp, args.curve_spp = "64x48", 2, 256, "64,128"
        args.thesis_factor, args.clean_aov_spp, args.cost_size, args.cost_repeats = 4, 256, "320x240", 1
    if args.ref_seeds < 2 or args.ref_seeds % 2:
        ap.error("--ref-seeds must be even and >= 2 (the floor compares the two halves)")
    from illumix.renderer_jobs.render_settings import RenderSettings

    d = RenderSettings()
    args.boost_factor = d.boost_factor if args.boost_factor is None else args.boost_factor
    args.boost_reach = d.boost_reach if args.boost_reach is None else args.boost_reach
    if args.boost_factor < 1 or not 0 < args.boost_reach <= 1:
        ap.error("--boost-factor must be >= 1 and --boost-reach in (0, 1]")
    args.res = tuple(int(v) for v in args.resolution.lower().split("x"))
    args.cost_size = tuple(int(v) for v in args.cost_size.lower().split("x"))
    args.curve_spp = sorted({int(s) for s in args.curve_spp.split(",")} | {args.spp})
    taken = {*range(1, len(args.curve_spp)), MIXED_SEED, UNIFORM_SEED, *range(REF_SEED0, REF_SEED0 + args.ref_seeds)}
    if args.seed in taken or args.seed < 0:
        ap.error(f"--seed {args.seed} is taken by another render of the benchmark ({sorted(taken)}) or negative; "
                 f"the test must be independent of them: pick e.g. {TEST_SEED} or 10")
    return args


def cache_dir(args) -> Path:
    """The render cache of ``args.room`` (room 0's renders at the top, another room's in ``room<N>/``)."""
    return OUT / "denoise-cache" / (f"room{args.room}" if args.room else "")


def main(argv: list[str] | None = None) -> dict:
    args = parse(argv)
    t0, c0 = time.perf_counter(), time.process_time()
    from illumix.scene.demo import demo_room
    from illumix.renderer_jobs.mitsuba.variant import select_variant
    from illumix.retarget.denoise import DEFAULT_METHOD, DENOISE_METHODS, Guides

    doc: dict = {"benchmark": "denoise", "variant": select_variant(), **machine(), "test_seed": args.seed,
                 "threads": os.environ.get("DRJIT_NUM_THREADS", "all"), "scene": f"demo-room-{args.room}", "view": args.view,
                 "resolution": list(args.res), "sensor": args.sensor,
                 "composition": {g: i for g, i in PAIR}, "spp": args.spp, "quick": args.quick,
                 "boost_factor": args.boost_factor, "boost_reach": args.boost_reach}
    scene = demo_room(args.room, args.res)
    cache = None if args.no_cache else cache_dir(args)
    R = render_all(args, scene, cache)
    groups = [g for g, _ in PAIR]
    guides = Guides.from_aovs(R["aovs"])
    if args.boost_factor <= 1:  # the renderer uses the straddle guide only with the targeted extra paths
        guides = replace(guides, straddle=None)
    M = dl.composition_weights(args.sensor, [i for _, i in PAIR], [R["test"][g]["emission"] for g in groups])
    ref = reference(R, M, guides)
    valid = ref["valid"]
    flat = dl.flat_pixels(R["clean_aovs"], valid)
    tex, chart = dl.texture_mask(R["clean_aovs"]["albedo"], valid)
    classes = {"all": valid, "edges": valid & ~flat, "flat": flat, "texture": tex, "chart": chart}
    doc["classes"] = {**{k: int(v.sum()) for k, v in classes.items()}, "chart_bbox_xyxy": dl.bbox(chart),
                      "render_lib_flat_mask_pixels": int((flat_mask(R["aovs"]) & valid).sum())}
    floor = reference_floor(ref, classes)
    ref["floor"] = floor
    log(f"reference ({args.ref_seeds} x {args.ref_spp} spp) floor: median {floor['median_rel_pct']:.3f} %  "
        f"p99.3 {floor['p99_3_rel_pct']:.3f} %  (halves differ by {floor['halves_median_rel_pct']:.3f} / "
        f"{floor['halves_p99_3_rel_pct']:.3f} %)")

    log("methods at the test spp")
    meas = measure_methods(args, R, guides, M, ref, classes)
    rows, maps = meas["rows"], meas["maps"]
    d = rows[DEFAULT_METHOD]
    doc.update({"default_method": DEFAULT_METHOD, "median_rel_pct": d["median_rel_pct"],
                "p99_3_rel_pct": d["p99_3_rel_pct"], "undenoised_median_rel_pct": rows["none"]["median_rel_pct"],
                "undenoised_p99_3_rel_pct": rows["none"]["p99_3_rel_pct"],
                "reference_floor_median_rel_pct": floor["median_rel_pct"],
                "reference_floor_p99_3_rel_pct": floor["p99_3_rel_pct"],
                "reference_spp": args.ref_seeds * args.ref_spp, "reference_seed_spp": args.ref_spp,
                "reference_seeds": [REF_SEED0 + k for k in range(args.ref_seeds)],
                "goal_median_rel_pct": GOALS["median_rel_pct"], "goal_p99_3_rel_pct": GOALS["p99_3_rel_pct"],
                "goal_met": bool(d["median_rel_pct"] <= GOALS["median_rel_pct"]
                                 and d["p99_3_rel_pct"] <= GOALS["p99_3_rel_pct"]),
                "reference_floor": floor, "methods": rows})

    log("error curve (undenoised)")
    curve = error_curve(args, R, M, ref)
    eq = equivalents(args, curve, rows, floor)
    e_med, e_p99 = eq[DEFAULT_METHOD]["median_rel_pct"], eq[DEFAULT_METHOD]["p99_3_rel_pct"]
    doc.update({"equivalent_spp_factor": e_med["factor"], "equivalent_spp_factor_p99_3": e_p99["factor"],
                "equivalent_spp_factor_floor_corrected": e_med["floor_corrected"]["factor"],
                "equivalent_spp_factor_p99_3_floor_corrected": e_p99["floor_corrected"]["factor"],
                "equivalent_spp": eq, "curve": curve,
                "undenoised_spp_to_goal": {k: dl.equivalent_spp([c["spp"] for c in curve], [c[k] for c in curve],
                                                                GOALS[k]) for k in STATS}})
    log(f"  equivalent spp factor ({DEFAULT_METHOD}): median {doc['equivalent_spp_factor']}x, "
        f"p99.3 {doc['equivalent_spp_factor_p99_3']}x")

    log("thesis protocol")
    doc["thesis_protocol"] = thesis_protocol(args, R, guides, args.sensor, ref, DEFAULT_METHOD)
    log("targeted extra paths against plain and equal-path uniform renders")
    doc["targeted_paths"] = targeted_paths(args, R, guides, M, ref, classes, DEFAULT_METHOD)
    doc["bias"] = bias(R, rows, maps, ref)
    doc["gain_angle_deg"] = {c: {"undenoised": rows["none"]["gain_angle_deg"][c],
                                 "denoised": rows[DEFAULT_METHOD]["gain_angle_deg"][c]} for c in ("edges", "flat")}
    doc["gain_angle_deg"]["reference_floor"] = floor["gain_angle_deg"]
    doc["gain_angle_deg"]["by_method"] = {k: v["gain_angle_deg"] for k, v in rows.items()}
    doc["worse_than_undenoised"] = worse(rows, maps, classes)
    log("ablation, OIDN, clean guides")
    doc["ablation_shading_guide"] = ablation(R, guides, M, ref, classes)
    doc["tail_diagnosis"] = tail_diagnosis(R, guides, M, ref, maps, classes, DEFAULT_METHOD)
    log(f"  tail: bias only p99.3 {doc['tail_diagnosis']['bias_only']['p99_3_rel_pct']:.3f} %, at the tail "
        f"{doc['tail_diagnosis']['tail_median_bias_only_rel_pct']:.3f} % (denoised "
        f"{doc['tail_diagnosis']['tail_median_denoised_rel_pct']:.3f} %)")
    doc["oidn"] = oidn_part(args, R, guides, R["aovs"], M, ref, classes)
    doc["guide_noise"] = guide_noise(R, R["aovs"], R["clean_aovs"], M, ref, classes, args, guides.straddle)
    log("cost")
    doc.update(cost(args, R, guides, R["aovs"]))

    titles = {"reference": f"reference ({args.ref_seeds}x{args.ref_spp} spp, raw, grey-world WB)",
              "undenoised": f"{args.spp} spp undenoised", "denoised": f"{args.spp} spp, {DEFAULT_METHOD}",
              "err_undenoised": f"undenoised: median {rows['none']['median_rel_pct']:.2f} %, "
                                f"p99.3 {rows['none']['p99_3_rel_pct']:.2f} %",
              "err_denoised": f"{DEFAULT_METHOD}: median {d['median_rel_pct']:.2f} %, p99.3 {d['p99_3_rel_pct']:.2f} %",
              "err_floor": f"reference floor err(A,B)/2: median {floor['median_rel_pct']:.2f} %, "
                           f"p99.3 {floor['p99_3_rel_pct']:.2f} %"}
    fits = {}
    for k in STATS:
        f = dl.power_fit([c["spp"] for c in curve], [c[k] for c in curve])
        if f:
            fits[k] = {"slope": f[0], "intercept": f[1]}
    den = {name: {"label": name, "default": name == DEFAULT_METHOD,
                  **{k: rows[name][k] for k in STATS},
                  **{f"equivalent_{k}": eq[name][k]["spp"] for k in STATS}} for name in DENOISE_METHODS.names}
    doc["plots"] = {
        "maps": dl.plot_maps(OUT / "denoise_maps.png", ref["raw"], maps["none"]["raw"], maps[DEFAULT_METHOD]["raw"],
                             maps["none"]["err"], maps[DEFAULT_METHOD]["err"], ref["floor_map"], valid, titles),
        "curve": dl.plot_curve(OUT / "denoise_curve.png", curve, den, floor, GOALS, args.spp, fits)}
    doc["plots"] = {k: (str(Path(v).relative_to(ROOT)) if v else None) for k, v in doc["plots"].items()}
    doc["renders"] = {"cache": str(cache.relative_to(ROOT)) if cache else None,
                      "rendered_this_run": sum(not r["cached"] for r in _all_renders(R)),
                      "read_from_cache": sum(r["cached"] for r in _all_renders(R)),
                      "render_cpu_s_this_run": round(sum(r["cpu_s"] for r in _all_renders(R) if not r["cached"]), 1)}
    doc["total_seconds"] = round(time.perf_counter() - t0, 1)
    doc["total_cpu_seconds"] = round(time.process_time() - c0, 1)
    log(f"done in {doc['total_seconds']} s ({doc['total_cpu_seconds']} s CPU); goal met: {doc['goal_met']}")
    text = dl.dumps(doc)
    if args.out:
        Path(args.out).write_text(text)
    print(text)
    return doc


def _all_renders(R: dict) -> list[dict]:
    """Every distinct render record (the curve's test-spp point is the test render itself)."""
    seen, out = set(), []
    uniform = [r for rs in R["uniform"]["renders"].values() for r in rs.values()] if R["uniform"] else []
    for r in [*R["test"].values(), *R["plain"].values(), *uniform, *(c for cs in R["curve"].values() for c in cs.values()), R["mixed"],
              *(c for refs in R["refs"] for c in refs.values())]:
        if id(r) not in seen:
            seen.add(id(r))
            out.append(r)
    return out


if __name__ == "__main__":
    main()
