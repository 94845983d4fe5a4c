"""Scale-out benchmark: a Ray cluster rendering into object storage, replicas, a lost node, throughput.

    python bench/cluster.py [--workers 2] [--skip-throughput]

On this machine (scripts/local_cluster.py): moto's S3 server, a Ray head and ``--workers`` worker
nodes as separate ``ray start`` processes on loopback addresses, one CPU each.

1. ``illumix render SCENE --store s3://… --executor ray``: the nodes that ran jobs; the cubes compared
   with a local run of the same seeds (``cubes_identical_to_local``); ``store verify``.
2. The same with a worker node killed (SIGKILL) after the first cube: the run finishes
   (``killed_worker_resumed``), and every cube is published once (``duplicate_cubes``, counted from
   the bucket's object versions).
3. Two ``illumix serve`` replicas on the store: seconds from an upload through one until the other
   lists it (``replica_upload_visible_s``, the worst of 5).
4. Throughput (CPU seconds of the render process and its children, so a shared machine's load does
   not count): the demo room's ``front`` view at 240×180 (3 cubes) and its ceiling group at 720×960
   (1 cube), default settings, one local worker → ``cubes_per_cpu_hour``. ``cubes_per_gpu_hour``:
   measured only where a GPU is present (None otherwise).

Human lines on stderr; one JSON object last on stdout. bench/CLUSTER.md turns it into the cost of a
1,000-room dataset.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "tests"))

from local_cluster import LocalCluster, free_port, scene_file  # noqa: E402

from illumix.store import CubeStore  # noqa: E402


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def render(env: dict, *args: str, timeout: float = 3600) -> dict:
    r = subprocess.run(["illumix", "render", *args, "--json"], env=env, capture_output=True, text=True,
                       timeout=timeout)
    if r.returncode:
        raise SystemExit(f"render failed: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def cubes(store: str, so=None) -> dict:
    st = CubeStore.open(store, mode="r", storage_options=so)
    return {(s, v, g): st.read_cube(s, v, g) for s in st.scenes() for v in st.views(s) for g in st.groups(s, v)}


def cluster_run(c: LocalCluster, scene: str, tmp: Path) -> dict:
    ray = ("--executor", "ray", "--address", c.address, "--spp", "8")
    t0 = time.perf_counter()
    out = render(c.env, scene, "--store", c.url("bench"), *ray)
    say(f"cluster: {len(out['rendered'])} jobs on nodes {out.get('nodes')} in {time.perf_counter() - t0:.1f} s")
    render(c.env, scene, "--store", str(tmp / "local"), "--spp", "8")
    remote, local = cubes(c.url("bench"), c.storage_options()), cubes(str(tmp / "local"))
    same = set(remote) == set(local) and all(np.array_equal(remote[k], local[k]) for k in local)
    ok = subprocess.run(["illumix", "store", "verify", c.url("bench")], env=c.env, capture_output=True).returncode == 0
    return {"nodes_used": out.get("nodes", []), "cubes_compared": len(local), "cubes_identical_to_local": same,
            "verify_ok": ok, "cluster_run_s": round(time.perf_counter() - t0, 1)}


def killed_worker(c: LocalCluster, scene: str) -> dict:
    cmd = ["illumix", "render", scene, "--store", c.url("faults"), "--spp", "8", "--json", "--executor", "ray",
           "--address", c.address]
    run = subprocess.Popen(cmd, env=c.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 600
    while c.complete_cubes("faults") < 1 and time.monotonic() < end and run.poll() is None:
        time.sleep(0.5)
    killed = c.kill_node(c.worker_ips[0])
    say(f"killed worker node {c.worker_ips[0]} ({killed} processes) after {c.complete_cubes('faults')} cube(s)")
    _, err = run.communicate(timeout=1800)
    ok = subprocess.run(["illumix", "store", "verify", c.url("faults")], env=c.env, capture_output=True).returncode == 0
    return {"killed_worker_resumed": run.returncode == 0 and ok, "killed_processes": killed,
            "cubes_after_kill": c.complete_cubes("faults"), "duplicate_cubes": c.duplicate_cubes("faults"),
            "error": None if run.returncode == 0 else err.strip().splitlines()[-1:]}


def replicas(c: LocalCluster) -> dict:
    import httpx
    import synthetic_store

    store = c.url("replicas")
    synthetic_store.build(store, extras=False, storage_options=c.storage_options())
    procs, urls = [], []
    for _ in range(2):
        port = free_port()
        procs.append(subprocess.Popen(["illumix", "serve", "--store", store, "--host", "127.0.0.1", "--port",
                                       str(port), "--token", "t"], env=c.env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, start_new_session=True))
        urls.append(f"http://127.0.0.1:{port}")
    try:
        for u in urls:
            while True:
                try:
                    if httpx.get(f"{u}/health", timeout=2).status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.2)
        csv = "wavelength,r,g,b\n" + "\n".join(f"{w},{0.2 + (w > 560) * 0.6},0.5,{0.2 + (w < 490) * 0.6}"
                                                 for w in range(380, 781, 10))
        waits = []
        for i in range(5):
            r = httpx.post(f"{urls[0]}/sensors", data={"name": f"cam-{i}"}, files={"file": ("c.csv", csv)},
                           headers={"Authorization": "Bearer t"})
            assert r.status_code == 201, r.text
            t0 = time.monotonic()
            while f"cam-{i}" not in httpx.get(f"{urls[1]}/sensors").json()["uploaded"]:
                time.sleep(0.02)
            waits.append(time.monotonic() - t0)
        say(f"replicas: upload visible on the other after {max(waits):.2f} s (worst of 5)")
        return {"replica_upload_visible_s": round(max(waits), 2), "replica_upload_visible_s_all": [round(w, 2) for w in waits]}
    finally:
        for p in procs:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(timeout=30)


def throughput(tmp: Path) -> dict:
    out = {}
    for label, args in (("240x180", ("--resolution", "240x180", "--views", "front")),
                        ("720x960", ("--resolution", "960x720", "--views", "front", "--groups", "ceiling"))):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        res = render(dict(os.environ), "--demo", "--store", str(tmp / f"tp-{label}"), *args)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        n = len([j for j in res["rendered"] if not j.endswith("[view+aovs]")])
        out[label] = {"cubes": n, "cpu_s": round(cpu, 1), "wall_s": round(time.perf_counter() - t0, 1),
                      "cubes_per_cpu_hour": round(3600 * n / cpu, 2)}
        say(f"throughput {label}: {n} cube(s), {cpu:.0f} CPU-s → {out[label]['cubes_per_cpu_hour']} cubes per CPU-hour")
    return out


def gpu_present() -> bool:
    try:
        return subprocess.run(["nvidia-smi", "-L"], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--skip-throughput", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d, LocalCluster(workers=args.workers, versioned=True) as c:
        tmp = Path(d)
        small, bigger = scene_file(tmp, views=2), scene_file(tmp, views=4)
        result = {"nodes": 1 + args.workers, "store_url": c.url("bench"), **cluster_run(c, small, tmp)}
        result |= killed_worker(c, bigger)
        result |= replicas(c)
    tp = None if args.skip_throughput else throughput(Path(tempfile.mkdtemp()))
    result["throughput"] = tp
    result["cubes_per_cpu_hour"] = None if tp is None else {k: v["cubes_per_cpu_hour"] for k, v in tp.items()}
    result["cubes_per_gpu_hour"] = None  # cuda_ad_spectral: measured only where a GPU is present
    result["gpu"] = "present: run bench/render_backends.py on it" if gpu_present() else "no device lent"
    result["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
