"""One thread-safe LRU cache, bounded by a cost per entry (1 per entry, or bytes).

The store keeps open zarr array handles in one (bounded by count); the service keeps decoded cubes
in another (bounded by bytes). Misses are counted so a service can report its hit ratio.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any, Generic, TypeVar

V = TypeVar("V")


def nbytes_cost(value: Any) -> int:
    """Cost of a numpy array: its ``nbytes``."""
    return int(value.nbytes)


class LRUCache(Generic[V]):
    """``key → value``, least recently used first out, total ``cost(value)`` ≤ ``max_cost``.

    A value costing more than the whole budget is returned by :meth:`get` without being kept.
    ``on_load`` runs on every freshly loaded value before it is shared (e.g. to make arrays
    read-only, so no caller can change what another caller gets).
    """

    def __init__(self, max_cost: int, cost: Callable[[V], int] = lambda _: 1,
                 on_load: Callable[[V], None] | None = None) -> None:
        self.max_cost = max(0, int(max_cost))
        self._cost = cost
        self._on_load = on_load
        self._items: OrderedDict[Hashable, tuple[V, int]] = OrderedDict()
        self._total = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    @property
    def total_cost(self) -> int:
        """Sum of the costs of the kept values (bytes for an ``nbytes_cost`` cache)."""
        return self._total

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key: Hashable) -> bool:
        with self._lock:
            return key in self._items

    def peek(self, key: Hashable) -> V | None:
        """The kept value (counted as a hit and made most recent), or ``None`` without counting a miss."""
        with self._lock:
            item = self._items.get(key)
            if item is None:
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return item[0]

    def get(self, key: Hashable, load: Callable[[], V]) -> V:
        """The kept value, or ``load()`` kept under ``key`` (evicting the least recently used)."""
        value = self.peek(key)
        if value is not None:
            return value
        value = load()
        if self._on_load is not None:
            self._on_load(value)
        cost = int(self._cost(value))
        with self._lock:
            self.misses += 1
            if cost <= self.max_cost and key not in self._items:
                self._items[key] = (value, cost)
                self._total += cost
                while self._total > self.max_cost:
                    _, (_, old) = self._items.popitem(last=False)
                    self._total -= old
        return value

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
            self._total = 0
