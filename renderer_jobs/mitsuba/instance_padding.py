"""Kernel reuse across scenes: Dr.Jit's instance registry padded to a few fixed sizes.

A symbolic call over shapes, BSDFs or emitters (every Mitsuba kernel has several) reads its
targets through an offset table with one entry per registry ID of the class, up to the class's
*ID bound* — so two scenes with different numbers of shapes compile kernels that differ only in
where those tables sit in the call-data buffer (``getelementptr … i64 32`` against ``48``: issue 38,
bench/RENDER_PERF.md). A new scene in a warm worker therefore paid ~1 CPU-s of LLVM builds for
kernels it already had.

:func:`pad_registry` registers inert instances (spheres sharing one ``null`` BSDF, ``null`` BSDFs,
point lights — objects in no scene, so never hit or sampled; inert *diffuse* BSDFs cost 20 % of the
warm demo in call recording, ``null`` ones nothing measurable: bench/RENDER_PERF.md) until each class's ID bound reaches
the next size in :func:`bucket` (16, 24, 32, 48, 64, …): scenes whose bounds fall in the same buckets, and
whose materials and shapes are of the same kinds, then share every kernel. Each load replaces the padding
(:func:`release_padding` before it). Its cost is the inert instances' share of recording each call
(bench/fixed_costs.py measures both sides). Without the registry query (``jit_registry_id_bound``
missing from this Dr.Jit, or a scalar variant) it does nothing: kernels are then built per scene,
as before, with identical results.
"""

from __future__ import annotations

import ctypes
import os
from functools import lru_cache

SMALLEST_BUCKET = 16
# ILLUMIX_KERNEL_PADDING=off: no padding (bench/fixed_costs.py measures with and without)
ENABLED = os.environ.get("ILLUMIX_KERNEL_PADDING", "on").lower() not in ("off", "0", "false", "no")
_held: list = []  # the current padding, replaced at every load


def bucket(bound: int) -> int:
    """The padded ID bound for ``bound`` registered instances: the next of 16, 24, 32, 48, 64, …
    (powers of two and 1.5× them).

    Every scene with up to 16 shapes, BSDFs and emitters shares one layout (inert spheres, null
    BSDFs and point lights are cheap to record). Above, half-octave steps keep the number of distinct layouts (so of kernel builds) logarithmic in
    scene size while padding by 17 % on average (50 % at most): every inert instance is recorded
    in every call, which costs CPU in every render (bench/fixed_costs.py: the demo's cubes)."""
    b = SMALLEST_BUCKET
    while b < bound:
        b = b * 3 // 2 if b & (b - 1) == 0 else b * 4 // 3
    return b


@lru_cache(maxsize=1)
def _id_bound_query():
    """Dr.Jit's ``jit_registry_id_bound(variant, domain)`` (a C++ symbol of libdrjit-core), or None."""
    try:
        import drjit
        lib = ctypes.CDLL(os.path.join(os.path.dirname(drjit.__file__), "libdrjit-core.so"))
        fn = lib._Z21jit_registry_id_boundPKcS0_  # the C++ symbol: no Python binding exposes it
    except (ImportError, OSError, AttributeError):
        return None
    fn.restype = ctypes.c_uint32
    fn.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
    return fn


def id_bounds(mi) -> dict[str, int]:
    """The current ID bound of the classes :func:`pad_registry` pads (empty when unknown)."""
    query = _id_bound_query()
    if query is None or not mi.variant().startswith(("llvm_", "cuda_")):
        return {}
    v = mi.variant().encode()
    return {d: int(query(v, d.encode())) for d in ("Shape", "BSDF", "Emitter")}


def release_padding() -> None:
    """Free the inert instances: their IDs are the lowest free ones for the next scene to take."""
    _held.clear()


def pad_registry(mi) -> dict[str, int]:
    """Register inert instances until each class's ID bound is its :func:`bucket`.

    Call after loading a scene (with :func:`release_padding` before it, so that the scene takes
    the padding's IDs rather than landing above them: kept across loads, padding ratcheted the
    bounds up a bucket at every load) and before rendering it. Returns the bounds ({} when the
    registry cannot be queried)."""
    if not ENABLED or not id_bounds(mi):
        return {}
    query, v = _id_bound_query(), mi.variant().encode()
    shared = mi.load_dict({"type": "null"})  # one BSDF for every inert sphere: BSDFs are padded next
    _held.append(shared)
    inert = (("Shape", {"type": "sphere", "bsdf": shared}), ("BSDF", {"type": "null"}),
             ("Emitter", {"type": "point"}))
    for domain, doc in inert:
        target = bucket(query(v, domain.encode()))
        while query(v, domain.encode()) < target:
            _held.append(mi.load_dict(doc))
    return id_bounds(mi)
