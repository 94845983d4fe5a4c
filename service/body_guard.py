"""ASGI middleware that bounds request bodies in size and time.

- A declared ``Content-Length`` above the path's limit is answered 413 at once, before a byte of
  the body is read (a 2 GB upload claim cannot hold a connection open).
- A body that grows past the limit while streaming (chunked encoding) is cut off with 413.
- A body that stops arriving for ``timeout`` seconds, or has not arrived whole after ``total``
  seconds (a trickle of one byte every few seconds), is answered 408 and the connection closed, so
  slow or absent bodies cannot hold workers and sockets.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from illumix.service.errors import error_response


class BodyTooLarge(HTTPException):
    def __init__(self, limit: int) -> None:
        super().__init__(413, f"the request body exceeds this endpoint's {limit}-byte limit; send a smaller file "
                              "or fewer batch items")


class BodyTimeout(HTTPException):
    def __init__(self, timeout: float, total: bool = False) -> None:
        what = f"has not arrived whole after {timeout:g} s" if total else f"stopped arriving for {timeout:g} s"
        super().__init__(408, f"the request body {what}; send it in one go")


class BodyGuard:
    """Wrap an ASGI app; ``limit_for(method, path)`` gives the body limit in bytes of a request."""

    def __init__(self, app: ASGIApp, limit_for: Callable[[str, str], int], timeout: float, total: float) -> None:
        self.app, self.limit_for, self.timeout, self.total = app, limit_for, timeout, max(timeout, total)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.limit_for(scope["method"], scope["path"])
        declared = _content_length(scope)
        if declared is not None and declared > limit:
            await error_response(413, "too_large", BodyTooLarge(limit).detail,
                                 headers={"Connection": "close"})(scope, receive, send)
            return
        received, complete = 0, False
        deadline = asyncio.get_running_loop().time() + self.total

        async def guarded() -> Message:
            nonlocal received, complete
            if complete:  # after the body only a disconnect can come: wait for it as long as it takes
                return await receive()
            left = deadline - asyncio.get_running_loop().time()
            try:
                message = await asyncio.wait_for(receive(), min(self.timeout, max(left, 0.0)))
            except asyncio.TimeoutError:
                raise BodyTimeout(self.total if left <= self.timeout else self.timeout, total=left <= self.timeout) \
                    from None
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit)
                complete = not message.get("more_body", False)
            return message

        await self.app(scope, guarded, send)


def _content_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", ()):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None
