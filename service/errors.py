"""One error shape for every 4xx/5xx answer, and the handlers that produce it.

Every error body is :class:`ErrorBody`: ``{"detail": "<one line: what, where, how to fix>",
"status": 422, "code": "invalid_parameter", "loc": ["query", "crop"]}``. ``detail`` is always one
string a person can act on; ``code`` is a stable slug a program can branch on; ``loc`` points at the
offending parameter when there is one. FastAPI's own validation errors (a list of dicts) are
rewritten into this shape, and an unknown parameter names its close match and the parameters of
the route it was sent to.
"""

from __future__ import annotations

import difflib
import errno
import logging
import typing
from collections.abc import Iterable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from illumix.engine.errors import Busy, NotFound, TooLarge
from illumix.retarget.errors import SpectralError, UnknownName
from illumix.store import StoreError, StoreKeyError

log = logging.getLogger("illumix.service")


class ErrorBody(BaseModel):
    """The body of every error answer."""

    detail: str = Field(description="What is wrong, where, and how to fix it (one line).")
    status: int = Field(description="The HTTP status code, repeated for convenience.")
    code: str = Field(description="A stable machine-readable slug, e.g. 'unknown_parameter', 'not_found'.")
    loc: list[str | int] | None = Field(None, description="Where the problem is, e.g. ['query', 'crop'].")


class ServiceError(Exception):
    """An error with its HTTP status and code, raised anywhere in the service."""

    def __init__(self, status: int, code: str, detail: str, *, loc: list | None = None,
                 headers: dict[str, str] | None = None) -> None:
        super().__init__(detail)
        self.status, self.code, self.detail, self.loc, self.headers = status, code, detail, loc, headers


_DESCRIPTIONS = {
    400: "Malformed request (e.g. an unreadable body or header).",
    401: "A write without `Authorization: Bearer <token>` or with the wrong token.",
    403: "A write that is never allowed (e.g. deleting a built-in sensor).",
    404: "Unknown scene, view, sensor or illuminant; `detail` lists close matches.",
    405: "Method not allowed on this path; the `Allow` header lists the allowed ones.",
    408: "The request body arrived too slowly or not at all.",
    409: "An upload whose name exists; send `overwrite=true` to replace it.",
    413: "The request, its body or its answer would be larger than the service's limits; `detail` "
         "says which limit and how to ask for less.",
    422: "A parameter is invalid or unknown; `detail` says which and how to fix it.",
    500: "A bug in the service (logged); `detail` names the error type.",
    501: "A format whose optional package this service lacks (format=dng|exr); `detail` names the install.",
    503: "The service is busy (retry after `Retry-After` seconds) or its store is damaged or "
         "unreachable (`detail` says to run `illumix store verify`).",
    507: "The store's disk is full (`store_full`) or refuses writes: read-only, no permission or an I/O "
         "error (`store_unwritable`). Nothing was written; deleting uploads needs no space, so it works on "
         "a full disk.",
}


def error_responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses=`` entries documenting ``statuses`` with :class:`ErrorBody`."""
    out: dict[int | str, dict[str, Any]] = {}
    for s in statuses:
        entry: dict[str, Any] = {"model": ErrorBody, "description": _DESCRIPTIONS[s]}
        if s == 405:
            entry["headers"] = {"Allow": {"description": "Allowed methods", "schema": {"type": "string"}}}
        if s == 503:
            entry["headers"] = {"Retry-After": {"description": "Seconds to wait before retrying (when busy)",
                                                "schema": {"type": "integer"}}}
        out[s] = entry
    return out


def error_response(status: int, code: str, detail: str, loc: list | None = None,
                   headers: dict[str, str] | None = None) -> JSONResponse:
    body = ErrorBody(detail=" ".join(str(detail).split()), status=status, code=code, loc=loc)
    return JSONResponse(body.model_dump(), status_code=status, headers=headers)


_CODES = {400: "bad_request", 401: "unauthorized", 403: "forbidden", 404: "not_found",
          405: "method_not_allowed", 408: "request_timeout", 409: "conflict", 413: "too_large",
          422: "invalid_parameter", 503: "unavailable"}


REFUSED_ATTRIBUTE = "illumix_refused_parameters"


def refuses(*names: str):
    """Mark an endpoint as refusing some parameters its model accepts (``/explore/frame`` fixes
    ``outputs``…): they are not offered as valid in its unknown-parameter answers."""
    def mark(endpoint):
        setattr(endpoint, REFUSED_ATTRIBUTE, names)
        return endpoint
    return mark


def _model(annotation) -> type[BaseModel] | None:
    """The pydantic model of a parameter annotated ``M``, ``list[M]`` or ``M | None``; else None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return next(filter(None, (_model(a) for a in typing.get_args(annotation))), None)


