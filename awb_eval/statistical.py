"""Low-level statistics colour constancy: the Gray-Edge framework, globally or per grid cell.

van de Weijer, Gevers & Gijsenij, "Edge-Based Color Constancy", IEEE TIP 16(9), 2007, eq. 10:
the illuminant colour of channel c is estimated (up to scale) as the Minkowski p-norm of the n-th
order derivative of the image smoothed by a Gaussian of scale σ,

::

    e_c ∝ ( Σ_x |∂ⁿ f_c^σ(x)|^p )^{1/p}           e^{n,p,σ}

    n = 0, p = 1, σ = 0   Gray World (Buchsbaum 1980)
    n = 0, p = ∞, σ = 0   White Patch / max-RGB (Land 1977)
    n = 0, p = 6, σ = 0   Shades of Gray (Finlayson & Trezzi 2004)
    n = 1                 Gray Edge: |∂f^σ| = √(f_x² + f_y²)
    n = 2                 2nd-order Gray Edge: √(f_xx² + 4 f_xy² + f_yy²) (the authors' code)

Derivatives are separable Gaussian derivative filters (radius 4σ) whose discrete moments are made exact
(:func:`gaussian_kernel`): a sampled, truncated kernel otherwise answers a constant (scipy's order-2
kernel at σ = 2 sums to -9e-5, which on raw offsets of 1e3 is a large false edge). For σ > 0 a border
of ⌈σ⌉ + 1 pixels is left out of the sums (the authors' ``set_border``), where the filter sees the
image's edge.

Patch-wise (thesis §5.2: "the image is divided into equal patches, and the algorithm makes
predictions for each patch individually"): the sums run over each cell of a rows × cols grid
(the same near-equal cells as :func:`retarget.metrics.grid_delta_e00`); the cell estimates become a
per-pixel illuminant map, bilinearly interpolated between the cell centres (or piecewise constant).
A cell with no usable pixel, or whose estimate has a zero channel, takes the global estimate; an
image with no usable estimate at all gets the neutral illuminant (no correction).

Images are linear camera raw ``(H, W, 3)``; estimates are chromaticities ``r + g + b = 1``, float64.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy import ndimage

from illumix.retarget.errors import SpectralError

INTERPOLATIONS = ("bilinear", "nearest")
# A channel estimate below this fraction of the strongest one is "no estimate" (cf.
# retarget.groundtruth.MIN_CHANNEL_RATIO: no meaningful gain exists).
MIN_RATIO = 1e-6


def derivative_magnitude(raw: np.ndarray, order: int, sigma: float) -> np.ndarray:
    """``|∂ⁿ f^σ|`` per channel, ``(H, W, 3)`` float64 (n = 0: ``|f^σ|``, the smoothed image).

    order 1: ``√(f_x² + f_y²)``; order 2: ``√(f_xx² + 4 f_xy² + f_yy²)``, Gaussian derivatives of
    scale ``sigma`` pixels (``mode="nearest"``: the image's edge is extended, not mirrored).
    """
    f = np.asarray(raw, dtype=np.float64)
    if order not in (0, 1, 2):
        raise SpectralError(f"gray edge: derivative order must be 0, 1 or 2, got {order}")
    if order > 0 and not sigma > 0:
        raise SpectralError(f"gray edge: order {order} needs a Gaussian scale sigma > 0, got {sigma}")
    if order == 0:
        return np.abs(f if sigma == 0 else _each_channel(f, sigma, (0, 0)))
    if order == 1:
        return np.hypot(_each_channel(f, sigma, (0, 1)), _each_channel(f, sigma, (1, 0)))
    xx, yy, xy = (_each_channel(f, sigma, o) for o in ((0, 2), (2, 0), (1, 1)))
    return np.sqrt(xx * xx + 4.0 * xy * xy + yy * yy)


def gaussian_kernel(sigma: float, order: int) -> np.ndarray:
    """A correlation kernel ``(2r + 1,)``, ``r = ⌊4σ + ½⌋``, of the Gaussian's ``order``-th derivative,
    its moments made exact so polynomials of degree ≤ 2 are smoothed / differentiated exactly:
    order 0: Σ K = 1; order 1: Σ K = 0, Σ k K = 1; order 2: Σ K = 0, Σ k K = 0, Σ k² K = 2."""
    r = max(1, int(4 * sigma + 0.5))
    k = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (k / sigma) ** 2)
    if order == 0:
        return g / g.sum()
    if order == 1:
        d = k * g
        return d / np.sum(k * d)
    d = (k * k / sigma ** 2 - 1.0) * g
    d -= d.mean()  # symmetric, so Σ k K stays 0
    return 2.0 * d / np.sum(k * k * d)


def _each_channel(f: np.ndarray, sigma: float, order: tuple[int, int]) -> np.ndarray:
    # order = (d/dy, d/dx): separable filters along rows then columns; the channel axis is not filtered
    out = ndimage.correlate1d(f, gaussian_kernel(sigma, order[0]), axis=0, mode="nearest")
    return ndimage.correlate1d(out, gaussian_kernel(sigma, order[1]), axis=1, mode="nearest")


def cell_bounds(size: int, cells: int) -> np.ndarray:
    """Near-equal cell edges ``(cells + 1,)`` over ``size`` pixels (as the ΔE00 grid's)."""
    return np.linspace(0, size, cells + 1).astype(int)


def grid_estimates(raw: np.ndarray, order: int = 0, p: float = 1.0, sigma: float = 0.0,
                   grid: tuple[int, int] = (1, 1), valid: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """e^{n,p,σ} per grid cell: ``(cell estimates (rows, cols, 3), global estimate (3,))``.

    Chromaticities (sum 1), float64; a cell without an estimate holds the global one, and a
    global estimate that does not exist is neutral ``(1/3, 1/3, 1/3)``. ``p = inf``: the maximum.
    ``valid``: optional ``(H, W)`` bool of the pixels a method may use (e.g. not saturated).
    """
    raw = np.asarray(raw)
    if raw.ndim != 3 or raw.shape[2] != 3:
        raise SpectralError(f"AWB estimate: raw must be (H, W, 3), got {raw.shape}")
    if not (p >= 1):
        raise SpectralError(f"AWB estimate: the Minkowski norm p must be >= 1 (or inf), got {p}")
    h, w = raw.shape[:2]
    rows, cols = grid
    if not (1 <= rows <= h and 1 <= cols <= w):
        raise SpectralError(f"AWB estimate: a {rows}×{cols} grid does not fit a {h}×{w} image")
    feat = derivative_magnitude(raw, order, sigma)
    use = np.ones((h, w), bool) if valid is None else np.asarray(valid, bool).copy()
    use &= np.all(np.isfinite(feat), axis=-1)
    border = math.ceil(sigma) + 1 if sigma > 0 else 0
    if border and h > 4 * border and w > 4 * border:
        use[:border], use[-border:], use[:, :border], use[:, -border:] = False, False, False, False
    feat = np.where(use[..., None], feat, 0.0)
    ys, xs = cell_bounds(h, rows), cell_bounds(w, cols)
    if math.isinf(p):
        cells = np.maximum.reduceat(np.maximum.reduceat(feat, ys[:-1], axis=0), xs[:-1], axis=1)
        total = cells.max(axis=(0, 1))
    else:
        # normalise by the peak before the power: x^6 of raw values would under/overflow
        scale = float(feat.max()) or 1.0
        powered = (feat / scale) ** p
        sums = np.add.reduceat(np.add.reduceat(powered, ys[:-1], axis=0), xs[:-1], axis=1)
        counts = np.add.reduceat(np.add.reduceat(use.astype(np.float64), ys[:-1], axis=0), xs[:-1], axis=1)
        cells = (sums / np.maximum(counts, 1.0)[..., None]) ** (1.0 / p)
        total = (sums.sum(axis=(0, 1)) / max(counts.sum(), 1.0)) ** (1.0 / p)
    neutral = np.full(3, 1.0 / 3.0)
    total = _chromaticity(total[None, None])[0, 0]
    total = np.where(np.isnan(total), neutral, total)
    cells = _chromaticity(cells)
    cells = np.where(np.isnan(cells), total, cells)
    return cells, total


def _chromaticity(e: np.ndarray) -> np.ndarray:
    """``e / Σe`` along the last axis; NaN where a channel is below MIN_RATIO of the strongest."""
    top = e.max(axis=-1, keepdims=True)
    ok = np.all(np.isfinite(e), axis=-1, keepdims=True) & (top > 0) & (e.min(axis=-1, keepdims=True) > MIN_RATIO * top)
    s = e.sum(axis=-1, keepdims=True)
    return np.where(ok, e / np.where(ok, s, 1.0), np.nan)


def illuminant_map(cells: np.ndarray, shape: tuple[int, int], interpolation: str = "bilinear") -> np.ndarray:
    """Per-pixel illuminant ``(H, W, 3)`` float32 from cell estimates ``(rows, cols, 3)``.

    ``bilinear``: OpenCV's linear resize, whose half-pixel convention puts each cell's value at the
    cell's centre (exactly, for cells of equal size) and holds it constant beyond the outer centres;
    ``nearest``: each pixel takes its own cell's estimate (the same cells as :func:`grid_estimates`).
    """
    h, w = shape
    rows, cols = cells.shape[:2]
    if interpolation == "nearest":
        iy = np.searchsorted(cell_bounds(h, rows), np.arange(h), side="right") - 1
        ix = np.searchsorted(cell_bounds(w, cols), np.arange(w), side="right") - 1
        return cells[iy[:, None], ix[None, :]].astype(np.float32)
    if interpolation != "bilinear":
        raise SpectralError(f"AWB estimate: unknown interpolation {interpolation!r} (valid: {', '.join(INTERPOLATIONS)})")
    if (rows, cols) == (1, 1):
        return np.broadcast_to(cells[0, 0].astype(np.float32), (h, w, 3)).copy()
    return cv2.resize(cells.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, 3)


def estimate(raw: np.ndarray, order: int = 0, p: float = 1.0, sigma: float = 0.0, grid: tuple[int, int] = (1, 1),
             interpolation: str = "bilinear", valid: np.ndarray | None = None) -> np.ndarray:
    """The e^{n,p,σ} illuminant of every pixel, ``(H, W, 3)`` float32 chromaticities (sum 1):
    global (``grid=(1, 1)``, one colour broadcast) or patch-wise."""
    cells, _ = grid_estimates(raw, order, p, sigma, grid, valid)
    return illuminant_map(cells, raw.shape[:2], interpolation)
