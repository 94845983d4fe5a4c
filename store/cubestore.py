"""``CubeStore``: spectral transport cubes per scene / view / light group in a zarr v3 store.

Typical use::

    st = CubeStore.open("./illumix-store", mode="a")          # or "s3://bucket/store", "memory://x"
    st.write_view("kitchen", "v0", ViewMeta(width=960, height=720, fov=60, groups=["window", "lamp"]),
                  {"albedo": albedo, "normal": normal, "depth": depth, "mask": mask})
    st.write_cube("kitchen", "v0", "window", cube, CubeMeta(grid=SpectralGrid(), spp=256, seed=1))
    crop = st.read_cube("kitchen", "v0", "window", crop=(x, y, 256, 256))   # (256, 256, 63) float32

Writes are complete-or-invisible (see :mod:`store.backend`), reads never return torn data (see
:mod:`store.nodes`), values follow the dtype policy of :mod:`store.codec`, chunking and compression
follow :mod:`store.layout`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from illumix.store import layout
from illumix.store.backend import STAGING, TRASH, Backend
from illumix.store.codec import POLICIES, Policy
from illumix.store.errors import StoreError, StoreKeyError
from illumix.store.names import check_name
from illumix.store.nodes import STATE_ATTR, array_handles, current_write_id, node_attrs, read_state
from illumix.store.schema import SCHEMA_VERSION, CubeMeta, ViewMeta, parse_stored, utc_now
from illumix.store import reader, writer

ROOT_ATTR = "illumix_store"
VIEW_ATTR = writer.VIEW_ATTR
CUBE_ATTR = writer.CUBE_ATTR

Crop = tuple[int, int, int, int]


class CubeStore:
    """A cube store at a local directory or fsspec URL. Create with :meth:`open`.

    Thread-safe for concurrent reads; several processes may write different cubes at once.
    """

    def __init__(self, backend: Backend, tile: int, codec: str, dtype_policy: Policy) -> None:
        self._b = backend
        self.tile, self.codec, self.dtype_policy = tile, codec, dtype_policy
        self.array_handles = array_handles()  # open zarr arrays, reused by reads (keyed by write id)

    # ---- opening -------------------------------------------------------------------------------
    @classmethod
    def exists(cls, location: str | os.PathLike, *, storage_options: dict | None = None) -> bool:
        """Whether an illumix store (a root ``zarr.json``) is at ``location``: False for a missing
        path, an empty directory or an fsspec URL with nothing there yet (``open(mode="a")`` creates
        one there). Reads only. Raises :class:`StoreError` for a location no store can be created
        at (a file, a non-empty directory that is not a store) or one that cannot be read."""
        b = _backend(location, read_only=True, storage_options=storage_options)
        if node_attrs(b, "") is not None:
            return True
        if b.local and b.root.exists() and (not b.root.is_dir() or any(b.root.iterdir())):
            what = "is not a directory" if not b.root.is_dir() else "is not empty and is not an illumix store"
            raise StoreError(f"{b.url} {what}; choose a new or empty directory")
        return False

    @classmethod
    def open(cls, location: str | os.PathLike, mode: str = "a", *, storage_options: dict | None = None,
             tile: int = layout.DEFAULT_TILE, codec: str = layout.DEFAULT_CODEC,
             dtype_policy: Policy = "auto", atomic_rename: bool | None = None) -> CubeStore:
        """Open (``mode="r"``) or open-or-create (``mode="a"``) the store at ``location``.

        ``location``: a local directory path (the embedded default) or an fsspec URL
        (``s3://…``, ``gs://…``, ``memory://…``) with ``storage_options`` for the filesystem.
        ``tile``: chunk edge in pixels for new cubes (chunks are ``(tile, tile, bands)``).
        ``codec``: compressor for new arrays (:data:`store.layout.CODECS`). ``dtype_policy``:
        default storage policy for new cubes (:mod:`store.codec`). ``atomic_rename``: publish
        writes by directory rename (default: local directories) or by completion marker.
        """
        if mode not in ("r", "a"):
            raise StoreError(f"unknown store mode {mode!r}; use 'r' (read-only) or 'a' (create if missing)")
        if codec not in layout.CODECS:
            raise StoreError(f"unknown codec {codec!r}; use one of {', '.join(layout.CODECS)}")
        if dtype_policy not in POLICIES:
            raise StoreError(f"unknown dtype policy {dtype_policy!r}; use one of {', '.join(POLICIES)}")
        if not 16 <= int(tile) <= 4096:
            raise StoreError(f"tile {tile} px is out of range; use 16-4096 (default {layout.DEFAULT_TILE})")
        b = _backend(location, read_only=(mode == "r"), storage_options=storage_options,
                     atomic_rename=atomic_rename)
        attrs = node_attrs(b, "")
        if attrs is None:
            if mode == "r" or (b.local and b.root.exists() and not b.root.is_dir()):
                what = "is not a directory" if b.local and b.root.exists() and not b.root.is_dir() \
                    else "does not exist (no zarr.json)"
                raise StoreError(f"no illumix store at {b.url}: it {what}; give the store directory "
                                 "or create one with `illumix render --store PATH`")
            if b.local and b.root.exists() and any(b.root.iterdir()):
                # Another process may be creating this store right now (its temp file is there,
                # zarr.json not yet renamed into place): give it a moment before refusing.
                for _ in range(40):
                    time.sleep(0.05)
                    attrs = node_attrs(b, "")
                    if attrs is not None:
                        break
                else:
                    raise StoreError(f"{b.url} exists, is not empty and is not an illumix store; "
                                     "choose a new or empty directory")
            if attrs is None:
                from illumix.store.checksums import write_manifest
                from illumix.store.nodes import write_group

                write_group(b, "", {ROOT_ATTR: {"schema_version": SCHEMA_VERSION, "created": utc_now()}})
                write_manifest(b, "", ["zarr.json"])
        if attrs is not None:
            root = attrs.get(ROOT_ATTR)
            if not isinstance(root, dict):
                raise StoreError(f"{b.url} is a zarr group but not an illumix store (no {ROOT_ATTR!r} "
                                 "attribute); give the store directory")
            v = root.get("schema_version")
            if not isinstance(v, int):
                raise StoreError(f"missing attribute 'schema_version' in {b.url}/zarr.json; the store is corrupt")
            if v > SCHEMA_VERSION:
                raise StoreError(f"store {b.url} has schema version {v}, newer than this illumix reads "
                                 f"({SCHEMA_VERSION}); upgrade illumix")
        return cls(b, int(tile), codec, dtype_policy)

    @property
    def url(self) -> str:
        """The store's location (absolute directory or URL)."""
        return self._b.url

    @property
    def read_only(self) -> bool:
        return self._b.read_only

    @property
    def backend(self) -> Backend:
        return self._b

    def __repr__(self) -> str:
        return f"CubeStore({self.url!r}, mode={'r' if self.read_only else 'a'})"

    def __enter__(self) -> CubeStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Drop cached array handles (the store holds no other resources)."""
        self.array_handles = array_handles()  # open zarr arrays, reused by reads (keyed by write id)

    # ---- listing -------------------------------------------------------------------------------
    def scenes(self) -> list[str]:
        """Scene names, sorted."""
        return [s for s in self._b.list_dirs("scenes") if self._b.exists(f"scenes/{s}/zarr.json")]

    def views(self, scene: str) -> list[str]:
        """Names of the scene's views that have metadata (written by :meth:`write_view`), sorted. A view
        whose metadata is damaged is not among them: :meth:`view_health` names it, with why."""
        return self.view_health(scene)[0]

    def view_health(self, scene: str) -> tuple[list[str], dict[str, str]]:
        """``(healthy views, {damaged view: why})`` from one read of the scene's view documents: views
        whose metadata cannot be read (damaged, or failing its checksum) are named, never left out
        silently, and one damaged view never hides the healthy ones."""
        self._check_scene(scene)
        out, damaged = [], {}
        for v in self._b.list_dirs(f"scenes/{scene}"):
            try:
                attrs = node_attrs(self._b, layout.view_path(scene, v))
            except StoreError as exc:
                damaged[v] = str(exc)
                continue
            if attrs is not None and VIEW_ATTR in attrs:
                out.append(v)
        return out, damaged

    def has_scene(self, scene: str) -> bool:
        """Whether ``scene`` exists (one file test; :meth:`scenes` lists them all)."""
        return _safe(scene) and self._b.exists(f"scenes/{scene}/zarr.json")

    def has_view(self, scene: str, view: str) -> bool:
        """Whether ``scene`` has the view ``view`` with metadata (one metadata read; :meth:`views`
        reads every view's)."""
        if not (_safe(scene) and _safe(view)):
            return False
        attrs = node_attrs(self._b, layout.view_path(scene, view))  # None as well when the scene is missing
        return attrs is not None and VIEW_ATTR in attrs

    def groups(self, scene: str, view: str, include_incomplete: bool = False) -> list[str]:
        """The view's light groups in stored order: first ``ViewMeta.groups`` (declared order), then
        undeclared ones in order of first write. Only complete groups (empty ones included) unless
        ``include_incomplete`` (then also interrupted or in-progress writes, and damaged ones).
        Raises :class:`StoreError` when a group's metadata is corrupt (without ``include_incomplete``),
        never leaving it out silently."""
        vm = self.view_meta(scene, view)
        cubes = f"{layout.view_path(scene, view)}/cubes"
        entries: dict[str, tuple[bool, str]] = {}
        for g in self._b.list_dirs(cubes):
            try:
                st = read_state(self._b, f"{cubes}/{g}")
            except StoreError as exc:
                if not include_incomplete:
                    # Dropping the group would silently re-shape the view (pair= would light
                    # other groups): a damaged view is an error until it is repaired.
                    raise StoreError(f"view {scene}/{view} is damaged: {exc}; run `illumix store verify "
                                     f"{self.url}` and re-render the group") from None
                st = {"complete": False}
            if st is not None:
                entries[g] = (bool(st.get("complete")), str(st.get("first_written") or ""))
        if include_incomplete:
            for st in self.pending_writes():
                parent, _, name = str(st.get("target", "")).rpartition("/")
                if parent == cubes:
                    entries.setdefault(name, (False, str(st.get("first_written") or "")))
        order = {g: i for i, g in enumerate(vm.groups)}
        names = [g for g, (done, _) in entries.items() if done or include_incomplete]
        return sorted(names, key=lambda g: (order.get(g, len(order)), entries[g][1], g))

    def is_complete(self, scene: str, view: str, group: str) -> bool:
        """True iff the cube (or empty-group record) is completely written."""
        check_name(scene, "scene"), check_name(view, "view"), check_name(group, "group")
        return current_write_id(self._b, layout.cube_path(scene, view, group)) is not None

    def pending_writes(self) -> list[dict[str, Any]]:
        """States of staged writes not yet published (in progress, or left by a killed writer):
        ``{target, write_id, started, pid, …}``. Local directories only; elsewhere ``[]``."""
        out = []
        for sid in self._b.list_dirs(STAGING):
            try:
                st = read_state(self._b, f"{STAGING}/{sid}")
            except StoreError:
                st = None
            out.append({**(st or {}), "path": f"{STAGING}/{sid}"})
        return out

    # ---- metadata ------------------------------------------------------------------------------
    def _check_scene(self, scene: str) -> None:
        check_name(scene, "scene")
        if not self._b.exists(f"scenes/{scene}/zarr.json"):
            raise StoreKeyError("scene", scene, self.scenes(), self.url)

    def view_meta(self, scene: str, view: str) -> ViewMeta:
        """The view's :class:`ViewMeta`."""
        check_name(view, "view")
        path = layout.view_path(scene, view)
        attrs = node_attrs(self._b, path) if self._b.exists(f"scenes/{scene}/zarr.json") else None
        if attrs is None or VIEW_ATTR not in attrs:
            self._check_scene(scene)
            raise StoreKeyError("view", view, self.views(scene), f"scene {scene!r}")
        return parse_stored(ViewMeta, attrs[VIEW_ATTR], f"{self.url}/{path}", required=("width", "height"))

    def complete_node(self, scene: str, view: str, group: str) -> tuple[str, dict, CubeMeta]:
        """``(node path, write state, metadata)`` of a complete cube: what a reader needs to read
        its arrays untorn (the state's ``write_id`` is compared before and after; :mod:`store.reader`).
        :class:`StoreKeyError` for an unknown or incomplete cube."""
        check_name(group, "group")
        path = layout.cube_path(scene, view, group)
        attrs = node_attrs(self._b, path)
        if attrs is None:
            self.view_meta(scene, view)
            raise StoreKeyError("group", group, self.groups(scene, view), f"{scene}/{view}")
        st = attrs.get(STATE_ATTR)
        if not isinstance(st, dict) or "write_id" not in st:
            raise StoreError(f"missing attribute {STATE_ATTR!r} in {self.url}/{path}; delete and rewrite this cube")
        if not st.get("complete"):
            raise StoreKeyError("group", group, self.groups(scene, view), f"{scene}/{view}",
                                detail=f"cube {path} is incomplete (being written or its writer was "
                                       "interrupted); rerun the render job to complete it")
        meta = parse_stored(CubeMeta, attrs.get(CUBE_ATTR), f"{self.url}/{path}",
                            required=("grid", "created", "storage", "stats"))
        if not (isinstance(st.get("shape"), list) and len(st["shape"]) == 3):
            raise StoreError(f"missing attribute 'shape' in {STATE_ATTR} of {self.url}/{path}; rewrite this cube")
        return path, st, meta

    def cube_meta(self, scene: str, view: str, group: str) -> CubeMeta:
        """The complete cube's :class:`CubeMeta` (with ``stats`` and ``storage`` filled in)."""
        return self.complete_node(scene, view, group)[2]

    def cube_shape(self, scene: str, view: str, group: str) -> tuple[int, int, int]:
        """``(H, W, bands)`` of the complete cube."""
        return tuple(self.complete_node(scene, view, group)[1]["shape"])  # type: ignore[return-value]

    # ---- reading -------------------------------------------------------------------------------
    def read_cube(self, scene: str, view: str, group: str, crop: Crop | None = None,
                  bands: Sequence[int] | None = None, kind: str = "transport", denoised: bool = False) -> np.ndarray:
        """The cube (or a crop of it) decoded to float32, in the renderer's radiometric units.

        ``crop=(x, y, w, h)`` in pixels (column, row, width, height); reads only the chunks it
        overlaps. ``bands``: optional band indices. ``kind``: ``"transport"`` (the cube) or
        ``"illumination"`` (its illumination cube; :class:`StoreKeyError` when the node has none).
        ``denoised``: the stored denoised copy instead (``meta.denoised`` says how it was made;
        :class:`StoreKeyError` when the node has none). Returns ``(h, w, k)`` float32 (``k`` = all
        bands or ``len(bands)``); zeros for an empty group.
        Raises :class:`StoreKeyError` for an unknown or incomplete cube and :class:`StoreError` for
        corrupt data (naming the array).
        """
        return reader.read_cube(self, scene, view, group, crop, bands, kind, denoised)

    def read_aov(self, scene: str, view: str, name: str, crop: Crop | None = None) -> np.ndarray:
        """An AOV of the view, ``(h, w)`` or ``(h, w, C)``: ``albedo`` / ``normal`` ``(h, w, 3)``
        float32, ``depth`` ``(h, w)`` float32 (scene units), ``mask`` / ``emitter`` ``(h, w)`` bool."""
        return reader.read_aov(self, scene, view, name, crop)

    # ---- writing -------------------------------------------------------------------------------
    def write_view(self, scene: str, view: str, meta: ViewMeta | Mapping[str, Any],
                   aovs: Mapping[str, np.ndarray] | None = None) -> ViewMeta:
        """Create or update a view: its metadata and AOVs (each complete-or-invisible).

        ``aovs``: ``albedo`` ``(H, W, 3)``, ``normal`` ``(H, W, 3)``, ``depth`` ``(H, W)`` (finite
        floats; use 0 where nothing was hit) and ``mask`` ``(H, W)`` bool; other names may be
        ``(H, W)`` or ``(H, W, C)`` floats. ``H, W`` = ``meta.height, meta.width``. AOVs written
        before and not given again are kept. Returns the stored :class:`ViewMeta`.
        """
        return self._retrying(f"view {scene}/{view}", lambda: writer.write_view(self, scene, view, meta, aovs))

    def write_cube(self, scene: str, view: str, group: str, cube: np.ndarray,
                   meta: CubeMeta | Mapping[str, Any], *, overwrite: bool = False,
                   dtype_policy: Policy | None = None,
                   progress: Callable[[int, int], None] | None = None,
                   illumination: np.ndarray | None = None,
                   denoised: Mapping[str, np.ndarray] | None = None) -> CubeMeta:
        """Store the transport cube of (scene, view, group); visible only once complete.

        ``cube``: ``(H, W, bands)`` finite floats (converted to float32) with ``H, W`` of the view
        and ``bands`` of ``meta.grid``. ``meta``: :class:`CubeMeta`; ``stats``, ``storage`` and
        ``created`` are filled in. ``overwrite``: replace an existing complete cube (readers see
        the old or the new one, never a mix). ``dtype_policy``: overrides the store default.
        ``progress(rows_done, rows_total)`` is called after each row of chunks. ``illumination``:
        the cube's illumination cube, same shape (stored in the same node, published with it;
        ``meta.illumination`` records it). ``denoised``: ``{"transport": …, "illumination": …}``
        denoised copies (same shapes; ``meta.denoised`` names the method; published with the rest).
        Returns the stored metadata.
        """
        def write() -> CubeMeta:
            return writer.write_cube(self, scene, view, group, cube, meta, overwrite=overwrite,
                                     policy=dtype_policy or self.dtype_policy, progress=progress,
                                     illumination=illumination, denoised=denoised)

        return self._retrying(f"cube {scene}/{view}/{group}", write, lambda: self.cube_meta(scene, view, group))

    def mark_empty(self, scene: str, view: str, group: str, meta: CubeMeta | Mapping[str, Any], *,
                   overwrite: bool = False) -> CubeMeta:
        """Record that ``group`` contributes nothing to this view (e.g. its lights are not visible
        from it and light nothing in it): no array data; reads return zeros."""
        def write() -> CubeMeta:
            return writer.write_cube(self, scene, view, group, None, meta, overwrite=overwrite, policy="float32",
                                     progress=None)

        return self._retrying(f"cube {scene}/{view}/{group}", write, lambda: self.cube_meta(scene, view, group))

    def delete(self, scene: str, view: str | None = None, group: str | None = None) -> None:
        """Delete a scene, a view or one group's cube (invisible at once on local directories)."""
        self._b.check_writable()
        check_name(scene, "scene")
        if view is None:
            self._check_scene(scene)
            self._b.remove(f"scenes/{scene}")
        elif group is None:
            self.view_meta(scene, view)
            self._b.remove(layout.view_path(scene, view))
        else:
            check_name(group, "group")
            path = layout.cube_path(scene, view, group)
            if node_attrs(self._b, path) is None:
                self.view_meta(scene, view)
                raise StoreKeyError("group", group, self.groups(scene, view, True), f"{scene}/{view}")
            self._b.remove(path)

    def cleanup(self, older_than_s: float = 3600.0, dead_writers: bool = False) -> int:
        """Remove staged writes older than ``older_than_s`` (left by killed writers; ``dead_writers``:
        also younger ones whose writer on this host is dead) and replaced nodes in ``_trash``.
        Returns how many entries were removed."""
        return writer.cleanup(self, older_than_s, dead_writers)

    def _retrying(self, what: str, write: Callable[[], Any], done: Callable[[], Any] | None = None) -> Any:
        from illumix.store.remote import node_write

        return node_write(self._b.local, what, write, done)

    def registry(self, kind: str, max_bytes: int | None = None) -> Any:
        """The persistent user registry ``"sensors"`` or ``"illuminants"`` (:class:`store.Registry`)."""
        from illumix.store.registry import Registry

        return Registry(self._b, kind, max_bytes=max_bytes)


def _safe(name: object) -> bool:
    """Whether ``name`` is a valid store name (:func:`store.names.check_name`), without raising."""
    try:
        check_name(name, "name")
    except StoreError:
        return False
    return True


def _backend(location: str | os.PathLike, **kwargs) -> Backend:
    """The store's file backend at ``location`` (a directory or fsspec URL); one-line errors."""
    loc = os.fspath(location)
    if not loc:
        raise StoreError("store path is empty; give a directory or an fsspec URL")
    try:
        return Backend(loc, **kwargs)
    except (ImportError, ValueError, OSError) as exc:
        raise StoreError(f"cannot open store {loc}: {exc}") from None
