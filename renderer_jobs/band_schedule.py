"""The stratified wavelength schedule of a cube's paths: which bands each path samples, and exactly
how many samples every (pixel, band) receives (see :mod:`renderer_jobs.mitsuba.render`, "Wavelength
sampling"). Pure numpy, deterministic from the seed."""

from __future__ import annotations

import numpy as np


def lane_stride(n_live: int) -> int:
    """Band offset between a path's 4 wavelengths when ``n_live`` bands are sampled (16 for 63)."""
    return max(1, round(n_live / 4))


def live_bands(emission: np.ndarray) -> np.ndarray:
    """Band indices the stratified schedule samples: where the cube's emission is non-zero (a band
    the group does not emit is exactly zero in the cube, so its samples would be wasted); every band
    if none is."""
    live = np.flatnonzero(np.asarray(emission) > 0)
    return live if live.size else np.arange(len(emission))


def hash_u32(x: np.ndarray, salt: int) -> np.ndarray:
    """A 32-bit integer hash (lowbias32) of ``x`` with ``salt``; vectorised, uint64 → uint64 < 2³²."""
    x = (x.astype(np.uint64) ^ np.uint64(salt & 0xFFFFFFFF)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    return x


def mix_seed(*parts: int) -> int:
    """A 32-bit seed from integer parts, hashing each into the running hash: unlike ``hash(a ^ b)``,
    different tuples do not collide by construction (``(0, 1)`` and ``(1, 0)`` once gave the same
    random numbers to two "independent" renders)."""
    h = 0x811C9DC5
    for p in parts:
        h = int(hash_u32(np.array([int(p) & 0xFFFFFFFF]), h)[0])
    return h


def group_seed(seed: int, groups) -> int:
    """The render seed of a cube lit by ``groups`` (names): ``seed`` mixed with each name's CRC-32.

    Every group's cube gets its own random numbers. With one seed for all, the groups of a view
    shared their paths, so their noise was correlated (a point light and the sun over the same
    floor: +0.52, the composed frame's noise variance 1.48× the groups' sum; a sun and its sky:
    −0.19), and denoising one group could raise the composed frame's error while lowering its own
    (bench/FIDELITY.md). Independent cubes' errors add in quadrature, whatever the illuminants."""
    import zlib

    return mix_seed(seed, *(zlib.crc32(str(g).encode()) for g in groups))


def band_counts(n_pixels: int, n_bands: int, spp: int | np.ndarray, seed: int,
                live: np.ndarray | None = None) -> np.ndarray:
    """Exact samples per (pixel, band) of the ``"stratified"`` schedule: ``(n_pixels, n_bands)`` int.
    ``spp``: paths per pixel, one number or ``(n_pixels,)`` (adaptive sampling); ``live``: the bands
    sampled (:func:`live_bands`; default all), the others get none."""
    live = np.arange(n_bands) if live is None else np.asarray(live)
    m = live.size
    off = (hash_u32(np.arange(n_pixels), seed ^ 0x5BD1E995) % np.uint64(m)).astype(np.int64)
    q, r = np.divmod(np.broadcast_to(np.asarray(spp, dtype=np.int64), (n_pixels,)), m)
    b = np.arange(m)
    on = np.zeros((n_pixels, m), dtype=np.int64)
    for i in range(4):
        on += q[:, None] + (((b[None, :] - off[:, None] - lane_stride(m) * i) % m) < r[:, None])
    counts = np.zeros((n_pixels, n_bands), dtype=np.int64)
    counts[:, live] = on
    return counts


def pass_sizes(spp: int, n_pixels: int, max_lanes: int) -> list[int]:
    """Paths per pixel of each pass, so that a pass traces at most ``max_lanes`` paths (≥ 1 per pixel)."""
    per = max(1, min(spp, max_lanes // max(n_pixels, 1)))
    sizes = [per] * (spp // per)
    if spp % per:
        sizes.append(spp % per)
    return sizes
