"""Error metrics for colour constancy and colour reproduction.

- angular error (thesis eq. 5.1): angle between two RGB vectors, degrees;
- relative R/G,B/G error (thesis eq. 4.1): ``‖c_ref − c_x‖ / ‖c_ref‖ · 100`` on ``(R/G, B/G)``;
- CIEDE2000 between sRGB images (colour-science ``delta_E(method="CIE 2000")``);
- grid CIEDE2000 (thesis appendix B): 12×16 cells, mean sRGB per cell, ΔE00 per cell, score = mean
  of the worst 25 % of cells;
- summary statistics of an error distribution as reported in colour constancy (mean, median,
  trimean, best 25 %, worst 25 %; Hordley & Finlayson 2006).
"""

from __future__ import annotations

import colour
import numpy as np

from illumix.retarget.errors import SpectralError


def angular_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between RGB vectors ``(..., 3)``; zero vectors give 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dot = np.sum(a * b, axis=-1)
    norm = np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)
    cos = np.where(norm > 0, dot / np.where(norm > 0, norm, 1.0), 1.0)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def relative_rg_bg(ref: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Relative R/G,B/G error in percent (eq. 4.1) for RGB ``(..., 3)`` with G > 0."""
    ref = np.asarray(ref, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if np.any(ref[..., 1] <= 0) or np.any(x[..., 1] <= 0):
        raise SpectralError("relative R/G,B/G: green must be > 0 in both inputs")
    cr = np.stack([ref[..., 0] / ref[..., 1], ref[..., 2] / ref[..., 1]], axis=-1)
    cx = np.stack([x[..., 0] / x[..., 1], x[..., 2] / x[..., 1]], axis=-1)
    return np.linalg.norm(cr - cx, axis=-1) / np.linalg.norm(cr, axis=-1) * 100.0


def srgb_to_lab(srgb: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of gamma-encoded sRGB in [0, 1]."""
    return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(np.asarray(srgb, dtype=np.float64)),
                             colour.RGB_COLOURSPACES["sRGB"].whitepoint)


def delta_e00(srgb_a: np.ndarray, srgb_b: np.ndarray) -> np.ndarray:
    """CIEDE2000 between two gamma-encoded sRGB images/colours ``(..., 3)``."""
    return np.asarray(colour.delta_E(srgb_to_lab(srgb_a), srgb_to_lab(srgb_b), method="CIE 2000"))


def grid_delta_e00(srgb_ref: np.ndarray, srgb: np.ndarray, grid: tuple[int, int] = (12, 16),
                   worst: float = 0.25) -> tuple[float, np.ndarray]:
    """Grid CIEDE2000 (thesis appendix B): ``(score, per-cell ΔE00 (rows, cols))``.

    The image is split into ``grid`` = (rows, cols) cells of near-equal size; each cell's mean sRGB
    is compared; the score is the mean of the worst ``worst`` fraction of cells (at least one).
    """
    if srgb_ref.shape != srgb.shape or srgb.ndim != 3:
        raise SpectralError(f"grid ΔE00: shapes {srgb_ref.shape} and {srgb.shape} must match (H, W, 3)")
    rows, cols = grid
    h, w = srgb.shape[:2]
    if h < rows or w < cols:
        raise SpectralError(f"grid ΔE00: image {h}×{w} is smaller than the {rows}×{cols} grid")
    ys = np.linspace(0, h, rows + 1).astype(int)
    xs = np.linspace(0, w, cols + 1).astype(int)

    def cell_means(img: np.ndarray) -> np.ndarray:
        # Sum over row strips then column strips (reduceat), then divide by cell areas.
        s = np.add.reduceat(np.add.reduceat(img.astype(np.float64), ys[:-1], axis=0), xs[:-1], axis=1)
        return s / (np.diff(ys)[:, None, None] * np.diff(xs)[None, :, None])

    cells = delta_e00(cell_means(srgb_ref), cell_means(srgb))
    k = max(1, int(round(worst * cells.size)))
    return float(np.sort(cells.ravel())[-k:].mean()), cells


def summary_statistics(errors: np.ndarray) -> dict[str, float]:
    """Mean, median, trimean ``(Q1 + 2·Q2 + Q3)/4``, mean of the best and worst 25 %, max."""
    e = np.sort(np.asarray(errors, dtype=np.float64).ravel())
    if e.size == 0:
        raise SpectralError("summary statistics: no errors given")
    q1, q2, q3 = np.percentile(e, [25, 50, 75])
    k = max(1, int(round(0.25 * e.size)))
    return {"mean": float(e.mean()), "median": float(q2), "trimean": float((q1 + 2 * q2 + q3) / 4),
            "best25": float(e[:k].mean()), "worst25": float(e[-k:].mean()), "max": float(e[-1])}
