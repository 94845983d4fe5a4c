"""Reading cubes and AOVs (behind :meth:`store.CubeStore.read_cube` / :meth:`~store.CubeStore.read_aov`).

Reads never return torn data: the node's ``write_id`` is read before and after the data, and a
node replaced in between is read again (see :mod:`store.nodes`). Cubes are decoded one row of
chunks at a time, so a full-frame read costs little beyond its float32 result.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from illumix.store import layout
from illumix.store.checksums import describe_chunk_error
from illumix.store.codec import EXPONENT_FILL, decode
from illumix.store.errors import StoreError, StoreKeyError
from illumix.store.names import check_name
from illumix.store.nodes import band_index, crop_region, current_write_id, open_array
from illumix.store.writer import DENOISED, ILLUMINATION

if TYPE_CHECKING:
    from illumix.store.cubestore import CubeStore

RETRIES = 8
KINDS = ("transport", "illumination")


def read_cube(st: CubeStore, scene: str, view: str, group: str, crop, bands: Sequence[int] | None,
              kind: str, denoised: bool = False) -> np.ndarray:
    """See :meth:`store.CubeStore.read_cube`."""
    if kind not in KINDS:
        raise StoreError(f"unknown cube kind {kind!r}; use one of {', '.join(KINDS)}")
    b = st.backend
    for _ in range(RETRIES):
        path, state, meta = st.complete_node(scene, view, group)
        h, w, nb = state["shape"]
        y0, y1, x0, x1 = crop_region(crop, h, w, f"{scene}/{view}/{group}")
        idx = band_index(bands, nb)
        k = nb if idx is None else idx.size
        if meta.empty:
            return np.zeros((y1 - y0, x1 - x0, k), np.float32)
        storage = meta.storage
        if denoised:
            storage, path = _denoised(meta, kind, path, f"{scene}/{view}/{group}")
        elif kind == ILLUMINATION:
            if meta.illumination is None or meta.illumination.storage is None:
                raise StoreKeyError("illumination cube", group, [], f"{scene}/{view}",
                                    detail=f"cube {scene}/{view}/{group} has no illumination cube (rendered "
                                           "before illumination cubes existed); re-render it")
            storage, path = meta.illumination.storage, f"{path}/{ILLUMINATION}"
        wid = state["write_id"]
        node = layout.cube_path(scene, view, group)
        beta = storage.band_exponent
        beta = None if beta is None else (beta if idx is None else np.asarray(beta)[idx])
        out = np.empty((y1 - y0, x1 - x0, k), np.float32)
        try:
            data = open_array(st.array_handles, b, f"{path}/data", wid, node)
            exp = open_array(st.array_handles, b, f"{path}/exponent", wid, node) if storage.dtype == "float16" else None
            ex = exp[y0:y1, x0:x1] if exp is not None else None  # one byte per pixel: read it whole
            if ex is not None and np.any(ex == EXPONENT_FILL):
                raise StoreError("missing exponent chunk")
            # One chunk row at a time: the stored (float16) copy in memory is one row band.
            step = max(data.chunks[0], 128)
            edges = [y0, *range((y0 // step + 1) * step, y1, step), y1]
            for a, c in zip(edges[:-1], edges[1:]):
                raw = data[a:c, x0:x1] if idx is None else data.oindex[a:c, x0:x1, idx]
                decode(raw, None if ex is None else ex[a - y0:c - y0], beta, out=out[a - y0:c - y0])
        except Exception as exc:  # noqa: BLE001 - any zarr/codec/IO failure
            if current_write_id(b, node) != wid:
                continue  # replaced while we read: retry on the new version
            why = describe_chunk_error(exc) or f"{type(exc).__name__}: {exc}"
            raise StoreError(f"cube {scene}/{view}/{group} is damaged ({st.url}/{path}/data): {why}; re-render "
                             "this cube (`illumix store verify` lists the damage)") from None
        if current_write_id(b, node) != wid:
            continue
        if np.isnan(out.sum(dtype=np.float64)):
            raise StoreError(f"missing or corrupt chunks in {st.url}/{path}/data (crop {crop}); "
                             "delete and rewrite this cube")
        return out
    raise StoreError(f"cube {scene}/{view}/{group} was replaced {RETRIES} times while being read; retry")


def _denoised(meta, kind: str, path: str, where: str):
    """``(storage, array group path)`` of a node's denoised copy of ``kind``."""
    dn = meta.denoised
    storage = None if dn is None else (dn.storage if kind == "transport" else dn.illumination_storage)
    if storage is None:
        raise StoreKeyError(f"denoised {kind} cube", where, [], where,
                            detail=f"cube {where} has no denoised {kind} copy; re-render it with "
                                   "`illumix render … --denoise dt-irradiance --overwrite`")
    return storage, f"{path}/{DENOISED}" + (f"/{ILLUMINATION}" if kind == ILLUMINATION else "")


def read_aov(st: CubeStore, scene: str, view: str, name: str, crop) -> np.ndarray:
    """See :meth:`store.CubeStore.read_aov`."""
    b = st.backend
    vm = st.view_meta(scene, view)
    check_name(name, "AOV")
    path = layout.aov_path(scene, view, name)
    y0, y1, x0, x1 = crop_region(crop, vm.height, vm.width, f"{scene}/{view}")
    for _ in range(RETRIES):
        wid = current_write_id(b, path)
        if wid is None:
            raise StoreKeyError("AOV", name, vm.aovs, f"{scene}/{view}")
        try:
            out = open_array(st.array_handles, b, path, wid)[y0:y1, x0:x1]
        except Exception as exc:  # noqa: BLE001
            if current_write_id(b, path) != wid:
                continue
            why = describe_chunk_error(exc) or f"{type(exc).__name__}: {exc}"
            raise StoreError(f"AOV {scene}/{view}/{name} is damaged ({st.url}/{path}): {why}; rewrite the "
                             "view's AOVs (`illumix store verify` lists the damage)") from None
        if current_write_id(b, path) == wid:
            if out.dtype.kind == "f" and np.isnan(out.sum(dtype=np.float64)):
                raise StoreError(f"missing or corrupt chunks in {st.url}/{path}; rewrite the view's AOVs")
            return out
    raise StoreError(f"AOV {scene}/{view}/{name} was replaced {RETRIES} times while being read; retry")
