"""What the service benchmarks share: a free loopback port and waiting for a started server."""

from __future__ import annotations

import socket
import subprocess
import time


def free_port() -> int:
    """A port on 127.0.0.1 nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_healthy(url: str, proc: subprocess.Popen | None = None, timeout: float = 60.0,
                 what: str = "the server", log=None) -> float:
    """Poll ``url``/health until it answers 200; seconds waited. Exits (SystemExit, one line) when
    ``proc`` ends first or ``timeout`` passes; ``log``: a readable file with the server's output."""
    import httpx

    t0 = time.monotonic()
    while True:
        try:
            if httpx.get(f"{url}/health", timeout=2).status_code == 200:
                return time.monotonic() - t0
        except httpx.HTTPError:
            pass
        if (proc is not None and proc.poll() is not None) or time.monotonic() - t0 > timeout:
            tail = ""
            if log is not None:
                log.seek(0)
                tail = ": " + log.read().decode(errors="replace")[-2000:]
            raise SystemExit(f"{what} did not start{tail}")
        time.sleep(0.1)
