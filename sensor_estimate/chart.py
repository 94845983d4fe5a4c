"""A photo of a ColorChecker Classic under a known light → its 24 patch means in linear camera RGB.

The chart's outline is given by its four corners (top-left, top-right, bottom-right, bottom-left of
the patch area, as the dark-skin patch sits top-left), in pixels of the image; each patch is averaged
over the middle half of its cell (edges, the black gaps and parallax stay out)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError

ROWS, COLS = 4, 6
INNER = 0.5  # the share of a cell (each way) averaged


def parse_corners(text: str) -> np.ndarray:
    """``x1,y1,…,x4,y4`` → ``(4, 2)`` (TL, TR, BR, BL)."""
    try:
        v = [float(x) for x in text.replace(";", ",").split(",") if x.strip()]
    except ValueError:
        v = []
    if len(v) != 8 or not np.all(np.isfinite(v)):
        raise SpectralError(f"--corners {text!r}: give eight numbers x1,y1,…,x4,y4 (the chart's top-left, "
                            "top-right, bottom-right and bottom-left corners, in pixels)")
    return np.asarray(v).reshape(4, 2)


def read_linear(path: str | Path) -> np.ndarray:
    """``(H, W, 3)`` float64 linear camera RGB of a photo: a raw file LibRaw reads (demosaiced at half
    size, black subtracted, no white balance, no colour conversion, no curve), or a linear 16-bit or
    float TIFF / ``.npy`` of camera RGB."""
    p = Path(path)
    if not p.is_file():
        raise SpectralError(f"{p}: {'is a directory' if p.is_dir() else 'does not exist'}")
    if p.suffix.lower() == ".npy":
        img = np.load(p)
    elif p.suffix.lower() in (".tif", ".tiff"):
        import tifffile

        img = tifffile.imread(p)
    else:
        img = _raw(p)
    img = np.asarray(img, np.float64)
    if img.ndim != 3 or img.shape[2] < 3:
        raise SpectralError(f"{p}: expected an RGB image, got shape {img.shape}")
    return img[..., :3]


def _raw(p: Path) -> np.ndarray:
    import rawpy

    from illumix.sensor_estimate.camera_file import with_raw

    return with_raw(p, lambda raw: raw.postprocess(gamma=(1, 1), no_auto_bright=True, output_bps=16, half_size=True,
                                                   user_wb=[1.0, 1.0, 1.0, 1.0], output_color=rawpy.ColorSpace.raw),
                    "--chart-photo of a raw file")


def patch_means(image: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """``(24, 3)`` mean RGB of each patch (row by row from the top-left), the chart's outline
    ``corners`` ``(4, 2)`` (TL, TR, BR, BL) in the image's pixels."""
    import cv2

    h, w = image.shape[:2]
    if np.any(corners < 0) or np.any(corners[:, 0] > w) or np.any(corners[:, 1] > h):
        raise SpectralError(f"chart corners {corners.round(1).tolist()} lie outside the {w}x{h} image")
    src = np.float32([[0, 0], [COLS, 0], [COLS, ROWS], [0, ROWS]])
    hom = cv2.getPerspectiveTransform(src, np.float32(corners))
    out = np.zeros((ROWS * COLS, 3))
    grid = (np.arange(8) + 0.5) / 8 * INNER + (1 - INNER) / 2  # 8 × 8 sample points in the cell's middle
    for k in range(ROWS * COLS):
        r, c = divmod(k, COLS)
        pts = np.stack(np.meshgrid(c + grid, r + grid), -1).reshape(-1, 1, 2).astype(np.float32)
        xy = cv2.perspectiveTransform(pts, hom).reshape(-1, 2)
        xi = np.clip(np.round(xy[:, 0] - 0.5).astype(int), 0, w - 1)
        yi = np.clip(np.round(xy[:, 1] - 0.5).astype(int), 0, h - 1)
        out[k] = image[yi, xi].mean(axis=0)
    if not np.all(out.max(axis=0) > 0):
        raise SpectralError("chart: a channel reads zero on every patch; check --corners and the exposure")
    return out


def find_patches(image: np.ndarray) -> np.ndarray:
    """``(24, 3)`` patch means of the ColorChecker Classic found in ``image`` ``(H, W, 3)`` linear RGB by
    colour-checker-detection's segmentation (Dallas 2024), in the chart's own patch order whichever way
    it lies. The detector fits a rotated rectangle, not a perspective: a patch whose sample straddles an
    edge (halves differing by more than noise explains) is refused, never averaged into the estimate."""
    try:
        from colour_checker_detection import detect_colour_checkers_segmentation
    except ImportError:
        raise SpectralError("automatic chart detection needs colour-checker-detection (bash scripts/install.sh "
                            "installs it); or give the chart's four --corners") from None
    scale = 1.5 * float(np.percentile(image, 99.9))  # headroom: only outliers (speculars, hot pixels) clip
    if not (np.isfinite(scale) and scale > 0):
        raise SpectralError("chart photo: the image is black or not finite")
    work = np.clip(image / scale, 0.0, 1.0).astype(np.float32)  # the detector wants [0, 1]
    found = detect_colour_checkers_segmentation(work, additional_data=True)
    if not found:
        raise SpectralError("chart photo: no ColorChecker found; give its four --corners (x1,y1,…,x4,y4)")
    best = found[0]
    rect, masks = np.asarray(best.colour_checker, np.float64), np.asarray(best.swatch_masks)
    _check_uniform(rect, masks)
    return np.asarray(best.swatch_colours, np.float64)[:, :3] * scale


def _check_uniform(rect: np.ndarray, masks: np.ndarray) -> None:
    """Each patch's sample box: its left/right and top/bottom halves agree within 10 standard errors
    (the detector's resampling correlates neighbouring pixels), 3 % of the patch and 1 % of the
    chart's brightest value: an edge or a neighbouring patch in the box shows as a step, noise does not."""
    floor = 0.01 * float(rect[..., :3].max())
    for k, (y0, y1, x0, x1) in enumerate(masks):
        box = rect[y0:y1, x0:x1, :3]
        hy, hx = box.shape[0] // 2, box.shape[1] // 2
        if hy == 0 or hx == 0:
            raise SpectralError("chart photo: the chart found is too small; give its four --corners")
        se = box.std(axis=(0, 1)) / np.sqrt(box.shape[0] * box.shape[1] / 2)
        tol = 10 * se + 0.03 * np.abs(box.mean(axis=(0, 1))) + floor
        for a, b in ((box[:hy], box[hy:]), (box[:, :hx], box[:, hx:])):
            if np.any(np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))) > tol):
                raise SpectralError(f"chart photo: patch {k + 1} of the chart found is not sampled cleanly "
                                    "(the photo is too oblique for the detector); give its four --corners")
