"""Bigger than one machine (issue 37), for real on one machine: a Ray head and two worker nodes as
separate ``ray start`` processes on loopback addresses, moto's standalone S3 server reached with s3fs
(the same client code as real S3), ``illumix render … --store s3://… --executor ray``
(scripts/local_cluster.py starts it all; README "Scaling out" gives the same commands).

* the cubes the cluster writes into object storage equal a local run's (same seeds), and verify;
* a worker node killed with SIGKILL mid-run: the run finishes, every cube is published exactly once
  (counted from the bucket's object versions), ``store verify`` is clean; a killed driver: the rerun
  resumes and renders only what is missing;
* an object store refusing writes for a while: the write is retried with backoff; refusing for good:
  one line naming what, after the documented attempts.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray", reason="the test extra installs Ray")
pytest.importorskip("s3fs", reason="the test extra installs s3fs")
if shutil.which("moto_server") is None:
    pytest.skip("the test extra installs moto[server]", allow_module_level=True)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from local_cluster import LocalCluster, scene_file  # noqa: E402

from illumix.store import CubeStore, StoreError  # noqa: E402

GROUPS = ("lamp", "bulb")


RENDER = ("--spp", "4", "--json")


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(workers=2, versioned=True) as c:
        yield c


def render(cluster, scene: str, store: str, *extra: str, timeout: float = 600) -> dict:
    r = subprocess.run(["illumix", "render", scene, "--store", store, *RENDER, *extra], env=cluster.env,
                       capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def cubes(store: str, storage_options=None) -> dict:
    st = CubeStore.open(store, mode="r", storage_options=storage_options)
    return {(v, g): st.read_cube("mini", v, g) for v in st.views("mini") for g in st.groups("mini", v)}


def test_three_nodes_render_into_s3_what_one_machine_renders(cluster, tmp_path):
    scene = scene_file(tmp_path, views=2)
    out = render(cluster, scene, cluster.url("same"), "--executor", "ray", "--address", cluster.address)
    assert len(out["nodes"]) >= 2, out  # the jobs ran on more than one node
    local = str(tmp_path / "local")
    render(cluster, scene, local)
    remote = cubes(cluster.url("same"), cluster.storage_options())
    here = cubes(local)
    assert set(remote) == set(here) == {(f"v{i}", g) for i in range(2) for g in GROUPS}
    for key, cube in here.items():
        np.testing.assert_array_equal(remote[key], cube, err_msg=str(key))
    r = subprocess.run(["illumix", "store", "verify", cluster.url("same")], env=cluster.env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and "OK" in r.stdout, r.stdout + r.stderr
    assert cluster.duplicate_cubes("same") == 0


def _wait_for_cubes(cluster, store: str, n: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cluster.complete_cubes(store) >= n:
            return
        time.sleep(0.5)
    raise AssertionError(f"fewer than {n} cubes in {store} after {timeout:.0f} s")


def test_a_lost_worker_node_and_a_killed_driver(cluster, tmp_path):
    scene = scene_file(tmp_path, views=4)
    cmd = ["illumix", "render", scene, "--store", cluster.url("faults"), *RENDER, "--executor", "ray",
           "--address", cluster.address]
    # a worker node lost mid-run: its tasks run again on the others
    run = subprocess.Popen(cmd, env=cluster.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_cubes(cluster, "faults", 1, 300)
    assert cluster.kill_node(cluster.worker_ips[0]) > 0
    out, err = run.communicate(timeout=600)
    assert run.returncode == 0, err[-2000:]
    assert cluster.complete_cubes("faults") == 8 and cluster.duplicate_cubes("faults") == 0
    # the driver killed mid-run: the rerun renders only what is missing
    st = CubeStore.open(cluster.url("faults"), mode="a", storage_options=cluster.storage_options())
    for v in ("v2", "v3"):
        st.delete("mini", v)
    run = subprocess.Popen(cmd, env=cluster.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           start_new_session=True)
    _wait_for_cubes(cluster, "faults", 5, 300)
    run.send_signal(signal.SIGKILL)
    run.wait(timeout=60)
    again = render(cluster, scene, cluster.url("faults"), "--executor", "ray", "--address", cluster.address)
    assert again["already_complete"] >= 5 and len(again["rendered"]) <= 5, again
    assert cluster.complete_cubes("faults") == 8
    r = subprocess.run(["illumix", "store", "verify", cluster.url("faults")], env=cluster.env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr


def test_refused_writes_are_retried_with_backoff_then_one_line(cluster, monkeypatch):
    from illumix.store import remote

    st = CubeStore.open(cluster.url("flaky"), mode="a", storage_options=cluster.storage_options())
    from store_testutil import add_view, cube, meta

    add_view(st)
    waits: list[float] = []
    monkeypatch.setattr(remote, "RETRY_DELAYS_S", (0.01, 0.02, 0.04))
    monkeypatch.setattr(remote, "_sleep", lambda s: waits.append(s))
    real = st.backend.fs.pipe_file
    refusals = {"left": 2}

    def flaky(path, data, **kw):
        if refusals["left"] > 0:
            refusals["left"] -= 1
            raise OSError(503, "SlowDown: please reduce your request rate")
        return real(path, data, **kw)

    monkeypatch.setattr(st.backend.fs, "pipe_file", flaky)
    st.write_cube("s", "v", "g", cube(), meta(emission_name="flat"))
    assert waits == [0.01, 0.02] and st.is_complete("s", "v", "g")
    refusals["left"] = 10**6
    with pytest.raises(StoreError, match=r"refused to write cube s/v/g2 for 0 s \(4 attempts; .*SlowDown.*resumes"):
        st.write_cube("s", "v", "g2", cube(), meta(emission_name="flat"))


def _serve(cluster, store: str, token: str):
    from server_testutil import free_port

    port = free_port()
    proc = subprocess.Popen(["illumix", "serve", "--store", store, "--host", "127.0.0.1", "--port", str(port),
                             "--token", token, "--cache-mb", "64"], env=cluster.env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    return proc, f"http://127.0.0.1:{port}"


def _until(check, timeout: float) -> float:
    """Seconds until ``check()`` holds (polled every 50 ms); fails after ``timeout``."""
    t0 = time.monotonic()
    while not check():
        assert time.monotonic() - t0 < timeout, f"not within {timeout} s"
        time.sleep(0.05)
    return time.monotonic() - t0


def test_two_stateless_replicas_on_one_bucket(cluster):
    """Two `illumix serve` processes on the same s3:// store, sharing nothing but the bucket: an
    upload through one is served by the other within the listing delay (store.remote.LISTING_TTL_S),
    a cube written later appears without a restart, and a replaced cube is never served from a cache."""
    import httpx
    import synthetic_store

    from illumix.store import remote

    store = cluster.url("replicas")
    synthetic_store.build(store, extras=False, storage_options=cluster.storage_options())
    (a, url_a), (b, url_b) = _serve(cluster, store, "tok"), _serve(cluster, store, "tok")
    try:
        for url in (url_a, url_b):
            _until(lambda u=url: _ok(httpx, f"{u}/health"), 120)
        csv = "wavelength,r,g,b\n" + "\n".join(f"{w},{0.2 + (w > 560) * 0.6},{0.5},{0.2 + (w < 490) * 0.6}"
                                                 for w in range(380, 781, 10))
        r = httpx.post(f"{url_a}/sensors", data={"name": "cam-a"}, files={"file": ("cam.csv", csv)},
                       headers={"Authorization": "Bearer tok"})
        assert r.status_code == 201, r.text
        seen = _until(lambda: "cam-a" in httpx.get(f"{url_b}/sensors").json()["uploaded"], 30)
        assert seen <= remote.LISTING_TTL_S + 5
        q = {"scene": "synth", "view": "v0", "pair": "D65,D65", "outputs": "raw", "seed": 1, "sensor": "cam-a"}
        first = httpx.get(f"{url_b}/sample", params=q)
        assert first.status_code == 200, first.text
        # a cube replaced on one machine: the other replica serves the new one, not its cached copy
        st = CubeStore.open(store, mode="a", storage_options=cluster.storage_options())
        meta = st.cube_meta("synth", "v0", "window")
        old = st.read_cube("synth", "v0", "window", kind="transport")
        st.write_cube("synth", "v0", "window", old * 2, meta.model_copy(update={"stats": None, "storage": None}),
                      overwrite=True)
        second = httpx.get(f"{url_b}/sample", params=q)
        assert second.status_code == 200 and second.content != first.content
        # a view written later appears without a restart
        st.write_view("synth", "late", st.view_meta("synth", "v0"))
        _until(lambda: "late" in [v["name"] for s in httpx.get(f"{url_a}/scenes").json()["scenes"]
                                  for v in s["views"]], 30)
    finally:
        for p in (a, b):
            p.send_signal(signal.SIGTERM)
            p.wait(timeout=30)


def _ok(httpx, url: str) -> bool:
    try:
        return httpx.get(url, timeout=2).status_code == 200
    except httpx.HTTPError:
        return False
