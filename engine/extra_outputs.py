"""Outputs beside the composed sample: the view's stored AOVs, the validity of the ground truth, and
per-pixel spectra (DESIGN.md "Physical GT"; MIST-style reflectance and illumination spectra).

- ``albedo`` ``(H, W, 3)`` (mean diffuse reflectance over 600–700, 500–600, 400–500 nm), ``normal``
  ``(H, W, 3)`` (unit, world space), ``depth`` ``(H, W)`` (metres along the ray, 0 = nothing hit):
  the AOVs as stored, cropped and area-resampled like the raw.
- validity: geometry is hit and it is not a light source's own surface; with the reason counts.
- ``reflectance`` ``(H, W, bands)``: ``Σ_g T_g / Σ_g U_g`` — the first hit's spectral reflectance
  where it is diffuse (exact: the illumination cube is the transport cube demodulated by it), its
  apparent reflectance elsewhere (specular light included); 0 where nothing is lit.
- ``illumination`` ``(H, W, bands)``: ``Σ_g a_g Φ̄_g/Ē_g · U_g`` — the spectral radiance a white
  Lambertian surface there would send to the camera under the request's lighting.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from illumix.retarget.errors import SpectralError

MASK_REASONS = {"no_geometry": "the pixel sees no surface (sky or background)",
                "emitter": "the pixel sees a light source's own surface",
                "no_light": "no light of the lit groups reaches the surface"}


def resize_image(img: np.ndarray, out_w: int, out_h: int) -> np.ndarray:
    """``(h, w[, C])`` → ``(out_h, out_w[, C])``: area average when shrinking, bilinear otherwise
    (linear, like the raw's, so the outputs stay aligned). Any number of channels."""
    h, w = img.shape[:2]
    if (w, h) == (out_w, out_h):
        return img
    interp = cv2.INTER_AREA if out_w <= w and out_h <= h else cv2.INTER_LINEAR
    a = np.ascontiguousarray(img, dtype=np.float32)
    if a.ndim == 3 and a.shape[2] > 4:  # OpenCV resizes at most 512 channels at once; go by blocks of 4
        return np.concatenate([cv2.resize(a[..., c:c + 4], (out_w, out_h), interpolation=interp).reshape(out_h, out_w, -1)
                               for c in range(0, a.shape[2], 4)], axis=2)
    out = cv2.resize(a, (out_w, out_h), interpolation=interp)
    return out.reshape(out_h, out_w, *a.shape[2:])


def view_validity(read_aov: Callable[[str], np.ndarray | None], out_w: int, out_h: int
                  ) -> tuple[np.ndarray | None, dict[str, int]]:
    """``(valid (H, W) bool or None, {reason: pixels})`` from the view's ``mask`` (geometry hit) and
    ``emitter`` AOVs (``read_aov(name)`` gives the crop or ``None`` when the store has no such AOV).
    A resampled pixel is valid when at least half of its area is."""
    hit, emitter = read_aov("mask"), read_aov("emitter")
    if hit is None and emitter is None:
        return None, {}
    shape = (hit if hit is not None else emitter).shape
    hit = np.ones(shape, bool) if hit is None else hit.astype(bool)
    emitter = np.zeros(shape, bool) if emitter is None else emitter.astype(bool)
    nogeo = resize_image((~hit).astype(np.float32), out_w, out_h) > 0.5
    emits = resize_image((hit & emitter).astype(np.float32), out_w, out_h) > 0.5
    return ~(nogeo | emits), {"no_geometry": int(nogeo.sum()), "emitter": int(emits.sum())}


def aov_outputs(read_aov: Callable[[str], np.ndarray | None], names: set[str], out_w: int, out_h: int
                ) -> dict[str, np.ndarray]:
    """The requested AOVs (:data:`engine.spec.AOV_OUTPUTS`), resampled; normals renormalised."""
    out = {}
    for name in ("albedo", "normal", "depth"):
        if name not in names:
            continue
        a = read_aov(name)
        if a is None:
            raise SpectralError(f"this view has no {name!r} AOV stored; re-render the view to get it")
        a = resize_image(a, out_w, out_h).astype(np.float32)
        if name == "normal":
            norm = np.linalg.norm(a, axis=-1, keepdims=True)
            a = np.where(norm > 0, a / np.where(norm > 0, norm, 1), 0.0).astype(np.float32)
        out[name] = a
    return out


def spectral_outputs(cubes: list[np.ndarray], illum: list[np.ndarray], scales: np.ndarray, names: set[str],
                     out_w: int, out_h: int) -> dict[str, np.ndarray]:
    """``reflectance`` and ``illumination`` spectra (module docstring) ``(H, W, bands)`` float32.

    cubes, illum : per group ``(h, w, bands)`` transport and illumination windows (zeros for groups
    not read); scales : ``(G, bands)`` relight factors ``a_g Φ̄_g/Ē_g``.
    """
    out = {}
    if "reflectance" in names:
        t, u = _sum(cubes), _sum(illum)  # in place: one window each, whatever the number of groups
        t, u = resize_image(t, out_w, out_h), resize_image(u, out_w, out_h)
        out["reflectance"] = np.divide(t, u, out=np.zeros_like(t), where=u > 0)
        del t, u
    if "illumination" in names:
        s = np.asarray(scales, np.float32)
        out["illumination"] = resize_image(_sum(illum, s), out_w, out_h)
    return out


def _sum(windows: list[np.ndarray], scales: np.ndarray | None = None) -> np.ndarray:
    """``Σ_g scales_g · windows_g`` ``(h, w, bands)`` float32, accumulated in one array."""
    acc = np.zeros(windows[0].shape, np.float32)
    for g, c in enumerate(windows):
        if scales is None:
            acc += c
        elif np.any(scales[g]):
            acc += c * scales[g]  # one window-sized temporary at a time
    return acc