def _field_names(model: type[BaseModel]) -> list[str]:
    return [f.alias or name for name, f in model.model_fields.items()]


def route_parameters(route) -> dict[str, list[str]]:
    """Location → the parameter names ``route`` (a FastAPI ``APIRoute``) accepts, read from its
    signature: ``"query"`` (a model parameter counts as its fields, less what the endpoint
    :func:`refuses`), ``"body"`` (the body model's fields) and, per body field holding models
    (``/batch``'s ``samples``), that field's name → the inner model's fields."""
    refused = set(getattr(getattr(route, "endpoint", None), REFUSED_ATTRIBUTE, ()))
    known: dict[str, list[str]] = {"query": [], "body": []}
    stack = [getattr(route, "dependant", None)]
    while stack:
        dep = stack.pop()
        if dep is None:
            continue
        stack.extend(dep.dependencies)
        for p in dep.query_params:
            model = _model(p.field_info.annotation)
            known["query"] += _field_names(model) if model else [p.alias]
        for p in dep.body_params:
            model = _model(p.field_info.annotation)
            if model is None:
                known["body"].append(p.alias)
                continue
            known["body"] += _field_names(model)
            for name, f in model.model_fields.items():
                if inner := _model(f.annotation):
                    known[f.alias or name] = _field_names(inner)
    return {where: [n for n in names if n not in refused] for where, names in known.items()}


def _describe_validation(errors: Iterable[dict[str, Any]], known: dict[str, list[str]]) -> tuple[str, str, list]:
    """``(detail, code, loc)`` of the first pydantic/FastAPI validation error, made readable."""
    # A typo shows up twice (the unknown name, and the real one missing): name the typo first.
    first = min(errors, key=lambda e: e.get("type") != "extra_forbidden", default=None)
    if first is None:
        return "invalid request", "invalid_parameter", []
    loc = [p for p in first.get("loc", ()) if p != "body"]
    where = ".".join(str(p) for p in loc[1:] if not isinstance(p, int)) or ".".join(str(p) for p in loc)
    if first.get("type") == "extra_forbidden":
        name = str(loc[-1]) if loc else "?"
        options = known.get(str(loc[0]) if len(loc) > 1 else "body", [])
        close = difflib.get_close_matches(name, options, n=2, cutoff=0.6)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else "."
        valid = f" Valid parameters: {', '.join(options)}." if options else ""
        return f"unknown parameter {name!r}{hint}{valid}", "unknown_parameter", loc
    if first.get("type") in ("missing", "missing_argument"):
        return f"{where}: required but missing", "missing_parameter", loc
    if first.get("type") == "json_invalid":
        return f"the body is not valid JSON ({first.get('ctx', {}).get('error', 'parse error')})", "invalid_body", loc
    msg = str(first.get("msg", "invalid value")).removeprefix("Value error, ")
    field = str(loc[-1]) if loc else ""
    if not where or msg.startswith(field):  # our messages already name the parameter
        return msg, "invalid_parameter", loc
    return f"{where}: {msg}", "invalid_parameter", loc


