"""Store inspection: :func:`info` (what is stored) and :func:`verify` (is every byte right).

``verify`` reads every array completely (chunk by chunk row, bounded memory) and checks: metadata
schemas, shapes against the view and grid, every chunk present, finiteness after decoding, and that
the decoded values reproduce the stored per-band statistics within the dtype policy's bound.
Interrupted writes (staged but unpublished, or incomplete in place) are *notes*, not problems: the
store stays valid and the cube is simply absent until a rerun completes it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import zarr

from illumix.store import checksums, layout
from illumix.store.codec import EXPONENT_FILL, decode
from illumix.store.cubestore import CUBE_ATTR, VIEW_ATTR, CubeStore
from illumix.store.errors import StoreError
from illumix.store.nodes import STATE_ATTR, node_attrs, read_state
from illumix.store.registry import KINDS
from illumix.store.schema import CubeMeta, ViewMeta, parse_stored
from illumix.store.writer import DENOISED, ILLUMINATION


def _group_info(st: CubeStore, scene: str, view: str, g: str) -> dict[str, Any]:
    path = layout.cube_path(scene, view, g)
    row: dict[str, Any] = {"name": g, "emission": None, "dtype": None, "complete": False, "empty": False,
                           "shape": None, "bytes": None}
    try:
        attrs = node_attrs(st.backend, path) or {}
        state = attrs.get(STATE_ATTR) or {}
        row["complete"] = bool(state.get("complete"))
        row["shape"] = state.get("shape")
        if row["complete"]:
            m = parse_stored(CubeMeta, attrs.get(CUBE_ATTR), path)
            row.update(emission=m.emission_name, dtype=m.storage.dtype if m.storage else None, empty=m.empty,
                       bytes=m.storage.nbytes_stored if m.storage else None, spp=m.spp,
                       renderer=m.renderer.name, chunks=m.storage.chunks if m.storage else None,
                       codec=m.storage.codec if m.storage else None,
                       illumination=m.illumination is not None and m.illumination.storage is not None,
                       denoised=m.denoised.method if m.denoised is not None and m.denoised.storage else None)
    except StoreError as exc:
        row["error"] = str(exc)
    return row


def info(st: CubeStore) -> dict[str, Any]:
    """Summary ``{store, scenes: [{name, views: [{name, width, height, aovs, groups: [{name,
    emission, dtype, complete, empty, shape, bytes, …}]}]}], registries, pending_writes}``.
    Groups are listed in stored order, incomplete ones included (``complete: false``)."""
    scenes = []
    for s in st.scenes():
        views = []
        for v in st.views(s):
            try:
                vm = st.view_meta(s, v)
                groups = [_group_info(st, s, v, g) for g in st.groups(s, v, include_incomplete=True)]
                views.append({"name": v, "width": vm.width, "height": vm.height, "aovs": vm.aovs,
                              "groups": groups})
            except StoreError as exc:
                views.append({"name": v, "width": None, "height": None, "aovs": [], "groups": [],
                              "error": str(exc)})
        scenes.append({"name": s, "views": views})
    regs = {}
    for k in KINDS:
        try:
            regs[k] = st.registry(k).names()
        except StoreError:
            regs[k] = []
    return {"store": st.url, "scenes": scenes, "registries": regs, "pending_writes": len(st.pending_writes())}


class _Report:
    def __init__(self) -> None:
        self.problems: list[dict[str, str]] = []
        self.notes: list[dict[str, str]] = []
        self.checked = {"views": 0, "aovs": 0, "cubes": 0, "registry_entries": 0, "files_checksummed": 0}

    def bad(self, where: str, what: str) -> None:
        self.problems.append({"where": where, "what": what})

    def note(self, where: str, what: str) -> None:
        self.notes.append({"where": where, "what": what})


def _chunks_ok(st: CubeStore, rep: _Report, path: str, arr: zarr.Array) -> bool:
    want = layout.n_chunks(arr.shape, arr.chunks)
    have = st.backend.count_files(f"{path}/c")
    if have != want:
        rep.bad(path, f"{want - have} of {want} chunks missing" if have < want else
                f"{have} chunk files but the array has {want} chunks")
        return False
    return True


def _check_aov(st: CubeStore, rep: _Report, path: str, vm: ViewMeta) -> None:
    state = read_state(st.backend, path)
    if state is None:
        rep.bad(path, "directory without zarr.json (not a zarr array)")
        return
    if not state.get("complete"):
        rep.note(path, "incomplete AOV write (interrupted); rewrite the view")
        return
    arr = zarr.open_array(st.backend.zstore, path=path, mode="r")
    if tuple(arr.shape[:2]) != (vm.height, vm.width):
        rep.bad(path, f"shape {arr.shape} does not match the view's {vm.height}x{vm.width}")
        return
    if _chunks_ok(st, rep, path, arr):
        a = arr[...]
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            rep.bad(path, f"{int(np.count_nonzero(~np.isfinite(a)))} NaN/inf values")
    rep.checked["aovs"] += 1


def _check_cube(st: CubeStore, rep: _Report, path: str, vm: ViewMeta) -> None:
    state = read_state(st.backend, path)
    if state is None:
        rep.bad(path, "directory without zarr.json (not a zarr group)")
        return
    if not state.get("complete"):
        rep.note(path, f"incomplete cube (writer pid {state.get('pid')} started {state.get('started')}); "
                       "rerun the render job")
        return
    attrs = node_attrs(st.backend, path) or {}
    meta = parse_stored(CubeMeta, attrs.get(CUBE_ATTR), path, required=("grid", "created", "storage", "stats"))
    shape = (vm.height, vm.width, meta.n_bands)
    if tuple(state.get("shape") or ()) != shape:
        rep.bad(path, f"recorded shape {state.get('shape')} != (view height, width, grid bands) {shape}")
        return
    rep.checked["cubes"] += 1
    if meta.empty:
        return
    _check_encoded(st, rep, path, shape, meta.storage, meta.stats)
    if meta.illumination is not None and meta.illumination.storage is not None:
        _check_encoded(st, rep, f"{path}/{ILLUMINATION}", shape, meta.illumination.storage, meta.illumination.stats)
    dn = meta.denoised
    if dn is not None and dn.storage is not None:
        _check_encoded(st, rep, f"{path}/{DENOISED}", shape, dn.storage, dn.stats)
    if dn is not None and dn.illumination_storage is not None:
        _check_encoded(st, rep, f"{path}/{DENOISED}/{ILLUMINATION}", shape, dn.illumination_storage,
                       dn.illumination_stats)


def _check_encoded(st: CubeStore, rep: _Report, path: str, shape: tuple, storage, stats) -> None:
    """One encoded cube (``path/data`` and, for float16, ``path/exponent``): shape, dtype, every
    chunk present, finite after decoding, and the decoded values reproduce the stored statistics."""
    f16 = storage.dtype == "float16"
    data = zarr.open_array(st.backend.zstore, path=f"{path}/data", mode="r")
    if tuple(data.shape) != shape or str(data.dtype) != storage.dtype:
        rep.bad(f"{path}/data", f"array {data.shape} {data.dtype} != metadata {shape} {storage.dtype}")
        return
    ok = _chunks_ok(st, rep, f"{path}/data", data)
    exp = zarr.open_array(st.backend.zstore, path=f"{path}/exponent", mode="r") if f16 else None
    if exp is not None:
        ok = _chunks_ok(st, rep, f"{path}/exponent", exp) and ok
    if not ok:
        return
    nb = shape[2]
    mx, mn = np.full(nb, -np.inf), np.full(nb, np.inf)
    total = np.zeros(nb)
    cy = data.chunks[0]
    for r0 in range(0, shape[0], cy):
        ex = exp[r0:r0 + cy] if exp is not None else None
        if ex is not None and np.any(ex == EXPONENT_FILL):
            rep.bad(f"{path}/exponent", f"missing exponent chunk in rows {r0}-{r0 + cy}")
            return
        blk = decode(data[r0:r0 + cy], ex, storage.band_exponent)
        fin = np.isfinite(blk)
        if not fin.all():
            y, x, b = np.argwhere(~fin)[0]
            rep.bad(f"{path}/data", f"{int(blk.size - fin.sum())} NaN/inf values (missing or corrupt chunk), "
                                    f"first at x={x}, y={r0 + y}, band {b}")
            return
        flat = blk.reshape(-1, nb)
        mx, mn = np.maximum(mx, flat.max(0)), np.minimum(mn, flat.min(0))
        total += flat.sum(0, dtype=np.float64)
    smax, smin, smean = np.array(stats.max), np.array(stats.min), np.array(stats.mean)
    rel = storage.rel_error_bound + 1e-9
    big = np.maximum(np.abs(smax), np.abs(smin))
    slack = (2.0**-24 * big if storage.underflow_values else 0) + 1e-30
    mean_abs = np.where(smin >= 0, np.abs(smean), big)
    checks = (("max", mx, smax, rel * np.abs(smax) + slack), ("min", mn, smin, rel * np.abs(smin) + slack),
              ("mean", total / (shape[0] * shape[1]), smean, rel * mean_abs + 1e-12 * big + slack))
    for name, got, want, tol in checks:
        off = np.abs(got - want) > tol
        if off.any():
            b = int(np.argmax(off))
            rep.bad(f"{path}/data", f"decoded {name} of band {b} is {got[b]:.6g} but the stored stats say "
                                    f"{want[b]:.6g} (tolerance {tol[b]:.3g}): corrupt data or metadata")
            return


def _check_group(b, rep: _Report, path: str) -> bool:
    """An intermediate group's ``zarr.json`` (if present) must be readable zarr v3 metadata: zarr
    itself refuses to open anything below a corrupt one."""
    if not b.exists(f"{path}/zarr.json"):
        return True
    try:
        node_attrs(b, path)
        return True
    except StoreError as exc:
        rep.bad(path, str(exc))
        return False


def _check_checksums(st: CubeStore, rep: _Report) -> None:
    """Every file against its node's manifest, every intermediate group against its exact content
    (:mod:`store.checksums`); the nodes' own files only where sub-folders are nodes of their own."""
    b = st.backend
    n = checksums.check_node(b, "", rep.bad, rep.note, own=["zarr.json"])
    for g in ("scenes", "_registry", "_staging", "_trash", *(f"_registry/{k}" for k in KINDS)):
        checksums.check_empty_group(b, g, rep.bad)
    for s in b.list_dirs("scenes"):
        if not checksums.check_empty_group(b, f"scenes/{s}", rep.bad):
            continue
        for v in b.list_dirs(f"scenes/{s}"):
            vp = layout.view_path(s, v)
            n += checksums.check_node(b, vp, rep.bad, rep.note, own=["zarr.json"])
            for sub in ("cubes", "aov"):
                if checksums.check_empty_group(b, f"{vp}/{sub}", rep.bad):
                    for node in b.list_dirs(f"{vp}/{sub}"):
                        n += checksums.check_node(b, f"{vp}/{sub}/{node}", rep.bad, rep.note)
    for k in KINDS:
        for e in b.list_dirs(f"_registry/{k}"):
            n += checksums.check_node(b, f"_registry/{k}/{e}", rep.bad, rep.note, own=["zarr.json"])
    rep.checked["files_checksummed"] = n


