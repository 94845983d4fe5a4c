"""Response encodings.

- ``npz`` (the default): one array per output (``raw``/``gain`` ``(H, W, 3)`` float32 — raw
  ``(H, W)`` when Bayer mosaicked — ``ccm`` ``(H, W, 3, 3)``, ``srgb`` ``(H, W, 3)`` float32 in
  [0, 1], ``weights`` ``(H, W, G)``, ``mask`` ``(H, W)`` bool) plus ``meta``, the metadata JSON as a
  0-d string array; with ``dtype=float16`` also ``scales`` (0-d JSON string ``{output: scale}``).
- ``arrays``: the same arrays in the flat container of :mod:`service.arrays_format` (faster to
  encode and decode than npz for large arrays; what the Python client asks for).
- ``dtype=float16`` (npz and arrays): every float output is sent as float16 with a power-of-two
  scale per output and sample, ``value = stored × scale`` (:func:`half_precision`); the scales are
  in ``meta["encoding"]["scales"]``, in the npz's ``scales`` and in the arrays header.
- ``png``: one image output, 16-bit unless noted, with a fixed, documented scale (never the frame's
  own peak, which would crush every mid-tone of a frame with a lamp in view):

  - ``raw``: DN = round(65535 · clip(raw, 0, 1)) with raw exposed so that 1.0 is the white level
    (``exposure=`` as asked, auto exposure — thesis eq. 4.2 — when not given); highlights above the
    white level clip as a camera's would. With ``noise=`` the sensor model's digital numbers are
    written as they are (its black and white levels apply).
  - ``gain``: value = gain × 4096 (gains up to 16); ``mask`` 8-bit 0/255; ``srgb`` 8-bit.

  The scale, black level and white level are in the PNG's ``tEXt`` chunk ``illumix`` (JSON), in
  the ``X-Illumix-Scale``/``X-Illumix-Black-Level``/``X-Illumix-White-Level`` headers and in the
  sample's metadata (``meta["encoding"]``).
- ``tiff``: one image output as float32 (``mask`` as uint8), exact.
- ``dng`` (the raw as a Bayer DNG) and ``exr`` (every output in one float32 OpenEXR):
  :mod:`service.file_downloads`.

Metadata JSON never carries NaN or inf: it is written with ``allow_nan=False``.
"""

from __future__ import annotations

import io
import json
import struct
import zlib

import cv2
import numpy as np
import tifffile

from illumix.engine.spec import IMAGE_OUTPUTS
from illumix.retarget.errors import SpectralError

GAIN_PNG_SCALE = 4096.0
RAW_PNG_WHITE = 65535
MEDIA = {"npz": "application/octet-stream", "arrays": "application/x-illumix-arrays", "png": "image/png",
         "tiff": "image/tiff", "dng": "image/x-adobe-dng", "exr": "image/x-exr"}
#: float16 scaling puts each output's largest magnitude in [2^(HALF_TOP-1), 2^HALF_TOP) as stored
HALF_TOP = 15


def meta_json(meta: dict) -> str:
    """The metadata as JSON; a non-finite number is a bug upstream, refused here rather than sent."""
    return json.dumps(meta, allow_nan=False)


def encode_npz(arrays: dict[str, np.ndarray], meta: dict | None, scales: dict | None = None) -> memoryview:
    """An uncompressed ``.npz`` of ``arrays`` (+ ``meta``, + ``scales`` when given), as a view of one
    buffer (no copy)."""
    buf = io.BytesIO()
    payload = dict(arrays)
    if meta is not None:
        payload["meta"] = np.array(meta_json(meta))
    if scales:
        payload["scales"] = np.array(meta_json(scales))
    np.savez(buf, **payload)
    return buf.getbuffer()


def half_scale(a: np.ndarray) -> int:
    """The exponent ``k`` of the power-of-two scale ``2^k`` for sending float ``a`` as float16.

    ``a``'s largest magnitude ``m·2^e`` (``m`` in [0.5, 1)) is stored as ``m·2^HALF_TOP``, in
    [2^14, 2^15): below float16's maximum (65504) with a factor 2 to spare, so rounding never
    overflows, and 28 binades above its smallest normal number (2^-14), so every value down to
    2^-28 of the maximum keeps float16's full relative precision (≤ 2^-11, round to nearest).
    ``k`` stays within [-126, 127] so the scale is a normal float32 (an array whose maximum is below
    2^-111 is then stored smaller than 2^14, with fewer binades to spare). ``0`` for an all-zero or
    empty array.
    """
    if a.size == 0:
        return 0
    peak = max(float(a.max()), -float(a.min()))
    if not np.isfinite(peak):
        raise SpectralError("an output is not finite; it cannot be sent (lower intensities= or exposure=)")
    if peak == 0:
        return 0
    return int(np.clip(np.frexp(peak)[1] - HALF_TOP, -126, 127))


