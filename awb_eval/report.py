"""Aggregates and tables of an evaluation (:class:`awb_eval.run.Results`).

Aggregation: every per-image score is averaged over the images, per method and per illuminant
pair; so ``angular_mean`` is the mean over images of each image's mean per-pixel angular error,
``angular_worst25`` the mean over images of each image's worst-25 %-of-pixels error, and
``grid_de00_worst25`` the mean over images of the thesis' per-image ΔE00-grid score (appendix B).
``ms`` is the mean time of the method per image.
"""

from __future__ import annotations

import numpy as np

from illumix.awb_eval.run import Results
from illumix.awb_eval.scoring import ANGULAR_STATS

KEYS = (*(f"angular_{k}" for k in ANGULAR_STATS), "grid_de00_worst25", "ms")
# (column title, key) of the markdown tables
COLUMNS = (("angular mean °", "angular_mean"), ("median °", "angular_median"), ("trimean °", "angular_trimean"),
           ("worst 25 % °", "angular_worst25"), ("ΔE00 grid worst 25 %", "grid_de00_worst25"), ("ms/image", "ms"))


def _mean_scores(images: list[dict], label: str) -> dict[str, float]:
    rows = [im["methods"][label] for im in images]
    out = {k: float(np.mean([r[k] for r in rows])) for k in KEYS}
    out["images"] = len(rows)
    return out


def aggregate(res: Results, labels: list[str]) -> dict:
    """``{"methods": {label: scores}, "pairs": {pair: {label: scores}}}`` (module docstring)."""
    if not res.images:
        return {"methods": {}, "pairs": {}}
    pairs = sorted({im["pair"] for im in res.images}, key=[im["pair"] for im in res.images].index)
    return {
        "white_points": white_point_span(res.images),
        "methods": {m: _mean_scores(res.images, m) for m in labels},
        "pairs": {p: {m: _mean_scores([im for im in res.images if im["pair"] == p], m) for m in labels}
                  for p in pairs},
    }


def white_point_span(images: list[dict]) -> dict:
    """The cameras the images were made for and the range of their illuminants' white points
    (R/G, B/G): with ``--sensor random`` each image has its own drawn camera, and this range is how
    widely the draws spread (bench/SENSORS.md compares it with the measured cameras')."""
    wps = np.array([w for im in images for w in im.get("white_points_rg_bg", [])], np.float64).reshape(-1, 2)
    out = {"sensors": len({im.get("sensor", "") for im in images})}
    if len(wps):
        out |= {"r_over_g": [round(float(wps[:, 0].min()), 4), round(float(wps[:, 0].max()), 4)],
                "b_over_g": [round(float(wps[:, 1].min()), 4), round(float(wps[:, 1].max()), 4)]}
    return out


def _fmt(key: str, v: float) -> str:
    return f"{v:.1f}" if key == "ms" else f"{v:.2f}"


def markdown(summary: dict, title: str = "AWB evaluation") -> str:
    """The per-method table, then the per-pair table, as GitHub markdown."""
    lines = [f"### {title}", "", "| method | images | " + " | ".join(c for c, _ in COLUMNS) + " |",
             "|---|---:|" + "---:|" * len(COLUMNS)]
    for m, s in summary["methods"].items():
        lines.append(f"| {m} | {s['images']} | " + " | ".join(_fmt(k, s[k]) for _, k in COLUMNS) + " |")
    per_pair = [c for c in COLUMNS if c[1] != "ms"]
    lines += ["", "Per illuminant pair:", "", "| pair | method | images | " + " | ".join(c for c, _ in per_pair) + " |",
              "|---|---|---:|" + "---:|" * len(per_pair)]
    for p, by_method in summary["pairs"].items():
        for m, s in by_method.items():
            lines.append(f"| {p} | {m} | {s['images']} | " + " | ".join(_fmt(k, s[k]) for _, k in per_pair) + " |")
    span = summary.get("white_points", {})
    if span.get("sensors", 0) > 1 and "r_over_g" in span:
        lines += ["", f"{span['sensors']} cameras; white points R/G {span['r_over_g'][0]:.3f}–{span['r_over_g'][1]:.3f}, "
                      f"B/G {span['b_over_g'][0]:.3f}–{span['b_over_g'][1]:.3f}"]
    return "\n".join(lines) + "\n"
