"""Pieces of ``bench/feed.py``: the benchmark store, the disk baseline, servers and timers.

The disk baseline is what an ML engineer would otherwise do: precompute the very samples the feed
serves (256² raw + gain), write raw as a 16-bit PNG (normalised by its maximum, as the dataset's
``raw_norm="max"``) and gain as a float32 ``.npy``, and read them back in a map-style ``Dataset``
with cv2/numpy into the same tensors.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from server_lib import free_port, wait_healthy

ROOT = Path(__file__).resolve().parents[1]
SENSOR_DIR = ROOT.parent / "shared" / "data" / "rawtoaces-data" / "data" / "camera"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def sensor_name() -> str:
    """The issue's camera (Nikon D810, from rawtoaces' data) when ../shared has it."""
    if (SENSOR_DIR / "Nikon_D810_380_780_5.json").is_file():
        os.environ["ILLUMIX_SENSOR_PATH"] = str(SENSOR_DIR)
        return "Nikon_D810"
    return "Nikon 5100 (NPL)"


def build_store(path: str, height: int, width: int, views: int = 3) -> int:
    """A store of ``views`` views × 2 flat-emission groups of synthetic render-like cubes
    (:func:`store.synth.synthetic_cube`, 5 % noise). Returns the decoded bytes of all cubes."""
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.store import CubeMeta, CubeStore, ViewMeta
    from illumix.store.synth import synthetic_cube

    st = CubeStore.open(path, mode="a")
    n = DEFAULT_GRID.n_bands
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"}, spp=0, seed=0,
                  scene_hash="synthetic")
    for v in range(views):
        st.write_view("room", f"v{v}", ViewMeta(width=width, height=height, fov=45.0))
        for g, name in enumerate(("window", "lamp")):
            cube = synthetic_cube(height, width, seed=10 * v + g, noise=0.05)
            st.write_cube("room", f"v{v}", name, cube, CubeMeta(emission=[1.0] * n, emission_name="flat", **common))
    return views * 2 * height * width * n * 4


# -- the disk baseline ---------------------------------------------------------------------------
def write_disk(samples, folder: Path, start: int = 0) -> None:
    """``i.png`` (16-bit raw / max) and ``i.npy`` (float32 gain) per sample, numbered from ``start``."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    for i, s in enumerate(samples, start):
        raw = np.asarray(s.raw, np.float32)
        peak = float(raw.max()) or 1.0
        png = np.round(np.clip(raw / peak, 0, 1) * 65535).astype(np.uint16)[..., ::-1]
        cv2.imwrite(str(folder / f"{i}.png"), np.ascontiguousarray(png))
        np.save(folder / f"{i}.npy", np.asarray(s.gain, np.float32))


def disk_dataset(folder: Path, n: int):
    import cv2
    import torch
    from torch.utils.data import Dataset

    class DiskDataset(Dataset):
        def __len__(self) -> int:
            return n

        def __getitem__(self, i: int) -> dict:
            raw = cv2.imread(str(folder / f"{i}.png"), cv2.IMREAD_UNCHANGED)[..., ::-1]
            raw = np.ascontiguousarray(raw.transpose(2, 0, 1), dtype=np.float32) / np.float32(65535)
            gain = np.load(folder / f"{i}.npy").transpose(2, 0, 1)
            return {"raw": torch.from_numpy(raw), "gain": torch.from_numpy(np.ascontiguousarray(gain)),
                    "index": i}

    return DiskDataset()


def read_one(folder: Path, i: int) -> None:
    import cv2

    cv2.imread(str(folder / f"{i}.png"), cv2.IMREAD_UNCHANGED)
    np.load(folder / f"{i}.npy")


# -- timing --------------------------------------------------------------------------------------
def feed_rate(dataset, workers: int, batch: int, epochs: int, set_epoch=None, persistent: bool = False) -> float:
    """Samples per second through a DataLoader (best of ``epochs`` epochs after one unmeasured);
    ``persistent``: one DataLoader whose workers live across epochs (``persistent_workers=True``),
    else fresh workers each epoch."""
    from torch.utils.data import DataLoader

    def loader():
        return DataLoader(dataset, batch_size=batch, num_workers=workers, shuffle=False,
                          persistent_workers=persistent and workers > 0)

    rates, kept = [], loader()
    for e in range(epochs + 1):
        if set_epoch is not None:
            set_epoch(e)
        it = kept if persistent else loader()
        t, n = time.perf_counter(), 0
        for b in it:
            n += len(b["index"])
        if e:
            rates.append(n / (time.perf_counter() - t))
    return max(rates)


def epoch_seconds(dataset, batch: int, epoch: int) -> float:
    from torch.utils.data import DataLoader

    dataset.set_epoch(epoch)
    t = time.perf_counter()
    for _ in DataLoader(dataset, batch_size=batch, num_workers=0):
        pass
    return time.perf_counter() - t


def p50_ms(fn, n: int) -> float:
    times = []
    for i in range(n):
        t = time.perf_counter()
        fn(i)
        times.append(1e3 * (time.perf_counter() - t))
    return statistics.median(times)


# -- a service in a subprocess -------------------------------------------------------------------


class Server:
    """``illumix serve`` on 127.0.0.1 in a subprocess (stopped on exit)."""

    def __init__(self, store: str, cache_mb: int, projection_mb: int, *extra: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        cmd = [sys.executable, "-m", "illumix.cli", "serve", "--store", store, "--host", "127.0.0.1",
               "--port", str(self.port), "--cache-mb", str(cache_mb), "--projection-cache-mb", str(projection_mb),
               "--max-request-mb", "512", "--inflight-mb", "1024", *extra]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.started = time.perf_counter()

    def __enter__(self) -> Server:
        wait_healthy(self.url, self.proc, timeout=120, what="bench/feed.py: the server")
        self.ready_s = time.perf_counter() - self.started
        return self

    def __exit__(self, *exc) -> None:
        self.proc.terminate()
        self.proc.wait(timeout=30)

    def rss_mb(self) -> tuple[float, float]:
        """(current, peak) resident memory of the server process, MiB."""
        fields = {}
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            k, _, v = line.partition(":")
            fields[k] = v.strip()
        return int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024

    def health(self) -> dict:
        import httpx

        return httpx.get(f"{self.url}/health", timeout=10).json()


def hit_ratio(before: dict, after: dict) -> tuple[float, dict]:
    """Share of group reads served from memory (a cached projection or decoded cube) between two
    ``/health`` answers: ``(cube hits + projection hits) / (cube reads + projection hits)``."""
    d = {k: after["cache"][k] - before["cache"][k] for k in ("hits", "misses")}
    pa, pb = after.get("projections") or {}, before.get("projections") or {}
    d["projection_hits"] = pa.get("hits", 0) - pb.get("hits", 0)
    d["projection_misses"] = pa.get("misses", 0) - pb.get("misses", 0)
    served = d["hits"] + d["projection_hits"]
    total = served + d["misses"]
    return (served / total if total else float("nan")), d
