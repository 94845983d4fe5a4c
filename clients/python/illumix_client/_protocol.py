"""What each API call sends and how its answer is read, plus the retry loop — shared by the sync
and async clients, which only differ in how they sleep and send.

A :class:`Call` is a plain description of one HTTP request with a ``parse`` function for a 2xx
answer. Both clients drive it through the same bounded retry loop, :func:`retry_loop`, written
sans-I/O (a generator that yields the wait before each try and is sent each try's outcome):

- *reads* (GET, POST /batch) retry on any transport error (refused, reset, dropped, timed out), on
  any 5xx answer and on 408 (the service gave up waiting for a slow request body);
- *writes* (uploads, deletes) retry only where the request cannot have been processed: a connection
  that never opened, 408, or 502/503/504;
- other 4xx answers are never retried: they are raised at once as typed exceptions (413, a request
  over the service's limits, as :class:`~illumix_client.errors.RequestTooLargeError`);
- a ``Retry-After`` header (seconds or an HTTP date, as the service sends with 503 when it is busy)
  stretches the next wait, up to ``RetryPolicy.max_backoff``;
- at most ``RetryPolicy.attempts`` tries in all; the last failure is raised.
"""

from __future__ import annotations

import random
import time
from collections.abc import Awaitable, Callable, Generator
from dataclasses import dataclass, field
from email.utils import parsedate_to_datetime
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx
import numpy as np

from illumix_client.errors import ConnectionFailed, IllumixError, error_for
from illumix_client.sample import as_specs, encode_spec, parse_batch, parse_sample

# Answers that say the request was not processed, so even a write may be resent: 408 (the body
# never fully arrived), 502/504 (a proxy got no answer upstream), 503 (busy or down; the service
# refuses before doing any work).
_UNPROCESSED = frozenset({408, 502, 503, 504})

Outcome = httpx.Response | httpx.TransportError
"""What one try produced: the service's answer, or the transport error that stopped it."""


@dataclass(frozen=True)
class RetryPolicy:
    """Bounded retries with exponential backoff.

    ``attempts`` tries in all (≥ 1). Before try ``k`` (k ≥ 1) the client waits
    ``min(max_backoff, backoff · 2^(k-1))`` seconds, stretched by up to ``jitter`` (a fraction) so
    many clients do not retry in lockstep; a ``Retry-After`` header in seconds is honoured up to
    ``max_backoff``.
    """

    attempts: int = 4
    backoff: float = 0.2
    max_backoff: float = 5.0
    jitter: float = 0.1

    def __post_init__(self) -> None:
        if self.attempts < 1 or self.backoff < 0 or self.max_backoff < 0 or not 0 <= self.jitter <= 1:
            raise ValueError(f"invalid retry policy {self}")

    def delay(self, attempt: int, retry_after: str | None = None) -> float:
        """Seconds to wait before try number ``attempt`` (1-based count of retries).

        ``retry_after`` is the previous answer's ``Retry-After`` header (delta-seconds or an HTTP
        date); it can lengthen the wait, never shorten it, and never past ``max_backoff``.
        """
        base = min(self.max_backoff, self.backoff * 2 ** (attempt - 1))
        asked = _retry_after_seconds(retry_after)
        if asked is not None:
            base = min(self.max_backoff, max(base, asked))
        return base * (1.0 + self.jitter * random.random())


def _retry_after_seconds(value: str | None) -> float | None:
    """A ``Retry-After`` header in seconds from now, or None when absent or unreadable."""
    if not value:
        return None
    try:
        seconds = float(value)
    except ValueError:
        try:
            when = parsedate_to_datetime(value)
        except (TypeError, ValueError):
            return None
        if when.tzinfo is None:  # an HTTP date is GMT; a naive one cannot be compared otherwise
            return None
        seconds = when.timestamp() - time.time()
    return seconds if seconds == seconds else None  # NaN reads as absent


