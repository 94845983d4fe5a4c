"""glibc allocator settings for a long-running service process.

The service allocates and frees tens of MB per request from many threads. glibc's defaults keep
freed memory in per-thread arenas and raise the mmap threshold after each large free, so resident
memory grows far past what is in use (measured with ``bench/load.py``: peak RSS 954 MiB with the
defaults against 505 MiB with fixed thresholds, same load, 128 MiB cache). A fixed mmap threshold
hands every array above it straight back to the kernel when it is freed; fewer arenas bound the
rest.

The thresholds trade page faults against retention. At a 256 KiB mmap threshold every temporary
of a 256² crop (0.75–3 MiB) was a fresh mmap whose pages the kernel zeroes on first touch: a
``POST /batch`` of 16 crops took 157 ms, against 78–92 ms with 4 MiB (crop-sized arrays reuse heap
memory; full-frame ones are still returned at once) and a 16 MiB trim threshold (the free memory
an arena keeps; 32 MiB / 64 MiB: 63 ms, but 100 MiB more peak RSS under ``bench/load.py``).
Environment variables (``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_``, ``MALLOC_ARENA_MAX``)
win, as glibc reads them at start-up; ``ILLUMIX_MALLOC_TUNING=off`` leaves glibc's defaults.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
M_ARENA_MAX = -8
MMAP_THRESHOLD = 4 * 2**20
TRIM_THRESHOLD = 16 * 2**20
ARENA_MAX = 2


def tune_for_service() -> bool:
    """Apply the settings through ``mallopt``; False where there is no glibc (nothing changes)."""
    name = ctypes.util.find_library("c")
    if not name or os.environ.get("ILLUMIX_MALLOC_TUNING", "").lower() in ("0", "off", "no", "false"):
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = True
    if "MALLOC_MMAP_THRESHOLD_" not in os.environ:
        ok &= mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        ok &= mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
    if "MALLOC_ARENA_MAX" not in os.environ:
        ok &= mallopt(M_ARENA_MAX, ARENA_MAX) == 1
    return bool(ok)
