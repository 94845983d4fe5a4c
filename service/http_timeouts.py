"""The header timeout uvicorn lacks: a request's head must arrive whole in bounded time.

uvicorn (0.54, h11) closes a kept-alive connection that stays silent for ``timeout_keep_alive``
seconds, and :mod:`service.body_guard` bounds request bodies, but nothing bounds the request line
and headers: a client that opens a connection and sends nothing, or half a header (slowloris), holds
its socket for as long as it likes. :func:`head_timeout_protocol` gives uvicorn's h11 protocol a
deadline for each request head — from the connection opening, or from the first byte of the next
request on a kept-alive connection; a trickle of bytes does not extend it. A connection whose head
is late is closed: silently when nothing of the head came (an idle pre-opened socket), else after a
408 :class:`service.errors.ErrorBody`. Head size stays bounded by h11 (16 KiB, then 400).

The same deadline bounds the rest of a body the service answered without reading (uvicorn ignores
those bytes and, once they start, its keep-alive timer is off).
"""

from __future__ import annotations

import asyncio
import json
import logging

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

log = logging.getLogger("illumix.service")
#: ``illumix serve --header-timeout`` default, seconds
DEFAULT_HEADER_TIMEOUT = 10.0


def _timeout_answer(seconds: float) -> bytes:
    detail = (f"the request line and headers did not arrive within {seconds:g} s; send the whole request "
              "head at once")
    body = json.dumps({"detail": detail, "status": 408, "code": "request_timeout", "loc": None}).encode()
    head = (b"HTTP/1.1 408 Request Timeout\r\ncontent-type: application/json\r\nconnection: close\r\n"
            b"content-length: " + str(len(body)).encode() + b"\r\n\r\n")
    return head + body


class HeadTimeoutH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline of :attr:`head_timeout` seconds for each request head."""

    head_timeout: float = DEFAULT_HEADER_TIMEOUT

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._head_timer: asyncio.TimerHandle | None = None
        self._head_started = False

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()

    def data_received(self, data: bytes) -> None:
        if self._awaiting_client():
            self._arm()
            self._head_started = self._head_started or self.conn.their_state is h11.IDLE
        super().data_received(data)
        if not self._awaiting_client():  # a head is complete: the request is the app's now
            self._disarm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def on_response_complete(self) -> None:
        self._head_started = False  # the next head's bytes are new
        super().on_response_complete()
        if self.conn.their_state is h11.SEND_BODY and not self.transport.is_closing():
            self._arm()  # answered before its body came whole: the rest is bounded too

    def _awaiting_client(self) -> bool:
        """Whether the client owes bytes no handler waits for: a request head, or the rest of an
        answered request's body."""
        their, ours = self.conn.their_state, self.conn.our_state
        return their is h11.IDLE or (their is h11.SEND_BODY and ours in (h11.DONE, h11.MUST_CLOSE))

    def _arm(self) -> None:
        if self._head_timer is None:
            self._head_timer = self.loop.call_later(self.head_timeout, self._head_timed_out)

    def _disarm(self) -> None:
        if self._head_timer is not None:
            self._head_timer.cancel()
            self._head_timer = None

    def _head_timed_out(self) -> None:
        self._head_timer = None
        if self.transport.is_closing() or not self._awaiting_client():
            return
        log.debug("closing %s: its request did not arrive within %g s", self.client, self.head_timeout)
        if self._head_started and self.conn.their_state is h11.IDLE:
            self.transport.write(_timeout_answer(self.head_timeout))
        try:
            self.conn.send(h11.ConnectionClosed())
        except h11.LocalProtocolError:
            pass
        self.transport.close()


def head_timeout_protocol(seconds: float) -> type[HeadTimeoutH11Protocol]:
    """The protocol class to give ``uvicorn.run(http=...)`` for a ``seconds`` header timeout."""
    if not seconds > 0:
        raise ValueError(f"the header timeout must be positive, got {seconds}")
    return type("HeadTimeoutH11Protocol", (HeadTimeoutH11Protocol,), {"head_timeout": float(seconds)})
