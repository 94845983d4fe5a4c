"""The client's shared retry loop (``illumix_client._protocol.retry_loop``) through fake transports:
``httpx.MockTransport`` behind both ``Client`` and ``AsyncClient``, with the waits recorded instead
of slept. Covers: retry then success, 4xx raised at once, writes resent only when unprocessed,
Retry-After, bounded attempts, 408/413/503, and the service's ``code`` in errors."""

from __future__ import annotations

import asyncio
import email.utils
import json
import time
from collections.abc import Callable

import httpx
import illumix_client as ic
import pytest
from illumix_client import _protocol as P
from illumix_client import aio as ic_aio
from illumix_client import client as ic_sync

# no jitter, so the waits are exact: 0.1, 0.2, 0.4, … capped at 1.0
POLICY = ic.RetryPolicy(attempts=4, backoff=0.1, max_backoff=1.0, jitter=0.0)
URL = "http://illumix.test"
SPD = b"wavelength,value\n400,1\n700,1\n"

Reply = httpx.Response | type[httpx.TransportError]


def error_body(status: int, detail: str, code: str | None = None) -> dict:
    """The service's error body (the new form, with ``code`` and ``loc``)."""
    return {"detail": detail, "status": status, "code": code, "loc": None}


def answer(status: int, **kw) -> httpx.Response:
    if status < 400 and "json" not in kw:
        kw["json"] = {"status": "ok"}
    elif status >= 400 and "json" not in kw and "content" not in kw:
        kw["json"] = error_body(status, f"canned {status}", f"canned_{status}")
    return httpx.Response(status, **kw)


class Script:
    """A fake service answering each request with the next scripted reply (the last one repeats);
    a TransportError class is raised instead of answered. Records the requests and the waits."""

    def __init__(self, *replies: Reply) -> None:
        self.replies = list(replies)
        self.requests: list[httpx.Request] = []
        self.waits: list[float] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        reply = self.replies[min(len(self.requests), len(self.replies) - 1)]
        self.requests.append(request)
        if isinstance(reply, type):
            raise reply(f"scripted {reply.__name__}", request=request)
        # a fresh copy: httpx rebinds a response's stream to the client that received it
        return httpx.Response(reply.status_code, headers=reply.headers, content=reply.content)


@pytest.fixture(params=["sync", "async"])
def call(request, monkeypatch) -> Callable[..., object]:
    """``call(script, method, *args)``: run one client method against ``script`` with the sync or the
    async client, the waits recorded in ``script.waits`` instead of slept."""
    current: list[Script] = []

    def record(seconds: float) -> None:
        current[-1].waits.append(seconds)

    async def record_async(seconds: float) -> None:
        record(seconds)

    monkeypatch.setattr(ic_sync, "_sleep", record)
    monkeypatch.setattr(ic_aio, "_sleep", record_async)

    def run(script: Script, method: str, *args):
        current.append(script)
        if request.param == "sync":
            with ic.Client(URL, token="t", retry=POLICY, transport=httpx.MockTransport(script)) as c:
                return getattr(c, method)(*args)

        async def main():
            async with ic.AsyncClient(URL, token="t", retry=POLICY, transport=httpx.MockTransport(script)) as c:
                return await getattr(c, method)(*args)

        return asyncio.run(main())

    return run


# -- reads ------------------------------------------------------------------------------------------
def test_read_retries_transport_errors_and_5xx_then_succeeds(call):
    s = Script(httpx.ConnectError, answer(500), httpx.ReadTimeout, answer(200))
    assert call(s, "health") == {"status": "ok"}
    assert len(s.requests) == 4 and all(r.url.path == "/health" for r in s.requests)
    assert s.waits == pytest.approx([0.1, 0.2, 0.4])  # exponential backoff, nothing before the first try


def test_4xx_is_raised_at_once_with_detail_and_code(call):
    s = Script(answer(404, json=error_body(404, "no scene 'synht'; did you mean 'synth'?", "scene_not_found")))
    with pytest.raises(ic.NotFoundError) as e:
        call(s, "sample", "synht")
    assert (e.value.status, e.value.code) == (404, "scene_not_found") and "did you mean" in e.value.detail
    assert len(s.requests) == 1 and s.waits == []
    s = Script(answer(422, json={"detail": [{"loc": ["query", "crop"], "msg": "bad crop"}]}))  # the old list form
    with pytest.raises(ic.InvalidRequestError) as e:
        call(s, "sample", "synth")
    assert (e.value.detail, e.value.code) == ("query.crop: bad crop", None) and len(s.requests) == 1


def test_413_is_request_too_large_and_not_retried(call):
    hint = "the batch needs 3.2 GB, over the 2 GB budget; ask for fewer samples or smaller crops"
    s = Script(answer(413, json=error_body(413, hint, "request_too_large")), answer(200))
    with pytest.raises(ic.RequestTooLargeError) as e:
        call(s, "batch", [{"scene": "synth"}])
    assert isinstance(e.value, ic.InvalidRequestError) and e.value.detail == hint
    assert e.value.code == "request_too_large" and len(s.requests) == 1


