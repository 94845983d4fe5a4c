"""The ``arrays`` container: ``format=arrays``, media type ``application/x-illumix-arrays``.

A flat binary body that a reader maps straight onto numpy arrays (``np.frombuffer``, no parsing of
the array bytes, no CRC, no zip directory), built without copying the arrays: the body is a list of
memoryviews (header, then each array's own buffer) that the service streams as it is.

Layout (integers little-endian; offsets from the start of the body)::

    0   8 bytes   magic  b"ILLUMIXA"
    8   1 byte    version (1)
    9   3 bytes   reserved, zero
    12  4 bytes   uint32 N, the header's length in bytes
    16  N bytes   header, UTF-8 JSON (no NaN/inf)
    …   zeros up to the first array's offset
        each array's raw C-order bytes at its ``offset`` (a multiple of 64), zeros between arrays;
        the body ends where the last array ends.

The header is ``{"arrays": {name: {"dtype", "shape", "offset", "nbytes"[, "scale"]}}, ...}``:

- ``dtype`` a numpy type string, little-endian or byte-order free (``"<f4"``, ``"<f2"``, ``"|b1"``);
  ``shape`` a list of ints (``[]`` for a 0-d array); ``nbytes`` = product(shape) × itemsize;
- ``scale`` (only on arrays sent as float16, ``dtype=float16``): the value is ``stored × scale``, a
  power of two chosen per array (see :func:`service.encoding.half_precision`);
- ``meta``: the sample's metadata (``GET /sample`` with ``meta`` in ``outputs``);
- ``items`` (``POST /batch``): one entry per sample, ``{"meta": {...}}`` when that item asked for
  meta, else ``{}``; the batch's arrays are named ``"{i}/{output}"``.

The client's decoder is ``clients/python/illumix_client/arrays_format.py`` (it imports no server
code; tests/test_wire.py checks the two against each other).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

MAGIC = b"ILLUMIXA"
VERSION = 1
MEDIA_TYPE = "application/x-illumix-arrays"
ALIGN = 64
PREFIX = struct.Struct("<8sB3xI")  # magic, version, reserved, header length: 16 bytes
_KINDS = "biufc"  # bool, signed, unsigned, float, complex: fixed-size plain bytes


def _little(a: np.ndarray) -> np.ndarray:
    """``a`` as C-contiguous little-endian (a copy only when it is neither)."""
    if a.dtype.kind not in _KINDS:
        raise ValueError(f"the arrays format holds bool/int/float arrays, not {a.dtype}")
    if a.dtype.byteorder == ">":
        a = a.astype(a.dtype.newbyteorder("<"))
    return a if a.flags.c_contiguous else a.copy(order="C")  # (ascontiguousarray makes 0-d arrays 1-d)


def _align(n: int) -> int:
    return -(-n // ALIGN) * ALIGN


@dataclass
class Encoded:
    """An encoded body: ``chunks`` (memoryviews; the arrays' own buffers, not copies) whose
    concatenation is the body, ``nbytes`` long. Keep it alive until the chunks are sent."""

    chunks: list[memoryview]
    nbytes: int

    def tobytes(self) -> bytes:
        """The body as one ``bytes`` (one copy of every array; for tests and in-process use)."""
        return b"".join(self.chunks)


def encode(arrays: Mapping[str, np.ndarray], scales: Mapping[str, float] | None = None, **extra) -> Encoded:
    """Encode ``arrays`` (name → array) with optional per-array ``scales`` and extra header keys
    (``meta=``, ``items=``; JSON-able, finite). No array is copied unless it is non-contiguous or
    big-endian."""
    parts = {k: _little(np.asarray(a)) for k, a in arrays.items()}
    scales = dict(scales or {})
    entries: dict[str, dict] = {}
    header = b""
    # The offsets depend on the header's length, which depends on the offsets' digits: iterate
    # until the first offset no longer moves (twice at most in practice).
    start = 0
    for _ in range(8):
        offset, entries = start, {}
        for k, a in parts.items():
            entries[k] = {"dtype": a.dtype.str, "shape": list(a.shape), "offset": offset, "nbytes": a.nbytes}
            if k in scales:
                entries[k]["scale"] = float(scales[k])
            offset = _align(offset + a.nbytes)
        header = json.dumps({"arrays": entries, **extra}, allow_nan=False, separators=(",", ":")).encode()
        first = _align(PREFIX.size + len(header))
        if first == start:
            break
        start = first
    else:  # pragma: no cover  (the header's length converges at once)
        raise RuntimeError("arrays format: header length did not converge")
    lead = bytearray(start)
    PREFIX.pack_into(lead, 0, MAGIC, VERSION, len(header))
    lead[PREFIX.size:PREFIX.size + len(header)] = header
    chunks, pos = [memoryview(lead)], start
    for k, a in parts.items():
        e = entries[k]
        if e["offset"] > pos:
            chunks.append(memoryview(bytes(e["offset"] - pos)))
        if a.nbytes:
            chunks.append(memoryview(a.reshape(-1).view(np.uint8)))
        pos = e["offset"] + a.nbytes
    return Encoded(chunks, pos)
