"""The composition engine's errors: what went wrong, in terms of the request, never of a protocol.

Every one is a :class:`retarget.errors.SpectralError` (bad input: one line, what, where and how to
fix), except :class:`Busy` (nobody's fault: retry). The service maps them to HTTP status codes
(:mod:`service.errors`: 404, 413, 503 with ``Retry-After``); the client's local mode, ``illumix
export`` and ``illumix evaluate`` report them as they are.
"""

from __future__ import annotations

from illumix.retarget.errors import SpectralError


class NotFound(SpectralError):
    """A scene or view that is not in the store (HTTP 404)."""


class TooLarge(SpectralError):
    """A request whose output, or working memory, exceeds the limits; ``detail`` says how to ask
    for less (HTTP 413)."""


class Busy(Exception):
    """Working memory is taken by other requests for longer than the queue timeout (HTTP 503):
    retry after ``retry_after`` seconds."""

    def __init__(self, detail: str, retry_after: int = 1) -> None:
        super().__init__(detail)
        self.retry_after = retry_after


__all__ = ["Busy", "NotFound", "TooLarge"]
