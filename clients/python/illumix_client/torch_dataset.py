"""``IllumixDataset``: a PyTorch ``IterableDataset`` streaming illumix samples into a DataLoader.

Item layout (a dict; every tensor channels-first, float32 unless noted)
--------------------------------------------------------------------------
==========  ===============  ==================================================================
key         shape            content
==========  ===============  ==================================================================
raw         (3, H, W)        camera raw, linear, normalised by ``raw_norm`` (``(1, H, W)`` when
                             Bayer mosaicked):
                             ``"max"`` (default) — divided by the sample's maximum, so max = 1;
                             ``"exposure"`` — the service's auto-exposure (thesis eq. 4.2) is
                             applied and raw is relative to the white level (1 = saturation);
                             with ``noise`` both first map DN to ``(DN − black) / (white − black)``;
                             ``"none"`` — as the service sends it.
gain        (3, H, W)        white-balance gain map ``max_j W_j / W_k`` (≥ 1; G ≈ 1).
mask        (1, H, W) bool   True where ground truth is defined (the pixel receives light).
srgb        (3, H, W)        sRGB rendering in [0, 1]               (only if in ``outputs``)
ccm         (3, 3, H, W)     per-pixel CCM, ``ccm[:, :, y, x] @ rgb`` (only if in ``outputs``)
weights     (G, H, W)        illuminant weight per light group (eq. 3.3) (only if in ``outputs``)
illum       (3, H, W)        per-pixel white point, G = 1 (physical GT where the store has it)
mixture     (G, H, W)        each group's share of that white point   (only if in ``outputs``)
albedo      (3, H, W)        view AOVs: albedo, unit normal (3, H, W), depth (1, H, W)
reflectance (B, H, W)        per-pixel spectra over the B bands: reflectance, illumination
index       int              the item's index in the epoch, ``0 … epoch_length − 1``
meta        str              the service's metadata as JSON (``json.loads`` it): scene, view,
                             groups, illuminants with sensor white points and CCMs, intensities,
                             seed, exposure gain, provenance
==========  ===============  ==================================================================

With a ``crop`` (or ``size``) every item has the same H × W, so PyTorch's default collate batches
them; without one, views of different sizes cannot be stacked.

Sampling, seeding, workers
--------------------------
Item ``i`` of epoch ``e`` is drawn from ``numpy.random.default_rng([seed, e, i])`` — scene/view,
one illuminant per light group (:class:`illumix_client.draw.IlluminantPool`), intensity ratios, a
sensor, a crop position and the service-side seed (noise) — so an epoch is the same whatever the
number of workers, and ``set_epoch(e)`` (call it each epoch, as with ``DistributedSampler``) gives a
fresh one. DataLoader workers made with ``persistent_workers=True`` keep their copy of the dataset,
which ``set_epoch`` in the main process never reaches: with ``auto_epoch=True`` each iteration
without a ``set_epoch`` in between is the next epoch, so they follow consecutive ``set_epoch``
calls (items then depend on how often each copy was iterated, not on ``set_epoch`` alone; leave it
off for a validation loader that must repeat). Use persistent workers with the local mode, whose
workers are forked from a process holding the decoded cubes (0.2–0.3 s each time one starts). The ``epoch_length`` indices are split between distributed ranks (``i % world_size``),
then in chunks of ``batch_size`` between DataLoader workers (``torch.utils.data.get_worker_info``):
no two workers ever produce the same item. Each chunk is one ``POST /batch``; ``prefetch`` chunks
per worker are requested ahead on background threads while the current one is consumed.

torch is imported by this module only; ``import illumix_client`` does not need it.
"""

from __future__ import annotations

import json
import os
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from itertools import islice
from typing import Any

import numpy as np

from illumix_client._requires import import_torch, torch_threads

torch = import_torch()  # without it: one error naming the extra to install (and the CPU-only build)
from torch.utils.data import IterableDataset, get_worker_info

from illumix_client._protocol import RetryPolicy
from illumix_client.client import Client
from illumix_client.draw import (
    IlluminantPool,
    SpecSampler,
    ViewInfo,
    select_views,
    views_from_scenes,
)
from illumix_client.sample import Sample