def test_408_is_retried_then_raised_as_request_timeout(call):
    s = Script(answer(408), answer(200))
    assert call(s, "health") == {"status": "ok"} and len(s.requests) == 2
    s = Script(answer(408))
    with pytest.raises(ic.RequestTimeoutError) as e:
        call(s, "health")
    assert e.value.status == 408 and len(s.requests) == POLICY.attempts


# -- writes ---------------------------------------------------------------------------------------
def test_write_not_retried_on_500_or_after_the_request_went_out(call):
    s = Script(answer(500), answer(200))
    with pytest.raises(ic.ServerError) as e:
        call(s, "upload_illuminant", "warm", SPD)
    assert e.value.status == 500 and len(s.requests) == 1 and s.waits == []
    s = Script(httpx.ReadError, answer(200))  # the upload may have landed: never resent
    with pytest.raises(ic.ConnectionFailed, match="1 try"):
        call(s, "delete_sensor", "cam")
    assert len(s.requests) == 1


@pytest.mark.parametrize("first", [answer(503), answer(502), answer(504), answer(408), httpx.ConnectError])
def test_write_resent_when_unprocessed(call, first):
    s = Script(first, answer(200, json={"name": "warm"}))
    assert call(s, "upload_illuminant", "warm", SPD) == {"name": "warm"}
    assert len(s.requests) == 2 and all(SPD in r.content for r in s.requests)  # the same file, resent
    assert s.requests[1].headers["authorization"] == "Bearer t"


# -- Retry-After and bounds -----------------------------------------------------------------------
def test_retry_after_seconds_is_honoured_up_to_max_backoff(call):
    s = Script(answer(503, headers={"Retry-After": "0.7"}), answer(503, headers={"Retry-After": "30"}),
               answer(503, headers={"Retry-After": "soon"}), answer(200))
    assert call(s, "health") == {"status": "ok"}
    # 0.7 beats the 0.1 backoff; 30 s is capped at max_backoff; an unreadable value is ignored
    assert s.waits == pytest.approx([0.7, 1.0, 0.4])


def test_retry_after_http_date_is_honoured(call):
    when = email.utils.formatdate(time.time() + 60, usegmt=True)
    s = Script(answer(503, headers={"Retry-After": when}), answer(200))
    assert call(s, "upload_sensor", "cam", b"wavelength,r,g,b\n") == {"status": "ok"}
    assert s.waits == pytest.approx([1.0])  # ~60 s away, capped
    assert P.RetryPolicy(jitter=0.0, max_backoff=100).delay(1, when) == pytest.approx(60, abs=2)
    past = email.utils.formatdate(time.time() - 60, usegmt=True)
    assert P.RetryPolicy(backoff=0.2, jitter=0.0).delay(1, past) == pytest.approx(0.2)


def test_attempts_are_bounded(call):
    s = Script(answer(503, headers={"Retry-After": "0.05"}))
    with pytest.raises(ic.ServerError) as e:
        call(s, "health")
    assert e.value.status == 503 and e.value.code == "canned_503"
    assert len(s.requests) == POLICY.attempts and s.waits == pytest.approx([0.1, 0.2, 0.4])
    s = Script(httpx.ConnectError)
    with pytest.raises(ic.ConnectionFailed, match="4 tries") as e:
        call(s, "health")
    assert e.value.status is None and isinstance(e.value.__cause__, httpx.ConnectError)
    assert len(s.requests) == POLICY.attempts


# -- the loop itself, without a client -------------------------------------------------------------
def test_retry_loop_is_sans_io():
    """The generator yields waits and takes outcomes; no socket, no clock."""
    req = httpx.Request("GET", URL + "/health")
    loop = P.retry_loop(P.health(), POLICY, URL)
    assert next(loop) == 0.0
    assert loop.send(httpx.ConnectError("refused", request=req)) == pytest.approx(0.1)
    assert loop.send(httpx.Response(503, headers={"Retry-After": "0.5"}, request=req)) == pytest.approx(0.5)
    with pytest.raises(StopIteration) as done:
        loop.send(httpx.Response(200, json={"status": "ok"}, request=req))
    assert done.value.value == {"status": "ok"}

    one = P.retry_loop(P.health(), P.RetryPolicy(attempts=1), URL)
    next(one)
    with pytest.raises(ic.ServerError):
        one.send(httpx.Response(500, content=b"oops", request=req))


def test_error_body_code_and_detail_of():
    from illumix_client.errors import detail_of, error_for

    body = json.dumps(error_body(503, "busy: 3 requests ahead", "busy")).encode()
    err = error_for(503, body)
    assert type(err) is ic.ServerError and (err.detail, err.code) == ("busy: 3 requests ahead", "busy")
    assert detail_of(body, "x") == "busy: 3 requests ahead"
    assert error_for(404, b'{"detail": "gone"}').code is None
    assert error_for(404, b'{"detail": "gone", "code": 7}').code is None  # not a slug
    assert error_for(502, b"<html>bad gateway</html>").code is None
    assert ic.IllumixError("x").code is None
