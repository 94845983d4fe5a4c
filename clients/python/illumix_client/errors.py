"""Typed exceptions for the service's answers.

Every error the service sends is JSON ``{"detail": ...}`` with an HTTP status; the client raises the
matching subclass of :class:`IllumixError` carrying ``status`` (int) and ``detail`` (the service's
message, a string; FastAPI's validation lists are flattened to ``"where: what; …"``).

=====================  ==========  ===========================================================
exception              status      meaning
=====================  ==========  ===========================================================
NotFoundError          404         unknown scene, view, sensor or illuminant (detail lists
                                   close matches)
InvalidRequestError    400, 422    malformed parameters, a relight the cube cannot support, a
                                   request over the service's limits
RequestTooLargeError   413         an upload over the size limit (an InvalidRequestError)
AuthError              401         a write without the right ``Authorization: Bearer`` token
ForbiddenError         403         a write that is never allowed (e.g. deleting a built-in
                                   sensor); an AuthError
ConflictError          409         an upload whose name exists; pass ``overwrite=True``
ServerError            5xx         the service failed (raised after the retries are spent)
ConnectionFailed       —           no answer at all (refused, dropped, timed out) after retries
=====================  ==========  ===========================================================
"""

from __future__ import annotations

import json


class IllumixError(Exception):
    """Base class. ``status`` is the HTTP status (``None`` when there was no response), ``detail`` the
    service's message, ``method``/``url`` the failed request."""

    def __init__(self, detail: str, status: int | None = None, *, method: str | None = None,
                 url: str | None = None) -> None:
        self.detail = detail
        self.status = status
        self.method = method
        self.url = url
        where = f" ({method} {url})" if method and url else ""
        code = f"HTTP {status}: " if status is not None else ""
        super().__init__(f"{code}{detail}{where}")


class InvalidRequestError(IllumixError):
    """400/422: the request is malformed or asks what the service refuses; fix the parameters."""


class RequestTooLargeError(InvalidRequestError):
    """413: the upload exceeds the service's size limit."""


class NotFoundError(IllumixError):
    """404: no such scene, view, sensor or illuminant."""


class AuthError(IllumixError):
    """401: the write needs ``Client(token=...)`` with the service's token."""


class ForbiddenError(AuthError):
    """403: the write is not allowed for anyone (e.g. deleting a built-in sensor)."""


class ConflictError(IllumixError):
    """409: the name is taken; upload with ``overwrite=True`` to replace it."""


class ServerError(IllumixError):
    """5xx: the service failed; raised once the retries are spent."""


class ConnectionFailed(IllumixError):
    """No HTTP answer (connection refused, dropped or timed out) after every retry."""


_BY_STATUS: dict[int, type[IllumixError]] = {
    400: InvalidRequestError, 401: AuthError, 403: ForbiddenError, 404: NotFoundError,
    409: ConflictError, 413: RequestTooLargeError, 422: InvalidRequestError,
}


def detail_of(body: bytes, fallback: str) -> str:
    """The service's message from an error body (``{"detail": str | list}``), else ``fallback``."""
    try:
        detail = json.loads(body)["detail"]
    except (ValueError, KeyError, TypeError):
        text = body.decode("utf-8", "replace").strip()
        return text[:500] or fallback
    if isinstance(detail, list):  # FastAPI request validation: [{"loc": [...], "msg": ...}, ...]
        parts = []
        for d in detail:
            if isinstance(d, dict):
                loc = ".".join(str(p) for p in d.get("loc", ()) if p != "body")
                parts.append(f"{loc}: {d.get('msg', d)}" if loc else str(d.get("msg", d)))
            else:
                parts.append(str(d))
        return "; ".join(parts) or fallback
    return str(detail)


def error_for(status: int, body: bytes, reason: str = "", *, method: str | None = None,
              url: str | None = None) -> IllumixError:
    """The typed exception for an HTTP error answer."""
    if status >= 500:
        cls: type[IllumixError] = ServerError
    else:
        cls = _BY_STATUS.get(status, IllumixError)
    return cls(detail_of(body, reason or f"HTTP {status}"), status, method=method, url=url)
