"""Object storage (``s3://``, ``gs://`` …) as a store for several machines at once.

Two things differ from a local directory, and both are settled here:

* **Listings are cached by the filesystem client** (fsspec's ``DirCache``; s3fs keeps a listing for
  the life of the process by default), so a service replica would never see a cube another machine
  rendered, nor another replica's upload. illumix lets a listing live :data:`LISTING_TTL_S` seconds
  (``listings_expiry_time``): what another process writes is visible within that delay. A caller's
  own ``storage_options`` win.
* **Object stores refuse writes for a while** (throttling, 5xx, a restarting endpoint). The client
  (botocore) retries a request a few times; :func:`with_retries` retries a whole node write —
  idempotent, since a node is invisible until its completion marker — with exponential backoff,
  :data:`RETRY_DELAYS_S` (≈ 31 s in all), then gives up with one line saying what was refused.
"""

from __future__ import annotations

import errno
import logging
import time
from collections.abc import Callable
from typing import Any, TypeVar

from illumix.store.errors import StoreError

log = logging.getLogger("illumix.store")

#: seconds a directory listing of object storage is trusted (the delay before another machine's
#: write is visible to this process)
LISTING_TTL_S = 2.0
#: pauses between attempts of a node write the object store refused (then the error)
RETRY_DELAYS_S = (1.0, 2.0, 4.0, 8.0, 16.0)
#: protocols whose fsspec filesystem caches listings (DirCache)
CACHING_PROTOCOLS = ("s3", "s3a", "gs", "gcs", "abfs", "az", "adl", "oss")

T = TypeVar("T")
_sleep = time.sleep  # the backoff's pause (a test replaces it, not the process's time.sleep)


def storage_options(url: str, given: dict[str, Any] | None) -> dict[str, Any]:
    """``given`` plus a bounded listing cache for object stores (module docstring)."""
    out = dict(given or {})
    if url.split("://", 1)[0].lower() in CACHING_PROTOCOLS:
        out.setdefault("listings_expiry_time", LISTING_TTL_S)
    return out


def _transient(exc: BaseException) -> bool:
    """An object-store refusal worth retrying: I/O and connection errors, not a missing or
    forbidden key, nor a bad argument."""
    if isinstance(exc, (FileNotFoundError, FileExistsError, PermissionError, IsADirectoryError)):
        return False
    if isinstance(exc, StoreError):
        return getattr(exc, "errno", None) == errno.EIO
    return isinstance(exc, (OSError, ConnectionError, TimeoutError)) or type(exc).__name__ in (
        "ClientError", "EndpointConnectionError", "ConnectTimeoutError", "ReadTimeoutError", "ServerTimeoutError",
        "ClientOSError", "ServerDisconnectedError")


def with_retries(what: str, fn: Callable[[], T], delays: tuple[float, ...] | None = None) -> T:
    """``fn()``, retried after each delay of ``delays`` (default :data:`RETRY_DELAYS_S`) while it
    fails with a transient object-store error; then :class:`StoreError` naming ``what``."""
    delays = RETRY_DELAYS_S if delays is None else delays
    for attempt in range(len(delays) + 1):
        try:
            return fn()
        except Exception as exc:  # noqa: BLE001 - classified below
            if not _transient(exc):
                raise
            if attempt == len(delays):
                waited = sum(delays)
                raise StoreError(f"the object store refused to write {what} for {waited:.0f} s ({attempt + 1} "
                                 f"attempts; last: {type(exc).__name__}: {exc}); check the store's endpoint, "
                                 "credentials and quota, then run the same command again: it resumes") from None
            log.warning("object store refused %s (%s: %s); retrying in %.1f s", what, type(exc).__name__, exc,
                        delays[attempt])
            _sleep(delays[attempt])
    raise AssertionError("unreachable")


def node_write(local: bool, what: str, write: Callable[[], T], done: Callable[[], T] | None = None) -> T:
    """A node write (``write()``), retried with backoff while object storage refuses it; a local
    directory's errors are final (a full disk does not heal by waiting). ``done``: what a retry
    returns when it finds the node already complete (the refused step came after the completion
    marker) instead of writing it a second time."""
    if local:
        return write()
    tries = []

    def attempt() -> T:
        tries.append(1)
        try:
            return write()
        except StoreError as exc:
            if len(tries) > 1 and done is not None and "already exists" in str(exc):
                return done()
            raise

    return with_retries(what, attempt)
