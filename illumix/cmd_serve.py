"""``illumix serve`` — run the FastAPI service over a store with uvicorn."""

from __future__ import annotations

import os
import sys

import typer

from illumix.errors import UserError

def open_store(path: str, *, create: bool = False):
    """The store at ``path`` opened for the service (which persists uploads). A path holding no
    store is refused unless ``create``: a typo must not silently serve a new, empty store."""
    from store import CubeStore, StoreError

    try:
        if not create and not CubeStore.exists(path):
            raise UserError(f"no illumix store at {path}; render one there with `illumix render --store "
                            f"{path} …`, or pass --create to serve a new, empty store")
        return CubeStore.open(path, mode="a")
    except StoreError as exc:
        raise UserError(str(exc)) from None


def resolve_token(token: str | None, host: str, port: int) -> str | None:
    """The service's token, ``None`` for none. An empty (or blank) token turns authentication off,
    which must not pass unnoticed: it is as likely an unset shell variable as a choice. click reads
    an empty ILLUMIX_TOKEN as unset, so the environment is consulted again here."""
    given = token if token is not None else os.environ.get("ILLUMIX_TOKEN")
    if given is not None and not given.strip():
        print(f"illumix: warning: the token is empty (--token '' or ILLUMIX_TOKEN=''), so authentication "
              f"is off: uploads and deletes are open to anyone who can reach {host}:{port}", file=sys.stderr)
        return None
    return given


def serve(
    store: str = typer.Option(..., "--store", help="Store path or fsspec URL (must hold a store unless --create)."),
    create: bool = typer.Option(False, "--create", help="Create an empty store at --store if none is there."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to bind (default loopback only)."),
    port: int = typer.Option(8000, "--port", min=0, max=65535),
    token: str | None = typer.Option(None, "--token", envvar="ILLUMIX_TOKEN",
                                     help="Bearer token required for uploads/deletes (or ILLUMIX_TOKEN); "
                                          "without one, writes are open."),
    cache_mb: int = typer.Option(1024, "--cache-mb", min=0, help="Decoded-cube LRU cache size, MiB."),
) -> None:
    """Serve samples over HTTP (OpenAPI docs at /docs)."""
    cube_store = open_store(store, create=create)  # refuse before anything starts
    token = resolve_token(token, host, port)
    import uvicorn

    from service.app import create_app

    uvicorn.run(create_app(cube_store, token=token, cache_mb=cache_mb), host=host, port=port, log_level="info")


def register(app: typer.Typer) -> None:
    app.command("serve")(serve)
