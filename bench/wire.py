"""Benchmark the wire formats (issue 19, "transfer less"): npz vs the arrays container, float32 vs float16.

1. Encode and decode alone, on arrays of the service's shapes and dtypes (random values; neither
   format compresses): a full 720×960 frame with every output (raw, gain, ccm, srgb, weights, mask,
   illum, mixture: ~70 MB), the same without ccm (the new default outputs), and a 256×256 crop of
   raw + gain. Each time is the median of ``--repeats`` runs after one warm-up run.
2. With ``--http``: a synthetic two-group 720×960×63 store (tests/synthetic_store.py) served by
   uvicorn in a subprocess; the median wall time of ``GET /sample`` read to the last byte (httpx) and
   decoded by the client, per format and dtype — and the arrays body streamed as views of the outputs
   (the service's way) against the same body joined into one ``bytes`` first. Each sample is
   composed once and reused (``--compose`` composes every request), so the times are the wire's:
   encoding, loopback transfer (uvicorn + h11) and client decoding.

Usage: python bench/wire.py [--repeats N] [--http]; JSON printed last on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from server_lib import free_port, wait_healthy  # bench/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "clients" / "python")]

PAYLOADS = {  # name → {output: (shape per pixel, dtype)}
    "full_all_720x960": (720, 960, ("raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture")),
    "full_default_720x960": (720, 960, ("raw", "gain", "srgb", "weights", "mask", "illum", "mixture")),
    "crop_raw_gain_256": (256, 256, ("raw", "gain")),
}
TAIL = {"raw": (3,), "gain": (3,), "ccm": (3, 3), "srgb": (3,), "weights": (2,), "mask": (), "illum": (3,),
        "mixture": (2,)}


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def payload(h: int, w: int, names) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {k: (rng.random((h, w)) > 0.5 if k == "mask" else rng.random((h, w, *TAIL[k]), dtype=np.float32))
            for k in names}


def median_ms(fn, repeats: int) -> float:
    fn()  # warm-up: first touches of fresh memory (page faults) are not the steady state
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(1e3 * (time.perf_counter() - t))
    return statistics.median(times)


def offline(repeats: int) -> dict:
    from illumix_client.sample import parse_sample

    from illumix.service import arrays_format
    from illumix.service.encoding import encode_npz, half_precision

    out = {}
    for name, (h, w, names) in PAYLOADS.items():
        out[name] = offline_row(payload(h, w, names), repeats, parse_sample, arrays_format, encode_npz,
                                half_precision)
        log(f"{name}: {out[name]}")
    return out


def offline_row(arrays, repeats, parse_sample, arrays_format, encode_npz, half_precision) -> dict:
    meta = {"scene": "x"}
    npz = bytes(encode_npz(arrays, meta))
    body = bytearray(arrays_format.encode(arrays, meta=meta).tobytes())
    body16 = bytearray(arrays_format.encode(*half_precision(arrays), meta=meta).tobytes())
    row = {
        "megabytes": round(sum(a.nbytes for a in arrays.values()) / 1e6, 2),
        "megabytes_float16": round(len(body16) / 1e6, 2),
        "encode_npz_ms": median_ms(lambda: encode_npz(arrays, meta), repeats),
        "encode_arrays_views_ms": median_ms(lambda: arrays_format.encode(arrays, meta=meta), repeats),
        "encode_arrays_joined_ms": median_ms(lambda: arrays_format.encode(arrays, meta=meta).tobytes(), repeats),
        "encode_float16_arrays_ms": median_ms(lambda: arrays_format.encode(*half_precision(arrays), meta=meta),
                                              repeats),
        "decode_npz_ms": median_ms(lambda: parse_sample(npz), repeats),
        "decode_arrays_ms": median_ms(lambda: parse_sample(body), repeats),
        "decode_float16_to_float32_ms": median_ms(lambda: parse_sample(body16), repeats),
    }
    row["encode_speedup_vs_npz"] = row["encode_npz_ms"] / max(row["encode_arrays_views_ms"], 1e-6)
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()}


SERVER = """
import sys, uvicorn
from illumix.service import arrays_format
from illumix.service.app import create_app
from illumix.engine.limits import Limits
from illumix.store import CubeStore
store, port, join = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "join"
if join:  # the same body, joined into one bytes before it is sent
    encode = arrays_format.encode
    arrays_format.encode = lambda *a, **k: encode(*a, **k).tobytes()
if sys.argv[4] == "memo":  # compose each sample once: what is timed is encoding and transfer
    import copy
    from illumix.service.routes import samples
    memo, real_build = {}, samples.build
    def build(p, ctx):
        key = p.spec.model_dump_json(exclude={"format", "dtype"})
        if key not in memo:
            memo[key] = real_build(p, ctx)
        arrays, meta = memo[key]
        return dict(arrays), copy.deepcopy(meta)
    samples.build = build
app = create_app(CubeStore.open(store, mode="r"), cache_mb=2048,
                 limits=Limits(max_request_mb=1024, inflight_mb=2048))
uvicorn.run(app, host="127.0.0.1", port=port, log_level="warning")
"""




def http(repeats: int, compose: bool) -> dict:
    import httpx
    import synthetic_store
    from illumix_client import Client

    cases = {"full_all": "raw,gain,ccm,srgb,weights,mask,illum,mixture,meta",
             "full_default": "raw,gain,srgb,weights,mask,illum,mixture,meta", "full_raw_gain": "raw,gain,meta",
             "crop256_raw_gain": "raw,gain,meta"}
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "store")
        log("building a synthetic 960x720x63 store …")
        synthetic_store.build(store, 720, 960, extras=False)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        for mode in ("views", "join"):
            port = free_port()
            proc = subprocess.Popen([sys.executable, "-c", SERVER, store, str(port), mode,
                                     "compose" if compose else "memo"], env=env,
                                    stdout=subprocess.DEVNULL)
            url = f"http://127.0.0.1:{port}"
            try:
                wait_healthy(url, proc, what="bench/wire.py: the server")
                formats = ("arrays",) if mode == "join" else ("npz", "arrays")
                for case, outputs in cases.items():
                    params = {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65", "outputs": outputs}
                    if case.startswith("crop"):
                        params["crop"] = "300,200,256,256"
                    for fmt in formats:
                        for dtype in ("float32", "float16"):
                            key = f"{case}/{fmt}{'-joined' if mode == 'join' else ''}/{dtype}"
                            out[key] = one_case(url, params, fmt, dtype, repeats, httpx, Client)
                            log(f"{key}: {out[key]}")
            finally:
                proc.terminate()
                proc.wait(timeout=30)
    return out


def one_case(url: str, params: dict, fmt: str, dtype: str, repeats: int, httpx, Client) -> dict:
    q = params | {"format": fmt, "dtype": dtype}
    with httpx.Client(timeout=120) as h, Client(url, wire_format=fmt) as c:
        size = len(h.get(f"{url}/sample", params=q).content)
        spec = {k: v for k, v in params.items()} | {"dtype": dtype}
        return {"megabytes": round(size / 1e6, 2),
                "http_read_ms": round(median_ms(lambda: h.get(f"{url}/sample", params=q).content, repeats), 2),
                "client_sample_ms": round(median_ms(lambda: c.sample(**spec), repeats), 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--http", action="store_true", help="also measure GET /sample over loopback")
    ap.add_argument("--compose", action="store_true", help="with --http: compose every request (default: once)")
    args = ap.parse_args()
    result = {"offline": offline(args.repeats)}
    if args.http:
        result["http"] = http(args.repeats, args.compose)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
