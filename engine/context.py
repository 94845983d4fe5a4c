"""The composition context: store, sensor/illuminant library, caches and memory budget.

One per service (:func:`service.app.create_app`) or per local client (``illumix_client.local``).
"""

from __future__ import annotations

from dataclasses import dataclass

from illumix.engine import budget
from illumix.engine.library import Library
from illumix.engine.limits import Limits
from illumix.engine.projections import ProjectionCache, projection_share
from illumix.store.lru import LRUCache, nbytes_cost


@dataclass
class Context:
    store: object
    library: Library
    cache: LRUCache
    limits: Limits
    memory: budget.MemoryBudget
    projections: ProjectionCache | None = None
    torch: object | None = None  # a engine.torch_sampling.TorchComposer when composing on a device


def make_context(store, *, cache_mb: int = 1024, projection_mb: int | None = None,
                 limits: Limits | None = None, device: str | None = None, device_cache_mb: int = 8192) -> Context:
    """The composition context over an open store: ``cache_mb`` bounds the decoded cubes,
    ``projection_mb`` (in addition) the whole-frame projections (default: a quarter of ``cache_mb``,
    at most 512 MiB; 0 turns them off). ``device``: compose eligible requests with torch there
    (:mod:`engine.torch_sampling`), with up to ``device_cache_mb`` of cubes on it. Used by the
    service and by the client's local mode."""
    limits = limits or Limits()
    projection_mb = projection_share(cache_mb) if projection_mb is None else projection_mb
    cache = LRUCache(cache_mb * 2**20, cost=nbytes_cost, on_load=_read_only, track_evicted=True)
    memory = budget.MemoryBudget(limits.inflight_mb * 2**20, limits.queue_timeout_s,
                                 per_request=limits.max_request_mb * 2**20)
    composer = None
    if device is not None:
        from illumix.engine.torch_sampling import TorchComposer

        composer = TorchComposer(device, device_cache_mb)
    return Context(store=store, library=Library(store), cache=cache, limits=limits, memory=memory,
                   projections=ProjectionCache(projection_mb * 2**20) if projection_mb > 0 else None,
                   torch=composer)


def _read_only(arr) -> None:
    arr.flags.writeable = False  # one cached cube serves every request: nobody may change it
