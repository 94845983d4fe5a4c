"""Writing views, AOVs and cubes (used by :class:`store.CubeStore`; see its methods for the API).

Every node is written complete-or-invisible: at ``_staging/<id>`` then renamed into place (local
directories), or in place with ``complete: false`` until its last metadata write (fsspec URLs).
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import ValidationError

from illumix.store import layout
from illumix.store.codec import EXPONENT_FILL, Policy, encode
from illumix.store.errors import StoreError
from illumix.store.names import check_name
from illumix.store.backend import TRASH
from illumix.store.checksums import pid_alive, write_manifest
from illumix.store.nodes import STATE_ATTR, create_array, group_meta_bytes, node_attrs, read_state, write_group
from illumix.store.schema import (SCHEMA_VERSION, BandStats, CubeMeta, DenoisedInfo, IlluminationInfo, StorageInfo, ViewMeta,
                          utc_now)

if TYPE_CHECKING:
    from illumix.store.cubestore import CubeStore

VIEW_ATTR = "illumix_view"
CUBE_ATTR = "illumix_cube"
#: Known AOVs: channels (``None`` = ``(H, W)``) and storage dtype.
ILLUMINATION = "illumination"  # sub-group of a cube node holding its illumination cube
DENOISED = "denoised"  # sub-group holding the denoised transport cube (and DENOISED/ILLUMINATION)
KNOWN_AOVS: dict[str, tuple[int | None, type]] = {
    "albedo": (3, np.float32), "normal": (3, np.float32), "depth": (None, np.float32), "mask": (None, np.bool_),
    "emitter": (None, np.bool_), "albedo_bands": (-1, np.float32), "straddle": (None, np.bool_)}


def _validated(model: type, meta: Any, what: str) -> Any:
    if isinstance(meta, model):
        return meta
    try:
        return model.model_validate(dict(meta))
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ValidationError):
            e = exc.errors()[0]
            loc = ".".join(str(p) for p in e["loc"]) or "(root)"
            raise StoreError(f"invalid {what} field {loc!r}: {e['msg']}") from None
        raise StoreError(f"{what} must be a {model.__name__} or a dict, got {type(meta).__name__}") from None


def _check_aov(name: str, arr: Any, h: int, w: int, where: str) -> np.ndarray:
    check_name(name, "AOV")
    a = np.asarray(arr)
    chans, dtype = KNOWN_AOVS.get(name, (-1, np.float32))
    if chans is None:
        ok, want = a.shape == (h, w), f"({h}, {w})"
    elif chans == -1:
        ok, want = a.shape[:2] == (h, w) and a.ndim in (2, 3), f"({h}, {w}) or ({h}, {w}, C)"
    else:
        ok, want = a.shape == (h, w, chans), f"({h}, {w}, {chans})"
    if not ok:
        raise StoreError(f"AOV {name!r} of {where} has shape {a.shape}; expected {want}")
    if dtype is np.bool_:
        if a.dtype != np.bool_ and not (a.dtype.kind in "iuf" and np.isin(a, (0, 1)).all()):
            raise StoreError(f"AOV {name!r} of {where} must be boolean (or 0/1), got dtype {a.dtype}")
        return a.astype(np.bool_)
    if a.dtype.kind not in "iuf":
        raise StoreError(f"AOV {name!r} of {where} must be numeric, got dtype {a.dtype}")
    a = a.astype(np.float32)
    bad = int(a.size - np.count_nonzero(np.isfinite(a)))
    if bad:
        raise StoreError(f"AOV {name!r} of {where} has {bad} NaN/inf values; use finite values "
                         "(0 where nothing was hit, with the mask marking valid pixels)")
    return a


def _check_cube(cube: Any, shape: tuple[int, int, int], where: str) -> np.ndarray:
    a = np.asarray(cube)
    if a.shape != shape:
        raise StoreError(f"cube for {where} has shape {a.shape}; expected {shape} = (view height, "
                         "view width, grid bands)")
    if a.dtype.kind != "f":
        raise StoreError(f"cube for {where} must be floating point, got dtype {a.dtype}")
    with np.errstate(over="ignore"):
        a = np.ascontiguousarray(a, dtype=np.float32)
    finite = np.isfinite(a)
    if not finite.all():
        bad = np.argwhere(~finite)
        y, x, b = bad[0]
        raise StoreError(f"cube for {where} has {len(bad)} NaN/inf values (or beyond float32), first at "
                         f"x={x}, y={y}, band {b}; the renderer output must be finite")
    return a


def write_array_node(st: CubeStore, final: str, arr: np.ndarray, chunks: tuple[int, ...],
                     dims: tuple[str, ...]) -> None:
    """Write one array node (an AOV) complete-or-invisible."""
    b = st.backend
    wpath, wid = b.new_write_path(final)
    state = {"complete": False, "write_id": wid, "target": final, "started": utc_now(), "pid": os.getpid(),
             "host": socket.gethostname()}
    try:
        fill = False if arr.dtype == np.bool_ else np.nan
        a = create_array(b, wpath, arr.shape, chunks, arr.dtype, st.codec, fill, dims, {STATE_ATTR: state})
        a[...] = arr
        a.attrs.update({STATE_ATTR: {**state, "complete": True, "finished": utc_now()}})
        write_manifest(b, wpath)
        b.publish(wpath, final, replace=True)
    except BaseException:
        if wpath != final:
            b.discard(wpath)
        raise


def discard_dead_staging(st: CubeStore, target: str) -> None:
    """Remove staged writes of ``target`` left by writers that died on this host (a rerun's cleanup)."""
    host = socket.gethostname()
    for pw in st.pending_writes():
        if pw.get("target") == target and pw.get("host") == host and not pid_alive(pw.get("pid")):
            st.backend.discard(pw["path"])


def cleanup(st: CubeStore, older_than_s: float, dead_writers: bool) -> int:
    """See :meth:`store.CubeStore.cleanup`."""
    import time
    from datetime import datetime

    b = st.backend
    b.check_writable()
    n = 0
    for pw in st.pending_writes():
        try:
            age = time.time() - datetime.fromisoformat(str(pw["started"]).replace("Z", "+00:00")).timestamp()
        except (KeyError, ValueError):
            age = float("inf")
        dead = dead_writers and pw.get("host") == socket.gethostname() and not pid_alive(pw.get("pid"))
        if age >= older_than_s or dead:
            b.discard(pw["path"])
            n += 1
    for tid in b.list_dirs(TRASH):
        b.discard(f"{TRASH}/{tid}")
        n += 1
    return n


def write_view(st: CubeStore, scene: str, view: str, meta: ViewMeta | Mapping[str, Any],
               aovs: Mapping[str, np.ndarray] | None) -> ViewMeta:
    b = st.backend
    b.check_writable()
    check_name(scene, "scene"), check_name(view, "view")
    meta = _validated(ViewMeta, meta, "ViewMeta")
    for g in meta.groups:
        check_name(g, "group")
    where = f"{scene}/{view}"
    h, w = meta.height, meta.width
    prepared = {n: _check_aov(n, a, h, w, where) for n, a in (aovs or {}).items()}
    vp = layout.view_path(scene, view)
    old_attrs = node_attrs(b, vp) or {}
    old = None
    if VIEW_ATTR in old_attrs:
        try:
            old = ViewMeta.model_validate(old_attrs[VIEW_ATTR])
        except ValidationError:
            old = None  # unreadable old metadata: replaced below
    kept: set[str] = set()
    if old is not None and (old.width, old.height) != (w, h):
        if st.groups(scene, view, include_incomplete=True):
            raise StoreError(f"view {where} is stored at {old.width}x{old.height} and has cubes; cannot change "
                             f"it to {w}x{h}: delete the view first (CubeStore.delete)")
        for name in old.aovs:
            b.remove(layout.aov_path(scene, view, name))
    elif old is not None:
        kept = set(old.aovs)
    b.ensure_group(f"scenes/{scene}")
    if node_attrs(b, vp) is None:
        write_group(b, vp, {})
    if prepared:
        b.ensure_group(f"{vp}/aov")
    tile = st.tile
    for name, arr in prepared.items():
        chunks = (min(tile, h), min(tile, w)) + arr.shape[2:]
        dims = ("y", "x") + (("channel",) if arr.ndim == 3 else ())
        write_array_node(st, layout.aov_path(scene, view, name), arr, chunks, dims)
    new = meta.model_copy(update={
        "aovs": sorted(kept | set(prepared)), "schema_version": SCHEMA_VERSION,
        "created": meta.created or (old.created if old else None) or utc_now()})
    doc = {**old_attrs, VIEW_ATTR: new.model_dump(mode="json")}
    write_group(b, vp, doc)
    write_manifest(b, vp, ["zarr.json"], {"zarr.json": group_meta_bytes(doc)})  # the AOVs have their own
    return new


def _storage(enc, policy: Policy, chunks: tuple[int, ...], codec: str) -> StorageInfo:
    return StorageInfo(dtype=enc.dtype, encoding="f16-exp2" if enc.dtype == "float16" else "raw",
                       policy=policy, reason=enc.reason, band_exponent=enc.band_exponent,
                       chunks=list(chunks), codec=codec, rel_error_bound=enc.rel_error_bound,
                       underflow_values=enc.underflow)


def _write_encoded(st: CubeStore, path: str, enc, shape: tuple[int, int, int], chunks: tuple[int, ...],
                   progress: Callable[[int, int], None] | None) -> None:
    """The encoded arrays of one cube at ``path/data`` (and ``path/exponent`` for float16)."""
    b = st.backend
    data = create_array(b, f"{path}/data", shape, chunks, enc.data.dtype, st.codec, np.nan, ("y", "x", "band"))
    cy = chunks[0]
    for r0 in range(0, shape[0], cy):
        data[r0:r0 + cy] = enc.data[r0:r0 + cy]
        if progress is not None:
            progress(min(r0 + cy, shape[0]), shape[0])
    if enc.exponent is not None:
        exp = create_array(b, f"{path}/exponent", shape[:2], layout.exponent_chunks(st.tile, *shape[:2]),
                           np.int8, "zstd", EXPONENT_FILL, ("y", "x"))
        exp[...] = enc.exponent


def write_cube(st: CubeStore, scene: str, view: str, group: str, cube: np.ndarray | None,
               meta: CubeMeta | Mapping[str, Any], *, overwrite: bool, policy: Policy,
               progress: Callable[[int, int], None] | None,
               illumination: np.ndarray | None = None,
               denoised: Mapping[str, np.ndarray] | None = None) -> CubeMeta:
    """Write a cube (``cube`` array, optionally with its ``illumination`` cube of the same shape and
    ``denoised`` copies ``{"transport": …, "illumination": …}``, described by ``meta.denoised``) or an
    empty-group record (``cube=None``). All arrays are published together or not at all."""
    b = st.backend
    b.check_writable()
    check_name(group, "group")
    vm = st.view_meta(scene, view)
    meta = _validated(CubeMeta, meta, "CubeMeta")
    where = f"{scene}/{view}/{group}"
    final = layout.cube_path(scene, view, group)
    prev = _previous_state(st, final, where, overwrite)
    nb = meta.n_bands
    shape = (vm.height, vm.width, nb)
    chunks = (min(st.tile, shape[0]), min(st.tile, shape[1]), nb)
    enc, stats, storage = _encode_transport(cube, shape, chunks, policy, st.codec, where)
    illum, enc_u = None, None  # metadata copied from another cube must not claim arrays this node lacks
    if illumination is not None and cube is not None:
        illum, enc_u = _encode_illumination(meta, illumination, shape, chunks, policy, st.codec, where)
    dn, enc_d = _encode_denoised(meta, denoised if cube is not None else None, illum is not None, shape, chunks,
                                 policy, st.codec, where)
    meta = meta.model_copy(update={"stats": stats, "storage": storage, "empty": cube is None, "illumination": illum,
                                   "denoised": dn,
                                   "created": meta.created or utc_now(), "schema_version": SCHEMA_VERSION})
    first = (prev or {}).get("first_written") or utc_now()
    b.ensure_group(f"{layout.view_path(scene, view)}/cubes")
    if b.atomic_rename:
        discard_dead_staging(st, final)
    wpath, wid = b.new_write_path(final)
    state = {"complete": False, "write_id": wid, "target": final, "shape": list(shape),
             "first_written": first, "started": utc_now(), "pid": os.getpid(), "host": socket.gethostname()}
    try:
        if wpath == final and prev is not None:
            b.remove(final)  # in-place (marker) mode: the old version disappears first
        write_group(b, wpath, {CUBE_ATTR: meta.model_dump(mode="json"), STATE_ATTR: state})
        if enc is not None:
            _write_planes(st, wpath, _planes(meta, enc, enc_u, enc_d), shape, chunks, progress)
        state = {**state, "complete": True, "finished": utc_now()}
        write_group(b, wpath, {CUBE_ATTR: meta.model_dump(mode="json"), STATE_ATTR: state})
        write_manifest(b, wpath)  # every file of the node, before it is published (store.checksums)
        try:
            b.publish(wpath, final, replace=overwrite or (prev is not None and not prev.get("complete")))
        except FileExistsError:
            raise StoreError(f"cube {where} was written by another writer meanwhile; pass overwrite=True "
                             "to replace it") from None
    except BaseException:
        if wpath != final:
            b.discard(wpath)
        raise
    return meta


def _previous_state(st: CubeStore, final: str, where: str, overwrite: bool) -> dict[str, Any] | None:
    """The state of the node at ``final`` (``None``: no node; ``{"complete": False}``: unreadable);
    :class:`StoreError` when it is a complete cube and ``overwrite`` is False."""
    b = st.backend
    try:
        prev = read_state(b, final)
    except StoreError:
        prev = {"complete": False}
    if prev and prev.get("complete") and not overwrite:
        raise StoreError(f"cube {where} already exists in {b.url}; pass overwrite=True to replace it")
    return prev


def _encode_transport(cube: np.ndarray | None, shape: tuple[int, int, int], chunks: tuple[int, ...], policy: Policy,
                      codec: str, where: str) -> tuple[Any, BandStats, StorageInfo]:
    """``(encoded, stats, storage)`` of the transport cube; ``encoded`` None (and zero stats) for an
    empty-group record (``cube=None``)."""
    nb = shape[2]
    if cube is None:
        enc = None
        stats = BandStats(max=[0.0] * nb, mean=[0.0] * nb, min=[0.0] * nb)
        storage = StorageInfo(dtype="none", encoding="empty", policy="auto", nbytes_stored=0,
                              reason="group contributes nothing to this view; reads give zeros")
    else:
        arr = _check_cube(cube, shape, where)
        stats = BandStats.of(arr)
        enc = encode(arr, policy)
        del arr
        storage = _storage(enc, policy, chunks, codec)
    return enc, stats, storage


def _encode_illumination(meta: CubeMeta, illumination: np.ndarray, shape: tuple[int, int, int],
                         chunks: tuple[int, ...], policy: Policy, codec: str,
                         where: str) -> tuple[IlluminationInfo, Any]:
    """``(meta.illumination filled in, encoded)`` for the cube's illumination cube."""
    arr = _check_cube(illumination, shape, f"{where} (illumination)")
    enc_u = encode(arr, policy)
    given = meta.illumination.model_dump(exclude={"stats", "storage"}) if meta.illumination else {}
    illum = IlluminationInfo(**given)
    illum.stats, illum.storage = BandStats.of(arr), _storage(enc_u, policy, chunks, codec)
    return illum, enc_u


def _planes(meta: CubeMeta, enc, enc_u, enc_d: dict) -> list[tuple[str, Any, StorageInfo]]:
    """The cube's planes as ``(sub-path under the cube's node, encoded array, its StorageInfo)``:
    the transport cube at the node itself, then its illumination cube and the denoised copies
    (nested: ``denoised/illumination`` is inside ``denoised``)."""
    planes = [("", enc, meta.storage)]
    if enc_u is not None:
        planes.append((ILLUMINATION, enc_u, meta.illumination.storage))
    if "transport" in enc_d:
        planes.append((DENOISED, enc_d["transport"], meta.denoised.storage))
    if ILLUMINATION in enc_d:
        planes.append((f"{DENOISED}/{ILLUMINATION}", enc_d[ILLUMINATION], meta.denoised.illumination_storage))
    return planes


def _write_planes(st: CubeStore, wpath: str, planes: list, shape, chunks, progress) -> None:
    """Write every plane (one loop), then set each one's ``nbytes_stored`` to its own bytes: its
    node's size less the planes nested in it (the progress callback follows the transport plane)."""
    b = st.backend
    for sub, enc, _ in planes:
        path = f"{wpath}/{sub}" if sub else wpath
        if sub:
            write_group(b, path, {})
        _write_encoded(st, path, enc, shape, chunks, progress if not sub else None)
    full = {sub: b.size(f"{wpath}/{sub}" if sub else wpath) for sub, _, _ in planes}

    def parent(sub: str) -> str:  # the nearest plane this one is nested in ("" holds them all)
        return max((p for p in full if p != sub and (p == "" or sub.startswith(p + "/"))), key=len)

    for sub, _, info in planes:
        info.nbytes_stored = full[sub] - sum(full[c] for c in full if c and c != sub and parent(c) == sub)


def _encode_denoised(meta: CubeMeta, denoised: Mapping[str, np.ndarray] | None, has_illumination: bool,
                     shape: tuple[int, int, int], chunks: tuple[int, ...], policy: Policy, codec: str,
                     where: str) -> tuple[DenoisedInfo | None, dict]:
    """``(meta.denoised filled in, {kind: encoded})`` for the denoised copies (none: ``(None, {})``)."""
    if not denoised:
        return None, {}
    unknown = set(denoised) - {"transport", ILLUMINATION}
    if unknown or "transport" not in denoised:
        raise StoreError(f"denoised copies of {where} must be {{'transport': …, 'illumination': …}}, "
                         f"got {sorted(denoised)}")
    if (ILLUMINATION in denoised) != has_illumination:
        raise StoreError(f"{where}: a denoised illumination cube needs the illumination cube, and vice versa")
    if meta.denoised is None or not meta.denoised.method:
        raise StoreError(f"{where}: denoised copies need meta.denoised naming the method")
    info = DenoisedInfo(**meta.denoised.model_dump(exclude={"stats", "storage", "illumination_stats",
                                                            "illumination_storage"}))
    enc = {}
    for kind, arr in denoised.items():
        a = _check_cube(arr, shape, f"{where} (denoised {kind})")
        enc[kind] = encode(a, policy)
        st_, sto = BandStats.of(a), _storage(enc[kind], policy, chunks, codec)
        if kind == "transport":
            info.stats, info.storage = st_, sto
        else:
            info.illumination_stats, info.illumination_storage = st_, sto
        del a
    return info, enc


__all__ = ["write_view", "write_cube", "write_array_node", "KNOWN_AOVS"]
