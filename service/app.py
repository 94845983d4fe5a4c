"""The FastAPI app (DESIGN.md "Service"). Build it with :func:`create_app`; run it with ``illumix serve``.

Reads are open; writes (uploading or deleting sensors and illuminants) need
``Authorization: Bearer TOKEN`` when the app has a token. Bad input is a 4xx whose body
(:class:`service.errors.ErrorBody`) says what to fix — never a 500 — and no response carries NaN or
inf (pixels with no light are flagged in ``mask``). Memory is bounded per request and in flight
(:mod:`engine.budget`); request bodies are bounded in size and time (:mod:`service.body_guard`).

Routers (one per resource): :mod:`service.routes.samples` (``/sample``, ``/batch``),
:mod:`service.routes.registries` (``/sensors``, ``/illuminants``), :mod:`service.routes.status`
(``/health``, ``/scenes``), :mod:`service.routes.metrics` (``/metrics``, Prometheus; collected by
:mod:`service.metrics`), :mod:`service.routes.explore` (``/explore/frame``, ``/explore/spectra``),
:mod:`service.routes.pixel` (``/explore/pixel``) and :mod:`service.routes.web`
(``/``, the web explorer page, and its static files under ``/web/``).
"""

from __future__ import annotations

import logging

from fastapi import FastAPI

from illumix.engine.context import make_context
from illumix.engine.limits import Limits
from illumix.service import errors
from illumix.service.body_guard import BodyGuard
from illumix.service.metrics import Metrics, RequestMetrics
from illumix.service.routes import (
    explore,
    metrics,
    pixel,
    registries,
    samples,
    sensor_estimate,
    status,
    web,
)

log = logging.getLogger("illumix.service")
_MULTIPART_OVERHEAD = 64 * 1024  # form fields and part headers around an uploaded file
_NO_BODY = 64 * 1024  # GET/DELETE: nothing is read, but do not let a huge claimed body hold a socket


def create_app(store, *, token: str | None = None, cache_mb: int = 1024, limits: Limits | None = None,
               projection_mb: int | None = None, device: str | None = None, device_cache_mb: int = 8192) -> FastAPI:
    """The service over an open :class:`store.CubeStore`.

    ``token``: bearer token required for writes (``None`` or empty: writes are open, with a warning
    in the log). ``cache_mb``: bound of the decoded-cube cache; ``projection_mb``: of the whole-frame
    projections, in addition (:mod:`engine.projections`; default a quarter of ``cache_mb``, at most
    512; 0 turns them off). ``limits``: :class:`Limits`. ``device``: compose eligible requests with torch there
    (:mod:`engine.torch_sampling`, e.g. ``"cuda"``; the rest on the CPU), keeping up to
    ``device_cache_mb`` of cubes there.
    """
    limits = limits or Limits()
    token = token or None  # an empty token would accept an empty Bearer header: treat as none
    if token is None:
        log.warning("no token set: uploads and deletes are open to anyone who can reach this service")
    app = FastAPI(title="illumix", version="0.1.0",
                  description="Mixed-illuminant colour-constancy samples with exact ground truth. Every error "
                              "answer is an ErrorBody: {detail, status, code, loc}.",
                  responses=errors.error_responses(405))
    app.state.ctx = make_context(store, cache_mb=cache_mb, projection_mb=projection_mb, limits=limits, device=device,
                                 device_cache_mb=device_cache_mb)
    app.state.token = token
    errors.install(app)
    app.state.metrics = Metrics(app.state.ctx)
    routers = (samples.router, sensor_estimate.router, registries.router, status.router, metrics.router, explore.router,
               pixel.router, web.router)
    for router in routers:
        app.include_router(router)
    web.mount_static(app)
    # every concrete route, for the Allow header of a 405 (FastAPI wraps included routers)
    app.state.routes = [r for r in app.routes if hasattr(r, "methods")] + [r for x in routers for r in x.routes]
    app.add_middleware(BodyGuard, limit_for=_body_limits(limits), timeout=limits.body_timeout_s,
                       total=limits.body_total_s)
    # outermost: the answers BodyGuard gives before routing are counted too
    app.add_middleware(RequestMetrics, metrics=app.state.metrics, routes=app.state.routes)
    return app


def _body_limits(limits: Limits):
    def limit_for(method: str, path: str) -> int:
        if method == "POST" and path in ("/sensors", "/illuminants"):
            return limits.max_upload_bytes + _MULTIPART_OVERHEAD
        if method == "POST" and path == "/batch":
            return limits.max_json_bytes
        return _NO_BODY
    return limit_for
