"""Typed exceptions for the service's answers.

Every error the service sends is JSON ``{"detail": str, "status": int, "code": str, "loc": list | null}``
with an HTTP status (older services send only ``{"detail": str | list}``); the client raises the
matching subclass of :class:`IllumixError` carrying ``status`` (int), ``detail`` (the service's
message, a string; FastAPI's validation lists are flattened to ``"where: what; …"``) and ``code``
(the service's machine-readable slug, ``None`` when the body has none).

=====================  ==========  ===========================================================
exception              status      meaning
=====================  ==========  ===========================================================
NotFoundError          404         unknown scene, view, sensor or illuminant (detail lists
                                   close matches)
InvalidRequestError    400, 422    malformed parameters, a relight the cube cannot support, a
                                   request over the service's limits
RequestTooLargeError   413         a request or upload over the size limit; the detail says
                                   how to shrink it (an InvalidRequestError)
AuthError              401         a write without the right ``Authorization: Bearer`` token
ForbiddenError         403         a write that is never allowed (e.g. deleting a built-in
                                   sensor); an AuthError
ConflictError          409         an upload whose name exists; pass ``overwrite=True``
RequestTimeoutError    408         the service gave up waiting for the request body (raised
                                   after the retries are spent)
ServerError            5xx         the service failed or is busy (503, with ``Retry-After``);
                                   raised after the retries are spent
ConnectionFailed       —           no answer at all (refused, dropped, timed out) after retries
=====================  ==========  ===========================================================
"""

from __future__ import annotations

import json


class IllumixError(Exception):
    """Base class. ``status`` is the HTTP status (``None`` when there was no response), ``detail`` the
    service's message, ``code`` its machine-readable slug (``None`` when it sent none),
    ``method``/``url`` the failed request."""

    def __init__(self, detail: str, status: int | None = None, *, code: str | None = None,
                 method: str | None = None, url: str | None = None) -> None:
        self.detail = detail
        self.status = status
        self.code = code
        self.method = method
        self.url = url
        where = f" ({method} {url})" if method and url else ""
        code = f"HTTP {status}: " if status is not None else ""
        super().__init__(f"{code}{detail}{where}")


class InvalidRequestError(IllumixError):
    """400/422: the request is malformed or asks what the service refuses; fix the parameters."""


class RequestTooLargeError(InvalidRequestError):
    """413: the request (an upload, or a sample/batch over the service's memory budget) is too large;
    ``detail`` says what to shrink."""


class RequestTimeoutError(IllumixError):
    """408: the request body arrived too slowly; retried, raised once the retries are spent."""


class NotFoundError(IllumixError):
    """404: no such scene, view, sensor or illuminant."""


class AuthError(IllumixError):
    """401: the write needs ``Client(token=...)`` with the service's token."""


class ForbiddenError(AuthError):
    """403: the write is not allowed for anyone (e.g. deleting a built-in sensor)."""


class ConflictError(IllumixError):
    """409: the name is taken; upload with ``overwrite=True`` to replace it."""


class ServerError(IllumixError):
    """5xx: the service failed, or is busy (503); raised once the retries are spent."""


class ConnectionFailed(IllumixError):
    """No HTTP answer (connection refused, dropped or timed out) after every retry."""


_BY_STATUS: dict[int, type[IllumixError]] = {
    400: InvalidRequestError, 401: AuthError, 403: ForbiddenError, 404: NotFoundError,
    408: RequestTimeoutError, 409: ConflictError, 413: RequestTooLargeError, 422: InvalidRequestError,
}


def detail_of(body: bytes, fallback: str) -> str:
    """The service's message from an error body (``{"detail": str | list, ...}``), else ``fallback``."""
    return _read_body(body, fallback)[0]


def _read_body(body: bytes, fallback: str) -> tuple[str, str | None]:
    """``(detail, code)`` from an error body; a body that is not the service's JSON gives its text
    (truncated) as the detail and no code."""
    try:
        doc = json.loads(body)
        detail = doc["detail"]
    except (ValueError, KeyError, TypeError):
        text = body.decode("utf-8", "replace").strip()
        return text[:500] or fallback, None
    code = doc.get("code")
    code = code if isinstance(code, str) and code else None
    if isinstance(detail, list):  # FastAPI request validation: [{"loc": [...], "msg": ...}, ...]
        parts = []
        for d in detail:
            if isinstance(d, dict):
                loc = ".".join(str(p) for p in d.get("loc", ()) if p != "body")
                parts.append(f"{loc}: {d.get('msg', d)}" if loc else str(d.get("msg", d)))
            else:
                parts.append(str(d))
        return "; ".join(parts) or fallback, code
    return str(detail), code


def error_for(status: int, body: bytes, reason: str = "", *, method: str | None = None,
              url: str | None = None) -> IllumixError:
    """The typed exception for an HTTP error answer."""
    if status >= 500:
        cls: type[IllumixError] = ServerError
    else:
        cls = _BY_STATUS.get(status, IllumixError)
    detail, code = _read_body(body, reason or f"HTTP {status}")
    return cls(detail, status, code=code, method=method, url=url)
