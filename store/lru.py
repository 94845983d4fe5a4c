"""One thread-safe LRU cache, bounded by a cost per entry (1 per entry, or bytes).

The store keeps open zarr array handles in one (bounded by count); the service keeps decoded cubes
in another (bounded by bytes). Misses are counted so a service can report its hit ratio.

An evicted value that callers still use stays in memory until they drop it. With
``track_evicted=True`` such values keep counting against the budget until they are freed (a weak
reference finalizer tells the cache), so the cache's *resident* footprint — kept plus still-used
evicted values — stays within ``max_cost`` (measured with ``bench/load.py``: a churning 256 MiB
cube cache under 16 clients otherwise pinned ~200 MiB of evicted cubes).
"""

from __future__ import annotations

import threading
import weakref
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
                 on_load: Callable[[V], None] | None = None, track_evicted: bool = False) -> None:
        self.max_cost = max(0, int(max_cost))
        self._cost = cost
        self._on_load = on_load
        self._track = track_evicted
        self._items: OrderedDict[Hashable, tuple[V, int]] = OrderedDict()
        self._total = 0
        self._evicted = 0  # cost of evicted values not freed yet (track_evicted)
        self._reserved = 0  # expected cost of values being loaded
        self._loading: dict[Hashable, _Flight] = {}
        self._lock = threading.Lock()
        self._evicted_lock = threading.Lock()  # finalizers run wherever the last reference drops
        self.hits = 0
        self.misses = 0

    @property
    def total_cost(self) -> int:
        """Sum of the costs of the kept values (bytes for an ``nbytes_cost`` cache)."""
        return self._total

    @property
    def evicted_cost(self) -> int:
        """Cost of evicted values still alive (callers use them); 0 unless ``track_evicted``."""
        return self._evicted

    def _freed(self, cost: int) -> None:
        with self._evicted_lock:
            self._evicted -= cost

    def __len__(self) -> int:
        return len(self._items)

    def oldest_key(self) -> Hashable | None:
        """The least recently used key (the next to be evicted), or ``None`` when empty."""
        with self._lock:
            return next(iter(self._items), None)

    def __contains__(self, key: Hashable) -> bool:
        with self._lock:
            return key in self._items

    def lookup(self, key: Hashable, count: bool = True) -> V | None:
        """The kept value (made most recent; a hit if ``count``), or ``None`` (not counted: a
        :meth:`get` follows). ``count=False`` for a caller that may not use the value: it calls
        :meth:`count_hit` when it does."""
        with self._lock:
            item = self._items.get(key)
            if item is None:
                return None
            self._items.move_to_end(key)
            self.hits += count
            return item[0]

    def count_hit(self) -> None:
        """Count a hit for a value found earlier by ``lookup(key, count=False)`` and now used."""
        with self._lock:
            self.hits += 1

    def get(self, key: Hashable, load: Callable[[], V], expected_cost: int | None = None) -> V:
        """The kept value, or ``load()`` kept under ``key`` (evicting the least recently used).

        ``expected_cost``: the value's cost if known before loading. Room is then made *before*
        ``load`` runs, and the space stays reserved while it runs, so loading never takes the
        cache past its bound. Concurrent callers of one missing key share one load.
        """
        with self._lock:
            item = self._items.get(key)
            if item is not None:
                self._items.move_to_end(key)
                self.hits += 1
                return item[0]
            flight = self._loading.get(key)
            if flight is None:
                # a value larger than the whole budget is returned, not kept: evict nothing for it
                fits = (expected_cost or 0) <= self.max_cost
                flight = self._loading[key] = _Flight(expected_cost or 0 if fits else 0)
                owner = True
                self._reserved += flight.reserved
                dropped = self._evict_locked(keep=0) if fits else []
            else:
                owner = False
                self.hits += 1  # served by another caller's load
        if not owner:
            return flight.wait()
        self._track_dropped(dropped)
        try:
            value = load()
            if self._on_load is not None:
                self._on_load(value)
            cost = int(self._cost(value))
        except BaseException as exc:
            with self._lock:
                self._reserved -= flight.reserved
                del self._loading[key]
            flight.fail(exc)
            raise
        with self._lock:
            self.misses += 1
            self._reserved -= flight.reserved
            del self._loading[key]
            dropped = []
            if cost <= self.max_cost:
                self._items[key] = (value, cost)
                self._total += cost
                dropped = self._evict_locked(keep=1)
        flight.done(value)
        self._track_dropped(dropped)
        return value

    def _evict_locked(self, keep: int) -> list[tuple[V, int]]:
        """Evict least recently used values until kept + evicted-in-use + reserved fit the bound
        (keeping at least ``keep`` values: the one just inserted). Call with the lock held."""
        dropped = []
        while self._total + self._evicted + self._reserved > self.max_cost and len(self._items) > keep:
            _, item = self._items.popitem(last=False)
            self._total -= item[1]
            dropped.append(item)
        return dropped

    def _track_dropped(self, dropped: list[tuple[V, int]]) -> None:
        """Outside the lock (a finalizer may run as soon as the last reference drops)."""
        while dropped:
            old, old_cost = dropped.pop()
            if self._track:
                with self._evicted_lock:
                    self._evicted += old_cost
                weakref.finalize(old, self._freed, old_cost)
            del old

    def clear(self) -> None:
        with self._lock:
            items = list(self._items.values())
            self._items.clear()
            self._total = 0
        self._track_dropped(items)


class _Flight:
    """One load in progress; other callers of the same key wait for its value."""

    def __init__(self, reserved: int) -> None:
        self.reserved = reserved
        self._event = threading.Event()
        self._value: Any = None
        self._error: BaseException | None = None

    def done(self, value: Any) -> None:
        self._value = value
        self._event.set()

    def fail(self, exc: BaseException) -> None:
        self._error = exc
        self._event.set()

    def wait(self) -> Any:
        self._event.wait()
        if self._error is not None:
            raise self._error
        return self._value
