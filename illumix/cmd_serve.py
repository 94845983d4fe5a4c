"""``illumix serve`` — run the FastAPI service over a store with uvicorn."""

from __future__ import annotations

import os
import socket
import sys

import typer

from illumix.errors import UserError


def open_store(path: str, *, create: bool = False):
    """The store at ``path`` opened for the service (which persists uploads). A path holding no
    store is refused unless ``create``: a typo must not silently serve a new, empty store."""
    from illumix.store import CubeStore, StoreError

    try:
        if not create and not CubeStore.exists(path):
            raise UserError(f"no illumix store at {path}; render one there with `illumix render --store "
                            f"{path} …`, or pass --create to serve a new, empty store")
        return CubeStore.open(path, mode="a")
    except StoreError as exc:
        raise UserError(str(exc)) from None


def check_address(host: str, port: int) -> None:
    """Refuse a --host this machine cannot listen on, or a --port already taken, with one line
    (uvicorn would log a few lines and exit 3). A port taken between here and uvicorn's own bind
    is still reported by uvicorn."""
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as exc:
        raise UserError(f"--host {host!r} is not an address: {exc.strerror}; give e.g. 127.0.0.1 or 0.0.0.0") from None
    with socket.socket(family, kind, proto) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds
        try:
            s.bind(addr)
        except OSError as exc:
            raise UserError(f"cannot listen on {host}:{port}: {exc.strerror}; choose another --port or "
                            "--host") from None


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
    cache_mb: int = typer.Option(1024, "--cache-mb", min=0,
                                 help="Decoded-cube LRU cache size, MiB."),
    projection_mb: int | None = typer.Option(None, "--projection-cache-mb", min=0,
                                             help="Whole-frame projections per (cube, sensor, illuminant) kept, "
                                                  "MiB, in addition to --cache-mb, so crops are slices (default "
                                                  "a quarter of --cache-mb, at most 512; 0: off)."),
    max_request_mb: int = typer.Option(160, "--max-request-mb", min=1,
                                       help="Most working memory one request or batch may need, MiB "
                                            "(priced before any work; above it: 413 with a hint)."),
    inflight_mb: int = typer.Option(160, "--inflight-mb", min=1,
                                    help="Working memory of all requests in flight, MiB (beyond it "
                                         "requests wait, then 503). RSS ≈ 200 MB + --cache-mb + --projection-cache-mb + this."),
    device: str | None = typer.Option(None, "--device",
                                      help="Compose raw/gain/mask/weights/illum/mixture requests with torch on this "
                                           "device (e.g. cuda; needs torch); everything else on the CPU."),
    device_cache_mb: int = typer.Option(8192, "--device-cache-mb", min=1,
                                        help="Cubes kept on --device, MiB (its memory; when it runs out, "
                                             "the request is composed on the CPU)."),
    warm: bool = typer.Option(False, "--warm",
                              help="Before serving, decode the cubes a default /sample of each view reads "
                                   "into the cache (one line per cube on stderr), until the cache is full, "
                                   "so the first requests are hits."),
    header_timeout: float = typer.Option(10.0, "--header-timeout", min=0.01,
                                         help="Seconds a request line and headers may take to arrive whole, from "
                                              "the connection opening (or the next request's first byte); then "
                                              "408 and the connection closed."),
    keep_alive_timeout: float = typer.Option(5.0, "--keep-alive-timeout", min=0.01,
                                             help="Seconds an idle kept-alive connection stays open."),
    body_timeout: float = typer.Option(10.0, "--body-timeout", min=0.01,
                                       help="Longest pause, s, while a request body arrives; then 408."),
    body_total_timeout: float = typer.Option(60.0, "--body-total-timeout", min=0.01,
                                             help="Longest time, s, a whole request body may take; then 408."),
) -> None:
    """Serve samples over HTTP (OpenAPI docs at /docs)."""
    check_address(host, port)  # refuse before anything starts or is created
    if inflight_mb < max_request_mb:
        raise UserError(f"--inflight-mb ({inflight_mb}) must be at least --max-request-mb ({max_request_mb}), "
                        "or the largest allowed request could never run")
    cube_store = open_store(store, create=create)
    token = resolve_token(token, host, port)
    from illumix.allocator import tune_for_service
    from illumix.engine.limits import Limits

    tune_for_service()
    limits = Limits(max_request_mb=max_request_mb, inflight_mb=inflight_mb, body_timeout_s=body_timeout,
                    body_total_s=max(body_timeout, body_total_timeout))
    app = make_app(cube_store, token=token, cache_mb=cache_mb, limits=limits, projection_mb=projection_mb,
                   device=device, device_cache_mb=device_cache_mb)
    if warm:  # before uvicorn binds: once the port answers, the cache is warm
        from illumix.engine.warm import warm_cache

        warm_cache(app.state.ctx, log=lambda line: print(f"illumix: {line}", file=sys.stderr, flush=True))
    run_server(app, host, port, header_timeout=header_timeout, keep_alive_timeout=keep_alive_timeout)


def make_app(cube_store, *, device: str | None, **options):
    """The service app (:func:`service.app.create_app`); a --device that cannot be used is one line."""
    from illumix.service.app import create_app

    try:
        return create_app(cube_store, device=device, **options)
    except ImportError:
        if device is None:
            raise
        raise UserError(f"--device {device}: torch is not installed; pip install torch") from None
    except RuntimeError as exc:
        if device is None:
            raise
        raise UserError(f"--device {device}: {exc}; leave out --device to compose on the CPU") from None


def run_server(app, host: str, port: int, *, header_timeout: float, keep_alive_timeout: float) -> None:
    """uvicorn (h11) with the timeouts slow clients meet: a request head must arrive whole within
    ``header_timeout`` s (:mod:`service.http_timeouts`), an idle kept-alive connection is closed after
    ``keep_alive_timeout`` s; request bodies are bounded by the app (:mod:`service.body_guard`)."""
    import uvicorn

    from illumix.service.http_timeouts import head_timeout_protocol

    uvicorn.run(app, host=host, port=port, log_level="info", http=head_timeout_protocol(header_timeout),
                timeout_keep_alive=keep_alive_timeout)


def register(app: typer.Typer) -> None:
    app.command("serve")(serve)
