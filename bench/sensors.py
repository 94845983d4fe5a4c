"""How close `illumix sensors estimate` comes to a camera's measured curves, every camera left out of
the prior in turn (issue 35).

    python bench/sensors.py [--cameras DIR] [--synth-set "CIE 2017"]

For each of the measured cameras (rawtoaces, ``../shared/data``): its DNG-convention colour matrices
are made from its own curves over ``--synth-set`` reflectances (not the fit's ColorChecker), for D65
alone and for A + D65; the estimate from them (the prior learned without that camera) is compared
with the measured curves:

- white-point angular error, mean over 11 illuminants (A, D50, D65, D75, FL2, FL7, FL11, LED-B3,
  LED-RGB1, LED-V1, HP1);
- the ColorChecker's ΔE00 under D65 when the true camera's raw is corrected by the CCM fitted to the
  estimate (white balance from its true white point), beside the CCM fitted to the true curves;
- the curves' RMSE (relative to the peak).

Baselines: the prior's mean camera, and the other measured camera whose D65 matrix is nearest.
:data:`sensor_estimate.fit.NOISE_SCALE` was chosen on the even-indexed cameras: the odd-indexed
ones are reported apart. Prints one JSON object last (``wp_err_mean_deg_d65``,
``wp_err_mean_deg_pair``, ``wp_err_mean_deg_chart`` (synthetic chart photos: :func:`chart_photo`),
``baseline_nearest_deg``, ``baseline_mean_deg``, …). Results: ``bench/SENSORS.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1]))

EVAL = ["A", "D50", "D65", "D75", "FL2", "FL7", "FL11", "LED-B3", "LED-RGB1", "LED-V1", "HP1"]
CAMERAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "rawtoaces-data" / "data" / "camera"


def reflectances(name: str, grid) -> np.ndarray:
    from illumix.sensor_estimate.fit import reflectance_columns

    return reflectance_columns(name, grid)


def wp_error(est: np.ndarray, true: np.ndarray, lights: np.ndarray) -> float:
    """Mean white-point angular error (degrees) of curves ``est`` against ``true`` over ``lights``."""
    from illumix.retarget.metrics import angular_error

    return float(angular_error(lights @ est, lights @ true).mean())


def ccm_delta_e(est: np.ndarray, true: np.ndarray, d65: np.ndarray, chart: np.ndarray, grid) -> float:
    """Mean ΔE00 of the ColorChecker: the true camera's raw corrected by the CCM fitted to ``est``."""
    import colour

    from illumix.retarget.ccm import fit_ccm, linear_srgb_to_lab, target_linear_srgb

    m = fit_ccm(est * grid.step, d65, chart.T, grid).matrix
    raw = (chart.T * d65) @ (true * grid.step)
    raw = raw / (d65 @ (true * grid.step))
    target = target_linear_srgb(d65, chart.T, grid, "CAT02")
    return float(np.mean(colour.delta_E(linear_srgb_to_lab(raw @ m.T), linear_srgb_to_lab(target), method="CIE 2000")))


def chart_photo(true: np.ndarray, spd: np.ndarray, chart: np.ndarray, seed: int) -> np.ndarray:
    """``(24, 3)`` patch means of a synthetic raw photo of a ColorChecker: the camera's responses to
    ``chart`` (a real chart's measured reflectances, not the fit's), the brightest patch at 0.8 of
    white, each patch the mean of 100 pixels with the "phone" sensor model's shot and read noise."""
    from illumix.retarget.sensor_model import NOISE_PRESETS, simulate_raw

    resp = (true.T @ (spd[:, None] * chart)).T
    resp = resp / resp.max() * 0.8
    model = NOISE_PRESETS["phone"]
    noisy = simulate_raw(np.repeat(resp[:, None, :], 100, axis=1).astype(np.float32), model, seed=seed)
    return ((noisy.astype(np.float64) - model.black_level) / (model.white - model.black_level)).mean(axis=1)


def draws_span(ms, lights: np.ndarray, n: int = 500) -> dict:
    """``sensor=random``'s draws against the measured cameras: the share of measured white points
    (R/G, B/G under each of the 11 illuminants) inside the draws' range, and the nearest draw's mean
    white-point error to each measured camera (beside the nearest other measured camera's)."""
    from illumix.sensor_estimate.draw import draw_camera
    from illumix.sensor_estimate.prior import learn_prior

    def ratios(c):
        wp = c.T @ lights.T  # (3, n_lights)
        return np.stack([wp[0] / wp[1], wp[2] / wp[1]])

    prior = learn_prior(ms)
    draws = [draw_camera(prior, s) for s in range(n)]
    d, m = np.stack([ratios(c) for c in draws]), np.stack([ratios(c) for c in ms.curves])
    inside = (m >= d.min(0)) & (m <= d.max(0))
    near_draw = [min(wp_error(c, t, lights) for c in draws) for t in ms.curves]
    near_meas = [min(wp_error(ms.curves[j], t, lights) for j in range(len(ms.curves)) if j != i)
                 for i, t in enumerate(ms.curves)]
    return {"draws": n, "measured_white_points_inside_draw_range": round(float(inside.mean()), 4),
            "nearest_draw_deg_mean": round(float(np.mean(near_draw)), 3),
            "nearest_other_measured_deg_mean": round(float(np.mean(near_meas)), 3)}


