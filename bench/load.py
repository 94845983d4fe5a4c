"""Load test of the running service on loopback: errors, refusals, latency, resident memory.

Builds a synthetic store (tests/synthetic_store.py's two-group view plus three more two-group views
and a one-group view, ``--height``×``--width``×63, float16 policy), runs ``illumix serve
--cache-mb N`` on 127.0.0.1 in a subprocess and sends it, from ``--clients`` threads for
``--seconds`` (bounded by ``--max-requests``), a mix of valid requests:

- ``GET /sample``: random view, illuminant pair (spiky ones included), sensor, full frame or a
  random crop, sometimes a ``size=`` up to 2048², a random subset of outputs, sometimes PNG;
- large ones (``--large-share``): all outputs at up to 4096² — refused with 413 and a hint when
  their priced working memory exceeds ``--max-request-mb``;
- ``POST /batch`` of 2–8 such samples (``--batch-share``);
- ``/health``, ``/scenes``, ``/sensors``.

Outcomes: 200; 413 ``too_large`` (a correct refusal); 503 ``busy`` (the in-flight memory budget was
full for the queue timeout: the client is told to retry); anything else — another 4xx, a 5xx, a
transport error, a NaN/inf in a JSON answer — is an error and must be 0.

Resident memory: ``VmRSS`` of the server process from ``/proc/<pid>/status`` every 0.25 s; the goal
(issue 13) is ``rss_peak ≤ N + 300 MiB`` (``rss_within_bound``). The server's own figures from
``/health`` (cache bytes and hits, peak in-flight reservation, 503s) are reported beside it.

``--leak-check N`` adds an in-process check that requests leave nothing allocated behind
(tracemalloc, numpy buffers included): RSS alone cannot tell a leak from allocator retention.

Usage: python bench/load.py [--clients 16 --seconds 60 --cache-mb 256] [--leak-check 600];
progress on stderr; JSON last on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from server_lib import free_port, wait_healthy  # bench/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

PAIRS = ["A,D65", "FL11,D65", "FL2,A", "LED-RGB1,D50", "daylight:5000,blackbody:2700", "D65,LED-B3", "FL11,A"]
SENSORS = ["XYZ", "Nikon 5100 (NPL)"]
OUTPUTS = ["raw", "gain", "ccm", "srgb", "weights", "mask"]


def log(msg: str) -> None:
    print(f"[bench/load] {msg}", file=sys.stderr, flush=True)




def build_store(path: str, h: int, w: int) -> list[tuple[str, str, int]]:
    """The synthetic store; returns ``(scene, view, n_groups)`` of every view."""
    import synthetic_store as synth

    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.store import CubeMeta, CubeStore, ViewMeta

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


def random_request(rng: random.Random, views, h: int, w: int, large: bool = False) -> dict:
    """One valid sample spec (query form); ``large``: all outputs at up to 4096²."""
    scene, view, groups = rng.choice(views)
    pair = rng.choice(PAIRS)
    p = {"scene": scene, "view": view, "sensor": rng.choice(SENSORS), "seed": rng.randrange(1 << 30)}
    if groups == 2:
        p["pair"] = pair
    else:
        p["illuminants"] = pair.split(",")[0]
    if large:
        side = rng.choice([1024, 2048, 3072, 4096])
        p.update(size=f"{side}x{side * 3 // 4}", outputs=",".join(OUTPUTS + ["meta"]))
        return p
    if rng.random() < 0.5:
        cw, ch = rng.randint(16, w), rng.randint(16, h)
        p["crop"] = f"{rng.randint(0, w - cw)},{rng.randint(0, h - ch)},{cw},{ch}"
    if rng.random() < 0.2:
        p["size"] = f"{rng.randint(8, 2048)}x{rng.randint(8, 1536)}"
    if rng.random() < 0.1:
        p.update(format="png", outputs="srgb")
    else:
        outs = rng.sample(OUTPUTS, rng.randint(1, len(OUTPUTS)))
        p["outputs"] = ",".join(outs + (["meta"] if rng.random() < 0.5 else []))
    return p


def random_call(rng: random.Random, views, h: int, w: int, large_share: float, batch_share: float
                ) -> tuple[str, str, dict]:
    """``(method, path, kwargs)`` of one request of the mix (see the module docstring)."""
    u = rng.random()
    if u < large_share:
        return "GET", "/sample", {"params": random_request(rng, views, h, w, large=True)}
    if u < large_share + batch_share:
        items = []
        for _ in range(rng.randint(2, 8)):
            item = random_request(rng, views, h, w)
            item.pop("format", None)
            items.append(item)
        return "POST", "/batch", {"json": {"samples": items}}
    if u < large_share + batch_share + 0.05:
        return "GET", rng.choice(["/health", "/scenes", "/sensors", "/illuminants"]), {}
    return "GET", "/sample", {"params": random_request(rng, views, h, w)}


def classify(r) -> str:
    """``ok``, ``refused_413``, ``busy_503`` or ``error``."""
    if r.status_code == 200:
        if r.headers.get("content-type", "").startswith("application/json"):
            json.loads(r.content, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        return "ok"
    code = r.json().get("code") if r.headers.get("content-type", "").startswith("application/json") else None
    if r.status_code == 413 and code == "too_large":
        return "refused_413"
    if r.status_code == 503 and code == "busy" and r.headers.get("retry-after"):
        return "busy_503"
    return "error"


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


def phase(store: str, views, h: int, w: int, args) -> dict:
    """Start a server, load it, stop it; outcomes, latency and the RSS series."""
    import httpx

    port = free_port()
    url = f"http://127.0.0.1:{port}"
    errlog = tempfile.TemporaryFile()  # uvicorn logs every request: a pipe nobody reads would block it
    cmd = [sys.executable, "-m", "illumix.cli", "serve", "--store", store, "--host", "127.0.0.1",
           "--port", str(port), "--cache-mb", str(args.cache_mb)]
    for flag in ("max_request_mb", "inflight_mb", "projection_cache_mb"):
        if getattr(args, flag) is not None:
            cmd += [f"--{flag.replace('_', '-')}", str(getattr(args, flag))]
    env = server_env(args.blas_threads) | ({"ILLUMIX_MALLOC_TUNING": "off"} if args.glibc_malloc else {})
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=errlog, cwd=ROOT, env=env)
    try:
        wait_healthy(url, proc, what="bench/load.py: the server", log=errlog)
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
        outcomes = {"ok": 0, "refused_413": 0, "busy_503": 0, "error": 0}
        errors: list[str] = []
        lock = threading.Lock()
        counter = iter(range(args.max_requests))
        end = t0 + args.seconds

        def client(i: int) -> None:
            rng = random.Random(args.seed * 1000 + i)
            with httpx.Client(timeout=120) as c:
                while time.monotonic() < end:
                    with lock:
                        if next(counter, None) is None:
                            return
                    method, path, kw = random_call(rng, views, h, w, args.large_share, args.batch_share)
                    t = time.perf_counter()
                    try:
                        r = c.request(method, f"{url}{path}", **kw)
                        kind, msg = classify(r), f"{r.status_code} {r.text[:200]} {method} {path} {kw}"
                    except (httpx.HTTPError, ValueError) as exc:
                        kind, msg = "error", f"{type(exc).__name__}: {exc} {method} {path}"
                    dt = 1e3 * (time.perf_counter() - t)
                    with lock:
                        outcomes[kind] += 1
                        if kind == "ok":
                            lat.append(dt)
                        elif kind == "error":
                            errors.append(msg[:600])

        sampler = threading.Thread(target=sample_rss, daemon=True)
        sampler.start()
        threads = [threading.Thread(target=client, args=(i,)) for i in range(args.clients)]
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
    pct = np.percentile(lat, [50, 99]) if lat else [float("nan")] * 2
    return {"seconds": round(wall, 1), "requests": sum(outcomes.values()), "outcomes": outcomes,
            "error_samples": errors[:5], "throughput_rps": round(len(lat) / wall, 2),
            "p50_ms": round(float(pct[0]), 1), "p99_ms": round(float(pct[1]), 1),
            "max_ms": round(max(lat), 1) if lat else None,
            "mean_ms": round(statistics.fmean(lat), 1) if lat else None,
            "rss_start_mb": round(float(rss[0]), 1), "rss_peak_mb": round(float(rss.max()), 1),
            "rss_end_mb": round(float(rss[-1]), 1), "health": health,
            "rss_series_mb": [[round(t, 1), round(v, 1)] for t, v in series[:: max(1, len(series) // 60)]]}


def leak_check(store: str, views, h: int, w: int, n: int, cache_mb: int, seed: int) -> dict:
    """In-process: ``n`` random requests through ``build_sample`` under tracemalloc (numpy reports
    its buffers to it). Memory still allocated afterwards minus the cache's bytes is what requests
    leave behind — independent of how the C allocator keeps freed memory (which is what RSS sees)."""
    import gc
    import tracemalloc

    from illumix.service.app import create_app
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

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
            trace.append([i, round((cur - base - ctx.cache.total_cost) / 2**20, 2)])
    tracemalloc.stop()
    return {"requests": n, "retained_minus_cache_mib": trace, "leak_free": abs(trace[-1][1]) < 1.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--max-requests", type=int, default=20000, help="request cap")
    ap.add_argument("--cache-mb", type=int, default=256)
    ap.add_argument("--rss-margin-mb", type=int, default=300, help="the goal: RSS <= the cube and projection caches + this")
    ap.add_argument("--max-request-mb", type=int, default=None, help="illumix serve's flag (default: its own)")
    ap.add_argument("--inflight-mb", type=int, default=None, help="illumix serve's flag (default: its own)")
    ap.add_argument("--projection-cache-mb", type=int, default=None, help="illumix serve's flag (default: its own)")
    ap.add_argument("--large-share", type=float, default=0.1, help="share of all-output requests up to 4096²")
    ap.add_argument("--batch-share", type=float, default=0.2, help="share of POST /batch requests")
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--leak-check", type=int, default=0, metavar="N",
                    help="also run N requests in-process under tracemalloc (see leak_check)")
    ap.add_argument("--glibc-malloc", action="store_true",
                    help="leave glibc's allocator defaults in the server (ILLUMIX_MALLOC_TUNING=off), to compare")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="OPENBLAS/OMP/MKL_NUM_THREADS for the server (default: illumix serve's own, 1)")
    args = ap.parse_args()
    if not (1 <= args.clients <= 64 and 0 < args.seconds <= 600 and args.height >= 16 and args.width >= 16
            and args.cache_mb >= 0 and 0 <= args.large_share + args.batch_share <= 0.95):
        ap.error("need 1..64 clients, 0 < seconds <= 600, a frame of at least 16x16, --cache-mb >= 0 and "
                 "large + batch shares <= 0.95")
    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "store")
        log(f"building a synthetic {args.width}x{args.height}x63 store …")
        views = build_store(store, args.height, args.width)
        cube_mb = args.height * args.width * 63 * 4 / 2**20
        n_cubes = sum(g for *_, g in views)
        log(f"--cache-mb {args.cache_mb}, {args.clients} clients, {args.seconds:g} s")
        run = phase(store, views, args.height, args.width, args)
        log(f"  {run['requests']} requests {run['outcomes']}, p50 {run['p50_ms']} ms, "
            f"RSS {run['rss_start_mb']} → peak {run['rss_peak_mb']} MiB")
        leak = None
        if args.leak_check:
            log(f"leak check: {args.leak_check} requests in-process under tracemalloc")
            leak = leak_check(store, views, args.height, args.width, args.leak_check, args.cache_mb, args.seed)
            log(f"  retained minus cache: {leak['retained_minus_cache_mib']} MiB")
    from illumix.engine.projections import projection_share

    # the projection cache is budgeted in addition to the cube cache (its default: projection_share)
    proj_mb = args.projection_cache_mb if args.projection_cache_mb is not None else projection_share(args.cache_mb)
    bound = args.cache_mb + proj_mb + args.rss_margin_mb
    mem = run["health"]["memory"]
    result = {
        "bench": "load", "frame": [args.width, args.height], "views": len(views),
        "decoded_cube_mb": round(cube_mb, 1), "all_cubes_mb": round(cube_mb * n_cubes, 1),
        "cache_mb": args.cache_mb, "projection_cache_mb": proj_mb, "clients": args.clients, "seconds": run["seconds"], "cpus": os.cpu_count(),
        "requests": run["requests"], "outcomes": run["outcomes"], "errors": run["outcomes"]["error"],
        "error_samples": run["error_samples"],
        "p50_ms": run["p50_ms"], "p99_ms": run["p99_ms"], "throughput_rps": run["throughput_rps"],
        "rss_start_mb": run["rss_start_mb"], "rss_peak_mb": run["rss_peak_mb"], "rss_end_mb": run["rss_end_mb"],
        "rss_bound_mb": bound, "rss_within_bound": run["rss_peak_mb"] <= bound,
        "rss_peak_over_cache_mb": round(run["rss_peak_mb"] - args.cache_mb - proj_mb, 1),
        "cache_bytes_end": run["health"]["cache"]["bytes"], "cache_hits": run["health"]["cache"]["hits"],
        "cache_misses": run["health"]["cache"]["misses"],
        "inflight_peak_mb": round(mem["peak_inflight_bytes"] / 2**20, 1),
        "inflight_limit_mb": round(mem["inflight_limit_bytes"] / 2**20, 1),
        "request_limit_mb": round(mem["request_limit_bytes"] / 2**20, 1),
        "blas_threads": args.blas_threads, "allocator": "glibc defaults" if args.glibc_malloc else "illumix serve's",
        "server_env": {k: os.environ[k] for k in ("OPENBLAS_NUM_THREADS", "MALLOC_ARENA_MAX", "MALLOC_MMAP_THRESHOLD_")
                       if k in os.environ},
        "leak_check": leak,
        "rss_series_mb": run["rss_series_mb"],
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
