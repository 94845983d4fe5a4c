"""Low-level node I/O shared by cubes, AOVs and registry entries.

A *node* is a zarr group or array directory. Writers create it (at a staging path or in place, see
:mod:`store.backend`) with ``complete: false`` in its state attribute, write its arrays, rewrite the
state with ``complete: true`` and publish it. Readers use :func:`read_state` before and after
reading data: if the ``write_id`` changed in between the node was replaced mid-read and the read is
retried, so a reader never returns a mix of two versions (a seqlock).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import zarr

from illumix.store.backend import Backend
from illumix.store.checksums import check_document
from illumix.store.errors import StoreError
from illumix.store.layout import compressors
from illumix.store.lru import LRUCache

STATE_ATTR = "illumix_state"


def group_meta_bytes(attrs: dict[str, Any]) -> bytes:
    """zarr v3 group metadata (``zarr.json``) holding ``attrs``."""
    return json.dumps({"zarr_format": 3, "node_type": "group", "attributes": attrs},
                      allow_nan=False, separators=(",", ":")).encode()


def write_group(backend: Backend, path: str, attrs: dict[str, Any]) -> None:
    """Create or rewrite the zarr group at ``path`` with ``attrs`` (one atomic file write)."""
    backend.write_bytes(f"{path}/zarr.json", group_meta_bytes(attrs))


def node_attrs(backend: Backend, path: str) -> dict[str, Any] | None:
    """Attributes of the node at ``path``; ``None`` if it does not exist. Shared with every other
    reader of the unchanged file (:meth:`store.backend.Backend.read_json`): never change them.
    A document its node's manifest disagrees with is refused (:func:`store.checksums.check_document`)."""
    js = backend.read_json(f"{path}/zarr.json" if path else "zarr.json",
                           lambda raw: check_document(backend, path, "zarr.json", raw))
    if js is None:
        return None
    if not isinstance(js, dict) or js.get("zarr_format") != 3:
        raise StoreError(f"corrupt metadata in {path}/zarr.json of {backend.url}: not zarr v3 metadata; "
                         "rewrite this node")
    attrs = js.get("attributes") or {}
    if not isinstance(attrs, dict):
        raise StoreError(f"corrupt attributes in {path}/zarr.json of {backend.url}; rewrite this node")
    return attrs


def read_state(backend: Backend, path: str) -> dict[str, Any] | None:
    """The node's state ``{complete, write_id, …}``; ``None`` when the node does not exist."""
    attrs = node_attrs(backend, path)
    if attrs is None:
        return None
    state = attrs.get(STATE_ATTR)
    if not isinstance(state, dict) or "write_id" not in state:
        raise StoreError(f"missing attribute {STATE_ATTR!r} in {path} of {backend.url}; the node was not "
                         "written by illumix or is corrupt: delete and rewrite it")
    return state


def current_write_id(backend: Backend, path: str) -> str | None:
    """``write_id`` of the complete node at ``path``, else ``None`` (absent, incomplete or unreadable)."""
    try:
        st = read_state(backend, path)
    except StoreError:
        return None
    return st["write_id"] if st and st.get("complete") else None


def create_array(backend: Backend, path: str, shape: tuple[int, ...], chunks: tuple[int, ...],
                 dtype: Any, codec: str, fill_value: Any, dims: tuple[str, ...],
                 attributes: dict[str, Any] | None = None) -> zarr.Array:
    """Create a chunked zarr v3 array at ``path`` (replacing anything there)."""
    itemsize = np.dtype(dtype).itemsize
    return zarr.create_array(backend.zstore, name=path, shape=shape, chunks=chunks, dtype=dtype,
                             compressors=compressors(codec, itemsize), fill_value=fill_value,
                             dimension_names=dims, attributes=attributes or {}, overwrite=True,
                             config={"write_empty_chunks": True})  # every chunk on disk: countable


def array_handles(size: int = 256) -> LRUCache[zarr.Array]:
    """Open zarr array handles keyed by ``(path, write_id)`` (a replaced node gets a new id), at
    most ``size`` of them. Opening an array reads its ``zarr.json``; caching the handle saves that
    on every crop read."""
    return LRUCache(size)


def open_array(handles: LRUCache[zarr.Array], backend: Backend, path: str, write_id: str,
               node: str | None = None) -> zarr.Array:
    """The read-only zarr array at ``path`` of the node version ``write_id``, through ``handles``;
    its ``zarr.json`` checked against the manifest of ``node`` (the array's own node by default)
    when first opened."""
    def opened() -> zarr.Array:
        root = path if node is None else node
        rel = "zarr.json" if root == path else f"{path[len(root) + 1:]}/zarr.json"
        raw = backend.read_bytes(f"{path}/zarr.json")
        if raw is not None:
            check_document(backend, root, rel, raw)
        return zarr.open_array(backend.zstore, path=path, mode="r")

    return handles.get((path, write_id), opened)


def crop_region(crop: tuple[int, int, int, int] | None, height: int, width: int,
                where: str) -> tuple[int, int, int, int]:
    """``crop=(x, y, w, h)`` in pixels → ``(y0, y1, x0, x1)``; the whole frame for ``None``.

    Raises :class:`StoreError` unless ``0 <= x``, ``0 <= y``, ``w, h >= 1`` and the crop lies inside
    the ``width × height`` frame.
    """
    if crop is None:
        return 0, height, 0, width
    try:
        x, y, w, h = (int(v) for v in crop)
    except (TypeError, ValueError):
        raise StoreError(f"crop must be four integers (x, y, w, h), got {crop!r}") from None
    if w < 1 or h < 1 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise StoreError(f"crop (x={x}, y={y}, w={w}, h={h}) is outside the {width}x{height} frame of "
                         f"{where}; use 0 <= x, x + w <= {width}, 0 <= y, y + h <= {height}")
    return y, y + h, x, x + w


def band_index(bands: Any, n_bands: int) -> np.ndarray | None:
    """Validated band indices ``(k,)`` int64, or ``None`` for all bands."""
    if bands is None:
        return None
    idx = np.asarray(bands, dtype=np.int64).ravel()
    if idx.size == 0 or idx.min() < 0 or idx.max() >= n_bands:
        raise StoreError(f"bands must be non-empty indices in [0, {n_bands}), got {list(idx[:8])}")
    return idx
