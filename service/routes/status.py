"""``GET /health`` and ``GET /scenes``: what the service holds and how it is doing."""

from __future__ import annotations

from fastapi import APIRouter, Request

from illumix.engine import catalogue
from illumix.service.deps import CtxDep
from illumix.service.errors import error_responses
from illumix.service.models import CacheStats, Health, MemoryStats, Scenes

router = APIRouter(tags=["status"])


@router.get("/health", response_model=Health)
async def health(request: Request, ctx: CtxDep) -> Health:
    """Liveness plus cache and working-memory figures. Runs on the event loop, not in the worker
    threads, so it answers even while every worker waits for working memory."""
    c, m, pc = ctx.cache, ctx.memory, ctx.projections
    return Health(status="ok", scenes=len(ctx.store.scenes()), cache_bytes=c.total_cost, cache_hits=c.hits,
                  cache_misses=c.misses,
                  cache=_stats(c),
                  projections=None if pc is None else _stats(pc.cache),
                  memory=MemoryStats(inflight_bytes=m.used, inflight_limit_bytes=m.capacity,
                                     request_limit_bytes=m.per_request, peak_inflight_bytes=m.peak,
                                     refused_busy=m.refused_busy),
                  auth=request.app.state.token is not None)


def _stats(c) -> CacheStats:
    return CacheStats(bytes=c.total_cost, evicted_in_use_bytes=c.evicted_cost, max_bytes=c.max_cost,
                      hits=c.hits, misses=c.misses)


@router.get("/scenes", response_model=Scenes, responses=error_responses(503))
def scenes(ctx: CtxDep) -> Scenes:
    """Every scene, view and light group the store holds. A damaged view is a 503 (run
    `illumix store verify`), never silently left out."""
    return Scenes.model_validate({"scenes": catalogue.scenes(ctx)})
