"""``illumix serve --warm``: decode the store's cubes into the cube cache before the first request.

A cold service decodes a whole cube on the first request that touches it (tens to hundreds of ms
per cube), so the first epoch of a training feed runs far slower than the next (issue 19). Warming
fills the cache with exactly the entries a default ``GET /sample`` of each view reads — the keys come
from :func:`engine.plan.plan` and :func:`engine.cubes.cube_key` / :func:`aov_key`, so a
warmed entry is a hit, never a look-alike:

- the view's ``mask`` and ``emitter`` AOVs (every sample reads them for its validity mask);
- per lit group, the transport cube — the stored denoised copy when every lit group has copies of
  one method (``/sample``'s default ``denoise``), else the raw cube;
- the groups' illumination cubes (of the same denoise choice) when the default ground truth is
  physical, i.e. every lit group has one.

Warming runs in the serving process before uvicorn starts (so the first request is already warm and
a training job can start as soon as the port answers). It stops, with a log line, at the first entry
that does not fit in what is left of the cache: it never evicts what it warmed. Views whose default
sample cannot be planned (a damaged view, more groups than ``max_groups``) are skipped with a line.
Warming loads are not counted as cache misses, so the hit ratio in ``/health`` and ``/metrics``
describes requests; that is why :func:`warm_cache` must run before requests are served.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from illumix.engine.context import Context
from illumix.engine.cubes import aov_key, cube_key
from illumix.engine.errors import Busy
from illumix.engine.plan import plan
from illumix.engine.spec import SampleSpec
from illumix.retarget.errors import SpectralError
from illumix.store import StoreError

#: the AOVs every sample reads (engine.extra_outputs.view_validity)
VALIDITY_AOVS = ("mask", "emitter")


@dataclass
class _Entry:
    key: tuple
    what: str  # "scene/view group kind" for the log
    nbytes: int | None  # known before loading (cubes); None: measured after reading (AOVs)
    load: Callable[[], np.ndarray]
    cube: bool


def _entries(ctx: Context, log: Callable[[str], None]) -> tuple[list[_Entry], int]:
    """Every cache entry a default ``/sample`` of each view reads, in store order, and the number of
    views skipped. Reads metadata only."""
    store, out, skipped = ctx.store, [], 0
    for scene in store.scenes():
        for view in store.views(scene):
            try:
                # a 1x1 crop: the window does not change what is read, and a full frame could exceed max_side
                p = plan(SampleSpec(scene=scene, view=view, crop=[0, 0, 1, 1], seed=0), ctx)
            except (SpectralError, Busy, StoreError) as exc:
                log(f"warm: skipping {scene}/{view}: {str(exc).splitlines()[0]}")
                skipped += 1
                continue
            stamp = tuple(p.stamps)
            for name in VALIDITY_AOVS:
                if name in p.aovs:
                    out.append(_Entry(aov_key(scene, view, name, stamp), f"{scene}/{view} aov {name}", None,
                                      lambda s=scene, v=view, n=name: store.read_aov(s, v, n), cube=False))
            w, h = p.full
            nbytes = w * h * p.metas[0].n_bands * 4  # float32, as sampling prices a decoded cube
            denoised = p.denoise != "none"
            for kind in ("transport", "illumination") if p.illumination else ("transport",):
                for g, stamp_g, lit in zip(p.groups, p.stamps, p.reads()):
                    if lit:
                        out.append(_Entry(cube_key(scene, view, g, kind, p.denoise, stamp_g),
                                          f"{scene}/{view} {g} {kind}" + (f" ({p.denoise})" if denoised else ""),
                                          nbytes, lambda s=scene, v=view, g=g, k=kind, d=denoised:
                                          store.read_cube(s, v, g, kind=k, denoised=d), cube=True))
    return out, skipped


def warm_cache(ctx: Context, log: Callable[[str], None] | None = None) -> dict:
    """Decode what a default ``/sample`` of every view reads into ``ctx.cache``, until it is full.

    ``log``: called with one line per entry warmed and a summary (``None``: silent). Returns
    ``{"cubes", "aovs", "bytes", "seconds", "skipped"}``: cubes and AOVs kept, their bytes, the time
    taken, and the entries (plus unplannable views) left cold.
    """
    log = log or (lambda _msg: None)
    t0 = time.perf_counter()
    cache = ctx.cache
    entries, skipped = _entries(ctx, log)
    cubes = aovs = nbytes = 0
    for i, e in enumerate(entries):
        if e.key in cache:
            continue
        t = time.perf_counter()
        try:
            kept = _keep_if_room(cache, e)
        except StoreError as exc:  # a damaged chunk: /sample will report it too; warm the rest
            log(f"warm: skipping {e.what}: {str(exc).splitlines()[0]}")
            skipped += 1
            continue
        if not kept:
            left = len(entries) - i
            log(f"warm: cache full ({_size(cache.total_cost)} of {_size(cache.max_cost)}); {left} of "
                f"{len(entries)} entries left cold (raise --cache-mb to warm them)")
            skipped += left
            break
        cubes, aovs, nbytes = cubes + e.cube, aovs + (not e.cube), nbytes + e.nbytes
        log(f"warm: {e.what} {_size(e.nbytes)} in {1e3 * (time.perf_counter() - t):.0f} ms "
            f"({i + 1}/{len(entries)})")
    seconds = time.perf_counter() - t0
    log(f"warm: {cubes} cubes and {aovs} AOVs, {_size(nbytes)} in {seconds:.1f} s"
        + (f"; {skipped} left cold" if skipped else ""))
    return {"cubes": cubes, "aovs": aovs, "bytes": nbytes, "seconds": seconds, "skipped": skipped}


def _keep_if_room(cache, e: _Entry) -> bool:
    """Load ``e`` into the cache if it fits in what is left of it (evicting nothing); whether it did."""
    value = None
    if e.nbytes is None:  # an AOV: its dtype is known once read (they are small)
        value = e.load()
        e.nbytes = int(value.nbytes)
    if e.nbytes > cache.max_cost - cache.total_cost - cache.evicted_cost:
        return False
    misses = cache.misses
    cache.get(e.key, (lambda: value) if value is not None else e.load, expected_cost=e.nbytes)
    cache.misses = misses  # warming is no request: hits and misses describe the traffic (module doc)
    return True


def _size(n: int) -> str:
    return f"{n / 2**20:.1f} MB" if n >= 2**20 // 10 else f"{n / 1024:.0f} KB"


def warm_projections(ctx: Context, sensors: list[str], illuminants: list[str],
                     log: Callable[[str], None] | None = None) -> dict:
    """Project every view's lit groups through each sensor × illuminant into ``ctx.projections``
    (:mod:`engine.projections`), until it is full, so a feed drawing from that pool slices crops
    from its first sample on. Returns ``{"projections", "bytes", "seconds", "skipped"}``.

    The keys are the ones :func:`engine.sampling.group_inputs` asks for (the cubes a default
    ``/sample`` reads: transport, and illumination where the physical ground truth is served). A
    sensor or illuminant the library does not know, or one a cube cannot be relit to, is skipped.
    """
    from illumix.engine.cubes import projection_key

    log = log or (lambda _msg: None)
    pc, t0 = ctx.projections, time.perf_counter()
    done = nbytes = 0
    skipped = [0]  # counted by the candidates too
    if pc is None:
        return {"projections": 0, "bytes": 0, "seconds": 0.0, "skipped": 0}
    for p, g, kind, skey, ikey, unit, frame in _candidates(ctx, sensors, illuminants, skipped):
        key = projection_key(p, g, kind, skey, ikey)
        if key in pc.cache:
            continue
        if frame > pc.cache.max_cost - pc.cache.total_cost - pc.cache.evicted_cost:
            log(f"warm: projection cache full after {done} projections")
            return {"projections": done, "bytes": nbytes, "seconds": time.perf_counter() - t0,
                    "skipped": skipped[0] + 1}
        if key[0] not in ctx.cache:  # project only what warm_cache decoded: never evict it
            skipped[0] += 1
            continue
        if _project(ctx, p, g, kind, key, unit, frame, log, skipped):
            done, nbytes = done + 1, nbytes + frame
    seconds = time.perf_counter() - t0
    log(f"warm: {done} projections, {_size(nbytes)} in {seconds:.1f} s")
    return {"projections": done, "bytes": nbytes, "seconds": seconds, "skipped": skipped[0]}


def _candidates(ctx: Context, sensors: list[str], illuminants: list[str], skipped: list[int]):
    """``(plan, group, kind, sensor key, illuminant key, unit weights, frame bytes)`` of every projection a
    default ``/sample`` of each view may ask for; what cannot be planned or relit counts in ``skipped``."""
    from illumix.engine.cubes import frame_bytes
    from illumix.engine.sampling import unit_weights

    for scene in ctx.store.scenes():
        for view in ctx.store.views(scene):
            try:
                p = plan(SampleSpec(scene=scene, view=view, crop=[0, 0, 1, 1], seed=0), ctx)
            except (SpectralError, Busy, StoreError):
                skipped[0] += 1
                continue
            grid, frame = p.metas[0].spectral_grid, frame_bytes(p)
            for s_name in sensors:
                for i_name in illuminants:
                    try:
                        sensor, skey = ctx.library.sensor(s_name, grid)
                        spd, ikey = ctx.library.illuminant(i_name, grid)
                    except SpectralError:
                        skipped[0] += 1
                        continue
                    for g, meta, lit in zip(p.groups, p.metas, p.reads()):
                        if not lit:
                            continue
                        try:
                            unit = unit_weights(spd, meta.emission, g, sensor, grid)
                        except SpectralError:
                            skipped[0] += 1
                            continue
                        for kind in ("transport", "illumination") if p.illumination else ("transport",):
                            yield p, g, kind, skey, ikey, unit, frame


def _project(ctx: Context, p, g: str, kind: str, key, unit, frame: int, log, skipped: list[int]) -> bool:
    """Project one group's whole cube into the projection cache (warming is no request: the caches'
    hit and miss counts are left as they were); False when skipped."""
    from illumix.engine.cubes import whole_cube

    pc = ctx.projections
    misses, hits = pc.cache.misses, ctx.cache.hits
    try:
        kept = pc.window(key, lambda: whole_cube(ctx, p, g, kind), unit, (0, 0, 1, 1), frame, whole_frame=True)
    except (SpectralError, StoreError) as exc:
        log(f"warm: skipping {p.scene}/{p.view} {g} {kind}: {str(exc).splitlines()[0]}")
        skipped[0] += 1
        return False
    finally:
        pc.cache.misses, ctx.cache.hits = misses, hits
    return kept is not None
