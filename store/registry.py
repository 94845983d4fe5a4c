"""Persistent user registries (uploaded sensors and illuminants) inside the store.

Each entry is one zarr group ``_registry/<kind>/<name>/`` whose ``zarr.json`` holds the payload
(base64), its format tag, size, SHA-256 and creation time, with its checksum manifest beside it
(:mod:`store.checksums`). Locally an entry is written whole in a hidden sibling folder
``.<name>.<pid>.<id>.partial`` (never listed) and moved into place with one rename (an overwritten
entry is renamed aside first, ``.<name>.<pid>.<id>.old``, and removed after; what a killed writer
left is finished by the next put); on object storage the document is one PUT, then its manifest.
A failed upload leaves nothing behind and a restart loses nothing. The payload is opaque bytes
here; the service parses and validates it (rawtoaces camera JSON, CSV …) before putting it.

A write the disk refuses (full, read-only, failing) is a :class:`StoreWriteError` carrying its
``errno`` (the service answers 507), with nothing left behind. A delete needs no new space, so it
works on a full disk and frees it: locally the entry's ``zarr.json`` is unlinked first (the entry is
gone from that moment: only a folder holding one counts), then its folder is removed; nothing is
written (no ``_trash`` folder, no temporary file).
"""

from __future__ import annotations

import base64
import errno
import hashlib
import os
import shutil
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

from illumix.store.backend import Backend
from illumix.store.errors import StoreError, StoreKeyError, StoreWriteError
from illumix.store.names import check_fmt, check_name
from illumix.store.checksums import pid_alive, write_manifest
from illumix.store.nodes import group_meta_bytes, node_attrs
from illumix.store.schema import SCHEMA_VERSION, utc_now

KINDS = ("sensors", "illuminants")
#: Default payload size limit in bytes (a rawtoaces camera JSON is ~10-50 kB).
DEFAULT_MAX_BYTES = 1 << 20
REG_ATTR = "illumix_registry"


@dataclass(frozen=True)
class RegistryEntry:
    """Metadata of one entry: ``size`` in bytes, ``sha256`` hex digest, ``created`` UTC ISO."""

    name: str
    kind: str
    fmt: str
    size: int
    sha256: str
    created: str


