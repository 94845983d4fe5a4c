"""Dependencies shared by the routers: the service context and the write token."""

from __future__ import annotations

import secrets
from typing import Annotated

from fastapi import Depends, Header, Request

from illumix.engine.context import Context
from illumix.service.errors import fail


async def get_ctx(request: Request) -> Context:
    # async: FastAPI runs a sync dependency on a worker thread, a hop that cost more than the lookup
    return request.app.state.ctx


CtxDep = Annotated[Context, Depends(get_ctx)]


def require_token(request: Request, authorization: Annotated[str | None, Header(
        description="`Bearer <token>`; needed for writes when the service has a token. Send it once: "
                    "a write with two or more Authorization headers is refused (400)")] = None) -> None:
    """Writes need ``Authorization: Bearer <token>`` when the service was started with a token.

    A write carrying more than one ``Authorization`` header is refused (400) whatever their order
    and whether or not the service has a token: which one counts would otherwise depend on the
    server (the first) and on any proxy in between (the last, or both joined)."""
    given_headers = request.headers.getlist("authorization")
    if len(given_headers) > 1:
        raise fail(400, f"this request carries {len(given_headers)} Authorization headers; send exactly one: "
                        "'Authorization: Bearer <token>'", code="duplicate_authorization")
    token: str | None = request.app.state.token
    if token is None:
        return
    scheme, _, given = (authorization or "").strip().partition(" ")
    hint = "this write needs the header 'Authorization: Bearer <token>' with the service's token"
    if not authorization:
        raise fail(401, hint, headers={"WWW-Authenticate": "Bearer"})
    if scheme.lower() != "bearer" or not given.strip():
        raise fail(401, f"the Authorization header must read 'Bearer <token>'; {hint}",
                   headers={"WWW-Authenticate": "Bearer"})
    # Headers arrive as Latin-1 text; compare bytes, since compare_digest refuses non-ASCII str.
    if not secrets.compare_digest(given.strip().encode("utf-8", "surrogateescape"), token.encode("utf-8")):
        raise fail(401, f"wrong token; {hint}", headers={"WWW-Authenticate": 'Bearer error="invalid_token"'})


TokenDep = Depends(require_token)
