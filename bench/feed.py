"""Benchmark: the training feed against reading the same samples from disk (issue 19).

Builds a 720×960 store (3 views × 2 light groups, synthetic render-like cubes) in a temporary
folder and measures, in one run, on the same machine:

- ``IllumixDataset`` → DataLoader, 256² raw+gain crops, samples/s at ``num_workers`` 0 and 2
  (epochs of ``--feed-epoch`` samples, best of 2 after one unmeasured; at 2 workers both with
  ``persistent_workers=True`` — ``feed_ratio_vs_disk``, the worse of 0 and 2 workers for the better
  of the two modes — and with fresh workers each epoch — ``feed_ratio_vs_disk_fresh_workers``), over
  HTTP (``illumix serve``) and in the local mode (composed in-process), against a disk baseline:
  the same samples precomputed as 16-bit PNG raw + float32 ``.npy`` gain, read with cv2/numpy;
- ``/sample`` latency p50: a 256² crop raw+gain (against reading one sample's two files), the full
  frame raw+gain and all outputs, over HTTP through ``Client.sample`` (request + arrays decoded; the
  crop also with ``wire_format="npz"``, ``/sample``'s own default) and in-process (compose + encode);
- a cold epoch on a fresh server (no ``--warm``) over a warm one, the cache hit ratio of that
  random-crop epoch, and the server's peak RSS over its cache settings (``--cache-mb`` +
  ``--projection-cache-mb``);
- accuracy: a served full frame against a float64 composition of the stored cubes (gain angular
  error, raw p99 relative error), with ``bench/pareto.py``'s tolerances (0.05°, 1e-3).

Usage: ``python bench/feed.py [--epoch 256] [--feed-epoch 1024] [--height 720 --width 960]``; progress on stderr,
JSON last on stdout. Record the results in ``bench/PERFORMANCE.md``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench"), str(ROOT / "clients" / "python")]

import feed_lib as fl
import numpy as np

CACHE_MB, PROJECTION_MB = 1024, 256  # the 996 MiB of cubes fit; projections in addition


def dataset_args(sensor: str, n: int, crop: int, batch: int) -> dict:
    return dict(scenes=None, illuminants=["A", "D65"], sensors=[sensor], crop=(crop, crop), outputs=("raw", "gain"),
                epoch_length=n, batch_size=batch, prefetch=2, seed=1, intensity_range=(0.25, 1.0),
                auto_epoch=True)  # persistent workers follow set_epoch


def in_process(store: str, sensor: str, repeats: int) -> dict:
    """Server-side ms (compose + npz encode), warm caches: min over ``repeats``."""
    from illumix.service.app import create_app
    from illumix.service.encoding import encode_npz
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    ctx = create_app(CubeStore.open(store, mode="r"), cache_mb=CACHE_MB, projection_mb=PROJECTION_MB).state.ctx
    base = dict(scene="room", view="v0", sensor=sensor, pair="A,D65")
    cases = {"crop_raw_gain": dict(crop="300,200,256,256", outputs="raw,gain"),
             "full_raw_gain": dict(outputs="raw,gain"), "full_all": dict(outputs="raw,gain,srgb,weights,mask,illum,mixture,meta"),
             "full_all_with_ccm": dict(outputs="raw,gain,ccm,srgb,weights,mask,illum,mixture,meta")}
    out = {}
    for name, kw in cases.items():
        spec = SampleSpec(**(base | kw))
        for _ in range(2):
            build_sample(spec, ctx)  # decode, project
        compose, encode = [], []
        for _ in range(repeats):
            t = time.perf_counter()
            arrays, meta = build_sample(spec, ctx)
            t1 = time.perf_counter()
            encode_npz(arrays, meta)
            compose.append(1e3 * (t1 - t))
            encode.append(1e3 * (time.perf_counter() - t1))
        out[name] = {"compose_ms": round(min(compose), 2), "encode_npz_ms": round(min(encode), 2),
                     "total_ms": round(min(c + e for c, e in zip(compose, encode)), 2)}
    return out


def client_p50(url: str, specs: list[dict], n: int, wire_format: str = "arrays",
               between: Callable[[int], None] | None = None) -> tuple[float, float | None]:
    """p50 ms of ``Client.sample`` over HTTP: the request and its arrays decoded, as a user of the
    client gets them (the disk baseline decodes its PNG and ``.npy`` too). ``between(i)``, timed
    too, runs after each request — the disk read it is compared with, interleaved so that a change
    in the machine's load moves both alike. Returns ``(client p50, between p50 or None)``."""
    from illumix_client import Client

    with Client(url, wire_format=wire_format, timeout=120) as c:
        c.sample(**specs[0])
        ours, theirs = [], []
        for i in range(n):
            t = time.perf_counter()
            s = c.sample(**specs[i % len(specs)])
            ours.append(1e3 * (time.perf_counter() - t))
            assert s.raw is not None and s.gain is not None
            if between is not None:
                t = time.perf_counter()
                between(i)
                theirs.append(1e3 * (time.perf_counter() - t))
    return statistics.median(ours), (statistics.median(theirs) if theirs else None)