@dataclass
class Call:
    """One HTTP request and how to read its 2xx answer."""

    method: str
    path: str
    parse: Callable[[httpx.Response], Any]
    params: dict[str, Any] | None = None
    json: Any = None
    data: dict[str, str] | None = None
    files: dict[str, tuple[str, bytes, str]] | None = None
    idempotent: bool = True
    #: stream a 2xx body into a bytearray (:attr:`body`, see :func:`read_body`) instead of httpx's bytes,
    #: so arrays decoded as views of it are writable without a copy
    buffered: bool = False
    body: bytearray | None = field(default=None, repr=False)

    def content(self, resp: httpx.Response) -> bytes | bytearray:
        """The answer's body: the buffered bytearray of a :attr:`buffered` call, else ``resp.content``."""
        return self.body if self.body is not None else resp.content

    def request_kwargs(self) -> dict[str, Any]:
        kw: dict[str, Any] = {}
        for name in ("params", "json", "data", "files"):
            value = getattr(self, name)
            if value is not None:
                kw[name] = value
        return kw

    # -- retry decisions -----------------------------------------------------------------------
    def retry_on_exception(self, exc: httpx.TransportError) -> bool:
        if isinstance(exc, httpx.UnsupportedProtocol):
            return False
        if self.idempotent:
            return True
        return isinstance(exc, (httpx.ConnectError, httpx.ConnectTimeout))

    def retry_on_status(self, status: int) -> bool:
        if status in _UNPROCESSED:
            return True
        return self.idempotent and status >= 500

    def failure(self, resp: httpx.Response) -> IllumixError:
        return error_for(resp.status_code, resp.content, resp.reason_phrase, method=self.method,
                         url=str(resp.request.url) if resp.request else self.path)

    def connection_failure(self, exc: Exception, base_url: str, tries: int) -> ConnectionFailed:
        kind = type(exc).__name__
        return ConnectionFailed(f"no answer from {base_url} after {tries} tr{'y' if tries == 1 else 'ies'} "
                                f"({kind}: {exc})", None, method=self.method, url=self.path)

    def read(self, resp: httpx.Response) -> Any:
        try:
            return self.parse(resp)
        except IllumixError:
            raise
        except ValueError as exc:  # JSON decoding
            raise IllumixError(f"could not decode the answer to {self.method} {self.path}: {exc}",
                               resp.status_code) from None


def retry_loop(call: Call, policy: RetryPolicy, base_url: str) -> Generator[float, Outcome, Any]:
    """The retry loop for ``call``, without I/O: the driver sleeps and sends.

    Yields the seconds to wait before each try (``0.0`` before the first), and must then be sent
    that try's :data:`Outcome` — the ``httpx.Response`` (any status) or the
    ``httpx.TransportError`` raised while sending. Finishes (``StopIteration.value``) with
    ``call.parse`` of the first 2xx/3xx answer, or raises the typed
    :class:`~illumix_client.errors.IllumixError` for an answer or error that is not retried or
    that used up the last of ``policy.attempts`` tries. See :func:`run_sync` for a driver.
    """
    retry_after: str | None = None
    for attempt in range(policy.attempts):
        outcome = yield policy.delay(attempt, retry_after) if attempt else 0.0
        last = attempt == policy.attempts - 1
        if isinstance(outcome, httpx.TransportError):
            if last or not call.retry_on_exception(outcome):
                raise call.connection_failure(outcome, base_url, attempt + 1) from outcome
            retry_after = None
            continue
        if outcome.status_code < 400:
            return call.read(outcome)
        if last or not call.retry_on_status(outcome.status_code):
            raise call.failure(outcome)
        retry_after = outcome.headers.get("retry-after")
    raise AssertionError("unreachable")  # pragma: no cover  (the last try returns or raises)


def run_sync(call: Call, policy: RetryPolicy, base_url: str, send: Callable[[Call], httpx.Response],
             sleep: Callable[[float], None]) -> Any:
    """Drive :func:`retry_loop` with a blocking ``send(call) -> Response`` and ``sleep(seconds)``."""
    loop = retry_loop(call, policy, base_url)
    wait = next(loop)
    while True:
        if wait > 0:
            sleep(wait)
        try:
            outcome: Outcome = send(call)
        except httpx.TransportError as exc:
            outcome = exc
        try:
            wait = loop.send(outcome)
        except StopIteration as done:
            return done.value


async def run_async(call: Call, policy: RetryPolicy, base_url: str,
                    send: Callable[[Call], Awaitable[httpx.Response]],
                    sleep: Callable[[float], Awaitable[None]]) -> Any:
    """:func:`run_sync` with an awaitable ``send`` and ``sleep``."""
    loop = retry_loop(call, policy, base_url)
    wait = next(loop)
    while True:
        if wait > 0:
            await sleep(wait)
        try:
            outcome: Outcome = await send(call)
        except httpx.TransportError as exc:
            outcome = exc
        try:
            wait = loop.send(outcome)
        except StopIteration as done:
            return done.value


