"""``illumix serve`` — run the FastAPI service over a store with uvicorn."""

from __future__ import annotations

import os

import typer

from illumix.errors import UserError


def open_store(path: str, mode: str = "r"):
    from store import CubeStore, StoreError

    try:
        return CubeStore.open(path, mode=mode)
    except StoreError as exc:
        raise UserError(str(exc)) from None


def serve(
    store: str = typer.Option(..., "--store", help="Store path or fsspec URL."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to bind (default loopback only)."),
    port: int = typer.Option(8000, "--port", min=0, max=65535),
    token: str | None = typer.Option(None, "--token", envvar="ILLUMIX_TOKEN",
                                     help="Bearer token required for uploads/deletes (or ILLUMIX_TOKEN)."),
    cache_mb: int = typer.Option(1024, "--cache-mb", min=0, help="Decoded-cube LRU cache size, MiB."),
) -> None:
    """Serve samples over HTTP (OpenAPI docs at /docs)."""
    import uvicorn

    from service.app import create_app

    app = create_app(open_store(store, mode="a"), token=token or os.environ.get("ILLUMIX_TOKEN"),
                     cache_mb=cache_mb)
    uvicorn.run(app, host=host, port=port, log_level="info")


def register(app: typer.Typer) -> None:
    app.command("serve")(serve)
