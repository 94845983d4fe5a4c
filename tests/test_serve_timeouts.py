"""Slow clients cannot hold sockets: ``illumix serve`` (a real server on 127.0.0.1, in a subprocess)
closes a connection whose request head does not arrive whole within ``--header-timeout`` seconds —
nothing sent, half a request line, headers trickled byte by byte, the next request on a kept-alive
connection — and the rest of a body it answered without reading. Well-behaved requests are served."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

import synthetic_store
from server_testutil import free_port

HEAD_TIMEOUT = 1.5  # the option under test; production default 10 s
SLACK = 2.0  # the event loop, a loaded 2-core machine


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    store = tmp_path_factory.mktemp("timeouts") / "store"
    synthetic_store.build(store, h=8, w=8, extras=False)
    port = free_port()
    log = open(store.parent / "serve.log", "wb")
    env = {k: v for k, v in os.environ.items() if k != "ILLUMIX_TOKEN"}
    proc = subprocess.Popen([sys.executable, "-m", "illumix.cli", "serve", "--store", str(store), "--host",
                             "127.0.0.1", "--port", str(port), "--cache-mb", "16", "--header-timeout",
                             str(HEAD_TIMEOUT), "--keep-alive-timeout", "30"], env=env, stdout=log,
                            stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while True:
            assert proc.poll() is None, (store.parent / "serve.log").read_text()[-2000:]
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "the server did not start within 60 s"
                time.sleep(0.1)
        yield port
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


def _until_closed(sock: socket.socket, started: float, trickle: bytes = b"") -> tuple[float, bytes]:
    """Read (sending ``trickle`` a byte every 0.2 s meanwhile) until the server closes; ``(seconds
    since started, what it sent)``."""
    sock.settimeout(0.2)
    got = b""
    while time.monotonic() - started < HEAD_TIMEOUT + 3 * SLACK:
        if trickle:
            try:
                sock.sendall(trickle[:1])
            except OSError:  # closed under us
                break
            trickle = trickle[1:]
        try:
            chunk = sock.recv(65536)
        except socket.timeout:
            continue
        except ConnectionResetError:
            break
        if not chunk:
            break
        got += chunk
    return time.monotonic() - started, got


def _probe(port: int, first: bytes = b"", trickle: bytes = b"", keep_alive_first: bool = False):
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        answered = b""
        if keep_alive_first:  # one whole request, answered, then the slow part on the same connection
            sock.sendall(b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n")
            while b"\r\n\r\n" not in answered or not answered.rstrip().endswith(b"}"):
                answered += sock.recv(65536)
        started = time.monotonic()
        sock.sendall(first)
        elapsed, got = _until_closed(sock, started, trickle)
    return answered, elapsed, got


CASES = {
    "nothing sent": dict(),
    "half a request line": dict(first=b"GET /hea"),
    "headers trickled": dict(first=b"GET /health HTTP/1.1\r\n", trickle=b"Host: 127.0.0.1\r\nX-Slow: " + b"a" * 40),
    "kept-alive, next head partial": dict(first=b"GET /health HTTP/1.1\r\nHo", keep_alive_first=True),
    "answered body never finished": dict(first=b"GET /health HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\nab",
                                         trickle=b"cdefghijklmnopqrstuvwxyz" * 2),
}


def test_slow_clients_are_closed_within_the_header_timeout(server):
    with ThreadPoolExecutor(len(CASES)) as pool:  # all at once: the test takes one timeout, not five
        results = dict(zip(CASES, pool.map(lambda kw: _probe(server, **kw), CASES.values())))
    for name, (answered, elapsed, got) in results.items():
        assert HEAD_TIMEOUT - 0.1 <= elapsed <= HEAD_TIMEOUT + SLACK, (name, elapsed, got)
        if name == "kept-alive, next head partial":
            assert answered.startswith(b"HTTP/1.1 200"), answered
        if name in ("half a request line", "headers trickled", "kept-alive, next head partial"):
            head, _, body = got.partition(b"\r\n\r\n")
            assert head.startswith(b"HTTP/1.1 408") and b"connection: close" in head.lower(), (name, got)
            error = json.loads(body)
            assert error["status"] == 408 and error["code"] == "request_timeout", error
            assert f"within {HEAD_TIMEOUT:g} s" in error["detail"] and "\n" not in error["detail"]
        elif name == "nothing sent":
            assert got == b"", got  # an idle pre-opened socket is closed silently
        else:  # the answer to the request, then the close: no second answer for a body never read
            assert got.count(b"HTTP/1.1 ") == 1 and got.startswith(b"HTTP/1.1 200"), got


def test_prompt_requests_are_served_and_kept_alive(server):
    with socket.create_connection(("127.0.0.1", server), timeout=10) as sock:
        for i in range(2):  # the second on the same connection, after more than the header timeout
            sock.sendall(b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n")
            data = b""
            while not data.rstrip().endswith(b"}"):
                data += sock.recv(65536)
            assert data.startswith(b"HTTP/1.1 200"), data
            if i == 0:  # an idle kept-alive connection is the keep-alive timeout's (30 s), not the header one
                time.sleep(HEAD_TIMEOUT + 0.5)


@pytest.mark.parametrize("args, expected", [
    ((), (10.0, 5.0, 10.0, 60.0)),
    (("--header-timeout", "3", "--keep-alive-timeout", "2", "--body-timeout", "4", "--body-total-timeout", "9"),
     (3.0, 2.0, 4.0, 9.0))])
def test_serve_passes_the_timeouts_to_uvicorn_and_the_app(tmp_path, capsys, monkeypatch, args, expected):
    """The documented defaults, and the options, reach uvicorn (header, keep-alive) and the app (bodies)."""
    import uvicorn

    from cli_testutil import run_cli

    calls = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: calls.append({"app": app, **kw}))
    monkeypatch.delenv("ILLUMIX_TOKEN", raising=False)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    synthetic_store.build(tmp_path / "st", h=8, w=8, extras=False)
    code, _, err = run_cli(capsys, "serve", "--store", str(tmp_path / "st"), "--port", "0", *args)
    assert code == 0 and len(calls) == 1, err
    call = calls[0]
    limits = call["app"].state.ctx.limits
    got = (call["http"].head_timeout, call["timeout_keep_alive"], limits.body_timeout_s, limits.body_total_s)
    assert got == expected
