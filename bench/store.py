"""Benchmark the cube store: dtype policy, chunk shape and codec.

    python bench/store.py                 # 720x960x63 synthetic render-like cube, ~1-2 min
    python bench/store.py --quick         # 240x320, seconds (smoke test)

For each full-band tile (64, 128, 256 px) × codec (zstd, blosc-lz4, blosc-zstd, none) it writes the
cube into a fresh local store and measures write time (encode + compress + publish), full-frame read
(decoded float32), 256×256 crop read (median over crops at seeded random positions, page cache warm)
and bytes on disk. Reads are repeated in interleaved rounds and the minimum kept (wall and process
CPU time), so other load on a shared machine distorts them as little as possible. The dtype section compares naive float16, a per-band scale and the store's
exponent-scaled float16 policy on the same cube. Human table on stderr; JSON last on stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from illumix.retarget.grid import DEFAULT_GRID  # noqa: E402
from illumix.store import CubeMeta, CubeStore, ViewMeta  # noqa: E402
from illumix.store.codec import REL_BOUND_F16, decode, encode  # noqa: E402
from illumix.store.layout import n_chunks  # noqa: E402
from illumix.store.synth import synthetic_cube  # noqa: E402


def _rel_err(a: np.ndarray, ref: np.ndarray) -> float:
    nz = ref != 0
    return float(np.max(np.abs(a[nz].astype(np.float64) - ref[nz]) / np.abs(ref[nz])))


def dtype_section(cube: np.ndarray) -> dict:
    """Naive float16 vs per-band scale vs the exponent-scaled policy on ``cube``."""
    out: dict = {"raw_float32_bytes": int(cube.nbytes)}
    with np.errstate(over="ignore"):
        naive = cube.astype(np.float16)
    fin = np.isfinite(naive)
    out["naive_float16"] = {
        "inf_values": int(np.count_nonzero(~fin)),
        "flushed_to_zero": int(np.count_nonzero((naive == 0) & (cube != 0))),
        "max_rel_err_where_finite": _rel_err(naive[fin].astype(np.float32), cube[fin])}
    flat = cube.reshape(-1, cube.shape[-1])
    beta = np.frexp(np.maximum(flat.max(0), -flat.min(0)).astype(np.float64))[1]
    scaled = cube * np.ldexp(np.float32(1), 15 - beta).astype(np.float32)
    below = (np.abs(scaled) < 2.0**-14) & (cube != 0)
    back = scaled.astype(np.float16).astype(np.float32) * np.ldexp(np.float32(1), beta - 15).astype(np.float32)
    out["per_band_scale_float16"] = {
        "values_below_normal_range": int(np.count_nonzero(below)),
        "max_rel_err": _rel_err(back, cube)}
    t0 = time.perf_counter()
    enc = encode(cube, "auto")
    t_enc = time.perf_counter() - t0
    t0 = time.perf_counter()
    dec = decode(enc.data, enc.exponent, enc.band_exponent)
    t_dec = time.perf_counter() - t0
    out["exp2_float16_policy"] = {
        "dtype": enc.dtype, "reason": enc.reason, "max_rel_err": _rel_err(dec, cube),
        "bound": REL_BOUND_F16 if enc.dtype == "float16" else 0.0,
        "nonfinite_after_decode": int(np.count_nonzero(~np.isfinite(dec))),
        "stored_bytes_uncompressed": int(enc.data.nbytes + (0 if enc.exponent is None else enc.exponent.nbytes)),
        "encode_s": round(t_enc, 4), "decode_s": round(t_dec, 4)}
    adv = cube.copy()
    adv[: adv.shape[0] // 8, : adv.shape[1] // 8] = 1e-7
    adv[-4:, -4:] = 1e6
    e2 = encode(adv, "auto")
    d2 = decode(e2.data, e2.exponent, e2.band_exponent)
    out["highlight_1e6_shadow_1e-7"] = {"dtype": e2.dtype, "max_rel_err": _rel_err(d2, adv),
                                        "nonfinite": int(np.count_nonzero(~np.isfinite(d2)))}
    return out


def _timed(fn) -> tuple[float, float]:
    """(wall seconds, process CPU seconds over all threads) of one call."""
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def layout_section(cube: np.ndarray, tiles: list[int], codecs: list[str], crops: int, rounds: int,
                   workdir: Path) -> list[dict]:
    """Write the cube once per (tile, codec); then ``rounds`` interleaved rounds of a full read and
    ``crops`` 256x256 crop reads per layout. Reported: the minimum over rounds (wall and CPU), which
    is robust to other load on a shared machine; crop figures are per crop (mean within a round)."""
    h, w, nb = cube.shape
    rng = np.random.default_rng(1)
    cw, ch = min(256, w), min(256, h)
    pos = [(int(rng.integers(0, w - cw + 1)), int(rng.integers(0, h - ch + 1))) for _ in range(crops)]
    rows, stores = [], []
    for tile in tiles:
        for codec in codecs:
            st = CubeStore.open(workdir / f"t{tile}-{codec}", tile=tile, codec=codec)
            st.write_view("s", "v", ViewMeta(width=w, height=h))
            holder = {}
            t_write, c_write = _timed(lambda: holder.update(m=st.write_cube("s", "v", "g", cube,
                                                                               CubeMeta(grid=DEFAULT_GRID))))
            stored = holder["m"]
            rows.append({"tile": tile, "codec": codec, "dtype": stored.storage.dtype,
                         "write_s": round(t_write, 4), "write_cpu_s": round(c_write, 4),
                         "bytes": int(stored.storage.nbytes_stored),
                         "files": st.backend.count_files("scenes/s/v/cubes/g"),
                         "ratio_vs_raw_f32": round(stored.storage.nbytes_stored / cube.nbytes, 4),
                         "chunks": n_chunks((h, w), (tile, tile)),
                         "read_full_s": np.inf, "read_full_cpu_s": np.inf,
                         "read_crop256_s": np.inf, "read_crop256_cpu_s": np.inf})
            stores.append(st)
    for _ in range(rounds):
        for row, st in zip(rows, stores):
            t, c = _timed(lambda: st.read_cube("s", "v", "g"))
            row["read_full_s"], row["read_full_cpu_s"] = min(row["read_full_s"], t), min(row["read_full_cpu_s"], c)
            t, c = _timed(lambda: [st.read_cube("s", "v", "g", crop=(x, y, cw, ch)) for x, y in pos])
            row["read_crop256_s"] = min(row["read_crop256_s"], t / crops)
            row["read_crop256_cpu_s"] = min(row["read_crop256_cpu_s"], c / crops)
    for row in rows:
        for k in ("read_full_s", "read_full_cpu_s", "read_crop256_s", "read_crop256_cpu_s"):
            row[k] = round(float(row[k]), 5)
        print(f"tile {row['tile']:4d} {row['codec']:10s} write {row['write_s']:6.3f}s  "
              f"full {row['read_full_s']:6.3f}s (cpu {row['read_full_cpu_s']:6.3f})  "
              f"crop {row['read_crop256_s'] * 1e3:7.2f}ms (cpu {row['read_crop256_cpu_s'] * 1e3:6.2f})  "
              f"{row['bytes'] / 2**20:6.1f} MiB ({row['ratio_vs_raw_f32']:.3f} of f32)  {row['files']} files",
              file=sys.stderr)
    return rows


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--quick", action="store_true", help="240x320, 2 tiles x 2 codecs")
    ap.add_argument("--tiles", default="64,128,256")
    ap.add_argument("--codecs", default="zstd,blosc-lz4,blosc-zstd,none")
    ap.add_argument("--crops", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    if args.quick:
        args.height, args.width, args.tiles, args.codecs, args.crops = 240, 320, "64,128", "zstd,blosc-lz4", 3
    t0 = time.perf_counter()
    cube = synthetic_cube(args.height, args.width)
    t_gen = time.perf_counter() - t0
    print(f"synthetic cube {cube.shape} in {t_gen:.1f}s; dtype policy:", file=sys.stderr)
    dt = dtype_section(cube)
    print(json.dumps(dt, indent=1), file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="illumix-bench-store-") as tmp:
        rows = layout_section(cube, [int(t) for t in args.tiles.split(",")], args.codecs.split(","),
                              args.crops, args.rounds, Path(tmp))
        st = CubeStore.open(Path(tmp) / "f32", dtype_policy="float32")
        st.write_view("s", "v", ViewMeta(width=args.width, height=args.height))
        f32 = st.write_cube("s", "v", "g", cube, CubeMeta(grid=DEFAULT_GRID))
    result = {"cube": {"shape": list(cube.shape), "generator": "store.synth.synthetic_cube(seed=0)",
                       "max": float(cube.max()), "min": float(cube.min()), "mean": float(cube.mean())},
              "dtype_policy": dt, "layouts": rows,
              "float32_default_layout_bytes": int(f32.storage.nbytes_stored)}
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
