"""Store layout, chunking and compression.

Layout (every directory is a zarr v3 group or array, so any zarr reader can open the store)::

    ROOT/                                    group; attrs illumix_store {schema_version, created}
      scenes/<scene>/<view>/                 group; attrs illumix_view (ViewMeta)
        aov/<name>                           array (H, W[, C]): albedo, normal, depth, mask, emitter, …
        cubes/<group>/                       group; attrs illumix_cube (CubeMeta), illumix_state
          data                               array (H, W, B) float16 (scaled) or float32
          exponent                           array (H, W) int8 per-pixel exponents (float16 only)
          illumination/                      group: the illumination cube (CubeMeta.illumination)
            data, exponent                   as above
      _registry/<kind>/<name>/               group; attrs illumix_registry (payload base64)
      _staging/<id>/                         writes in progress (local directories only)
      _trash/<id>/                           replaced nodes awaiting deletion

Chunks are full-band tiles ``(tile, tile, B)``: a crop read touches only the tiles it overlaps and a
pixel's whole spectrum is in one chunk (relighting needs every band).

Defaults chosen by measurement (``python bench/store.py``; see :data:`BENCH_NOTE`).
"""

from __future__ import annotations

from typing import Any

from zarr.codecs import BloscCodec, Crc32cCodec, ZstdCodec

#: Default full-band tile edge in pixels.
DEFAULT_TILE = 128
#: Default compressor name (see :func:`compressors`).
DEFAULT_CODEC = "blosc-lz4"
CODECS = ("zstd", "blosc-lz4", "blosc-zstd", "none")

BENCH_NOTE = """
python bench/store.py — synthetic 720x960x63 render-like cube, exponent-scaled float16, page cache warm,
2-core VM shared with other work (minimum over interleaved rounds; CPU = process time, all threads):

tile codec       write  full read  crop 256² (cpu)   on disk    files
  64 zstd        1.09s   0.40s     62 ms (44 ms)     67.7 MiB   195
  64 blosc-lz4   1.13s   0.38s     54 ms (37 ms)     65.6 MiB   195
  64 blosc-zstd  1.28s   0.36s     43 ms (43 ms)     59.4 MiB   195
  64 none        0.87s   0.22s     26 ms (26 ms)     88.7 MiB   195
 128 zstd        0.87s   0.78s     52 ms (47 ms)     67.9 MiB    55
 128 blosc-lz4   0.86s   0.31s     32 ms (32 ms)     65.7 MiB    55   <- default
 128 blosc-zstd  1.68s   0.31s     45 ms (44 ms)     59.6 MiB    55
 128 none        1.17s   0.22s     25 ms (25 ms)     94.6 MiB    55
 256 zstd        1.28s   0.32s     88 ms (65 ms)     68.2 MiB    16
 256 blosc-lz4   1.04s   0.88s     45 ms (40 ms)     66.0 MiB    16
 256 blosc-zstd  1.69s   0.47s     86 ms (59 ms)     59.6 MiB    16
 256 none        0.77s   0.29s     37 ms (26 ms)     94.6 MiB    16
float32 (no float16 policy), 128 blosc-lz4: 128.8 MiB.

Choice: 128 px tiles — a 256² crop at a random offset decodes 2.25× its area (64 px: 1.56×, 256 px:
4×) and the 256 px tiles are measurably slower for crops, while 64 px tiles read no faster here and
need 3.5× the files (one GET each on object storage). blosc-lz4 with bit shuffle — the fastest
compressed reads (crop 32 ms vs 47 ms zstd, 44 ms blosc-zstd) and writes, 31 % smaller than no
compression; blosc-zstd is 9 % smaller still but reads ~40 % and writes ~2× slower. Reads dominate
a data service, so read latency decides. Timings on this loaded VM vary ±50 % between runs; sizes
are exact. Decompression alone (numcodecs, one thread): blosc-lz4 ~2.6 GB/s, zstd ~0.65 GB/s.
"""


def compressors(name: str, itemsize: int) -> Any:
    """zarr v3 compressor list for a codec name: ``zstd`` (level 3, no shuffle), ``blosc-lz4``
    (bit shuffle, level 5), ``blosc-zstd`` (byte shuffle, level 3) or ``none`` — each followed by
    a CRC-32C of the stored chunk, which zarr checks on every decode (:mod:`store.checksums`).

    Shuffles matter for float16: they separate the sign/exponent bits, which compress, from the
    low mantissa bits, which carry Monte-Carlo noise and do not."""
    if name == "zstd":
        return [ZstdCodec(level=3), Crc32cCodec()]
    if name == "blosc-lz4":
        return [BloscCodec(cname="lz4", clevel=5, shuffle="bitshuffle", typesize=itemsize), Crc32cCodec()]
    if name == "blosc-zstd":
        return [BloscCodec(cname="zstd", clevel=3, shuffle="shuffle", typesize=itemsize), Crc32cCodec()]
    if name == "none":
        return [Crc32cCodec()]
    raise ValueError(f"unknown codec {name!r}; use one of {', '.join(CODECS)}")


def exponent_chunks(tile: int, height: int, width: int) -> tuple[int, int]:
    """Chunks of the int8 per-pixel exponent array: 4× the data tile (it is 1/126 of the data's
    size, so larger chunks cost nothing to decode and keep the file count near the data's)."""
    return min(4 * tile, height), min(4 * tile, width)


def view_path(scene: str, view: str) -> str:
    return f"scenes/{scene}/{view}"


def cube_path(scene: str, view: str, group: str) -> str:
    return f"scenes/{scene}/{view}/cubes/{group}"


def aov_path(scene: str, view: str, name: str) -> str:
    return f"scenes/{scene}/{view}/aov/{name}"


def n_chunks(shape: tuple[int, ...], chunks: tuple[int, ...]) -> int:
    """Number of chunks of an array of ``shape`` with chunk shape ``chunks``."""
    n = 1
    for s, c in zip(shape, chunks):
        n *= -(-s // c)
    return n
