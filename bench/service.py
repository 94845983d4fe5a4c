"""Benchmark GET /sample latency and throughput over loopback.

Builds a synthetic two-group 720×960×63 store in a temporary folder (analytic cubes, see
tests/synthetic_store.py), starts ``illumix serve`` on 127.0.0.1 in a subprocess, and sends bounded
batches of requests for a 256×256 crop and for the full frame with 1, 4 and 16 concurrent clients.
The baseline measured in the same run is the in-process composition of the same sample (no HTTP,
no encoding): ``p50_ratio_vs_in_process`` is service latency over that median (HTTP + encoding
overhead at 1 client, queueing beyond), ``throughput_ratio_vs_in_process_serial`` the served rate
over the serial in-process rate (2 cores bound it near 1–2).

Usage: python bench/service.py [--requests N] [--max-seconds S]; JSON printed last on stdout.
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
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from server_lib import free_port, wait_healthy

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "bench")]


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)




def in_process_ms(store_path: str, params: dict, repeats: int) -> float:
    from illumix.service.app import create_app
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    ctx = create_app(CubeStore.open(store_path, mode="r"), cache_mb=2048).state.ctx
    spec = SampleSpec(**params)
    build_sample(spec, ctx)  # warm cache and CCMs
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        build_sample(spec, ctx)
        times.append(1e3 * (time.perf_counter() - t))
    return statistics.median(times)


def run_load(url: str, params: dict, clients: int, n: int, max_s: float) -> dict:
    import httpx

    lat: list[float] = []
    errors = 0
    deadline = time.perf_counter() + max_s

    def one(i: int) -> None:
        nonlocal errors
        if time.perf_counter() > deadline:
            return
        t = time.perf_counter()
        r = client.get(f"{url}/sample", params=params | {"seed": i})
        dt = 1e3 * (time.perf_counter() - t)
        if r.status_code != 200:
            errors += 1
        else:
            lat.append(dt)

    with httpx.Client(timeout=120, limits=httpx.Limits(max_connections=clients)) as client:
        one(0)  # warm: cube cache, CCMs
        lat.clear()
        errors = 0
        t0 = time.perf_counter()
        with ThreadPoolExecutor(clients) as pool:
            list(pool.map(one, range(n)))
        wall = time.perf_counter() - t0
    if not lat:
        return {"errors": errors, "completed": 0}
    q = np.percentile(lat, [50, 95])
    return {"clients": clients, "completed": len(lat), "errors": errors, "p50_ms": float(q[0]),
            "p95_ms": float(q[1]), "throughput_rps": len(lat) / wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=24, help="requests per (case, concurrency)")
    ap.add_argument("--max-seconds", type=float, default=30.0, help="time cap per (case, concurrency)")
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--width", type=int, default=960)
    args = ap.parse_args()
    import synthetic_store

    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "store")
        log(f"building a synthetic {args.width}x{args.height}x63 store …")
        synthetic_store.build(store, args.height, args.width, extras=False)
        port = free_port()
        proc = subprocess.Popen([sys.executable, "-m", "illumix.cli", "serve", "--store", store,
                                 "--host", "127.0.0.1", "--port", str(port), "--cache-mb", "2048",
                                 # full 720x960 frames with every output need ~190 MiB each, above the
                                 # default per-request bound (sized for bench/load.py's RSS goal)
                                 "--max-request-mb", "512", "--inflight-mb", "2048"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        url = f"http://127.0.0.1:{port}"
        try:
            wait_healthy(url, proc, what="bench/service.py: the server")
            cases = {
                "crop256": {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65",
                            "crop": "300,200,256,256"},
                "full": {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65"},
            }
            results = {}
            for name, params in cases.items():
                base = in_process_ms(store, params, repeats=5)
                rows = []
                for c in (1, 4, 16):
                    log(f"{name}: {c} client(s) …")
                    row = run_load(url, params, c, args.requests, args.max_seconds)
                    row["p50_ratio_vs_in_process"] = row.get("p50_ms", float("nan")) / base
                    row["throughput_ratio_vs_in_process_serial"] = row.get("throughput_rps", 0.0) * base / 1e3
                    rows.append(row)
                results[name] = {"in_process_compose_ms": base, "load": rows}
        finally:
            proc.terminate()
            proc.wait(timeout=20)
    print(json.dumps({"bench": "service", "size": [args.width, args.height], "cpus": os.cpu_count(),
                      "results": results}))


if __name__ == "__main__":
    main()
