"""Texture maps of glTF materials as illumix holds them: pixel arithmetic for :mod:`scene_import.gltf_materials`.

illumix materials take one BSDF kind per shape, a roughness number and an area emitter of one
radiance; glTF varies metalness, roughness and emission per texel. The importer therefore

- **classifies triangles**: each triangle's metalness and emission are the mean of the texels under
  :data:`BARY` (seven points spread over the triangle, nearest texel, REPEAT wrapping); a triangle is
  metal when that mean metalness is ≥ 0.5 and emits when its mean emissive luminance exceeds
  :data:`EMIT_FRACTION` of the map's peak. Each class of a primitive becomes a mesh of its own;
- **averages texels** for the numbers a class needs (the roughness of its texels, a metal's base colour);
- **bakes normal maps** with glTF's ``normalTexture.scale`` applied, as 8-bit PNGs read raw by the renderer.

Images are ``(H, W, C)`` float32 arrays; row 0 is the image's top, where glTF's ``v = 0`` lies.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np

from illumix.scene_import.colour_match import srgb_decode

#: barycentric sample points per triangle: the centroid, three points towards the corners and three
#: towards the edge midpoints — enough to catch emissive detail a few texels wide on a large triangle
BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3],
                 [0.4, 0.4, 0.2], [0.4, 0.2, 0.4], [0.2, 0.4, 0.4]])
EMIT_FRACTION = 0.01  # a triangle emits when its mean emissive luminance is > 1 % of the map's peak
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # linear sRGB → Y (IEC 61966-2-1)


def raw(image) -> np.ndarray:
    """A data texture (metallic-roughness, normal) as ``(H, W, 3)`` float32 in [0, 1], no sRGB decoding."""
    return np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0


def linear(image) -> np.ndarray:
    """A colour texture (base colour, emissive: sRGB-encoded) as ``(H, W, 3)`` float32 linear sRGB."""
    return srgb_decode(np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0).astype(np.float32)


def resized(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``a`` ``(H, W, C)`` resampled (bilinear) to ``shape`` ``(H', W')`` — to compare maps of other sizes."""
    if a.shape[:2] == tuple(shape):
        return a
    import cv2

    return cv2.resize(a, (shape[1], shape[0]), interpolation=cv2.INTER_LINEAR).reshape(*shape, a.shape[2])


def triangle_means(img: np.ndarray, uv: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Mean texel ``(m, C)`` under each triangle: nearest texels at :data:`BARY`, UVs wrapped (REPEAT)."""
    h, w = img.shape[:2]
    p = np.einsum("kj,mjc->mkc", BARY, np.asarray(uv, dtype=np.float64)[tris])  # (m, 7, 2)
    x = np.clip(np.floor((p[..., 0] % 1.0) * w).astype(np.int64), 0, w - 1)
    y = np.clip(np.floor((p[..., 1] % 1.0) * h).astype(np.int64), 0, h - 1)
    return img[y, x].mean(axis=1)


def triangle_areas(pos: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Areas ``(m,)`` of triangles ``tris`` ``(m, 3)`` over vertex positions ``pos`` ``(n, 3)``."""
    p = np.asarray(pos, dtype=np.float64)
    return 0.5 * np.linalg.norm(np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]), axis=1)


def emitting(em_tri: np.ndarray, peak: float) -> np.ndarray:
    """Which triangles emit ``(m,)`` bool, from their mean emissive colours ``(m, 3)`` and the map's peak
    luminance (:data:`EMIT_FRACTION`)."""
    return (em_tri @ LUMINANCE) > EMIT_FRACTION * peak if peak > 0 else np.zeros(len(em_tri), bool)


def submesh(pos, nrm, uv, tris: np.ndarray):
    """``(positions, normals, uvs, triangles)`` with only the vertices ``tris`` uses, re-indexed."""
    used, inv = np.unique(tris.ravel(), return_inverse=True)
    pick = (lambda a: None if a is None else np.asarray(a)[used])
    return pick(pos), pick(nrm), pick(uv), inv.reshape(-1, 3)


def class_mean(values: np.ndarray, mask: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Mean of ``values`` ``(H, W, C)`` over texels where ``mask`` ``(H, W)`` holds (``fallback`` if none)."""
    return values[mask].mean(axis=0) if mask.any() else np.asarray(fallback, dtype=np.float32)


def with_factor(image, factor) -> tuple:
    """``(8-bit sRGB PIL image, fraction of texels clipped)``: ``image`` (sRGB) × the linear ``factor`` ``(3,)``
    per texel in linear light, clipped to 1 where the product exceeds it (only there)."""
    from PIL import Image

    from illumix.retarget.isp import encode_srgb

    lin = linear(image) * np.asarray(factor, dtype=np.float32)[:3]
    over = float((lin > 1).any(axis=-1).mean())
    return Image.fromarray(np.round(encode_srgb(np.clip(lin, 0, 1)) * 255).astype(np.uint8), "RGB"), over


def normal_png(image, scale: float, strength: float = 1.0) -> tuple[bytes, str]:
    """``(PNG bytes, short content hash)`` of a tangent-space normal map with glTF's ``scale`` applied,
    ``n = normalize((2c − 1) · (scale, scale, 1))``, or Blender's Normal Map ``strength``,
    ``n = normalize(z + s · (n − z))`` (Cycles' own blend towards the unbent normal ``z``), re-encoded
    as ``c' = (n + 1) / 2`` in 8 bits."""
    from PIL import Image

    n = raw(image).astype(np.float64) * 2.0 - 1.0
    if scale != 1.0:
        n[..., :2] *= scale
    if strength != 1.0:
        n = np.array([0.0, 0.0, 1.0]) + max(strength, 0.0) * (n - np.array([0.0, 0.0, 1.0]))
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    n[..., 2] = np.maximum(n[..., 2], 0.0)  # a normal below the surface is meaningless; clamp to the horizon
    c = np.round((n + 1.0) * 127.5).clip(0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(c, "RGB").save(buf, format="PNG")
    data = buf.getvalue()
    return data, hashlib.sha256(data).hexdigest()[:12]


def write_bytes(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