class Registry:
    """A named collection of uploaded payloads (``kind`` = ``"sensors"`` or ``"illuminants"``).

    Names follow :func:`store.names.check_name` (no path separators, no ``..``, ≤ 128 characters
    of ``[A-Za-z0-9_.+-]``); payloads are limited to ``max_bytes`` (default 1 MiB).
    """

    def __init__(self, backend: Backend, kind: str, max_bytes: int | None = None) -> None:
        if kind not in KINDS:
            raise StoreError(f"unknown registry {kind!r}; use one of {', '.join(KINDS)}")
        self._b, self.kind = backend, kind
        self.max_bytes = DEFAULT_MAX_BYTES if max_bytes is None else int(max_bytes)
        self._what = kind[:-1]

    def _path(self, name: str) -> str:
        return f"_registry/{self.kind}/{check_name(name, self._what)}"

    def put(self, name: str, data: bytes, fmt: str, overwrite: bool = False) -> RegistryEntry:
        """Store ``data`` (``fmt`` e.g. ``"csv"``/``"json"``) under ``name``, atomically.

        Raises :class:`StoreError` for a bad name or format, an empty or oversized payload, or an
        existing entry unless ``overwrite``.
        """
        self._b.check_writable()
        path = self._path(name)
        check_fmt(fmt)
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise StoreError(f"{self._what} {name!r}: payload must be bytes, got {type(data).__name__}")
        data = bytes(data)
        if not data:
            raise StoreError(f"{self._what} {name!r}: the uploaded file is empty")
        if len(data) > self.max_bytes:
            raise StoreError(f"{self._what} {name!r}: {len(data)} bytes exceeds the {self.max_bytes}-byte limit; "
                             "upload a smaller file")
        entry = RegistryEntry(name, self.kind, fmt, len(data), hashlib.sha256(data).hexdigest(), utc_now())
        attrs = {REG_ATTR: {"schema_version": SCHEMA_VERSION, **entry.__dict__,
                            "data_b64": base64.b64encode(data).decode("ascii")}}
        doc = group_meta_bytes(attrs)
        try:
            self._b.ensure_group(f"_registry/{self.kind}")
            if self._b.local:
                self._put_local(name, path, doc, overwrite)
            else:
                self._put_remote(path, doc, overwrite)
        except FileExistsError:
            raise StoreError(f"{self._what} {name!r} already exists in the {self.kind} registry of "
                             f"{self._b.url}; pass overwrite=True to replace it") from None
        except OSError as exc:  # the staged entry is removed: nothing half-written stays behind
            raise StoreWriteError(f"could not write {self._what} {name!r} to {self._b.url}: "
                                  f"{exc.strerror or exc}; nothing was written — {_fix(exc.errno)}",
                                  exc.errno) from None
        return entry

    def _put_remote(self, path: str, doc: bytes, overwrite: bool) -> None:
        """The document (one PUT), then its manifest; a new entry whose manifest fails is removed again."""
        if not overwrite and self._b.exists(f"{path}/zarr.json"):
            raise FileExistsError(path)
        self._b.write_bytes(f"{path}/zarr.json", doc)
        try:
            write_manifest(self._b, path, ["zarr.json"], {"zarr.json": doc})
        except OSError:
            if not overwrite:
                self._b.remove(path)
            raise

    def _put_local(self, name: str, path: str, doc: bytes, overwrite: bool) -> None:
        """Write the entry in a hidden sibling folder and rename it into place (module docstring)."""
        final = self._b.root / path
        _sweep(final.parent)
        stage = final.with_name(f".{name}.{os.getpid()}.{uuid.uuid4().hex}.partial")
        old = None
        try:
            staged = f"_registry/{self.kind}/{stage.name}"
            self._b.write_bytes(f"{staged}/zarr.json", doc)
            write_manifest(self._b, staged, ["zarr.json"], {"zarr.json": doc})
            if not (final / "zarr.json").exists():
                shutil.rmtree(final, ignore_errors=True)  # a folder without its document is no entry
            elif overwrite:
                old = final.with_name(f".{name}.{os.getpid()}.{uuid.uuid4().hex}.old")
                os.rename(final, old)
            try:
                os.rename(stage, final)
            except OSError as exc:
                if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):  # another request wrote it meanwhile: it stays
                    raise FileExistsError(path) from None
                if old is not None:  # put the old entry back
                    os.rename(old, final)
                    old = None
                raise
        finally:
            shutil.rmtree(stage, ignore_errors=True)
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)

    def _load(self, name: str) -> dict:
        path = self._path(name)
        attrs = node_attrs(self._b, path)
        if attrs is None:
            raise StoreKeyError(self._what, name, self.names(), f"the {self.kind} registry")
        rec = attrs.get(REG_ATTR)
        need = ("schema_version", "fmt", "size", "sha256", "created", "data_b64")
        if not isinstance(rec, dict) or any(k not in rec for k in need):
            missing = next((k for k in need if not isinstance(rec, dict) or k not in rec), REG_ATTR)
            raise StoreError(f"missing attribute {missing!r} in {self._b.url}/{path}; delete and re-upload it")
        if not isinstance(rec["schema_version"], int) or rec["schema_version"] > SCHEMA_VERSION:
            raise StoreError(f"{self._b.url}/{path} has schema version {rec['schema_version']}, newer than this "
                             f"illumix reads ({SCHEMA_VERSION}); upgrade illumix")
        return rec

    def get(self, name: str) -> tuple[bytes, str]:
        """``(payload bytes, format tag)``; verifies size and SHA-256."""
        rec = self._load(name)
        try:
            data = base64.b64decode(rec["data_b64"], validate=True)
        except ValueError:
            data = b""
        if len(data) != rec["size"] or hashlib.sha256(data).hexdigest() != rec["sha256"]:
            raise StoreError(f"corrupt registry entry {self._b.url}/{self._path(name)}: payload does not match its "
                             "size/SHA-256; delete and re-upload it")
        return data, rec["fmt"]

    def info(self, name: str) -> RegistryEntry:
        """The entry's metadata without decoding the payload."""
        rec = self._load(name)
        return RegistryEntry(name, self.kind, rec["fmt"], int(rec["size"]), rec["sha256"], rec["created"])

    def names(self) -> list[str]:
        """Entry names, sorted."""
        base = f"_registry/{self.kind}"
        return [n for n in self._b.list_dirs(base) if self._b.exists(f"{base}/{n}/zarr.json")]

    def delete(self, name: str) -> None:
        """Remove an entry (:class:`StoreKeyError` if absent), needing no new space (module docstring)."""
        self._b.check_writable()
        path = self._path(name)
        if not self._b.exists(f"{path}/zarr.json"):  # (its content is not read: a damaged entry can go too)
            raise StoreKeyError(self._what, name, self.names(), f"the {self.kind} registry")
        try:
            if self._b.local:
                try:
                    os.unlink(self._b.root / path / "zarr.json")
                except FileNotFoundError:  # deleted meanwhile by another request
                    raise StoreKeyError(self._what, name, self.names(), f"the {self.kind} registry") from None
                shutil.rmtree(self._b.root / path, ignore_errors=True)  # a leftover folder counts as no entry
            else:
                self._b.remove(path)  # object storage: deleting objects needs no space
        except OSError as exc:
            raise StoreWriteError(f"could not delete {self._what} {name!r} from {self._b.url}: "
                                  f"{exc.strerror or exc}; {_fix(exc.errno, 'delete it again')}", exc.errno) from None

    def __contains__(self, name: object) -> bool:
        try:
            return isinstance(name, str) and self._b.exists(f"{self._path(name)}/zarr.json")
        except StoreError:
            return False

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())


def _sweep(folder) -> None:
    """Finish what a put killed mid-way left in ``folder`` (its writer's pid, in the name, is dead): a
    staged entry is removed; an entry renamed aside for an overwrite goes back when nothing replaced
    it, else is removed. Best effort: a failure here is the next put's to retry."""
    try:
        hidden = [p for p in folder.iterdir() if p.name.startswith(".") and p.name.endswith((".partial", ".old"))]
        for p in hidden:
            parts = p.name.rsplit(".", 3)
            if len(parts) != 4 or not parts[1].isdigit() or pid_alive(int(parts[1])):
                continue
            final = folder / parts[0][1:]
            if parts[3] == "old" and not (final / "zarr.json").exists():
                shutil.rmtree(final, ignore_errors=True)
                os.rename(p, final)
            else:
                shutil.rmtree(p, ignore_errors=True)
    except OSError:
        pass


def _fix(n: int | None, then: str = "upload again") -> str:
    """What to do about a write the storage refused (``n``: its errno)."""
    if n in (errno.ENOSPC, errno.EDQUOT):
        return f"free space on the store's disk (deleting uploads works on a full disk) and {then}"
    if n in (errno.EROFS, errno.EACCES, errno.EPERM):
        return f"make the store writable for the service and {then}"
    return f"check the store's disk and {then}"