def half_precision(arrays: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """``(arrays, scales)``: every float array as float16 ``stored = value / 2^k`` (exact scaling,
    one rounding to float16), ``scales[name] = 2^k`` (see :func:`half_scale`); other dtypes (the
    bool ``mask``) unchanged."""
    out, scales = {}, {}
    for name, a in arrays.items():
        if a.dtype.kind != "f":
            out[name] = a
            continue
        k = half_scale(a)
        out[name] = np.ldexp(a, np.int32(-k), out=np.empty(a.shape, np.float16), casting="same_kind")
        scales[name] = float(2.0 ** k)
    return out, scales


def image_output(arrays: dict[str, np.ndarray], fmt: str) -> str:
    names = list(arrays)
    if len(names) != 1 or names[0] not in IMAGE_OUTPUTS[fmt]:
        raise SpectralError(f"format={fmt} returns exactly one image output, one of "
                            f"{', '.join(IMAGE_OUTPUTS[fmt])}; ask e.g. outputs=srgb&format={fmt}")
    return names[0]


def png_scale(name: str, noise) -> dict:
    """How the PNG of output ``name`` maps to values: ``value = (DN - black_level) / scale``."""
    if name == "raw":
        if noise is not None:
            return {"scale": 1.0, "black_level": float(noise.black_level), "white_level": float(noise.white),
                    "units": "sensor digital numbers (noise model)"}
        return {"scale": float(RAW_PNG_WHITE), "black_level": 0.0, "white_level": float(RAW_PNG_WHITE),
                "units": "linear raw, 1.0 = white level (exposed), clipped above"}
    if name == "gain":
        return {"scale": GAIN_PNG_SCALE, "black_level": 0.0, "white_level": 65535.0, "units": "gain"}
    if name == "mask":
        return {"scale": 255.0, "black_level": 0.0, "white_level": 255.0, "units": "valid pixel"}
    return {"scale": 255.0, "black_level": 0.0, "white_level": 255.0, "units": "sRGB, 8-bit"}


def encode_image(arrays: dict[str, np.ndarray], fmt: str, noise=None, meta: dict | None = None
                 ) -> tuple[bytes, dict]:
    """``(bytes, extra headers)`` for a one-output png/tiff request (see the module docstring)."""
    name = image_output(arrays, fmt)
    a = arrays[name]
    headers = {"X-Illumix-Output": name}
    if fmt == "tiff":
        data = a.astype(np.uint8) * 255 if name == "mask" else a.astype(np.float32)
        buf = io.BytesIO()
        rgb = data.ndim == 3 and data.shape[2] == 3
        tifffile.imwrite(buf, data, photometric="rgb" if rgb else "minisblack")
        return buf.getvalue(), headers
    scale = png_scale(name, noise)
    if name == "srgb":
        img = np.round(np.clip(a, 0, 1) * 255).astype(np.uint8)
    elif name == "mask":
        img = a.astype(np.uint8) * 255
    elif name == "gain":
        img = np.round(np.clip(a * GAIN_PNG_SCALE, 0, 65535)).astype(np.uint16)
    elif noise is not None:
        img = np.clip(np.round(a), 0, 65535).astype(np.uint16)
    else:
        img = np.round(np.clip(a, 0.0, 1.0) * RAW_PNG_WHITE).astype(np.uint16)
    headers.update({"X-Illumix-Scale": repr(scale["scale"]), "X-Illumix-Black-Level": repr(scale["black_level"]),
                    "X-Illumix-White-Level": repr(scale["white_level"])})
    if img.ndim == 3:
        img = img[..., ::-1]  # OpenCV writes BGR
    ok, png = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise SpectralError("could not encode PNG")
    text = {"output": name, **scale}
    if meta is not None:
        text.update({k: meta[k] for k in ("scene", "view", "seed", "exposure_gain") if k in meta})
    return add_png_text(png.tobytes(), "illumix", meta_json(text)), headers


def add_png_text(png: bytes, key: str, text: str) -> bytes:
    """``png`` with a ``tEXt`` chunk ``key``/``text`` (Latin-1) inserted after the header chunk.

    OpenCV writes 16-bit PNGs but no text chunks; a chunk is length + type + data + CRC-32 (PNG
    spec §5.3), placed right after IHDR so every reader sees it before the image data.
    """
    data = key.encode("latin-1") + b"\0" + text.encode("latin-1", "replace")
    chunk = struct.pack(">I", len(data)) + b"tEXt" + data + struct.pack(">I", zlib.crc32(b"tEXt" + data))
    ihdr_end = 8 + 4 + 4 + 13 + 4  # signature, IHDR length/type/data/CRC
    return png[:ihdr_end] + chunk + png[ihdr_end:]
