"""What each API call sends and how its answer is read, plus the retry policy — shared by the sync
and async clients, which only differ in how they wait.

A :class:`Call` is a plain description of one HTTP request with a ``parse`` function for a 2xx
answer. Both clients run it through the same bounded retry loop:

- *reads* (GET, POST /batch) retry on any transport error (refused, reset, dropped, timed out) and
  on any 5xx answer;
- *writes* (uploads, deletes) retry only where the request cannot have been processed: a connection
  that never opened, or 502/503/504;
- 4xx answers are never retried: they are raised at once as typed exceptions.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx
import numpy as np

from illumix_client.errors import ConnectionFailed, IllumixError, error_for
from illumix_client.sample import as_specs, encode_spec, parse_batch, parse_sample

_UNPROCESSED_5XX = frozenset({502, 503, 504})


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
        """Seconds to wait before try number ``attempt`` (1-based count of retries)."""
        base = min(self.max_backoff, self.backoff * 2 ** (attempt - 1))
        if retry_after:
            try:
                base = min(self.max_backoff, max(base, float(retry_after)))
            except ValueError:
                pass
        return base * (1.0 + self.jitter * random.random())


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
        if status < 500:
            return False
        return self.idempotent or status in _UNPROCESSED_5XX

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


def delete_sensor(name: str) -> Call:
    return Call("DELETE", f"/sensors/{quote(name, safe='')}", _json, idempotent=False)


def sample(spec: dict[str, Any]) -> Call:
    return Call("GET", "/sample", lambda r: parse_sample(r.content), params=encode_spec(spec))


def batch(specs) -> Call:
    items = as_specs(specs)
    return Call("POST", "/batch", lambda r: parse_batch(r.content, len(items)), json={"samples": items})


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
