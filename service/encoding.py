"""Response encodings.

- ``npz``: one array per output (``raw``/``gain`` ``(H, W, 3)`` float32 — raw ``(H, W)`` when Bayer
  mosaicked — ``ccm`` ``(H, W, 3, 3)``, ``srgb`` ``(H, W, 3)`` float32 in [0, 1], ``weights``
  ``(H, W, G)``, ``mask`` ``(H, W)`` bool) plus ``meta``, the metadata JSON as a 0-d string array.
- ``png``: one image output. ``srgb`` 8-bit; ``raw`` 16-bit linear with 65535 = the largest value
  reported in ``X-Illumix-Scale`` (raw DN are written as they are when noise was simulated);
  ``gain`` 16-bit with value = gain × 4096 (gains up to 16); ``mask`` 8-bit 0/255.
- ``tiff``: one image output as float32 (``mask`` as uint8), exact.
"""

from __future__ import annotations

import io
import json

import cv2
import numpy as np
import tifffile

from retarget.errors import SpectralError

GAIN_PNG_SCALE = 4096.0
IMAGE_OUTPUTS = {"png": ("raw", "gain", "srgb", "mask"), "tiff": ("raw", "gain", "srgb", "mask", "weights")}
MEDIA = {"npz": "application/octet-stream", "png": "image/png", "tiff": "image/tiff"}


def encode_npz(arrays: dict[str, np.ndarray], meta: dict | None) -> bytes:
    buf = io.BytesIO()
    payload = dict(arrays)
    if meta is not None:
        payload["meta"] = np.array(json.dumps(meta))
    np.savez(buf, **payload)
    return buf.getvalue()


def image_output(arrays: dict[str, np.ndarray], fmt: str) -> str:
    names = [k for k in arrays]
    if len(names) != 1 or names[0] not in IMAGE_OUTPUTS[fmt]:
        raise SpectralError(f"format={fmt} returns exactly one image output, one of "
                            f"{', '.join(IMAGE_OUTPUTS[fmt])}; ask e.g. outputs=srgb&format={fmt}")
    return names[0]


def encode_image(arrays: dict[str, np.ndarray], fmt: str, noisy_raw: bool = False) -> tuple[bytes, dict]:
    """``(bytes, extra headers)`` for a one-output png/tiff request."""
    name = image_output(arrays, fmt)
    a = arrays[name]
    headers = {"X-Illumix-Output": name}
    if fmt == "tiff":
        data = a.astype(np.uint8) * 255 if name == "mask" else a.astype(np.float32)
        buf = io.BytesIO()
        rgb = data.ndim == 3 and data.shape[2] == 3
        tifffile.imwrite(buf, data, photometric="rgb" if rgb else "minisblack")
        return buf.getvalue(), headers
    if name == "srgb":
        img = np.round(np.clip(a, 0, 1) * 255).astype(np.uint8)
    elif name == "mask":
        img = a.astype(np.uint8) * 255
    elif name == "gain":
        img = np.round(np.clip(a * GAIN_PNG_SCALE, 0, 65535)).astype(np.uint16)
        headers["X-Illumix-Scale"] = str(GAIN_PNG_SCALE)
    else:
        if noisy_raw:
            img = np.clip(a, 0, 65535).astype(np.uint16)
            headers["X-Illumix-Scale"] = "1"
        else:
            peak = float(a.max()) if a.size else 0.0
            scale = 65535.0 / peak if peak > 0 else 1.0
            img = np.round(a * scale).astype(np.uint16)
            headers["X-Illumix-Scale"] = repr(peak)
    if img.ndim == 3:
        img = img[..., ::-1]  # OpenCV writes BGR
    ok, png = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise SpectralError("could not encode PNG")
    return png.tobytes(), headers