def read_body(call: Call, resp: httpx.Response) -> httpx.Response:
    """Read a streamed answer for ``call``: a 2xx body into ``call.body`` (a bytearray grown chunk by
    chunk: one copy, as httpx's own join would make), anything else as usual; then close it."""
    try:
        call.body = None
        if 200 <= resp.status_code < 300:
            buf = bytearray()
            for chunk in resp.iter_bytes():
                buf += chunk
            call.body = buf
        else:
            resp.read()
    finally:
        resp.close()
    return resp


async def aread_body(call: Call, resp: httpx.Response) -> httpx.Response:
    """:func:`read_body` for an ``httpx.AsyncClient`` answer."""
    try:
        call.body = None
        if 200 <= resp.status_code < 300:
            buf = bytearray()
            async for chunk in resp.aiter_bytes():
                buf += chunk
            call.body = buf
        else:
            await resp.aread()
    finally:
        await resp.aclose()
    return resp


def _json(resp: httpx.Response) -> Any:
    return resp.json()


def _file(path_or_bytes: str | Path | bytes, default_name: str) -> tuple[str, bytes, str]:
    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
        data, filename = bytes(path_or_bytes), default_name
    else:
        p = Path(path_or_bytes)
        data, filename = p.read_bytes(), p.name
    ctype = "application/json" if filename.lower().endswith(".json") else "text/csv"
    return filename, data, ctype


# -- the API, one builder per endpoint ------------------------------------------------------------
def health() -> Call:
    return Call("GET", "/health", _json)


def scenes() -> Call:
    return Call("GET", "/scenes", lambda r: r.json()["scenes"])


def sensors() -> Call:
    return Call("GET", "/sensors", _json)


def sensor(name: str) -> Call:
    def parse(r: httpx.Response) -> dict:
        d = r.json()
        d["wavelengths"] = np.asarray(d["wavelengths"], dtype=np.float64)
        d["sensitivities"] = np.asarray(d["sensitivities"], dtype=np.float64)
        return d

    return Call("GET", f"/sensors/{quote(name, safe='')}", parse)


def illuminants() -> Call:
    return Call("GET", "/illuminants", _json)


def upload(kind: str, name: str, file: str | Path | bytes, overwrite: bool) -> Call:
    default = "sensor.csv" if kind == "sensors" else "illuminant.csv"
    return Call("POST", f"/{kind}", _json, data={"name": name, "overwrite": "true" if overwrite else "false"},
                files={"file": _file(file, default)}, idempotent=False)


def delete(kind: str, name: str) -> Call:
    """``DELETE /sensors/{name}`` or ``/illuminants/{name}``."""
    return Call("DELETE", f"/{kind}/{quote(name, safe='')}", _json, idempotent=False)


WIRE_FORMATS = ("arrays", "npz")


def check_wire_format(wire_format: str) -> str:
    if wire_format not in WIRE_FORMATS:
        raise ValueError(f"wire_format must be 'arrays' (fast, the default) or 'npz', got {wire_format!r}")
    return wire_format


def sample(spec: dict[str, Any], wire_format: str = "arrays", keep_float16: bool = False) -> Call:
    params = encode_spec(spec)
    if wire_format != "npz":  # npz is the service's default: not sent, so older services answer too
        params["format"] = wire_format
    call = Call("GET", "/sample", _unset, params=params, buffered=True)
    call.parse = lambda r: parse_sample(call.content(r), keep_float16)
    return call


def batch(specs, wire_format: str = "arrays", keep_float16: bool = False) -> Call:
    items = as_specs(specs)
    if wire_format != "npz":
        items = [{**it, "format": wire_format} for it in items]
    call = Call("POST", "/batch", _unset, json={"samples": items}, buffered=True)
    call.parse = lambda r: parse_batch(call.content(r), len(items), keep_float16)
    return call


def _unset(resp: httpx.Response) -> Any:  # pragma: no cover  (replaced right after construction)
    raise AssertionError("parse not set")


def image(output: str, fmt: str, spec: dict[str, Any]) -> Call:
    if fmt not in ("png", "tiff"):
        raise ValueError(f"image format must be png or tiff, got {fmt!r}")
    params = encode_spec({**spec, "outputs": output})
    params["format"] = fmt
    return Call("GET", "/sample", lambda r: r.content, params=params)


def check_base_url(base_url: str) -> str:
    if not base_url.startswith(("http://", "https://")):
        raise ValueError(f"base_url must start with http:// or https://, got {base_url!r}")
    return base_url.rstrip("/")


def headers(token: str | None) -> dict[str, str]:
    h = {"User-Agent": "illumix-client/0.1"}
    if token:
        h["Authorization"] = f"Bearer {token}"
    return h
