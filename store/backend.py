"""Where a store lives: a local directory or any fsspec URL.

The two differ in how a write becomes visible (*complete-or-invisible*):

* **local directory** (the embedded default): a node (cube group, AOV array) is written whole under
  ``_staging/<id>`` and then moved into place with one ``os.rename`` of its directory — atomic on
  POSIX, so readers see either nothing or everything. A replaced node is first renamed into
  ``_trash/<id>`` and deleted afterwards.
* **fsspec URL** (object storage, ``memory://`` …) has no atomic directory rename: the node is
  written in place with ``complete: false`` in its metadata and the metadata is rewritten with
  ``complete: true`` as the very last write (one object PUT, atomic on object stores). Readers
  treat an incomplete node as absent.

Both write small metadata files atomically (temp file + rename locally; one PUT remotely).
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zarr

from illumix.store.errors import StoreError

#: an empty zarr v3 group's ``zarr.json`` as illumix writes it (:func:`store.nodes.group_meta_bytes`)
EMPTY_GROUP_BYTES = b'{"zarr_format":3,"node_type":"group","attributes":{}}'
STAGING = "_staging"
TRASH = "_trash"
#: bytes of parsed metadata a local store remembers (a parsed cube ``zarr.json`` takes ~3× its
#: 5–16 KiB on disk); the least recently read go first
JSON_MEMO_BYTES = 16 * 2**20
#: a file modified more recently than this is not remembered: on a file system whose timestamps are
#: coarse (ext3: 1 s; ext4 before Linux 6.13: a few ms), a rewrite within the same tick that also
#: reuses the inode could not be told apart from the version remembered (git's "racy" rule)
JSON_MEMO_SETTLE_NS = 2 * 10**9


def is_local(location: str) -> bool:
    """A local path (or ``file://`` URL) rather than another fsspec protocol."""
    return "://" not in location or location.startswith("file://")


class Backend:
    """File-level access to a store root plus the zarr store object for array I/O.

    Keys are ``/``-separated paths relative to the root (``"scenes/s/v/zarr.json"``).
    """

    def __init__(self, location: str | os.PathLike, read_only: bool,
                 storage_options: dict[str, Any] | None = None, atomic_rename: bool | None = None) -> None:
        loc = os.fspath(location)
        self.read_only = read_only
        self.local = is_local(loc)
        if self.local:
            self.root: Path | None = Path(loc.removeprefix("file://")).expanduser().absolute()
            self.url = str(self.root)
            self._root_s = self.url + os.sep
            self.zstore = zarr.storage.LocalStore(self.root, read_only=read_only)
            self.fs = None
            self.fsroot = ""
        else:
            import fsspec

            from illumix.store.remote import storage_options as remote_options

            self.root = None
            self.url = loc.rstrip("/")
            storage_options = remote_options(self.url, storage_options)  # a bounded listing cache
            self.fs, self.fsroot = fsspec.core.url_to_fs(self.url, **storage_options)
            self.fsroot = self.fsroot.rstrip("/")
            self.zstore = zarr.storage.FsspecStore.from_url(
                self.url, storage_options=storage_options, read_only=read_only)
        #: True: publish by directory rename; False: in-place write + completion marker.
        self.atomic_rename = self.local if atomic_rename is None else (atomic_rename and self.local)
        # key -> ((inode, mtime_ns, size), parsed, cost): a service reads the same few metadata files
        # on every request; a stat tells whether one changed (every write replaces the file: a new
        # inode and mtime) at a tenth of the cost of reading and parsing it again
        self._json_memo: OrderedDict[str, tuple[tuple[int, int, int], Any, int]] = OrderedDict()
        self._json_bytes = 0
        self._json_lock = threading.Lock()

    # ---- files -------------------------------------------------------------------------------
    def _p(self, key: str) -> Path:
        assert self.root is not None
        return self.root / key.lstrip("/")  # never an absolute path: keys stay under the root

    def _s(self, key: str) -> str:
        """The local path of ``key`` as a str (the hot read paths: joining a Path costs more than
        the stat or scandir it is for)."""
        return self._root_s + key.lstrip("/")

    def _f(self, key: str) -> str:
        key = key.lstrip("/")
        return f"{self.fsroot}/{key}" if key else self.fsroot

    def exists(self, key: str) -> bool:
        return os.path.exists(self._s(key)) if self.local else bool(self.fs.exists(self._f(key)))

    def read_bytes(self, key: str) -> bytes | None:
        """The file's bytes, or ``None`` when it does not exist."""
        try:
            if self.local:
                with open(self._s(key), "rb") as f:
                    return f.read()
            return bytes(self.fs.cat_file(self._f(key)))
        except (FileNotFoundError, NotADirectoryError):
            return None
        except IsADirectoryError:
            return None

    def read_json(self, key: str, validate: Callable[[bytes], None] | None = None) -> Any:
        """Parsed JSON of ``key``; ``None`` when missing; :class:`StoreError` when unreadable.
        ``validate(raw bytes)`` runs on every fresh read (not on a remembered one) and may raise.

        Local stores remember what they parsed while the file's inode, mtime and size stay the same
        (files older than :data:`JSON_MEMO_SETTLE_NS`, up to :data:`JSON_MEMO_BYTES`), so the result
        is shared between calls: read it, never change it."""
        stamp = None
        if self.local:
            try:
                st = os.stat(self._s(key))
            except (FileNotFoundError, NotADirectoryError):
                return None
            stamp = (st.st_ino, st.st_mtime_ns, st.st_size)
            with self._json_lock:
                hit = self._json_memo.get(key)
                if hit is not None and hit[0] == stamp:
                    self._json_memo.move_to_end(key)
                    return hit[1]
        raw = self.read_bytes(key)
        if raw is None:
            return None
        try:
            parsed = json.loads(raw)
        except ValueError as exc:
            raise StoreError(f"corrupt metadata file {key} in {self.url}: {exc}; rewrite this node") from None
        if validate is not None:
            validate(raw)
        # a file replaced since the stat has another inode or mtime: the next call reads it again
        if stamp is not None and time.time_ns() - stamp[1] > JSON_MEMO_SETTLE_NS:
            self._remember(key, stamp, parsed, 3 * len(raw))
        return parsed

    def _remember(self, key: str, stamp: tuple[int, int, int], parsed: Any, cost: int) -> None:
        with self._json_lock:
            old = self._json_memo.pop(key, None)
            self._json_bytes -= old[2] if old else 0
            if cost > JSON_MEMO_BYTES:
                return
            self._json_memo[key] = (stamp, parsed, cost)
            self._json_bytes += cost
            while self._json_bytes > JSON_MEMO_BYTES:
                self._json_bytes -= self._json_memo.popitem(last=False)[1][2]

    def write_bytes(self, key: str, data: bytes, exclusive: bool = False) -> None:
        """Atomically write ``key`` (temp file + rename locally, one PUT remotely).

        ``exclusive``: fail with ``FileExistsError`` if it exists (atomic via ``os.link`` locally;
        check-then-put remotely, where two simultaneous creators may race).
        """
        self.check_writable()
        if self.local:
            p = self._p(key)
            p.parent.mkdir(parents=True, exist_ok=True)
            # the writer's pid in the name: `store verify --repair` removes a partial whose writer died
            tmp = p.with_name(f"{p.name}.{os.getpid()}.{uuid.uuid4().hex}.partial")
            try:
                with open(tmp, "wb") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
                if exclusive:
                    os.link(tmp, p)
                else:
                    os.replace(tmp, p)
            finally:
                tmp.unlink(missing_ok=True)
        else:
            path = self._f(key)
            if exclusive and self.fs.exists(path):
                raise FileExistsError(path)
            self.fs.pipe_file(path, data)

    def list_dirs(self, key: str) -> list[str]:
        """Names of the sub-directories (node children) of ``key``; ``[]`` when it does not exist."""
        if self.local:
            try:
                with os.scandir(self._s(key)) as it:
                    return sorted(e.name for e in it if e.is_dir() and not e.name.startswith("."))
            except (FileNotFoundError, NotADirectoryError):
                return []
        try:
            entries = self.fs.ls(self._f(key), detail=True)
        except FileNotFoundError:
            return []
        return sorted(e["name"].rstrip("/").rsplit("/", 1)[-1] for e in entries if e.get("type") == "directory")

    def list_files(self, key: str) -> list[str]:
        """Every file under ``key`` (recursively), as sorted paths relative to it; ``[]`` when absent."""
        if self.local:
            base = self._p(key)
            out = []
            for dirpath, _, files in os.walk(base):
                rel = os.path.relpath(dirpath, base)
                out += [name if rel == "." else f"{rel}/{name}".replace(os.sep, "/") for name in files]
            return sorted(out)
        root = self._f(key)
        try:
            found = self.fs.find(root)
        except FileNotFoundError:
            return []
        strip = root.rstrip("/") + "/"
        return sorted(f[len(strip):] if f.startswith(strip) else f for f in found)

    def mtime(self, key: str) -> float:
        """Modification time (s since the epoch) of the local file ``key``."""
        return os.stat(self._s(key)).st_mtime

    def size(self, key: str) -> int:
        """Total bytes of all files under ``key``."""
        if self.local:
            total = 0
            for dirpath, _, files in os.walk(self._p(key)):
                for name in files:
                    try:
                        total += os.stat(os.path.join(dirpath, name)).st_size
                    except FileNotFoundError:
                        pass
            return total
        try:
            return int(self.fs.du(self._f(key), total=True))
        except FileNotFoundError:
            return 0

    def count_files(self, key: str) -> int:
        """Number of files under ``key`` (used to check that every chunk is present)."""
        if self.local:
            return sum(len(files) for _, _, files in os.walk(self._p(key)))
        try:
            return len(self.fs.find(self._f(key)))
        except FileNotFoundError:
            return 0

    # ---- nodes -------------------------------------------------------------------------------
    def check_writable(self) -> None:
        if self.read_only:
            raise StoreError(f"store {self.url} is opened read-only; open it with mode='a' to write")

    def ensure_group(self, key: str) -> None:
        """Create the zarr group ``key`` (and its parents) if missing; never touches existing attrs.
        Safe against concurrent writers creating the same group (the loser finds it there). Written
        in illumix's compact form, so ``store verify`` can tell any altered byte
        (:func:`store.checksums.check_empty_group`)."""
        parts = key.strip("/").split("/")
        for i in range(1, len(parts) + 1):
            sub = "/".join(parts[:i])
            if not self.exists(f"{sub}/zarr.json"):
                try:
                    self.write_bytes(f"{sub}/zarr.json", EMPTY_GROUP_BYTES, exclusive=True)
                except FileExistsError:
                    pass

    def new_write_path(self, final: str) -> tuple[str, str]:
        """(path to write the node at, write id). A staging path when publishing by rename."""
        wid = uuid.uuid4().hex
        if self.atomic_rename:
            self.ensure_group(STAGING)
        return (f"{STAGING}/{wid}" if self.atomic_rename else final), wid

    def publish(self, written: str, final: str, replace: bool) -> None:
        """Make the node written at ``written`` visible at ``final`` (rename mode only; in marker
        mode the node is already in place and its ``complete`` flag published it).

        ``replace``: an existing node at ``final`` is swapped out (renamed to ``_trash`` and
        deleted); otherwise an existing node makes this raise ``FileExistsError``.
        """
        if written == final:
            return
        src, dst = self._p(written), self._p(final)
        dst.parent.mkdir(parents=True, exist_ok=True)
        for _ in range(20):
            try:
                os.rename(src, dst)
                return
            except OSError as exc:
                if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.EISDIR):
                    raise
                if not replace:
                    raise FileExistsError(final) from None
                self.remove(final)
        raise StoreError(f"could not replace {final} in {self.url}: another writer keeps replacing it")

    def remove(self, key: str) -> None:
        """Delete the node ``key`` (atomically invisible locally: renamed to ``_trash`` first)."""
        self.check_writable()
        if self.local:
            try:
                self.ensure_group(TRASH)
                trash = self._p(f"{TRASH}/{uuid.uuid4().hex}")
            except OSError as exc:
                if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                    raise
                # a full disk: _trash cannot be created, but deleting must still free space; a rename
                # beside the node needs no new blocks and still hides it from readers at once
                p = self._p(key)
                trash = p.with_name(f".{p.name}.{uuid.uuid4().hex}.deleting")
            try:
                os.rename(self._p(key), trash)
            except FileNotFoundError:
                return
            shutil.rmtree(trash, ignore_errors=True)
        else:
            try:
                self.fs.rm(self._f(key), recursive=True)
            except FileNotFoundError:
                pass

    def discard_file(self, key: str) -> None:
        """Remove one file (a leftover temporary file); absent is fine."""
        self.check_writable()
        try:
            if self.local:
                os.unlink(self._s(key))
            else:
                self.fs.rm_file(self._f(key))
        except FileNotFoundError:
            pass

    def discard(self, key: str) -> None:
        """Best-effort removal of a staging node after a failed write."""
        try:
            if self.local:
                shutil.rmtree(self._p(key), ignore_errors=True)
            else:
                self.fs.rm(self._f(key), recursive=True)
        except (FileNotFoundError, OSError):
            pass
