"""store.lru.LRUCache: the one LRU of the project (zarr handles by count, decoded cubes by bytes)."""

from __future__ import annotations

import gc
import threading

import numpy as np

from illumix.store.lru import LRUCache, nbytes_cost


def test_count_bound_order_and_counters():
    c = LRUCache(2)
    assert c.get("a", lambda: 1) == 1 and c.get("b", lambda: 2) == 2
    assert c.get("a", lambda: 0) == 1  # a hit (the loader does not run); a becomes most recent
    c.get("c", lambda: 3)  # evicts b
    assert "b" not in c and "a" in c and "c" in c and len(c) == 2
    assert (c.hits, c.misses) == (1, 3)
    assert c.get("z", lambda: 9) == 9 and len(c) == 2


def test_byte_bound_and_values_bigger_than_the_budget():
    c = LRUCache(100, cost=nbytes_cost, on_load=lambda a: setattr(a.flags, "writeable", False))
    big = c.get("big", lambda: np.zeros(20))  # 160 bytes: returned, not kept
    assert big.shape == (20,) and "big" not in c and c.total_cost == 0
    small = c.get("s", lambda: np.zeros(4))
    assert c.total_cost == 32 and not small.flags.writeable  # shared values are read-only


def test_evicted_values_in_use_keep_counting_until_freed():
    c = LRUCache(100, cost=nbytes_cost, track_evicted=True)
    held = c.get("a", lambda: np.zeros(10))  # 80 bytes, a caller still uses it
    c.get("b", lambda: np.zeros(5))  # 40 more: a is evicted but alive
    assert "a" not in c and c.evicted_cost == 80 and c.total_cost == 40
    c.get("c", lambda: np.zeros(5))  # 40 + 40 + 80 alive > 100: b goes too
    assert "b" not in c and c.total_cost == 40
    view = held[2:5]
    del held
    gc.collect()
    assert c.evicted_cost == 80  # a view keeps the evicted array alive
    del view
    gc.collect()
    assert c.evicted_cost == 0
    c.clear()
    gc.collect()
    assert c.total_cost == 0 and c.evicted_cost == 0


def test_concurrent_gets_keep_the_books_balanced():
    c = LRUCache(64 * 8 * 3, cost=nbytes_cost, track_evicted=True)

    def work(seed: int) -> None:
        rng = np.random.default_rng(seed)
        for _ in range(300):
            k = int(rng.integers(0, 12))
            a = c.get(k, lambda: np.full(64, float(k)))
            assert a[0] == k

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    gc.collect()
    assert c.evicted_cost == 0 and c.total_cost == 64 * 8 * len(c) <= c.max_cost


def test_room_is_made_before_loading_and_one_key_loads_once():
    c = LRUCache(100, cost=nbytes_cost, track_evicted=True)
    c.get("a", lambda: np.zeros(8))  # 64 bytes
    seen = []

    def load():
        seen.append((c.total_cost, c.evicted_cost))  # a was evicted before this load started
        return np.zeros(8)

    c.get("b", load, expected_cost=64)
    assert seen == [(0, 0)] and "a" not in c
    started, release = threading.Event(), threading.Event()
    calls = []

    def slow():
        calls.append(1)
        started.set()
        release.wait(5)
        return np.ones(4)

    results = []
    t1 = threading.Thread(target=lambda: results.append(c.get("k", slow, expected_cost=32)))
    t1.start()
    started.wait(5)
    t2 = threading.Thread(target=lambda: results.append(c.get("k", slow, expected_cost=32)))
    t2.start()
    release.set()
    t1.join(), t2.join()
    assert len(calls) == 1 and len(results) == 2 and results[0] is results[1]


def test_a_failed_load_releases_its_reservation_and_reaches_every_waiter():
    c = LRUCache(100, cost=nbytes_cost)

    def boom():
        raise OSError("disk")

    for _ in range(2):
        try:
            c.get("x", boom, expected_cost=50)
        except OSError:
            pass
        else:
            raise AssertionError("the load error must propagate")
    assert c.get("y", lambda: np.zeros(12)).nbytes == 96  # nothing stays reserved