def _partials(st: CubeStore, rep: _Report, repair: bool, min_age_s: float) -> list[str]:
    """Temporary ``.partial`` files of interrupted writes: noted, and removed with ``repair`` when
    orphaned (:func:`store.checksums.orphaned`). Returns the keys removed."""
    removed = []
    for key, pid, age in checksums.partial_files(st.backend):
        if repair and checksums.orphaned(pid, age, min_age_s):
            if st.backend.list_files(key):  # a staged folder (a registry entry's)
                st.backend.discard(key)
            else:
                st.backend.discard_file(key)
            removed.append(key)
        else:
            rep.note(key, f"temporary file of an interrupted write (writer pid {pid}, {age:.0f} s old); "
                          "`illumix store verify --repair` removes it once its writer is gone")
    return removed


def verify(st: CubeStore, repair: bool = False, min_age_s: float = 600.0) -> dict[str, Any]:
    """Check the whole store. Returns ``{ok, problems: [{where, what}], notes: [...], checked,
    repaired}``. ``repair``: first remove what interrupted writes left (orphaned ``.partial`` files,
    staged writes of dead writers, ``_trash``); damaged data is never removed, only reported."""
    rep = _Report()
    b = st.backend
    repaired = _partials(st, rep, repair, min_age_s)
    if repair:
        n = st.cleanup(older_than_s=min_age_s, dead_writers=True)
        if n:
            repaired.append(f"{n} staged write(s) of dead writers or trashed node(s)")
    _check_checksums(st, rep)
    _check_group(b, rep, "scenes")
    for s in b.list_dirs("scenes"):
        if not b.exists(f"scenes/{s}/zarr.json"):
            rep.bad(f"scenes/{s}", "directory without zarr.json (not a zarr group)")
            continue
        if not _check_group(b, rep, f"scenes/{s}"):
            continue
        for v in b.list_dirs(f"scenes/{s}"):
            vp = layout.view_path(s, v)
            try:
                attrs = node_attrs(b, vp)
                if attrs is None or VIEW_ATTR not in attrs:
                    (rep.bad if b.list_dirs(f"{vp}/cubes") else rep.note)(
                        vp, "view without metadata (interrupted write_view?); rewrite the view")
                    continue
                vm = parse_stored(ViewMeta, attrs[VIEW_ATTR], vp, required=("width", "height"))
            except StoreError as exc:
                rep.bad(vp, str(exc))
                continue
            rep.checked["views"] += 1
            for sub in ("cubes", "aov"):
                _check_group(b, rep, f"{vp}/{sub}")
            for a in vm.aovs:
                if not b.exists(f"{layout.aov_path(s, v, a)}/zarr.json"):
                    rep.bad(layout.aov_path(s, v, a), "AOV listed in the view metadata is missing")
            for kind, names, fn in (("aov", b.list_dirs(f"{vp}/aov"), _check_aov),
                                    ("cubes", b.list_dirs(f"{vp}/cubes"), _check_cube)):
                for n in names:
                    p = f"{vp}/{kind}/{n}"
                    try:
                        fn(st, rep, p, vm)
                    except StoreError as exc:
                        rep.bad(p, str(exc))
                    except Exception as exc:  # noqa: BLE001 - corrupt zarr metadata or chunks
                        rep.bad(p, f"unreadable: {type(exc).__name__}: {exc}")
    for pw in st.pending_writes():
        rep.note(pw["path"], f"staged write of {pw.get('target')} not published (pid {pw.get('pid')}, started "
                             f"{pw.get('started')}): in progress or interrupted; `CubeStore.cleanup()` removes it")
    for k in KINDS:
        reg = st.registry(k)
        for n in reg.names():
            try:
                reg.get(n)
                rep.checked["registry_entries"] += 1
            except StoreError as exc:
                rep.bad(f"_registry/{k}/{n}", str(exc))
    return {"store": st.url, "ok": not rep.problems, "problems": rep.problems, "notes": rep.notes,
            "checked": rep.checked, "repaired": repaired}
