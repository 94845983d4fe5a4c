"""Load test of the running service on loopback (issue 7, item 4): errors, latency, resident memory.

Builds a synthetic store (tests/synthetic_store.py's two-group view plus three more two-group
views and a one-group view, ``--height``×``--width``×63, float16 policy), then runs ``illumix serve``
on 127.0.0.1 twice in a subprocess:

1. ``--cache-mb 0`` for ``--baseline-seconds``: every request reads and decodes its cubes; the
   RSS growth of this phase is the server's *transient* footprint (requests in flight, allocator
   slack) without a cache — the baseline measured in the same run;
2. ``--cache-mb M`` for ``--seconds`` (the same duration by default: glibc's allocator keeps
   freed memory in per-thread arenas and its heap, so RSS creeps for minutes before it levels off,
   and both phases must creep for as long): the cube cache fills up to M MiB and then churns (the
   cubes of all views together are several times M).

Environment variables of this process reach the server, so allocator or BLAS settings can be
compared: ``MALLOC_MMAP_THRESHOLD_=1048576 python bench/load.py`` (recorded in ``server_env``).

In each phase ``--clients`` threads send requests back to back until the time or the request cap
(``--max-requests``) is reached: random view, illuminant pair (spiky ones included), sensor, full
frame or a random crop (each new crop window is a new cache entry while its full frame is not
cached), sometimes a ``size=`` resize, a random subset of outputs, sometimes PNG. Every request is
valid: any non-200 answer or transport error counts as an error (must be 0).

Resident memory: ``VmRSS`` of the server process from ``/proc/<pid>/status`` every 0.25 s.
``rss_start`` is taken after a warm-up request (imports, CCM fits, BLAS buffers).
``rss_growth_within_cache_bound``: the cached phase grows by at most M MiB plus the transient
footprint measured in phase 1 (×1.25 + 16 MiB for run-to-run variation: how many large requests
happen to be in flight together varies); ``rss_plateau``: the median RSS of the last quarter of
phase 2 exceeds that of its second quarter by less than 10 % of that bound (no trend; a short run
cannot rule out a very slow leak — run longer with ``--seconds``).

``--leak-check N`` adds an in-process check that requests leave nothing allocated behind
(tracemalloc, numpy buffers included): RSS alone cannot tell a leak from allocator retention.

Usage: python bench/load.py [--clients 8 --seconds 40 --baseline-seconds 40 --cache-mb 64] [--leak-check 600];
progress on stderr; JSON last on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

PAIRS = ["A,D65", "FL11,D65", "FL2,A", "LED-RGB1,D50", "daylight:5000,blackbody:2700", "D65,LED-B3", "FL11,A"]
SENSORS = ["XYZ", "Nikon 5100 (NPL)"]
OUTPUTS = ["raw", "gain", "ccm", "srgb", "weights", "mask"]


def log(msg: str) -> None:
    print(f"[bench/load] {msg}", file=sys.stderr, flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def build_store(path: str, h: int, w: int) -> list[tuple[str, str, int]]:
    """The synthetic store; returns ``(scene, view, n_groups)`` of every view."""
    import synthetic_store as synth
    from retarget.grid import DEFAULT_GRID
    from store import CubeMeta, CubeStore, ViewMeta

    synth.build(path, h, w, extras=False)
    st = CubeStore.open(path, mode="a")
    refl = synth.reflectance_image(h, w)
    fw, fl = synth.falloffs(h, w)
    meta = dict(grid=DEFAULT_GRID.to_dict(), emission=[1.0] * DEFAULT_GRID.n_bands, emission_name="flat")
    views = [("synth", "v0", 2)]
    for i in range(1, 4):  # shifted materials and light falloffs: different cubes, same kind
        st.write_view("synth", f"v{i}", ViewMeta(width=w, height=h, fov=45.0))
        r = np.roll(refl, 7 * i, axis=1) * np.float32(0.6 + 0.2 * i)
        for g, f in (("window", np.roll(fw, 5 * i, axis=1)), ("lamp", np.roll(fl, -5 * i, axis=0))):
            st.write_cube("synth", f"v{i}", g, r * (f / np.float32(np.pi))[..., None], CubeMeta(**meta))
        views.append(("synth", f"v{i}", 2))
    st.write_view("synth", "solo", ViewMeta(width=w, height=h, fov=45.0))
    st.write_cube("synth", "solo", "lamp", refl * (fl / np.float32(np.pi))[..., None], CubeMeta(**meta))
    views.append(("synth", "solo", 1))
    return views


def random_request(rng: random.Random, views, h: int, w: int) -> dict:
    scene, view, groups = rng.choice(views)
    pair = rng.choice(PAIRS)
    p = {"scene": scene, "view": view, "sensor": rng.choice(SENSORS), "seed": rng.randrange(1 << 30)}
    if groups == 2:
        p["pair"] = pair
    else:
        p["illuminants"] = pair.split(",")[0]
    if rng.random() < 0.5:
        cw, ch = rng.randint(16, w), rng.randint(16, h)
        p["crop"] = f"{rng.randint(0, w - cw)},{rng.randint(0, h - ch)},{cw},{ch}"
    if rng.random() < 0.2:
        p["size"] = f"{rng.randint(8, 128)}x{rng.randint(8, 128)}"
    if rng.random() < 0.1:
        p.update(format="png", outputs="srgb")
    else:
        outs = rng.sample(OUTPUTS, rng.randint(1, len(OUTPUTS)))
        p["outputs"] = ",".join(outs + (["meta"] if rng.random() < 0.5 else []))
    return p


def server_env(blas_threads: int | None) -> dict:
    env = dict(os.environ)
    if blas_threads:
        for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env[k] = str(blas_threads)
    return env


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


def phase(store: str, views, h: int, w: int, cache_mb: int, clients: int, seconds: float,
          max_requests: int, seed: int, blas_threads: int | None = None) -> dict:
    """Start a server with ``cache_mb``, load it, stop it; latency, errors and the RSS series."""
    import httpx

    port = free_port()
    url = f"http://127.0.0.1:{port}"
    errlog = tempfile.TemporaryFile()  # uvicorn logs every request: a pipe nobody reads would block it
    proc = subprocess.Popen([sys.executable, "-m", "illumix.cli", "serve", "--store", store, "--host", "127.0.0.1",
                             "--port", str(port), "--cache-mb", str(cache_mb)],
                            stdout=subprocess.DEVNULL, stderr=errlog, cwd=ROOT, env=server_env(blas_threads))
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(f"{url}/health", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                errlog.seek(0)
                raise SystemExit(f"bench/load.py: the server did not start: {errlog.read().decode()[-2000:]}")
            time.sleep(0.1)
        with httpx.Client(timeout=120) as c:  # warm-up: imports, CCM fits, BLAS buffers
            for pair in PAIRS:
                for sensor in SENSORS:
                    c.get(f"{url}/sample", params={"scene": "synth", "view": "v0", "pair": pair, "sensor": sensor,
                                                   "crop": "0,0,16,16"}).raise_for_status()
        series: list[tuple[float, float]] = []
        stop = threading.Event()
        t0 = time.monotonic()

        def sample_rss() -> None:
            while not stop.is_set():
                series.append((time.monotonic() - t0, rss_mb(proc.pid)))
                stop.wait(0.25)

        lat: list[float] = []
        errors: list[str] = []
        lock = threading.Lock()
        counter = iter(range(max_requests))
        end = t0 + seconds

        def client(i: int) -> None:
            rng = random.Random(seed * 1000 + i)
            with httpx.Client(timeout=120) as c:
                while time.monotonic() < end:
                    with lock:
                        if next(counter, None) is None:
                            return
                    p = random_request(rng, views, h, w)
                    t = time.perf_counter()
                    try:
                        r = c.get(f"{url}/sample", params=p)
                        ok, msg = r.status_code == 200, f"{r.status_code} {r.text[:200]} {p}"
                    except httpx.HTTPError as exc:
                        ok, msg = False, f"{type(exc).__name__}: {exc} {p}"
                    dt = 1e3 * (time.perf_counter() - t)
                    with lock:
                        (lat.append(dt) if ok else errors.append(msg))

        sampler = threading.Thread(target=sample_rss, daemon=True)
        sampler.start()
        threads = [threading.Thread(target=client, args=(i,)) for i in range(clients)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        wall = time.monotonic() - t0
        stop.set()
        sampler.join()
        health = httpx.get(f"{url}/health", timeout=10).json()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        errlog.close()
    rss = np.array([v for _, v in series])
    q = len(rss) // 4
    pct = np.percentile(lat, [50, 99]) if lat else [float("nan")] * 2
    return {"cache_mb": cache_mb, "clients": clients, "seconds": round(wall, 1), "requests": len(lat) + len(errors),
            "errors": len(errors), "error_samples": errors[:5], "throughput_rps": round(len(lat) / wall, 2),
            "p50_ms": round(float(pct[0]), 1), "p99_ms": round(float(pct[1]), 1),
            "max_ms": round(max(lat), 1) if lat else None,
            "mean_ms": round(statistics.fmean(lat), 1) if lat else None,
            "rss_start_mb": round(float(rss[0]), 1), "rss_peak_mb": round(float(rss.max()), 1),
            "rss_end_mb": round(float(rss[-1]), 1), "rss_growth_mb": round(float(rss.max() - rss[0]), 1),
            "rss_median_q2_mb": round(float(np.median(rss[q:2 * q])), 1),
            "rss_median_q4_mb": round(float(np.median(rss[3 * q:])), 1),
            "cache_bytes_end": health["cache_bytes"], "cache_hits": health["cache_hits"],
            "cache_misses": health["cache_misses"],
            "rss_series_mb": [[round(t, 1), round(v, 1)] for t, v in series[:: max(1, len(series) // 60)]]}


def leak_check(store: str, views, h: int, w: int, n: int, cache_mb: int, seed: int) -> dict:
    """In-process: ``n`` random requests through ``build_sample`` under tracemalloc (numpy reports
    its buffers to it). Memory still allocated afterwards minus the cache's bytes is what requests
    leave behind — independent of how the C allocator keeps freed memory (which is what RSS sees)."""
    import gc
    import tracemalloc

    from service.app import create_app
    from service.sampling import build_sample
    from service.spec import SampleSpec
    from store import CubeStore

    ctx = create_app(CubeStore.open(store, mode="r"), cache_mb=cache_mb).state.ctx
    rng = random.Random(seed)

    def one() -> None:
        p = random_request(rng, views, h, w)
        p.pop("format", None)
        build_sample(SampleSpec(**p | {"outputs": p.get("outputs", "srgb").split(",")}), ctx)

    for _ in range(min(50, n)):  # warm: CCM fits, imports, lazily built tables
        one()
    ctx.cache.clear()  # cached arrays allocated before tracing would be counted as negative
    gc.collect()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    trace = []
    for i in range(1, n + 1):
        one()
        if i % max(1, n // 6) == 0 or i == n:
            gc.collect()
            cur = tracemalloc.get_traced_memory()[0]
            trace.append([i, round((cur - base - ctx.cache.nbytes) / 2**20, 2)])
    tracemalloc.stop()
    return {"requests": n, "retained_minus_cache_mib": trace, "leak_free": abs(trace[-1][1]) < 1.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clients", type=int, default=8)
    ap.add_argument("--seconds", type=float, default=40.0, help="duration of the cached phase")
    ap.add_argument("--baseline-seconds", type=float, default=40.0,
                    help="duration of the cache-less phase (keep it equal: allocator retention grows with time)")
    ap.add_argument("--max-requests", type=int, default=5000, help="request cap per phase")
    ap.add_argument("--cache-mb", type=int, default=64)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--leak-check", type=int, default=0, metavar="N",
                    help="also run N requests in-process under tracemalloc (see leak_check)")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="OPENBLAS/OMP/MKL_NUM_THREADS for the server (default: the library's own)")
    args = ap.parse_args()
    if not (1 <= args.clients <= 64 and 0 < args.seconds <= 600 and 0 < args.baseline_seconds <= 600
            and args.height >= 16 and args.width >= 16 and args.cache_mb >= 1):
        ap.error("need 1..64 clients, 0 < seconds <= 600, a frame of at least 16x16 and --cache-mb >= 1")
    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "store")
        log(f"building a synthetic {args.width}x{args.height}x63 store …")
        views = build_store(store, args.height, args.width)
        cube_mb = args.height * args.width * 63 * 4 / 2**20
        n_cubes = sum(g for *_, g in views)
        log(f"phase 1: --cache-mb 0, {args.clients} clients, {args.baseline_seconds:g} s")
        base = phase(store, views, args.height, args.width, 0, args.clients, args.baseline_seconds,
                     args.max_requests, args.seed, args.blas_threads)
        log(f"  {base['requests']} requests, {base['errors']} errors, p50 {base['p50_ms']} ms, "
            f"RSS {base['rss_start_mb']} → peak {base['rss_peak_mb']} MiB")
        log(f"phase 2: --cache-mb {args.cache_mb}, {args.clients} clients, {args.seconds:g} s")
        main_ = phase(store, views, args.height, args.width, args.cache_mb, args.clients, args.seconds,
                      args.max_requests, args.seed + 1, args.blas_threads)
        log(f"  {main_['requests']} requests, {main_['errors']} errors, p50 {main_['p50_ms']} ms, "
            f"RSS {main_['rss_start_mb']} → peak {main_['rss_peak_mb']} MiB")
        leak = None
        if args.leak_check:
            log(f"leak check: {args.leak_check} requests in-process under tracemalloc")
            leak = leak_check(store, views, args.height, args.width, args.leak_check, args.cache_mb, args.seed)
            log(f"  retained minus cache: {leak['retained_minus_cache_mib']} MiB")
    transient = base["rss_growth_mb"]
    bound = args.cache_mb + 1.25 * transient + 16
    result = {
        "bench": "load", "frame": [args.width, args.height], "views": len(views),
        "decoded_cube_mb": round(cube_mb, 1), "all_cubes_mb": round(cube_mb * n_cubes, 1),
        "cache_mb": args.cache_mb, "clients": args.clients, "cpus": os.cpu_count(),
        "errors": base["errors"] + main_["errors"], "requests": main_["requests"],
        "p50_ms": main_["p50_ms"], "p99_ms": main_["p99_ms"], "throughput_rps": main_["throughput_rps"],
        "rss_start": main_["rss_start_mb"], "rss_peak": main_["rss_peak_mb"], "rss_end": main_["rss_end_mb"],
        "rss_growth_mb": main_["rss_growth_mb"], "transient_mb_without_cache": transient,
        "rss_bound_mb": round(bound, 1), "rss_growth_within_cache_bound": main_["rss_growth_mb"] <= bound,
        "rss_plateau": main_["rss_median_q4_mb"] - main_["rss_median_q2_mb"] <= 0.1 * bound,
        "blas_threads": args.blas_threads,
        "server_env": {k: os.environ[k] for k in ("OPENBLAS_NUM_THREADS", "MALLOC_ARENA_MAX", "MALLOC_MMAP_THRESHOLD_")
                       if k in os.environ},
        "cache_bytes_within_limit": main_["cache_bytes_end"] <= args.cache_mb * 2**20,
        "leak_check": leak,
        "phases": {"no_cache": base, "cached": main_},
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
