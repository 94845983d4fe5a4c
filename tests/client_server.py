"""Helpers for the client tests: a real illumix server in a subprocess on 127.0.0.1, and a tiny TCP
proxy on 127.0.0.1 that misbehaves on chosen connections (drops them, answers a canned status)
before proxying the rest — to test the client's retries against real sockets."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from server_testutil import free_port

REPO_ROOT = Path(__file__).resolve().parents[1]


class ServerProcess:
    """``python -m illumix.cli serve --store PATH --host 127.0.0.1 --port N --token T`` until stopped."""

    def __init__(self, store: Path, token: str | None, log: Path) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        cmd = [sys.executable, "-m", "illumix.cli", "serve", "--store", str(store), "--host", "127.0.0.1",
               "--port", str(self.port), "--cache-mb", "64"]
        if token:
            cmd += ["--token", token]
        env = {k: v for k, v in os.environ.items() if k != "ILLUMIX_TOKEN"}
        self.log = log
        self._log = open(log, "wb")
        self.proc = subprocess.Popen(cmd, cwd=REPO_ROOT, env=env, stdout=self._log, stderr=subprocess.STDOUT)

    def wait_ready(self, timeout: float = 60.0) -> None:
        """Poll /health (bounded by ``timeout`` seconds)."""
        import httpx

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited {self.proc.returncode}: {self.log.read_text()[-2000:]}")
            try:
                if httpx.get(self.url + "/health", timeout=2.0).status_code == 200:
                    return
            except httpx.TransportError:
                pass
            time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"server not ready after {timeout} s: {self.log.read_text()[-2000:]}")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._log.close()


def _read_request(conn: socket.socket, limit: int = 4 * 2**20) -> bytes:
    """Read one HTTP request (headers + Content-Length body), bounded by ``limit`` bytes."""
    data = b""
    while b"\r\n\r\n" not in data and len(data) < limit:
        chunk = conn.recv(65536)
        if not chunk:
            return data
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    length = 0
    for line in head.split(b"\r\n")[1:]:
        k, _, v = line.partition(b":")
        if k.strip().lower() == b"content-length":
            length = int(v.strip())
    while len(body) < min(length, limit):
        chunk = conn.recv(65536)
        if not chunk:
            break
        body += chunk
    return head + b"\r\n\r\n" + body


class FlakyProxy:
    """TCP proxy on 127.0.0.1 in front of ``upstream`` port. ``behaviour(n)`` decides connection
    ``n`` (0-based): ``"drop"`` (read the request, close without answering), an int status (answer
    it with a JSON detail and close) or ``"proxy"`` (relay both ways). ``start(delay)`` keeps the port
    refusing connections for ``delay`` seconds first. ``connections`` counts accepted connections,
    ``requests`` the request lines of the dropped or answered ones."""

    def __init__(self, upstream: int, behaviour: Callable[[int], str | int]) -> None:
        self.upstream, self.behaviour = upstream, behaviour
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        self.connections = 0
        self.requests: list[str] = []
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()

    def start(self, delay: float = 0.0) -> FlakyProxy:
        """Start accepting; with ``delay`` seconds the port is bound but refuses connections first."""
        def run() -> None:
            if delay:
                time.sleep(delay)
            self.sock.listen(16)
            self.sock.settimeout(0.1)
            while not self._stop.is_set():
                try:
                    conn, _ = self.sock.accept()
                except (TimeoutError, OSError):
                    continue
                with self._lock:
                    n = self.connections
                    self.connections += 1
                t = threading.Thread(target=self._handle, args=(conn, n), daemon=True)
                t.start()
                self._threads.append(t)

        t = threading.Thread(target=run, daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def _handle(self, conn: socket.socket, n: int) -> None:
        conn.settimeout(30)
        what = self.behaviour(n)
        try:
            if what == "proxy":
                self._relay(conn)
                return
            req = _read_request(conn)
            with self._lock:
                self.requests.append(req.split(b"\r\n", 1)[0].decode("latin-1"))
            if isinstance(what, int):
                body = json.dumps({"detail": f"canned {what} from the test proxy"}).encode()
                conn.sendall(b"HTTP/1.1 %d X\r\nContent-Type: application/json\r\nContent-Length: %d\r\n"
                             b"Retry-After: 0\r\nConnection: close\r\n\r\n%s" % (what, len(body), body))
        except OSError:
            pass
        finally:
            conn.close()

    def _relay(self, conn: socket.socket) -> None:
        up = socket.create_connection(("127.0.0.1", self.upstream), timeout=30)

        def pump(src: socket.socket, dst: socket.socket) -> None:
            try:
                while True:
                    data = src.recv(65536)
                    if not data:
                        break
                    dst.sendall(data)
            except OSError:
                pass
            finally:
                for s in (dst,):
                    try:
                        s.shutdown(socket.SHUT_WR)
                    except OSError:
                        pass

        t = threading.Thread(target=pump, args=(up, conn), daemon=True)
        t.start()
        pump(conn, up)
        t.join(timeout=30)
        up.close()

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)
        self.sock.close()

    def __enter__(self) -> FlakyProxy:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
