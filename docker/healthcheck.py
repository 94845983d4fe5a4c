#!/usr/bin/env python3
"""Container health check for both illumix images (standard library only, fast).

Looks at what the container runs and checks that:

* ``illumix serve`` — ``GET /health`` on the address it serves answers 200 with ``"status": "ok"``
  (host and port read from the serve command line, else ``ILLUMIX_HOST`` / ``ILLUMIX_PORT``; a
  wildcard bind is checked on loopback);
* a Ray node (``ray-head`` / ``ray-worker``) — its raylet is running and the cluster's GCS accepts a
  TCP connection (head: ``RAY_NODE_IP:RAY_PORT``, loopback when unset; worker: ``RAY_ADDRESS``);
* anything else (a one-shot ``illumix render`` job) — healthy while it runs.

Exit 0 healthy, 1 unhealthy (Docker's HEALTHCHECK convention); one line on stdout either way.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import urllib.request
from pathlib import Path


def _processes() -> list[list[str]]:
    out = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            raw = (p / "cmdline").read_bytes()
        except OSError:
            continue
        if raw:
            out.append([a.decode(errors="replace") for a in raw.rstrip(b"\0").split(b"\0")])
    return out


def _opt(argv: list[str], name: str) -> str | None:
    for i, a in enumerate(argv):
        if a == name and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith(name + "="):
            return a.split("=", 1)[1]
    return None


def _is_serve(argv: list[str]) -> bool:
    return any(Path(a).name == "illumix" for a in argv[:2]) and "serve" in argv


def check_serve(argv: list[str]) -> tuple[bool, str]:
    host = _opt(argv, "--host") or os.environ.get("ILLUMIX_HOST", "127.0.0.1")
    port = _opt(argv, "--port") or os.environ.get("ILLUMIX_PORT", "8000")
    if host in ("0.0.0.0", "", "::"):
        host = "127.0.0.1"
    url = f"http://[{host}]:{port}/health" if ":" in host else f"http://{host}:{port}/health"
    try:
        with urllib.request.urlopen(url, timeout=float(os.environ.get("ILLUMIX_HEALTH_TIMEOUT", "4"))) as r:
            body = json.loads(r.read() or b"{}")
            ok = r.status == 200 and body.get("status") == "ok"
            return ok, f"{url} -> {r.status} {json.dumps(body)}"
    except Exception as exc:  # noqa: BLE001 — any failure is "unhealthy"
        return False, f"{url} -> {type(exc).__name__}: {exc}"


def _tcp(addr: str) -> tuple[bool, str]:
    host, _, port = addr.rpartition(":")
    try:
        with socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)), timeout=3):
            return True, f"GCS {addr} reachable"
    except (OSError, ValueError) as exc:
        return False, f"GCS {addr} unreachable: {exc}"


def check_ray(procs: list[list[str]], head: bool) -> tuple[bool, str]:
    if not any(Path(a[0]).name == "raylet" for a in procs if a):
        return False, "ray node: no raylet process"
    if head:
        addr = f"{os.environ.get('RAY_NODE_IP') or '127.0.0.1'}:{os.environ.get('RAY_PORT', '6379')}"
    else:
        addr = os.environ.get("RAY_ADDRESS", "")
        if not addr or addr == "auto":
            return True, "ray worker: raylet running (no RAY_ADDRESS to probe)"
    ok, msg = _tcp(addr)
    return ok, f"ray {'head' if head else 'worker'}: raylet running, {msg}"


def main() -> int:
    procs = _processes()
    serve = [a for a in procs if _is_serve(a)]
    if serve:
        ok, msg = check_serve(serve[0])
    elif any(Path(a[0]).name == "raylet" for a in procs if a) or any("ray" in " ".join(a[:3]) and "start" in a
                                                                      for a in procs):
        head = any("--head" in a and "start" in a for a in procs)
        ok, msg = check_ray(procs, head)
    else:
        ok, msg = True, "no long-running illumix role in this container (one-shot job)"
    print(("healthy: " if ok else "unhealthy: ") + msg)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
