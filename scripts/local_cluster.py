"""A real multi-node Ray cluster and an S3-compatible object store on one machine, for the cluster
test and benchmark (tests/test_cluster.py, bench/cluster.py) and for trying illumix's scale-out
layout by hand:

    python scripts/local_cluster.py up [--workers 2]     # prints the environment to export
    python scripts/local_cluster.py down

What it starts, each as its own process (the commands README "Scaling out" gives):

* ``moto_server -H 127.0.0.1 -p PORT`` — moto's standalone S3 server; illumix reaches it with s3fs,
  the same client code as real S3 (``AWS_ENDPOINT_URL`` points botocore at it);
* ``ray start --head --node-ip-address 127.0.0.2 --port PORT`` and, per worker node,
  ``ray start --address 127.0.0.2:PORT --node-ip-address 127.0.0.N`` — separate raylets on loopback
  addresses (Ray would replace 127.0.0.1 by the machine's outward address), token authentication on
  (``RAY_AUTH_MODE=token`` with a fresh ``RAY_AUTH_TOKEN``), one CPU each.

:meth:`LocalCluster.kill_node` kills a worker node with SIGKILL (its raylet and every worker process
on that address), as a lost machine.
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HEAD_IP = "127.0.0.2"
STATE = Path(os.environ.get("ILLUMIX_LOCAL_CLUSTER_STATE", "/tmp/illumix-local-cluster.json"))


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _wait_port(host: str, port: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            socket.create_connection((host, port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"nothing listens at {host}:{port} after {timeout:.0f} s")


class LocalCluster:
    """Start with :meth:`up` (or ``with LocalCluster(...) as c``), stop with :meth:`down`.
    ``env``: what a driver, a service or a ``ray start`` needs (the S3 endpoint and credentials,
    the Ray token); ``address``: the head's ``HOST:PORT``; ``bucket``: an empty bucket."""

    def __init__(self, workers: int = 2, bucket: str = "illumix", cpus_per_node: int = 1,
                 versioned: bool = False) -> None:
        self.n_workers, self.bucket, self.cpus, self.versioned = workers, bucket, cpus_per_node, versioned
        self.s3_port = free_port()
        self.ray_port = free_port(HEAD_IP)
        self.address = f"{HEAD_IP}:{self.ray_port}"
        self.worker_ips = [f"127.0.0.{3 + i}" for i in range(workers)]
        self.env = {**os.environ, "AWS_ACCESS_KEY_ID": "illumix", "AWS_SECRET_ACCESS_KEY": "illumix-secret",
                    "AWS_DEFAULT_REGION": "us-east-1", "AWS_ENDPOINT_URL": f"http://127.0.0.1:{self.s3_port}",
                    "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
                    "RAY_USAGE_STATS_ENABLED": "0"}
        self.moto: subprocess.Popen | None = None

    def __enter__(self) -> LocalCluster:
        return self.up()

    def __exit__(self, *exc) -> None:
        self.down()

    def up(self) -> LocalCluster:
        self.moto = subprocess.Popen(["moto_server", "-H", "127.0.0.1", "-p", str(self.s3_port)], env=self.env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        _wait_port("127.0.0.1", self.s3_port, 60)
        self._ray(["ray", "start", "--head", "--node-ip-address", HEAD_IP, "--port", str(self.ray_port),
                   "--num-cpus", str(self.cpus), "--include-dashboard=false", "--disable-usage-stats"])
        for ip in self.worker_ips:
            self._ray(["ray", "start", "--address", self.address, "--node-ip-address", ip,
                       "--num-cpus", str(self.cpus)])
        self.s3().mkdir(self.bucket)
        if self.versioned:  # every object version kept: how many times each cube was published
            self.boto().put_bucket_versioning(Bucket=self.bucket, VersioningConfiguration={"Status": "Enabled"})
        return self

    def _ray(self, cmd: list[str]) -> None:
        r = subprocess.run(cmd, env=self.env, capture_output=True, text=True, timeout=180)
        if r.returncode:
            tail = (r.stderr or r.stdout).strip().splitlines()[-3:]
            raise RuntimeError(f"{' '.join(cmd[:3])} failed: {' | '.join(tail)}")

    def storage_options(self) -> dict:
        """fsspec ``storage_options`` of the object store (for a process without :attr:`env`)."""
        return {"key": self.env["AWS_ACCESS_KEY_ID"], "secret": self.env["AWS_SECRET_ACCESS_KEY"],
                "endpoint_url": self.env["AWS_ENDPOINT_URL"]}

    def s3(self):
        """An s3fs filesystem on the cluster's object store."""
        import s3fs

        return s3fs.S3FileSystem(skip_instance_cache=True, **self.storage_options())

    def boto(self):
        import boto3

        return boto3.client("s3", endpoint_url=self.env["AWS_ENDPOINT_URL"], region_name="us-east-1",
                            aws_access_key_id=self.env["AWS_ACCESS_KEY_ID"],
                            aws_secret_access_key=self.env["AWS_SECRET_ACCESS_KEY"])

    def url(self, path: str) -> str:
        return f"s3://{self.bucket}/{path}"

    def _cube_documents(self, store: str, versions: bool):
        """``(key, body)`` of every cube node document (every version of it with ``versions``)."""
        c, prefix = self.boto(), f"{store}/scenes/"
        pages = c.get_paginator("list_object_versions" if versions else "list_objects_v2")
        for page in pages.paginate(Bucket=self.bucket, Prefix=prefix):
            for o in page.get("Versions" if versions else "Contents", []):
                parts = o["Key"][len(prefix):].split("/")
                if len(parts) == 5 and parts[2] == "cubes" and parts[4] == "zarr.json":
                    extra = {"VersionId": o["VersionId"]} if versions else {}
                    yield o["Key"], c.get_object(Bucket=self.bucket, Key=o["Key"], **extra)["Body"].read()

    @staticmethod
    def _complete(body: bytes) -> bool:
        try:
            return bool(json.loads(body)["attributes"]["illumix_state"]["complete"])
        except (ValueError, KeyError, TypeError):
            return False

    def complete_cubes(self, store: str) -> int:
        """Cube nodes of the store (its path in the bucket) published complete."""
        return sum(self._complete(body) for _, body in self._cube_documents(store, versions=False))

    def duplicate_cubes(self, store: str) -> int:
        """Cube nodes published complete more than once (from the bucket's object versions: needs
        ``versioned=True``): a cube rendered twice into the store."""
        seen: dict[str, int] = {}
        for key, body in self._cube_documents(store, versions=True):
            seen[key] = seen.get(key, 0) + self._complete(body)
        return sum(n > 1 for n in seen.values())

    def kill_node(self, ip: str) -> int:
        """SIGKILL every process of the node at ``ip`` (raylet, object store, workers): a lost machine.
        Returns how many processes were killed."""
        n = 0
        for pid, cmd in _processes():
            if f"node_ip_address={ip}" in cmd or f"node-ip-address={ip}" in cmd or f"--node-ip-address {ip}" in cmd:
                try:
                    os.kill(pid, signal.SIGKILL)
                    n += 1
                except ProcessLookupError:
                    pass
        return n

    def down(self) -> None:
        """Stop this cluster's processes only (``ray stop`` would stop every Ray on the machine)."""
        marks = (f"{HEAD_IP}:{self.ray_port}", f"gcs_server_port={self.ray_port}")  # this cluster's GCS
        for pid, cmd in _processes():
            if pid != os.getpid() and ("ray" in cmd or "raylet" in cmd) and any(m in cmd for m in marks):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        # `ray start --head` names this cluster the machine's current one (ray.init() with no address
        # would join it); without `ray stop`, forget it here
        current = Path(tempfile.gettempdir()) / "ray" / "ray_current_cluster"
        try:
            if current.read_text().strip() == self.address:
                current.unlink()
        except OSError:
            pass
        if self.moto is not None:
            os.killpg(self.moto.pid, signal.SIGKILL)
            self.moto.wait(timeout=30)
            self.moto = None


def _processes():
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                yield int(p.name), (p / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue


def scene_file(folder: Path, views: int) -> str:
    """A small scene file in ``folder``: a lamp panel and a point light (two light groups) seen from
    ``views`` views of 24×16 pixels — seconds per cube, for exercising the cluster."""
    import numpy as np
    import yaml

    d = {"name": "mini",
         "materials": {"grey": {"kind": "diffuse", "reflectance": {"value": 0.5}},
                       "cc": {"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "sample": "red"}}},
         "shapes": [{"name": "floor", "type": "rectangle", "material": "grey",
                     "transform": {"scale": 2, "rotate": [{"axis": [1, 0, 0], "angle": -90}]}},
                    {"name": "ball", "type": "sphere", "material": "cc", "center": [0, 0.4, 0], "radius": 0.4},
                    {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 5},
                     "transform": {"scale": 0.3, "rotate": [{"axis": [1, 0, 0], "angle": 90}],
                                   "translate": [0, 2, 0]}}],
         "lights": [{"name": "bulb", "type": "point", "group": "bulb", "position": [1, 1, 1], "strength": 2}],
         "views": [{"name": f"v{i}", "origin": [2 * np.cos(i), 1.2, 2 * np.sin(i) + 1], "target": [0, 0.3, 0],
                    "resolution": [24, 16]} for i in range(views)],
         "max_depth": 4}
    d["views"] = [{**v, "origin": [round(float(x), 4) for x in v["origin"]]} for v in d["views"]]
    p = folder / f"mini-{views}.yaml"
    p.write_text(yaml.safe_dump(d))
    return str(p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("action", choices=["up", "down"])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    if args.action == "down":
        if STATE.exists():
            st = json.loads(STATE.read_text())
            subprocess.run(["ray", "stop", "--force"], env={**os.environ, **st["env"]}, capture_output=True)
            try:
                os.killpg(st["moto_pid"], signal.SIGKILL)
            except ProcessLookupError:
                pass
            STATE.unlink()
        return
    c = LocalCluster(workers=args.workers).up()
    keep = {k: c.env[k] for k in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_DEFAULT_REGION",
                                  "AWS_ENDPOINT_URL", "RAY_AUTH_MODE", "RAY_AUTH_TOKEN")}
    STATE.write_text(json.dumps({"env": keep, "moto_pid": c.moto.pid, "address": c.address}))
    for k, v in keep.items():
        print(f"export {k}={v}")
    print(f"# Ray head: {c.address}; bucket: s3://{c.bucket}; stop with: python {sys.argv[0]} down")


if __name__ == "__main__":
    main()
