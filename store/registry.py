"""Persistent user registries (uploaded sensors and illuminants) inside the store.

Each entry is one zarr group ``_registry/<kind>/<name>/`` whose single ``zarr.json`` holds the
payload (base64), its format tag, size, SHA-256 and creation time, so an entry is written with one
atomic file write (temp + rename/link locally, one PUT on object storage): a failed upload leaves
nothing behind and a restart loses nothing. The payload is opaque bytes here; the service parses
and validates it (rawtoaces camera JSON, CSV …) before putting it.
"""

from __future__ import annotations

import base64
import errno
import hashlib
from collections.abc import Iterator
from dataclasses import dataclass

from illumix.store.backend import Backend
from illumix.store.errors import StoreError, StoreKeyError, StoreWriteError
from illumix.store.names import check_fmt, check_name
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
        self._b.ensure_group(f"_registry/{self.kind}")
        try:
            self._b.write_bytes(f"{path}/zarr.json", group_meta_bytes(attrs), exclusive=not overwrite)
        except FileExistsError:
            raise StoreError(f"{self._what} {name!r} already exists in the {self.kind} registry of "
                             f"{self._b.url}; pass overwrite=True to replace it") from None
        except OSError as exc:  # the temp file is removed: nothing half-written stays behind
            full = exc.errno in (errno.ENOSPC, errno.EDQUOT)
            raise StoreWriteError(f"could not write {self._what} {name!r} to {self._b.url}: "
                                  f"{exc.strerror or exc}; nothing was written"
                                  f"{' — free disk space and upload again' if full else ''}", exc.errno) from None
        return entry

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
        """Remove an entry (:class:`StoreKeyError` if absent)."""
        self._b.check_writable()
        path = self._path(name)
        if node_attrs(self._b, path) is None:
            raise StoreKeyError(self._what, name, self.names(), f"the {self.kind} registry")
        try:
            self._b.remove(path)
        except OSError as exc:
            raise StoreWriteError(f"could not delete {self._what} {name!r} from {self._b.url}: "
                                  f"{exc.strerror or exc}", exc.errno) from None

    def __contains__(self, name: object) -> bool:
        try:
            return isinstance(name, str) and self._b.exists(f"{self._path(name)}/zarr.json")
        except StoreError:
            return False

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())
