"""Raw DNG frames of an LSMI-layout folder (``illumix export --format dng``), read as LSMI reads its
cameras' raws: LSMI's ``0_cvt2tiff.py`` turns each Bayer raw into its TIFF with ``dcraw -h -D -4 -T``
— half size (one RGB pixel per 2 × 2 CFA block: its R, the mean of its two G, its B; dcraw's
``(G₁ + G₂) >> 1``), document mode (no black subtraction, no white balance, no scaling) — so a
Bayer DNG is read here into that same half-size RGB from libraw's ``raw_image_visible`` and
``raw_pattern``, never ``postprocess()`` (which would demosaic, white-balance and colour-convert).
A LinearRaw DNG (``--bayer none``) is RGB already: its ``raw_image[..., :3]`` at full size. The
frame's full-size maps (mixture, ground truth, validity) are reduced to the same half size by
:func:`half_size`: the mean over each block, valid where all four pixels are.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError


def read_dng_rgb(path: Path) -> tuple[np.ndarray, tuple[int, int]]:
    """``(rgb, (H, W))``: ``(h, w, 3)`` float32 digital numbers (black level included) and the size
    of the DNG's own pixel grid (a Bayer DNG: ``h = H // 2``; LinearRaw: the same)."""
    try:
        import rawpy
    except ImportError:
        raise SpectralError(f"{path}: reading DNG raws needs rawpy (libraw): pip install 'illumix[evaluate]'") from None
    try:
        with rawpy.imread(str(path)) as r:
            raw = np.array(r.raw_image_visible, copy=True)
            pattern = None if r.raw_pattern is None else np.array(r.raw_pattern)
            desc = r.color_desc.decode()
    except Exception as exc:  # noqa: BLE001 — libraw raises its own types; one line for all
        raise SpectralError(f"{path}: libraw cannot read it ({type(exc).__name__}: {exc})") from None
    if raw.ndim == 3:
        return raw[..., :3].astype(np.float32), raw.shape[:2]
    letters = "" if pattern is None or pattern.shape != (2, 2) else "".join(desc[i] for i in pattern.ravel())
    if sorted(letters) != ["B", "G", "G", "R"]:
        raise SpectralError(f"{path}: CFA {letters or 'unknown'} is not a 2×2 Bayer pattern of R, G, G, B")
    h, w = raw.shape[0] // 2 * 2, raw.shape[1] // 2 * 2
    out = np.zeros((h // 2, w // 2, 3), np.int64)
    for (dy, dx), c in zip(((0, 0), (0, 1), (1, 0), (1, 1)), letters):
        out[..., "RGB".index(c)] += raw[dy:h:2, dx:w:2]
    out[..., 1] >>= 1  # dcraw's green of a half-size pixel: (G1 + G2) >> 1
    return out.astype(np.float32), raw.shape[:2]


def half_size(a: np.ndarray) -> np.ndarray:
    """``(H, W, …)`` → ``(H // 2, W // 2, …)``: the mean over each 2 × 2 block (bool: all of it)."""
    h, w = a.shape[0] // 2 * 2, a.shape[1] // 2 * 2
    blocks = a[:h, :w].reshape(h // 2, 2, w // 2, 2, *a.shape[2:])
    if a.dtype == bool:
        return blocks.all(axis=(1, 3))
    return blocks.mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
