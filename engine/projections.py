"""Whole-frame camera raw per (cube, sensor, illuminant), kept so crops are slices, not products.

A random-crop training feed asks the same few views under a pool of sensors and illuminants again
and again. Projecting a 256² crop reads 63 bands per pixel (~2 ms per group, memory bound); slicing
the frame's projection, computed once at intensity 1 (:class:`retarget.projected.Projected`), reads
3. The result equals the cube path to float32 rounding (the intensity multiplies after the band sum
instead of inside it).

Admission, so a pool that rarely repeats a key (a continuous CCT range) does not churn the cache
with frames used once: a key is projected from its ``min_uses``-th request on (its first, for a
whole frame, which is projected anyway), and only while the cache has room or the key has been
asked for more often than the least recently used entry it would evict (TinyLFU's rule: Einziger,
Friedman & Manes 2017), with request counts halved every ``_AGE_EVERY`` requests so that old
popularity fades (lazily: a count remembers the age it was last touched at and is shifted when read,
so no request pays for halving them all). The entries live in their own LRU cache (``--projection-cache-mb``, in addition
to ``--cache-mb``), so they never evict the decoded cubes they are made from.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable

import numpy as np

from illumix.retarget.projected import Projected
from illumix.retarget.relight import project_groups
from illumix.store.lru import LRUCache, nbytes_cost

MIN_USES = 2  # a key's projection is cached on its second request
_SEEN = 65536  # keys whose request count is remembered (a bounded LRU of counters, a few MiB)
_AGE_EVERY = 8192  # requests between halvings of the counts


def projection_share(cache_mb: int) -> int:
    """Default ``--projection-cache-mb``: a quarter of ``--cache-mb``, at most 512 MiB."""
    return min(cache_mb // 4, 512)


class ProjectionCache:
    """``key → Projected`` of whole frames; :meth:`window` returns a crop of one, or ``None``."""

    def __init__(self, max_bytes: int, min_uses: int = MIN_USES) -> None:
        self.cache: LRUCache[np.ndarray] = LRUCache(max_bytes, cost=nbytes_cost, on_load=_read_only,
                                                    track_evicted=True)
        self.min_uses = max(1, int(min_uses))
        self._seen: OrderedDict[Hashable, tuple[int, int]] = OrderedDict()  # key -> (count, age then)
        self._lock = threading.Lock()
        self._ops = self._age = 0

    @property
    def hits(self) -> int:
        return self.cache.hits

    @property
    def misses(self) -> int:
        return self.cache.misses

    def _aged(self, entry: tuple[int, int] | None) -> int:
        """A remembered count, halved once per ``_AGE_EVERY`` requests since it was last touched."""
        if entry is None:
            return 0
        n, age = entry
        return n >> min(self._age - age, 63)

    def _count(self, key: Hashable) -> int:
        with self._lock:
            n = self._aged(self._seen.pop(key, None)) + 1
            self._seen[key] = (n, self._age)
            while len(self._seen) > _SEEN:
                self._seen.popitem(last=False)
            self._ops += 1
            if self._ops >= _AGE_EVERY:  # popularity fades
                self._ops, self._age = 0, self._age + 1
            return n

    def _admit(self, key: Hashable, count: int, frame_bytes: int) -> bool:
        c = self.cache
        if c.total_cost + c.evicted_cost + frame_bytes <= c.max_cost:
            return True  # room without evicting anything
        victim = c.oldest_key()
        with self._lock:
            return victim is None or count > self._aged(self._seen.get(victim))

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
        n = self._count(key)
        if raw is None:
            if (not whole_frame and n < self.min_uses) or not self._admit(key, n, frame_bytes):
                return None
            # a copy that owns its memory: the cache's eviction accounting follows the array it
            # keeps, and crops of a view would keep its base alive unseen
            raw = self.cache.get(key, lambda: project_groups([whole_cube()], weights[None])[0].copy(),
                                 expected_cost=frame_bytes)
        n_bands = weights.shape[0]
        return Projected(raw, weights, n_bands).window(*window)

    def clear(self) -> None:
        self.cache.clear()
        with self._lock:
            self._seen.clear()


def _read_only(arr: np.ndarray) -> None:
    arr.flags.writeable = False  # shared by every request that slices it
