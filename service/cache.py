"""A byte-bounded, thread-safe LRU cache of decoded cubes (and other arrays)."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable

import numpy as np


class ArrayCache:
    """LRU over ``key → np.ndarray`` bounded by total ``nbytes``; arrays are returned read-only.

    An array larger than the whole budget is returned without being cached.
    """

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max(0, int(max_bytes))
        self._items: OrderedDict[Hashable, np.ndarray] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    @property
    def nbytes(self) -> int:
        return self._bytes

    def peek(self, key: Hashable) -> np.ndarray | None:
        with self._lock:
            arr = self._items.get(key)
            if arr is not None:
                self._items.move_to_end(key)
                self.hits += 1
            return arr

    def get(self, key: Hashable, load: Callable[[], np.ndarray]) -> np.ndarray:
        arr = self.peek(key)
        if arr is not None:
            return arr
        arr = load()
        arr.flags.writeable = False
        with self._lock:
            self.misses += 1
            if arr.nbytes <= self.max_bytes and key not in self._items:
                self._items[key] = arr
                self._bytes += arr.nbytes
                while self._bytes > self.max_bytes:
                    _, old = self._items.popitem(last=False)
                    self._bytes -= old.nbytes
        return arr

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
            self._bytes = 0
