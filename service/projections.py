"""Whole-frame camera raw per (cube, sensor, illuminant), kept so crops are slices, not products.

A random-crop training feed asks the same few views under a pool of sensors and illuminants again
and again. Projecting a 256² crop reads 63 bands per pixel (~2 ms per group, memory bound); slicing
the frame's projection, computed once at intensity 1 (:class:`retarget.projected.Projected`), reads
3. The projection is exact (linear in the intensity), so the sample is the same either way.

A frame is projected when a key is asked for the ``min_uses``-th time (a continuous CCT range
rarely repeats a key: projecting the whole frame for one crop would cost ~10× the crop), or at
once when the request is the whole frame (it is projected anyway). The entries live in their own
LRU cache, carved out of ``--cache-mb``, so they never evict the decoded cubes they are made from.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable

import numpy as np

from retarget.projected import Projected
from retarget.relight import project_groups
from store.lru import LRUCache, nbytes_cost

MIN_USES = 2  # a key's projection is cached on its second request
_SEEN = 65536  # keys whose request count is remembered (a bounded LRU of counters)


def projection_share(cache_mb: int) -> int:
    """MiB of ``--cache-mb`` given to projections by default: a quarter, at most 512."""
    return min(cache_mb // 4, 512)


class ProjectionCache:
    """``key → Projected`` of whole frames; :meth:`window` returns a crop of one, or ``None``."""

    def __init__(self, max_bytes: int, min_uses: int = MIN_USES) -> None:
        self.cache: LRUCache[np.ndarray] = LRUCache(max_bytes, cost=nbytes_cost, on_load=_read_only,
                                                    track_evicted=True)
        self.min_uses = max(1, int(min_uses))
        self._seen: OrderedDict[Hashable, int] = OrderedDict()
        self._lock = threading.Lock()

    @property
    def hits(self) -> int:
        return self.cache.hits

    @property
    def misses(self) -> int:
        return self.cache.misses

    def _count(self, key: Hashable) -> int:
        with self._lock:
            n = self._seen.pop(key, 0) + 1
            self._seen[key] = n
            while len(self._seen) > _SEEN:
                self._seen.popitem(last=False)
            return n

    def window(self, key: Hashable, whole_cube: Callable[[], np.ndarray], weights: np.ndarray,
               window: tuple[int, int, int, int], frame_bytes: int, whole_frame: bool) -> Projected | None:
        """The ``window`` ``(x, y, w, h)`` of ``whole_cube() @ weights`` if it is (or is now) kept,
        else ``None`` (the caller projects its window of the cube itself).

        weights : ``(B, 3)`` the group's band weights at intensity 1; frame_bytes : the projection's
        size (``H·W·3·4``), so room is made before it is computed.
        """
        if frame_bytes > self.cache.max_cost:
            return None
        raw = self.cache.lookup(key)
        if raw is None:
            if not whole_frame and self._count(key) < self.min_uses:
                return None
            raw = self.cache.get(key, lambda: project_groups([whole_cube()], weights[None])[0],
                                 expected_cost=frame_bytes)
        n_bands = weights.shape[0]
        return Projected(raw, weights, n_bands).window(*window)

    def clear(self) -> None:
        self.cache.clear()
        with self._lock:
            self._seen.clear()


def _read_only(arr: np.ndarray) -> None:
    arr.flags.writeable = False  # shared by every request that slices it
