"""A real uvicorn server on 127.0.0.1 in a thread, for tests that need sockets (timeouts, headers)."""

from __future__ import annotations

import socket
import threading
import time


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ThreadServer:
    """``with ThreadServer(app) as url:`` — uvicorn on 127.0.0.1 in a thread; stops on exit."""

    def __init__(self, app, **config):
        import uvicorn

        self.port = free_port()
        self.server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=self.port, log_level="warning",
                                                    **config))
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def __enter__(self) -> str:
        self.thread.start()
        deadline = time.time() + 20
        while not self.server.started:
            if time.time() > deadline:
                raise RuntimeError("server did not start")
            time.sleep(0.05)
        return f"http://127.0.0.1:{self.port}"

    def __exit__(self, *exc) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=10)


def synthetic_service_fixtures(prefix: str, token: str | None = None, **build):
    """Module-scoped pytest fixtures ``(store_path, client)``: a synthetic store
    (:mod:`synthetic_store`, ``build`` passed to its ``build``, e.g. ``illumination=True``) in a fresh
    temporary folder, and a ``TestClient`` of the service on it (token ``token``, 64 MiB cache). In a
    test module: ``store_path, client = synthetic_service_fixtures(...)``."""
    import pytest

    @pytest.fixture(scope="module")
    def store_path(tmp_path_factory):
        import synthetic_store

        path = tmp_path_factory.mktemp(prefix) / "store"
        synthetic_store.build(path, **build)
        return path

    @pytest.fixture(scope="module")
    def client(store_path):
        from fastapi.testclient import TestClient

        from illumix.service.app import create_app
        from illumix.store import CubeStore

        with TestClient(create_app(CubeStore.open(str(store_path), mode="a"), token=token, cache_mb=64)) as c:
            yield c

    return store_path, client