RAW_NORMS = ("max", "exposure", "none")


class IllumixDataset(IterableDataset):
    """Random mixed-illuminant samples from an illumix service, as tensors (layout above).

    Parameters
    ----------
    base_url, token, timeout, retry
        Where the service is (see :class:`illumix_client.Client`).
    store, cache_mb, warm
        Local mode: compose in this process from a store path or fsspec URL instead of asking a
        service (:class:`illumix_client.local.LocalClient`; needs ``illumix-client[local]``), with
        ``cache_mb`` of decoded cubes and projections. ``warm`` decodes every cube at construction,
        so DataLoader workers forked afterwards share them instead of decoding them each.
    device
        Local mode only: compose with torch on this device (``"cuda"``; items are then tensors on
        it; use ``num_workers=0``). Serves raw, gain, mask, weights, illum and mixture at the crop
        size (:mod:`engine.torch_sampling`); raw_norm ``"max"`` or ``"none"``.
    scenes
        Which views to draw from: ``None`` (all), scene names, ``"scene/view"`` keys or fnmatch
        patterns, or a predicate on :class:`illumix_client.draw.ViewInfo`. Views smaller than
        ``crop`` or with fewer than ``min_groups`` light groups are left out.
    illuminants
        The illuminant pool (names, ranges like ``"blackbody:2500-7500"``, or a per-group mapping);
        see :mod:`illumix_client.draw`. ``distinct_illuminants`` redraws so groups differ.
    sensors
        Sensor names, one drawn uniformly per item.
    intensity_range
        ``(lo, hi)``: per-group intensities ~ U(lo, hi), divided by their maximum.
    crop, size
        ``(w, h)`` crop placed uniformly in the frame (an int for a square), optional ``(W, H)``
        resample after it; ``None`` = full frame.
    outputs
        Tensors to fetch: any of raw, gain, mask, srgb, ccm, weights, illum, mixture, albedo, normal,
        depth, reflectance, illumination (layout above).
    gt
        ``"physical"`` or ``"formula"`` ground truth (default: physical where the store has it).
    denoise
        ``"none"`` or a denoise method (``"dt-irradiance"``): the store's denoised cube copies (default:
        those where the store has them).
    auto_epoch
        Each iteration without a ``set_epoch`` in between is the next epoch (for
        ``persistent_workers=True``; see "Sampling, seeding, workers"). Default off.
    dtype
        ``"float16"`` halves the bytes on the wire (per-output power-of-two scales; items are still
        float32, scaled back); pays on links slower than loopback (README "Transfer less").
    exposure, noise, bayer
        Passed to the service (``noise`` a preset like ``"phone"`` or a parameter mapping).
    raw_norm
        ``"max"``, ``"exposure"`` or ``"none"`` (see the layout table).
    epoch_length
        Items per epoch, over all ranks and workers.
    batch_size, prefetch
        Items per ``POST /batch`` (≤ the service's batch limit, 64 by default) and requests in
        flight per worker (in the local mode: chunks composed ahead on background threads at
        ``num_workers=0``; local-mode DataLoader workers compose in their own thread, one chunk at a
        time). ``prefetch=0``: each chunk is fetched when the previous one is consumed.
    seed
        Makes the stream reproducible; ``None`` draws one at construction (shared by all workers).
    rank, world_size
        Distributed sharding; by default from ``torch.distributed`` when it is initialised.
    threads
        torch's intra-op threads while the dataset is iterated (restored after; ``None``: leave torch's
        setting), default 1: at ``num_workers=0`` the batches are stacked in the main process, where
        torch's thread per core cost ~10× the CPU per sample (client README, "Threads").

    The constructor asks the service for its scenes, sensors and illuminants once, so a typo fails
    here rather than in a worker.
    """

    def __init__(self, base_url: str = "http://127.0.0.1:8000", *, store: str | None = None,
                 cache_mb: int = 2048, warm: bool = True, device: str | None = None, token: str | None = None,
                 timeout: float | None = 60.0, retry: RetryPolicy | None = None,
                 scenes: str | Sequence[str] | Callable[[ViewInfo], bool] | None = None,
                 illuminants: Any = ("A", "D65", "FL11", "blackbody:2500-7500", "daylight:4000-10000"),
                 sensors: Sequence[str] = ("XYZ",), intensity_range: tuple[float, float] = (0.25, 1.0),
                 crop: int | tuple[int, int] | None = None, size: tuple[int, int] | None = None,
                 outputs: Sequence[str] = ("raw", "gain", "mask"), exposure: str | float | None = None,
                 noise: str | Mapping[str, float] | None = None, bayer: str | None = None,
                 raw_norm: str = "max", epoch_length: int = 1024, batch_size: int = 16, prefetch: int = 2,
                 seed: int | None = None, min_groups: int = 1, distinct_illuminants: bool = True,
                 cct_step: float = 50.0, rank: int | None = None, world_size: int | None = None,
                 gt: str | None = None, denoise: str | None = None, dtype: str | None = None,
                 auto_epoch: bool = False, threads: int | None = 1) -> None:
        super().__init__()
        if raw_norm not in RAW_NORMS:
            raise ValueError(f"raw_norm must be one of {', '.join(RAW_NORMS)}, got {raw_norm!r}")
        if epoch_length < 1 or batch_size < 1 or prefetch < 0:
            raise ValueError("epoch_length and batch_size must be >= 1 and prefetch >= 0")
        if raw_norm == "exposure" and exposure is None:
            exposure = "auto"
        self.base_url, self.token, self.timeout, self.retry = base_url, token, timeout, retry
        self.store, self.cache_mb, self.device = store, int(cache_mb), device
        if device is not None and (store is None or raw_norm == "exposure"):
            raise ValueError("device= composes in the local mode (give store=) with raw_norm 'max' or 'none'")
        self._local = None
        self.raw_norm, self.epoch_length = raw_norm, int(epoch_length)
        self.batch_size, self.prefetch = int(batch_size), int(prefetch)
        self.seed = int(seed) if seed is not None else int.from_bytes(os.urandom(4), "little")
        self.epoch, self._begun = 0, 0  # _begun: iterations since set_epoch (see __iter__)
        self.auto_epoch = bool(auto_epoch)
        if threads is not None and int(threads) < 1:
            raise ValueError(f"threads must be >= 1 or None, got {threads}")
        self.threads = None if threads is None else int(threads)
        if world_size is None or rank is None:
            dist = torch.distributed
            on = dist.is_available() and dist.is_initialized()
            rank = rank if rank is not None else (dist.get_rank() if on else 0)
            world_size = world_size if world_size is not None else (dist.get_world_size() if on else 1)
        if not 0 <= rank < world_size:
            raise ValueError(f"need 0 <= rank < world_size, got {rank}, {world_size}")
        self.rank, self.world_size = int(rank), int(world_size)
        pool = IlluminantPool(illuminants, cct_step=cct_step)
        crop_wh = (crop, crop) if isinstance(crop, int) else (tuple(crop) if crop is not None else None)
        with self._client() if store is None else nullcontext(self._client()) as c:
            views = select_views(views_from_scenes(c.scenes()), scenes, min_groups=min_groups, crop=crop_wh)
            _check_names(c, pool, sensors)
            if store is not None and warm:
                # the pool's named illuminants are projected ahead (a CCT range rarely repeats a key)
                c.warm(sensors=list(sensors), illuminants=sorted({e.name for e in pool.entries() if e.name}))
        self.sampler = SpecSampler(views, pool, sensors, intensity_range=intensity_range, crop=crop_wh,
                                   size=size, outputs=outputs, exposure=exposure, noise=noise,
                                   bayer=bayer, distinct=distinct_illuminants, gt=gt,
                                   denoise=denoise, dtype=dtype)

    # -- indices ---------------------------------------------------------------------------------
    def set_epoch(self, epoch: int) -> None:
        """Choose the epoch whose items the next iteration yields (call before each epoch)."""
        self.epoch = int(epoch)
        self._begun = 0

    def _rank_indices(self) -> range:
        return range(self.rank, self.epoch_length, self.world_size)

    def __len__(self) -> int:
        return len(self._rank_indices())

    def worker_chunks(self, worker_id: int = 0, num_workers: int = 1) -> list[list[int]]:
        """The epoch indices this (rank, worker) yields, in request chunks of ``batch_size``."""
        idx = list(self._rank_indices())
        chunks = [idx[i:i + self.batch_size] for i in range(0, len(idx), self.batch_size)]
        return chunks[worker_id::num_workers]

    def spec(self, index: int, epoch: int | None = None) -> dict[str, Any]:
        """The /batch item for ``index`` of ``epoch`` (default: the current one)."""
        e = self.epoch if epoch is None else int(epoch)
        return self.sampler.spec(np.random.default_rng([self.seed, e, int(index)]))

    # -- iteration -------------------------------------------------------------------------------
    def _client(self):
        """An HTTP :class:`Client` (closed after use), or the dataset's one local client (kept: it
        holds the decoded cubes)."""
        if self.store is None:
            return Client(self.base_url, token=self.token, timeout=self.timeout, retry=self.retry)
        if self._local is None:
            from illumix_client.local import LocalClient

            self._local = LocalClient(self.store, cache_mb=self.cache_mb, device=self.device)
        return self._local

    def __getstate__(self) -> dict:
        # a worker started by pickling (spawn) opens its own local client; forked workers inherit it
        return self.__dict__ | {"_local": None}

    def __iter__(self) -> Iterator[dict[str, Any]]:
        with torch_threads(self.threads):  # `threads` while iterating (the class docstring)
            yield from self._iterate()

    def _iterate(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        wid, nw = (info.id, info.num_workers) if info is not None else (0, 1)
        chunks = self.worker_chunks(wid, nw)
        # auto_epoch: each iteration of this object without a set_epoch() in between is the next
        # epoch, so a persistent DataLoader worker (whose copy set_epoch() in the main process never
        # reaches) advances in step with consecutive set_epoch calls
        epoch = self.epoch + (self._begun if self.auto_epoch else 0)
        self._begun += 1
        client = self._client()
        # A local-mode DataLoader worker composes in its own thread, one chunk at a time: composing
        # is CPU work, the DataLoader already prefetches across workers, and background threads in
        # every worker only contend for the cores (2 workers, 2 cores: 330-405 against 298-307
        # samples/s with them). Over HTTP they overlap the requests' network waits.
        depth = 0 if (self.store is not None and info is not None) else self.prefetch
        pool = ThreadPoolExecutor(max_workers=depth, thread_name_prefix="illumix") if depth else None
        pending: deque = deque()

        def fetch(chunk: list[int]) -> tuple[list[int], list[Sample]]:
            return chunk, client.batch([self.spec(i, epoch) for i in chunk])

        def submit(chunk: list[int]) -> Future:
            if pool is not None:
                return pool.submit(fetch, chunk)
            done: Future = Future()  # no prefetching: fetched now, in this thread
            try:
                done.set_result(fetch(chunk))
            except Exception as exc:  # raised by .result(), where a pool's would be
                done.set_exception(exc)
            return done

        def refill() -> None:
            nxt = next(it, None)
            if nxt is not None:
                pending.append(submit(nxt))

        it = iter(chunks)
        try:
            for chunk in islice(it, max(1, depth)):
                pending.append(submit(chunk))
            while pending:
                indices, samples = pending.popleft().result()
                if depth:
                    refill()  # keep `prefetch` requests in flight while this chunk is consumed
                for i, s in zip(indices, samples):
                    yield self.to_item(i, s)
                if not depth:
                    refill()
        finally:
            for f in pending:
                f.cancel()
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
            if self.store is None:
                client.close()

    # -- conversion ------------------------------------------------------------------------------
    def to_item(self, index: int, s: Sample) -> dict[str, Any]:
        """A :class:`Sample` → the item dict (layout in the module docstring)."""
        item: dict[str, Any] = {}
        if any(isinstance(v, torch.Tensor) for v in s.arrays().values()):
            return self._tensor_item(index, s)
        if s.raw is not None:
            item["raw"] = torch.from_numpy(self._norm_raw(s))
        for k in ("gain", "srgb", "weights", "illum", "mixture", "albedo", "normal", "reflectance", "illumination"):
            a = getattr(s, k)
            if a is not None:
                item[k] = torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1), dtype=np.float32))
        if s.depth is not None:
            item["depth"] = torch.from_numpy(np.ascontiguousarray(s.depth[None], dtype=np.float32))
        if s.ccm is not None:
            item["ccm"] = torch.from_numpy(np.ascontiguousarray(s.ccm.transpose(2, 3, 0, 1), dtype=np.float32))
        if s.mask is not None:
            item["mask"] = torch.from_numpy(np.ascontiguousarray(s.mask[None], dtype=bool))
        item["index"] = int(index)
        item["meta"] = json.dumps(s.meta)
        return item

    def _tensor_item(self, index: int, s: Sample) -> dict[str, Any]:
        """The item of a sample composed with torch on a device (local mode with ``device=``)."""
        item: dict[str, Any] = {}
        for k in ("raw", "gain", "weights", "illum", "mixture"):
            a = getattr(s, k)
            if a is not None:
                item[k] = a.permute(2, 0, 1).contiguous()
        if "raw" in item and self.raw_norm == "max":
            peak = item["raw"].amax()
            item["raw"] = torch.where(peak > 0, item["raw"] / torch.where(peak > 0, peak, 1), item["raw"])
        if s.mask is not None:
            item["mask"] = s.mask[None]
        item["index"] = int(index)
        item["meta"] = json.dumps(s.meta)
        return item

    def _norm_raw(self, s: Sample) -> np.ndarray:
        """The CHW float32 raw item, normalised as ``raw_norm`` says, in one pass over the raw."""
        raw = np.asarray(s.raw, dtype=np.float32)
        src = raw[None] if raw.ndim == 2 else raw.transpose(2, 0, 1)  # a CHW view of the HWC raw
        if self.raw_norm == "none" or not raw.size:
            return np.ascontiguousarray(src)
        noise = s.meta.get("noise")
        black, span = 0.0, 1.0  # DN -> (DN - black) / (white - black) with noise
        if noise:
            white = noise.get("white_level") or 2 ** int(noise.get("bit_depth", 12)) - 1
            black = float(noise.get("black_level", 0.0))
            span = max(white - black, 1e-12)
        if self.raw_norm == "max":
            top = float(raw.max()) - black  # the peak of (raw - black), so that the peak becomes 1
            if top > 0:
                span = top
        out = np.empty(src.shape, np.float32)
        if black:
            src = np.subtract(src, np.float32(black), out=out)
        return np.divide(src, np.float32(span), out=out)


def _check_names(client: Client, pool: IlluminantPool, sensors: Sequence[str]) -> None:
    """Fail at construction on sensor or illuminant names the service does not know."""
    if isinstance(sensors, str):
        raise ValueError("sensors must be a list of names, e.g. ['XYZ']")
    known_s = client.sensors()
    known = set(known_s["builtin"]) | set(known_s["uploaded"])
    bad = [s for s in sensors if s not in known and s.partition(":")[0].lower() != "random"]
    if bad:
        raise ValueError(f"unknown sensor(s) {bad}; the service has {sorted(known)}")
    ill = client.illuminants()
    names = set(ill["builtin"]) | set(ill["uploaded"])
    param = ill.get("parametric", {})
    for e in pool.entries():
        if e.name is not None:
            kind, sep, _ = e.name.partition(":")
            if e.name not in names and not (sep and kind.lower() in param):
                raise ValueError(f"unknown illuminant {e.name!r}; see Client.illuminants()")
        else:
            lim = param.get(e.kind)
            if lim is None or e.lo < lim["min_kelvin"] or e.hi > lim["max_kelvin"]:
                raise ValueError(f"illuminant range {e.kind}:{e.lo:g}-{e.hi:g} is outside what the "
                                 f"service allows: {param}")
