"""The ColorChecker's corners in a view, found in its albedo AOV (for LSMI's ``MCCCoord``).

The store keeps no scene geometry, but every rendered view keeps its albedo AOV: the diffuse
reflectance of the first hit averaged over 600–700, 500–600 and 400–500 nm (R, G, B;
``renderer_jobs.mitsuba.aovs.ALBEDO_BANDS``), or per band (``albedo_bands``). A ColorChecker Classic
(``ColorChecker N Ohta`` spectra, as the demo room's) is recognised there by its 24 known albedos,
whatever the light, the camera or the exposure:

1. each patch's albedo, reduced to the AOV's bands, is looked for (3×3 mean filter against the AOV's
   sampling noise; max-channel distance ≤ ``tol``); the largest connected blobs become candidates;
2. a homography from the chart's own coordinates (patch ``i`` centred at ``(col + ½, row + ½)``,
   chart order, 6 × 4) to the blob centroids is fitted with RANSAC (OpenCV), so blobs of walls or
   objects that share a patch's colour are outliers;
3. with at least ``min_patches`` distinct patches agreeing, the chart's outline ``(0, 0)–(6, 4)``
   (TL, TR, BR, BL as seen facing the chart — LSMI's corner order) is mapped into the image.

Robust to perspective, partial occlusion and unrelated same-coloured surfaces; a chart seen at
grazing angles, or smaller than ~2 px per patch, is reported as not found (``None``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

CHART_SET = "ColorChecker N Ohta"
COLS, ROWS = 6, 4
ALBEDO_BANDS = ((600.0, 700.0), (500.0, 600.0), (400.0, 500.0))  # = renderer_jobs.mitsuba.aovs.ALBEDO_BANDS
OUTLINE = np.float32([[0, 0], [COLS, 0], [COLS, ROWS], [0, ROWS]])  # TL, TR, BR, BL in patch pitches


@lru_cache(maxsize=4)
def _chart(bands: int | None) -> np.ndarray:
    """``(24, C)``: the patches' albedo as the AOV holds it (``bands=None``: the RGB albedo)."""
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.reflectances import get_reflectances

    _, refl = get_reflectances(CHART_SET, DEFAULT_GRID)
    if bands is not None:
        return np.asarray(refl, np.float32)
    wl = DEFAULT_GRID.wavelengths
    return np.stack([refl[:, (wl >= a) & (wl <= b)].mean(axis=1) for a, b in ALBEDO_BANDS], axis=1).astype(np.float32)


def chart_albedos(channels: int) -> np.ndarray:
    """``(24, channels)`` reference albedos for an AOV with ``channels`` channels (3: RGB; else bands)."""
    return _chart(None if channels == 3 else channels)


def find_chart(albedo: np.ndarray, *, tol: float = 0.04, min_patches: int = 8,
               per_patch: int = 3) -> np.ndarray | None:
    """Corners ``(4, 2)`` ``[x, y]`` float32 in pixel-index coordinates (pixel ``(i, j)``'s centre is
    ``(j, i)``) of the ColorChecker in ``albedo`` ``(H, W, C)``, TL, TR, BR, BL; ``None`` if not found."""
    import cv2

    a = np.asarray(albedo, np.float32)
    if a.ndim != 3:
        return None
    ref = chart_albedos(a.shape[2])
    if ref.shape[1] != a.shape[2]:
        return None
    a = cv2.blur(a, (3, 3)) if a.shape[2] <= 4 else np.stack([cv2.blur(a[..., c], (3, 3)) for c in range(a.shape[2])], -1)
    src, dst, idx, areas = [], [], [], []
    for i, r in enumerate(ref):
        hit = (np.abs(a - r).max(axis=-1) <= tol).astype(np.uint8)
        n, _, stats, cents = cv2.connectedComponentsWithStats(hit, connectivity=4)
        blobs = sorted(range(1, n), key=lambda j: -stats[j, cv2.CC_STAT_AREA])[:per_patch]
        for j in blobs:
            if stats[j, cv2.CC_STAT_AREA] >= 2:
                row, col = divmod(i, COLS)
                src.append((col + 0.5, row + 0.5))
                dst.append(cents[j])
                idx.append(i)
                areas.append(stats[j, cv2.CC_STAT_AREA])
    if len(set(idx)) < min_patches:
        return None
    thresh = max(1.5, 0.35 * float(np.sqrt(np.median(areas))))  # ~a third of a patch's side
    h, inliers = cv2.findHomography(np.float32(src), np.float32(dst), cv2.RANSAC, thresh)
    if h is None or len({i for i, ok in zip(idx, inliers.ravel()) if ok}) < min_patches:
        return None
    corners = cv2.perspectiveTransform(OUTLINE[None], h)[0]
    height, width = a.shape[:2]
    if not np.all(np.isfinite(corners)) or np.any(np.abs(corners) > 4 * max(height, width)):
        return None
    return corners.astype(np.float32)


def scale_corners(corners: np.ndarray, src_size: tuple[int, int], dst_size: tuple[int, int]) -> np.ndarray:
    """Pixel-index corners of a ``src_size`` ``(W, H)`` image in a resampled ``dst_size`` one (pixel
    centres at ``index + ½`` of the continuous frame, which resampling scales)."""
    s = np.float32([dst_size[0] / src_size[0], dst_size[1] / src_size[1]])
    return (np.asarray(corners, np.float32) + 0.5) * s - 0.5
