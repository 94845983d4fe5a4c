"""``GET /metrics``: the app's Prometheus metrics (:mod:`service.metrics`) in the text exposition format."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import PlainTextResponse, Response
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest

# The classic text format (version 0.0.4) that generate_latest writes; prometheus_client >= 0.22
# names it apart from CONTENT_TYPE_LATEST, which there announces the 1.0.0 format.
try:
    from prometheus_client.exposition import CONTENT_TYPE_PLAIN_0_0_4 as CONTENT_TYPE
except ImportError:  # prometheus_client < 0.22: LATEST is 0.0.4
    CONTENT_TYPE = CONTENT_TYPE_LATEST

router = APIRouter(tags=["status"])


# response_class=Response, as for /sample: PlainTextResponse there would document the app-wide JSON
# error answers (405) as text/plain too. The 200 is documented here and answered as plain text.
@router.get("/metrics", response_class=Response,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}},
                             "description": "Prometheus text exposition format (version 0.0.4)"}})
async def metrics(request: Request) -> PlainTextResponse:
    """Requests by route, method and status; latency histogram by route; cube cache hits, misses and
    bytes; working memory in flight; 503s refused busy; process RSS and CPU. Runs on the event loop,
    like ``/health``, so a scrape answers while every worker waits for working memory."""
    return PlainTextResponse(generate_latest(request.app.state.metrics.registry), media_type=CONTENT_TYPE)
