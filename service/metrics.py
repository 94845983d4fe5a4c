"""Prometheus metrics of one app: requests, latency, the cube cache, working memory, RSS.

So a user can see what the service is doing (issue 19) with any Prometheus scraper at
``GET /metrics``. Each app has its own :class:`prometheus_client.CollectorRegistry` — tests build
many apps in one process, and the global default registry would refuse the second app's metrics.

- :class:`RequestMetrics`, a pure ASGI middleware, counts requests by route *template* (``/sample``,
  ``/sensors/{name}``; paths that match no route are ``other``), method and status, and times them
  from the first byte in to the last byte out. Labels are bounded, so no client can grow the
  exposition by inventing paths or methods.
- :class:`ServiceCollector` reads the cube cache and the memory budget at scrape time, so the
  figures are the ones ``/health`` reports, never a second count that could drift.
- :class:`prometheus_client.ProcessCollector` adds ``illumix_process_resident_memory_bytes`` (and
  CPU, open files) from ``/proc`` on Linux.
"""

from __future__ import annotations

import time

from prometheus_client import CollectorRegistry, Counter, Histogram, ProcessCollector
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: seconds, from a cached 256² crop (~1 ms) to a cold full frame of all outputs under load (~30 s)
BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0)
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
OTHER = "other"


class Metrics:
    """The registry of one app and its request instruments."""

    def __init__(self, ctx) -> None:
        self.registry = CollectorRegistry()
        self.requests = Counter("illumix_requests", "HTTP requests answered, by route template, method and status",
                                ("route", "method", "status"), registry=self.registry)
        self.duration = Histogram("illumix_request_duration_seconds",
                                  "Time from request to the last byte of the answer, by route template",
                                  ("route",), buckets=BUCKETS, registry=self.registry)
        self.registry.register(ServiceCollector(ctx))
        ProcessCollector(namespace="illumix", registry=self.registry)


class ServiceCollector(Collector):
    """The cube cache and working-memory figures of a :class:`engine.context.Context`, read live."""

    def __init__(self, ctx) -> None:
        self.ctx = ctx

    def collect(self):
        c, m = self.ctx.cache, self.ctx.memory
        yield CounterMetricFamily("illumix_cache_hits", "Decoded-cube cache hits (a request found the cube decoded)",
                                  value=c.hits)
        yield CounterMetricFamily("illumix_cache_misses", "Decoded-cube cache misses (a cube was decoded)",
                                  value=c.misses)
        yield GaugeMetricFamily("illumix_cache_bytes", "Decoded cube bytes the cache holds", value=c.total_cost)
        yield GaugeMetricFamily("illumix_cache_max_bytes", "The cube cache's bound (--cache-mb)", value=c.max_cost)
        yield GaugeMetricFamily("illumix_cache_evicted_in_use_bytes",
                                "Evicted cubes that requests still use (counted against the bound)",
                                value=c.evicted_cost)
        yield GaugeMetricFamily("illumix_cache_entries", "Entries (cubes and AOVs) the cache holds", value=len(c))
        pc = self.ctx.projections
        if pc is not None:
            yield CounterMetricFamily("illumix_projection_hits", "Samples sliced from a cached whole-frame projection "
                                      "(per group; no cube read)", value=pc.hits)
            yield CounterMetricFamily("illumix_projection_misses", "Whole-frame projections computed and kept",
                                      value=pc.misses)
            yield GaugeMetricFamily("illumix_projection_bytes", "Projection bytes kept (bounded by --projection-cache-mb)",
                                    value=pc.cache.total_cost)
        yield GaugeMetricFamily("illumix_inflight_bytes",
                                "Working memory reserved by requests being computed or sent", value=m.used)
        yield GaugeMetricFamily("illumix_inflight_limit_bytes", "The in-flight bound (--inflight-mb)",
                                value=m.capacity)
        yield CounterMetricFamily("illumix_refused_busy",
                                  "Requests answered 503 because the working-memory budget stayed full",
                                  value=m.refused_busy)


class RequestMetrics:
    """ASGI middleware recording every HTTP request in a :class:`Metrics`; ``routes``: the app's
    concrete routes (FastAPI wraps included routers in objects without a path template)."""

    def __init__(self, app: ASGIApp, metrics: Metrics, routes: list) -> None:
        self.app, self.metrics, self.routes = app, metrics, routes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        status = 500  # an exception before the answer started: the server answers 500

        async def recorded(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, recorded)
        finally:
            route = self.template(scope)
            method = scope["method"] if scope["method"] in METHODS else OTHER
            self.metrics.requests.labels(route, method, str(status)).inc()
            self.metrics.duration.labels(route).observe(time.perf_counter() - start)

    def template(self, scope: Scope) -> str:
        """The path template of the route the path matches (a wrong method still names it), else ``other``."""
        partial = None
        for route in self.routes:
            if not hasattr(route, "path"):
                continue
            match, _ = route.matches(scope)
            if match == Match.FULL:
                return getattr(route, "path_format", route.path)  # "{name}", not "{name:convertor}"
            if match == Match.PARTIAL and partial is None:
                partial = getattr(route, "path_format", route.path)
        return partial or OTHER