#: rawtoaces names whose LibRaw model differs from the name after the maker
LIBRAW_MODELS = {"Canon_Digital_Rebel_XTi": "EOS 400D", "Canon_EOS_200D_II": "EOS 250D",
                 "Canon_EOS_R5m2": "EOS R5 Mark II", "Canon_EOS_R6m2": "EOS R6 Mark II"}


def adobe_matrices(path: str, names) -> dict:
    """``{camera: XYZ → camera D65 matrix (3, 3)}`` from LibRaw's ``src/tables/colordata.cpp`` (Adobe DNG
    Converter's matrices, ×10000), matched as LibRaw matches: the first entry of the camera's maker
    whose model is a prefix of the camera's model. Not stored in this repository: give the file."""
    import re

    text = Path(path).read_text(errors="replace")
    pattern = r'LIBRAW_CAMERAMAKER_(\w+),\s*"([^"]+)",\s*[^,{]+,\s*[^,{]+,\s*\{\s*(-?\d+(?:\s*,\s*-?\d+){8,11})\s*,?\s*\}'
    entries = [(m[1].lower(), m[2], [float(x) for x in m[3].split(",")]) for m in re.finditer(pattern, text)]
    out = {}
    for name in names:
        maker, _, rest = name.partition("_")
        model = LIBRAW_MODELS.get(name, rest.replace("_", " "))
        for mk, prefix, vals in entries:
            if mk == maker.lower() and model.lower().startswith(prefix.lower()) and len(vals) >= 9 and any(vals[:9]):
                out[name] = np.asarray(vals[:9]).reshape(3, 3) / 10000.0
                break
    return out


