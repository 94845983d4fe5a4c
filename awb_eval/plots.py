"""Figures of an evaluation (matplotlib, Agg): per-method box plots and per-pixel error maps.

- :func:`box_plots`: per-image mean angular error and ΔE00-grid worst 25 % of every method, one box
  per method (median, quartiles, whiskers at 1.5 IQR, outliers);
- :func:`error_map`: for one image, the GT rendering and each method's angular error map in
  degrees (false colour with a colour bar, one scale for all methods; grey where the GT is undefined).
"""

from __future__ import annotations

import numpy as np

from illumix.awb_eval.run import ErrorMaps


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt

    return plt


def box_plots(images: list[dict], labels: list[str]):
    """A figure with two panels of box plots over the images: angular mean (°) and ΔE00 grid."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(max(8.0, 1.1 * len(labels) + 3), 4.8), constrained_layout=True)
    for ax, key, title in ((axes[0], "angular_mean", "per-image mean angular error (°)"),
                           (axes[1], "grid_de00_worst25", "per-image ΔE00 grid, worst 25 %")):
        data = [[im["methods"][m][key] for im in images] for m in labels]
        ax.boxplot(data, showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels, rotation=35, ha="right", fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(f"{len(images)} images", fontsize=10)
    return fig


def error_map(maps: ErrorMaps):
    """A figure: the GT sRGB and each method's angular error map (degrees, shared colour scale)."""
    plt = _pyplot()
    labels = list(maps.errors)
    n = len(labels) + 1
    cols = min(n, 4)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.9 * rows), squeeze=False, constrained_layout=True)
    valid = [e[maps.mask] for e in maps.errors.values()]
    top = max(1.0, float(np.percentile(np.concatenate(valid), 99))) if valid else 1.0
    cmap = plt.get_cmap("magma").copy()
    cmap.set_bad("0.6")  # pixels without ground truth
    axes = axes.ravel()
    axes[0].imshow(maps.srgb)
    axes[0].set_title("ground truth sRGB", fontsize=9)
    image = None
    for ax, label in zip(axes[1:], labels):
        err = np.ma.masked_array(maps.errors[label], mask=~maps.mask)
        image = ax.imshow(err, cmap=cmap, vmin=0.0, vmax=top)
        ax.set_title(f"{label}: mean {float(err.mean()):.2f}°", fontsize=9)
    for ax in axes:
        ax.set_axis_off()
    if image is not None:
        fig.colorbar(image, ax=axes[1:n].tolist(), label="angular error (°)", shrink=0.85)
    fig.suptitle(maps.name, fontsize=10)
    return fig
