"""Bounded memory per request and in flight: estimate, refuse (413) or queue (503 when busy).

Every sample request is priced before any cube is read, by an upper bound of the bytes it will
allocate (:func:`sample_bytes`): decoded cube windows that are not cached, the composition's
intermediates, the requested outputs and their encoding. A request or batch priced above
``Limits.max_request_mb`` is refused with 413 and a hint; otherwise it reserves its price from a
shared :class:`MemoryBudget` of ``Limits.inflight_mb`` and waits (up to ``Limits.queue_timeout_s``)
while other requests hold it, so the service's working memory stays bounded however many clients
call at once. Resident memory is then about: the process (~200 MB with numpy, colour-science,
zarr, OpenCV) + the cube cache (``--cache-mb``) + ``inflight_mb``.

The per-pixel constants are upper bounds measured with ``tracemalloc`` over the output combinations
(``tests/test_service_limits.py`` checks the bound holds).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable

from illumix.engine.errors import Busy, TooLarge
from illumix.engine.spec import SPECTRAL_OUTPUTS as SPECTRAL  # one float32 per band each
from illumix.retarget.compose import GT_OUTPUTS

#: bytes per output pixel of each output as returned (float32; ccm 3×3; mask bool; weights per group)
OUTPUT_BYTES = {"raw": 12, "gain": 12, "ccm": 36, "srgb": 12, "mask": 1, "illum": 12, "albedo": 12, "normal": 12,
                "depth": 4}
WEIGHT_BYTES_PER_GROUP = 4  # weights and mixture: one float32 per group
# Working memory per pixel, measured with tracemalloc (tests/test_service_limits.py checks the bound):
PROJECT_BYTES_PER_GROUP = 12  # per-group raw (float32 RGB) at the window's and the output's size
PROJECT_BYTES = 12            # the summed raw
GT_BYTES = 42                 # float64 weights sum, mixed white point, gain map, mask …
GT_BYTES_PER_GROUP = 12       # per-group weights
SRGB_BYTES = 56               # CCM-map product, exposure, encoding curve temporaries
NOISE_BYTES = 128             # float64 electrons, Poisson draws, read noise
#: a lit group's window as float32 when the request alone holds it (a cube too big for the cache is
#: read window by window), per pixel and band
WINDOW_BYTES_PER_BAND = 4
#: decoding from the store, per pixel and band of one chunk-row band (the window is decoded a row of
#: chunks at a time): float16 chunks, their assembly, the exponents
DECODE_BYTES_PER_BAND = 6
TILE = 128
SAFETY = 1.1  # allocator rounding and the spread between measured shapes
BASE_BYTES = 1 << 20  # metadata, npz headers, small temporaries of any request


def output_bytes(outputs: Iterable[str], n_groups: int, out_px: int, bands: int = 63) -> int:
    """Bytes of the returned arrays of one sample."""
    outputs = set(outputs)
    per = sum(OUTPUT_BYTES.get(o, 0) for o in outputs)
    per += WEIGHT_BYTES_PER_GROUP * n_groups * len(outputs & {"weights", "mixture"})
    per += 4 * bands * len(outputs & SPECTRAL)
    return per * out_px


def sample_bytes(*, window: tuple[int, int], out_size: tuple[int, int], bands: int, window_copies: int,
                 read_width: int | None = None,
                 groups_to_read: int, n_groups: int, outputs: Iterable[str], noise: bool = False,
                 encoded: bool = True, physical: bool = False) -> int:
    """Upper bound of the bytes one sample allocates (numpy allocations, as ``tracemalloc`` counts).

    window : ``(w, h)`` of the crop read from the cubes; read_width : width of what is decoded (the
    whole cube's when it goes to the cache; default the window's); out_size : ``(W, H)`` returned;
    window_copies : lit groups whose float32 window the request holds alone (not in the cache, whose
    bytes are bounded by ``--cache-mb``); groups_to_read : windows decoded from the store (one
    after another);
    n_groups : groups composed; noise : sensor noise is simulated; encoded : include the encoded
    answer (a copy of the outputs); physical : the ground truth comes from the illumination cubes.
    """
    outputs = set(outputs)
    w, h = window
    in_px, out_px = w * h, out_size[0] * out_size[1]
    row_band = TILE * (_round_up(read_width or w, TILE) + TILE)
    # groups are decoded one after another: one row band in flight, however many groups
    decode = window_copies * in_px * bands * WINDOW_BYTES_PER_BAND + \
        (groups_to_read > 0) * row_band * bands * DECODE_BYTES_PER_BAND
    # The physical ground truth projects the illumination cubes once the raw's per-group arrays
    # are freed: the same peak, plus the formula's weights when those are asked for too.
    per_px = PROJECT_BYTES_PER_GROUP * n_groups + PROJECT_BYTES
    work = per_px * (in_px + (out_px if out_px != in_px else 0))
    if outputs & GT_OUTPUTS:
        work += int((GT_BYTES + GT_BYTES_PER_GROUP * n_groups) * out_px * (1.25 if physical else 1))
    if outputs & SPECTRAL:  # summed windows (transport, illumination), one scaled copy, resampled
        work += 5 * 4 * bands * max(in_px, out_px)
    if "srgb" in outputs:
        work += SRGB_BYTES * out_px
    if noise:
        work += NOISE_BYTES * out_px
    out = output_bytes(outputs, n_groups, out_px, bands) if encoded else 0
    return int(SAFETY * (decode + work + out)) + BASE_BYTES


def _round_up(n: int, k: int) -> int:
    return -(-n // k) * k


def mib(n: int) -> str:
    return f"{n / 2**20:.0f} MiB"


class Reservation:
    """Bytes held in a :class:`MemoryBudget` until :meth:`release` (idempotent)."""

    def __init__(self, budget: MemoryBudget, nbytes: int) -> None:
        self._budget, self.nbytes, self._held = budget, nbytes, True

    def release(self) -> None:
        if self._held:
            self._held = False
            self._budget._give_back(self.nbytes)


class MemoryBudget:
    """A byte budget shared by the requests being computed and sent (a counting semaphore over bytes).

    ``capacity`` bytes in all; :meth:`acquire` waits up to ``timeout`` seconds for room, then
    answers 503 with ``Retry-After``. A price above ``per_request`` (≤ ``capacity``) is a 413.
    The answer holds its reservation until it has been sent (the app releases it in a background
    task), because the encoded body is the largest single allocation.
    """

    def __init__(self, capacity: int, timeout: float, per_request: int | None = None) -> None:
        self.capacity = int(capacity)
        self.per_request = min(self.capacity, int(per_request if per_request is not None else capacity))
        self.timeout = float(timeout)
        self._used = 0
        self._cond = threading.Condition()
        self.peak = 0
        self.refused_busy = 0

    @property
    def used(self) -> int:
        return self._used

    def acquire(self, nbytes: int, what: str) -> Reservation:
        nbytes = max(0, int(nbytes))
        if nbytes > self.per_request:
            raise TooLarge(f"{what} needs about {mib(nbytes)} of working memory; the service allows "
                           f"{mib(self.per_request)} per request: ask for fewer outputs (ccm is 36 bytes per "
                           "pixel), a smaller crop= or size=, or fewer batch items")
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while self._used + nbytes > self.capacity:
                left = deadline - time.monotonic()
                if left <= 0:
                    self.refused_busy += 1
                    raise Busy(f"the service is busy ({mib(self._used)} of {mib(self.capacity)} working "
                               "memory in use); retry after the Retry-After seconds", retry_after=1)
                self._cond.wait(left)
            self._used += nbytes
            self.peak = max(self.peak, self._used)
        return Reservation(self, nbytes)

    def _give_back(self, nbytes: int) -> None:
        with self._cond:
            self._used -= nbytes
            self._cond.notify_all()