def install(app: FastAPI) -> None:
    """Register the handlers that turn every failure into an :class:`ErrorBody` answer (an unknown
    parameter is matched against the parameters of the route it was sent to, :func:`route_parameters`)."""

    @app.exception_handler(ServiceError)
    async def _service(request: Request, exc: ServiceError):
        return error_response(exc.status, exc.code, exc.detail, exc.loc, exc.headers)

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError):
        detail, code, loc = _describe_validation(exc.errors(), route_parameters(request.scope.get("route")))
        return error_response(422, code, detail, loc)

    @app.exception_handler(UnknownName)
    @app.exception_handler(NotFound)
    @app.exception_handler(StoreKeyError)
    async def _not_found(request: Request, exc: Exception):
        return error_response(404, "not_found", str(exc))

    @app.exception_handler(TooLarge)
    async def _too_large(request: Request, exc: TooLarge):
        return error_response(413, "too_large", str(exc))

    @app.exception_handler(Busy)
    async def _busy(request: Request, exc: Busy):
        return error_response(503, "busy", str(exc), headers={"Retry-After": str(exc.retry_after)})

    @app.exception_handler(StoreError)
    async def _store(request: Request, exc: StoreError):
        if (refused := _storage_refused(exc)) is not None:
            return refused
        # Not the client's fault: the store itself is damaged or unreachable.
        log.error("store problem: %s", exc)
        return error_response(503, "store_damaged", f"store problem: {exc}; run `illumix store verify`")

    @app.exception_handler(SpectralError)
    async def _bad_input(request: Request, exc: SpectralError):
        return error_response(422, "invalid_parameter", str(exc))

    @app.exception_handler(OSError)
    async def _os_error(request: Request, exc: OSError):
        # a write some code path let through unwrapped: the disk, not a bug, when it is full or read-only
        if (refused := _storage_refused(exc)) is not None:
            return refused
        raise exc  # on to the handler of unexpected errors (500, logged), as before

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception):
        # A bug, not the client's fault: logged with its traceback, answered in the common shape.
        log.exception("unexpected error on %s %s", request.method, request.url.path)
        return error_response(500, "internal", f"internal error ({type(exc).__name__}); the service log has the "
                                               "details — please report it")

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException):
        code = _CODES.get(exc.status_code, "error")
        detail = exc.detail if isinstance(exc.detail, str) else str(exc.detail)
        if exc.status_code == 400 and detail == "There was an error parsing the body":
            detail = ("the request body could not be read (not UTF-8 JSON, or a broken multipart form); "
                      "send JSON for /batch and a multipart form with 'name' and 'file' for uploads")
        elif exc.status_code == 404 and detail == "Not Found":
            detail = f"no endpoint {request.url.path!r}; see /docs for the API"
        headers = exc.headers
        if exc.status_code == 405:
            allow = _allowed_methods(request)
            headers = {**(exc.headers or {}), "Allow": allow}
            detail = f"{request.method} is not allowed on {request.url.path}; allowed: {allow}"
        return error_response(exc.status_code, code, detail, headers=headers)


#: a write the store's disk refused (its errno) → the 507 answer's code
_REFUSED = {errno.ENOSPC: "store_full", errno.EDQUOT: "store_full", errno.EFBIG: "store_full",
            errno.EROFS: "store_unwritable", errno.EACCES: "store_unwritable", errno.EPERM: "store_unwritable",
            errno.EIO: "store_unwritable"}
#: the errnos only a write raises (EACCES or EIO may come from a read)
_WRITE_ONLY = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS}


def _storage_refused(exc: Exception):
    """The 507 answer of a write the storage refused — the store's ``StoreWriteError`` with one of
    :data:`_REFUSED`'s errnos, or a bare ``OSError`` with one of :data:`_WRITE_ONLY`'s — else ``None``."""
    n = getattr(exc, "errno", None)
    if n not in _REFUSED or (not isinstance(exc, StoreError) and n not in _WRITE_ONLY):
        return None
    detail = str(exc) if isinstance(exc, StoreError) else (
        f"the store's disk refused a write ({exc.strerror or exc}); "
        + ("free space on it and try again" if _REFUSED[n] == "store_full" else "make it writable and try again"))
    return error_response(507, _REFUSED[n], detail)


def _allowed_methods(request: Request) -> str:
    """Every method some route accepts on this path (Starlette names only the first route's)."""
    methods: set[str] = set()
    for route in request.app.state.routes:
        match, _ = route.matches(request.scope)
        if match != Match.NONE:
            methods |= set(getattr(route, "methods", None) or ())
    return ", ".join(sorted(methods))


def fail(status: int, detail: str, *, code: str | None = None, loc: list | None = None,
         headers: dict[str, str] | None = None) -> ServiceError:
    """A :class:`ServiceError` for ``status`` (``code`` defaults by status) — ``raise fail(...)``."""
    return ServiceError(status, code or _CODES.get(status, "error"), detail, loc=loc, headers=headers)
