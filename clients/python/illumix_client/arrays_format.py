"""Decoder of the illumix ``arrays`` container (``format=arrays``, ``application/x-illumix-arrays``).

Layout (integers little-endian, offsets from the start of the body)::

    0   8 bytes   magic  b"ILLUMIXA"
    8   1 byte    version (1)
    9   3 bytes   reserved
    12  4 bytes   uint32 N, the header's length
    16  N bytes   header, UTF-8 JSON:
                  {"arrays": {name: {"dtype", "shape", "offset", "nbytes"[, "scale"]}},
                   "meta": {...} (a sample that asked for meta), "items": [{"meta": {...}} | {}, ...] (a batch)}
    …   each array's C-order bytes at its offset (a multiple of 64)

``dtype`` is a numpy type string (``"<f4"``, ``"<f2"``, ``"|b1"``); ``scale`` is on float16 arrays
only: value = stored × scale. The service's encoder is ``service/arrays_format.py``; this module
imports nothing from the server.

:func:`decode` maps each array onto the body with ``np.frombuffer`` — no copy. The arrays are
views of the body: writable when the body is (a ``bytearray``, as the client reads answers into),
read-only over ``bytes``; they keep the body alive as long as any of them is.
"""

from __future__ import annotations

import json
import math
import struct
from typing import Any

import numpy as np

from illumix_client.errors import IllumixError

MAGIC = b"ILLUMIXA"
VERSION = 1
MEDIA_TYPE = "application/x-illumix-arrays"
PREFIX = struct.Struct("<8sB3xI")  # 16 bytes
_KINDS = "biufc"


def _bad(why: str) -> IllumixError:
    return IllumixError(f"the response is not a valid illumix arrays body: {why}")


def decode(body: bytes | bytearray | memoryview) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, header)`` of an arrays body: ``arrays`` name → numpy view of ``body`` (shape and
    dtype as sent; float16 arrays as stored, their scales in ``header["arrays"][name]["scale"]``),
    ``header`` the parsed JSON header. Raises :class:`IllumixError` (one line) on a wrong magic, an
    unknown version, a truncated body or an inconsistent header."""
    view = memoryview(body).cast("B") if not isinstance(body, (bytes, bytearray)) else body
    size = len(view)
    if size < PREFIX.size:
        raise _bad(f"{size} bytes, shorter than the {PREFIX.size}-byte prefix (truncated?)")
    magic, version, n = PREFIX.unpack_from(view, 0)
    if magic != MAGIC:
        raise _bad(f"magic {bytes(magic)!r}, expected {MAGIC!r} (an npz or error page?)")
    if version != VERSION:
        raise _bad(f"version {version}; this client reads version {VERSION} (upgrade illumix-client)")
    if PREFIX.size + n > size:
        raise _bad(f"the header needs {PREFIX.size + n} bytes, the body has {size} (truncated)")
    try:
        header = json.loads(bytes(view[PREFIX.size:PREFIX.size + n]))
        entries = header["arrays"]
        if not isinstance(entries, dict):
            raise TypeError("'arrays' is not an object")
    except (ValueError, KeyError, TypeError) as exc:
        raise _bad(f"unreadable header ({exc})") from None
    arrays = {}
    for name, e in entries.items():
        arrays[name] = _array(view, size, PREFIX.size + n, name, e)
    return arrays, header


def _array(body, size: int, data_start: int, name: str, e: Any) -> np.ndarray:
    try:
        dtype = np.dtype(e["dtype"])
        shape = tuple(int(x) for x in e["shape"])
        offset, nbytes = int(e["offset"]), int(e["nbytes"])
    except (KeyError, TypeError, ValueError) as exc:
        raise _bad(f"array {name!r}: malformed entry ({exc})") from None
    if dtype.kind not in _KINDS or dtype.byteorder == ">" or dtype.hasobject:
        raise _bad(f"array {name!r}: unsupported dtype {e['dtype']!r}")
    count = math.prod(shape)  # a Python int: np.prod would wrap around on a forged shape
    if any(x < 0 or x > size for x in shape) or count * dtype.itemsize != nbytes:  # no side beyond the body
        raise _bad(f"array {name!r}: shape {list(shape)} × {dtype.itemsize} bytes is not nbytes {nbytes}")
    if offset < data_start or offset + nbytes > size:
        raise _bad(f"array {name!r} spans bytes {offset}..{offset + nbytes}, outside the body's "
                   f"{data_start}..{size} (truncated)")
    return np.frombuffer(body, dtype=dtype, count=count, offset=offset).reshape(shape)


def scales(header: dict[str, Any]) -> dict[str, float]:
    """``{name: scale}`` of the float16 arrays in a decoded header (value = stored × scale)."""
    return {k: float(e["scale"]) for k, e in header.get("arrays", {}).items() if "scale" in e}