def real_matrices(ms, table: dict, lights, prior_of, chart, obs, d65, full_prior) -> dict:
    """The acceptance check: each camera from its real Adobe D65 matrix, left out of the prior; and two
    floors: the same with the camera *in* the prior, and how far the real matrix's own D65 white lies
    from the measured curves' (what no estimator honouring the matrix can undo)."""
    from illumix.sensor_estimate import fit

    def angle(a, b):
        cos = (a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))
        return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))

    rows = []
    for i, name in enumerate(ms.names):
        if name not in table:
            continue
        est = fit.estimate(prior_of(name), [(table[name], d65)], chart, obs).curves
        inside = fit.estimate(full_prior, [(table[name], d65)], chart, obs).curves
        rows.append({"camera": name, "deg": wp_error(est, ms.curves[i], lights),
                     "in_prior": wp_error(inside, ms.curves[i], lights),
                     "own_white": angle(table[name] @ (obs.T @ d65), ms.curves[i].T @ d65)})
    if not rows:
        return {"cameras": 0}
    errs, own = np.array([r["deg"] for r in rows]), np.array([r["own_white"] for r in rows])
    worst = rows[int(np.argmax(errs))]
    return {"cameras": len(rows), "wp_err_mean_deg": round(float(errs.mean()), 3),
            "wp_err_max_deg": round(float(errs.max()), 3), "worst_camera": worst["camera"],
            "camera_in_prior_mean_deg": round(float(np.mean([r["in_prior"] for r in rows])), 3),
            "matrix_own_d65_white_deg": {"mean": round(float(own.mean()), 3), "median": round(float(np.median(own)), 3),
                                         "max": round(float(own.max()), 3), "over_1_5": int((own > 1.5).sum())},
            "per_camera": {r["camera"]: round(r["deg"], 3) for r in rows}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cameras", default=str(CAMERAS))
    ap.add_argument("--synth-set", default="CIE 2017", help="reflectances the synthetic matrices are made from")
    ap.add_argument("--adobe-table", default=None, help="LibRaw's src/tables/colordata.cpp: also estimate each "
                                                        "camera from its real Adobe D65 matrix (the acceptance check)")
    args = ap.parse_args()
    from illumix.retarget import illuminants as ill
    from illumix.retarget.grid import DEFAULT_GRID as G
    from illumix.sensor_estimate import fit
    from illumix.sensor_estimate.prior import learn_prior, load_measured

    t0 = time.perf_counter()
    ms = load_measured([args.cameras], G)
    obs, synth, chart = fit.xyz_observer(G), reflectances(args.synth_set, G), reflectances(fit.FIT_REFLECTANCES, G)
    real_chart = reflectances("BabelColor Average", G)  # a chart as measured (30 charts' mean), not the fit's
    lights = np.stack([ill.illuminant_spd(n, G) for n in EVAL])
    d65, a = ill.illuminant_spd("D65", G), ill.illuminant_spd("A", G)
    mats = [fit.colour_matrix(c, d65, synth, obs) for c in ms.curves]
    rows = []
    for i, name in enumerate(ms.names):
        true = ms.curves[i]
        prior = learn_prior(ms.without([name]))
        e1 = fit.estimate(prior, [(mats[i], d65)], chart, obs).curves
        e2 = fit.estimate(prior, [(mats[i], d65), (fit.colour_matrix(true, a, synth, obs), a)], chart, obs).curves
        near = min((k for k in range(len(ms.names)) if k != i), key=lambda k: np.linalg.norm(mats[k] - mats[i]))
        chart_err = [wp_error(fit.estimate_from_patches(prior, [(chart_photo(true, spd, real_chart, i), spd)], chart).curves,
                              true, lights) for spd in (d65, a)]
        both = fit.estimate_from_patches(prior, [(chart_photo(true, spd, real_chart, i), spd) for spd in (d65, a)], chart)
        rows.append({"camera": name, "d65": wp_error(e1, true, lights), "pair": wp_error(e2, true, lights),
                     "chart_two_photos": wp_error(both.curves, true, lights),
                     "mean": wp_error(prior.mean, true, lights), "nearest": wp_error(ms.curves[near], true, lights),
                     "nearest_camera": ms.names[near], "chart": float(np.mean(chart_err)),
                     "ccm_de00_d65": ccm_delta_e(e1, true, d65, chart, G),
                     "ccm_de00_true": ccm_delta_e(true, true, d65, chart, G),
                     "rmse_d65": float(np.sqrt(np.mean((e1 / e1.max() - true / true.max()) ** 2)))})
        print(f"{name}: D65 {rows[-1]['d65']:.2f}°, pair {rows[-1]['pair']:.2f}°, mean camera "
              f"{rows[-1]['mean']:.2f}°, nearest {rows[-1]['nearest']:.2f}°", file=sys.stderr, flush=True)

    def stat(key, sel=slice(None)):
        v = np.array([r[key] for r in rows])[sel]
        return round(float(v.mean()), 3)

    span = draws_span(ms, lights)
    real = None
    if args.adobe_table:
        real = real_matrices(ms, adobe_matrices(args.adobe_table, ms.names), lights,
                             lambda n: learn_prior(ms.without([n])), chart, obs, d65, learn_prior(ms))
    worst = max(rows, key=lambda r: r["d65"])
    out = {"n_cameras": len(rows), "synth_reflectances": args.synth_set, "fit_reflectances": fit.FIT_REFLECTANCES,
           "noise_scale": fit.NOISE_SCALE,
           "wp_err_mean_deg_d65": stat("d65"), "wp_err_mean_deg_pair": stat("pair"), "wp_err_mean_deg_chart": stat("chart"),
           "wp_err_mean_deg_chart_two_photos": stat("chart_two_photos"),
           "baseline_nearest_deg": stat("nearest"), "baseline_mean_deg": stat("mean"),
           "wp_err_max_deg_d65": round(worst["d65"], 3), "worst_camera_d65": worst["camera"],
           "wp_err_max_deg_pair": round(max(r["pair"] for r in rows), 3),
           "wp_err_max_deg_chart": round(max(r["chart"] for r in rows), 3),
           "tuning_even": {"d65": stat("d65", slice(0, None, 2)), "pair": stat("pair", slice(0, None, 2))},
           "held_out_odd": {"d65": stat("d65", slice(1, None, 2)), "pair": stat("pair", slice(1, None, 2)),
                            "chart": stat("chart", slice(1, None, 2)),
                            "chart_two_photos": stat("chart_two_photos", slice(1, None, 2)),
                            "nearest": stat("nearest", slice(1, None, 2))},
           "ccm_de00_mean_d65": stat("ccm_de00_d65"), "ccm_de00_mean_true_curves": stat("ccm_de00_true"),
           "curves_rmse_d65": stat("rmse_d65"), "random_draws": span, "real_adobe_d65": real, "seconds": round(time.perf_counter() - t0, 1),
           "cameras": rows}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