def accuracy(url: str, store: str, sensor: str) -> dict:
    """A served full frame (A on group 0 at 1, D65 on group 1 at 0.5) against float64 from the cubes."""
    import httpx

    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor
    from illumix.store import CubeStore

    r = httpx.get(f"{url}/sample", params=dict(scene="room", view="v1", sensor=sensor, pair="A,D65",
                                               intensities="1,0.5", outputs="raw,gain,mask"), timeout=120)
    z = np.load(io.BytesIO(r.content))
    st = CubeStore.open(store, mode="r")
    w = get_sensor(sensor).weights()
    raws = []
    for g, ill, a in (("window", "A", 1.0), ("lamp", "D65", 0.5)):
        cube = st.read_cube("room", "v1", g).astype(np.float64)
        raws.append(a * (cube @ (illuminant_spd(ill)[:, None] * w)))
    raw = raws[0] + raws[1]
    wps = [illuminant_spd(i) @ w for i in ("A", "D65")]
    wps = [x / x[1] for x in wps]
    share = raws[0][..., 1] / (raws[0][..., 1] + raws[1][..., 1])
    white = share[..., None] * wps[0] + (1 - share[..., None]) * wps[1]
    gain = white.max(-1, keepdims=True) / white
    m = z["mask"]
    cos = (z["gain"].astype(np.float64) * gain).sum(-1) / np.linalg.norm(z["gain"], axis=-1) / np.linalg.norm(gain, axis=-1)
    ang = np.degrees(np.arccos(np.clip(cos, -1, 1)))[m]
    rel = (np.abs(z["raw"] - raw) / np.maximum(np.abs(raw), 1e-30))[m]
    return {"gain_angular_deg_max": float(ang.max()), "raw_p99_rel": float(np.percentile(rel, 99)),
            "within_tolerance": bool(ang.max() <= 0.05 and np.percentile(rel, 99) <= 1e-3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epoch", type=int, default=256, help="samples in the cold/warm epochs (hit ratio)")
    ap.add_argument("--feed-epoch", type=int, default=1024,
                    help="samples per epoch for the feed rates (fresh DataLoader workers each epoch)")
    ap.add_argument("--crop", type=int, default=256)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--requests", type=int, default=300, help="requests per crop latency case")
    ap.add_argument("--device", default=None,
                    help="torch device for the local mode's device= composition (default: cuda if available, else cpu)")
    args = ap.parse_args()
    import torch

    # One intra-op thread in the process that collates: on this 2-vCPU VM torch 2.13's two-thread
    # torch.stack of 16 crops takes ~120 ms against ~5 ms with one (DataLoader workers already run
    # with one), which would swamp both the disk and the illumix feeds at num_workers=0.
    torch.set_num_threads(1)
    import illumix_client as ic
    from illumix_client.local import LocalClient

    sensor = fl.sensor_name()
    res: dict = {"bench": "feed", "size": [args.width, args.height], "crop": args.crop, "epoch": args.epoch,
                 "feed_epoch": args.feed_epoch,
                 "sensor": sensor, "cache_mb": CACHE_MB, "projection_mb": PROJECTION_MB,
                 "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                             "load_avg": list(os.getloadavg())}}
    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "store")
        fl.log(f"building a {args.width}x{args.height} store, 3 views x 2 groups …")
        res["store_decoded_mb"] = round(fl.build_store(store, args.height, args.width) / 2**20, 1)
        dargs = dataset_args(sensor, args.epoch, args.crop, args.batch)
        fargs = dataset_args(sensor, args.feed_epoch, args.crop, args.batch)

        fl.log("disk baseline: precomputing the epoch's samples …")
        folder = Path(tmp) / "disk"
        with LocalClient(store, cache_mb=CACHE_MB) as local:
            probe = ic.IllumixDataset(store=store, warm=False, **fargs)
            specs = [probe.spec(i, 1) for i in range(args.feed_epoch)]
            for i in range(0, len(specs), 64):  # bounded memory: 64 samples at a time
                fl.write_disk(local.batch(specs[i:i + 64]), folder, start=i)
        disk = fl.disk_dataset(folder, args.feed_epoch)
        res["disk"] = {f"feed_w{w}": round(fl.feed_rate(disk, w, args.batch, 2), 1) for w in (0, 2)}
        res["disk"]["feed_w2_persistent"] = round(fl.feed_rate(disk, 2, args.batch, 2, persistent=True), 1)
        res["disk"]["read_p50_ms"] = round(fl.p50_ms(lambda i: fl.read_one(folder, i % args.feed_epoch), args.requests), 3)

        fl.log("HTTP: a fresh server, cold epoch then warm …")
        with fl.Server(store, CACHE_MB, PROJECTION_MB) as srv:
            ds = ic.IllumixDataset(srv.url, **dargs)
            h0 = srv.health()
            cold = fl.epoch_seconds(ds, args.batch, 0)
            h1 = srv.health()
            warm = min(fl.epoch_seconds(ds, args.batch, e) for e in (1, 2))
            ratio, counts = fl.hit_ratio(h0, h1)
            http = {"cold_epoch_s": round(cold, 2), "warm_epoch_s": round(warm, 2), "cold_epoch_counts": counts}
            http["cache_hit_ratio_cold_epoch"] = round(ratio, 4)
            fds = ic.IllumixDataset(srv.url, **fargs)
            for w in (0, 2):
                fl.log(f"HTTP feed, {w} workers …")
                http[f"feed_w{w}"] = round(fl.feed_rate(fds, w, args.batch, 2, fds.set_epoch), 1)
            http["feed_w2_persistent"] = round(fl.feed_rate(fds, 2, args.batch, 2, fds.set_epoch, persistent=True), 1)
            crop_specs = specs[:32]
            def disk_read(i: int) -> None:
                fl.read_one(folder, i % args.feed_epoch)

            for fmt, key in (("arrays", ""), ("npz", "_npz")):
                ours, theirs = client_p50(srv.url, crop_specs, args.requests, fmt, between=disk_read)
                http[f"crop_p50_ms{key}"], http[f"crop_p50_disk_ms{key}"] = round(ours, 2), round(theirs, 3)
            full = dict(scene="room", view="v0", sensor=sensor, pair="A,D65")
            http["full_raw_gain_p50_ms"] = round(client_p50(srv.url, [full | {"outputs": "raw,gain"}], 15)[0], 1)
            http["full_all_p50_ms"] = round(client_p50(srv.url, [full | {"outputs": "raw,gain,srgb,weights,mask,illum,mixture,meta"}], 10)[0], 1)
            res["accuracy"] = accuracy(srv.url, store, sensor)
            rss, peak = srv.rss_mb()
            http["rss_mb"], http["peak_rss_mb"] = round(rss, 1), round(peak, 1)
            http["health"] = {k: srv.health()[k] for k in ("cache", "projections")}
        res["http"] = http

        fl.log("HTTP: a fresh server started with --warm, its first epoch …")
        with fl.Server(store, CACHE_MB, PROJECTION_MB, "--warm") as srv:
            ds = ic.IllumixDataset(srv.url, **dargs)
            res["http_warm_start"] = {"ready_s": round(srv.ready_s, 2),
                                      "first_epoch_s": round(fl.epoch_seconds(ds, args.batch, 0), 2)}

        fl.log("in-process (server side) …")
        res["in_process"] = in_process(store, sensor, repeats=5)

        fl.log("local mode …")
        t = time.perf_counter()
        lds = ic.IllumixDataset(store=store, cache_mb=CACHE_MB, **fargs)
        res["local"] = {"warm_s": round(time.perf_counter() - t, 2)}
        for w in (0, 2):
            fl.log(f"local feed, {w} workers …")
            res["local"][f"feed_w{w}"] = round(fl.feed_rate(lds, w, args.batch, 2, lds.set_epoch), 1)
        res["local"]["feed_w2_persistent"] = round(fl.feed_rate(lds, 2, args.batch, 2, lds.set_epoch, persistent=True), 1)

        del lds
        device = args.device or ("cuda" if torch.cuda.is_available() else "cpu")
        fl.log(f"local mode with torch on {device} …")
        tds = ic.IllumixDataset(store=store, cache_mb=CACHE_MB, device=device, **fargs)
        res["local_torch"] = {"device": device, "feed_w0": round(fl.feed_rate(tds, 0, args.batch, 2, tds.set_epoch), 1)}
        del tds

    disk_min = min(res["disk"]["feed_w0"], res["disk"]["feed_w2"])
    def ratio(m: str, w2: str) -> float:  # the worse of workers 0 and 2
        return min(res[m]["feed_w0"] / res["disk"]["feed_w0"], res[m][w2] / res["disk"][w2])

    per_mode = {m: ratio(m, "feed_w2_persistent") for m in ("http", "local")}
    fresh = {m: ratio(m, "feed_w2") for m in ("http", "local")}
    best = max(per_mode, key=per_mode.get)
    res |= {
        "feed_ratio_vs_disk": round(per_mode[best], 3), "feed_mode": best,
        "feed_ratio_vs_disk_http": round(per_mode["http"], 3), "feed_ratio_vs_disk_local": round(per_mode["local"], 3),
        "feed_ratio_vs_disk_fresh_workers": round(max(fresh.values()), 3),
        "feed_ratio_vs_disk_fresh_workers_http": round(fresh["http"], 3),
        # each against the disk reads interleaved with its own requests
        "crop_p50_ratio_vs_disk": round(res["http"]["crop_p50_ms"] / res["http"]["crop_p50_disk_ms"], 2),
        "crop_p50_ratio_vs_disk_npz": round(res["http"]["crop_p50_ms_npz"] / res["http"]["crop_p50_disk_ms_npz"], 2),
        "full_raw_gain_ms": res["in_process"]["full_raw_gain"]["total_ms"],
        "full_all_ms": res["in_process"]["full_all"]["total_ms"],
        "full_raw_gain_http_ms": res["http"]["full_raw_gain_p50_ms"], "full_all_http_ms": res["http"]["full_all_p50_ms"],
        "cold_over_warm": round(res["http_warm_start"]["first_epoch_s"] / res["http"]["warm_epoch_s"], 2),
        "cold_over_warm_without_warm_flag": round(res["http"]["cold_epoch_s"] / res["http"]["warm_epoch_s"], 2),
        "cache_hit_ratio": res["http"]["cache_hit_ratio_cold_epoch"],
        # the cache settings: --cache-mb plus --projection-cache-mb (both bound what is kept)
        "rss_mb_over_cache": round(res["http"]["peak_rss_mb"] - CACHE_MB - PROJECTION_MB, 1),
        "disk_feed_min": disk_min,
    }
    print(json.dumps(res))


if __name__ == "__main__":
    main()
