"""Benchmark the web explorer's updates at 480×640 (issue 21: each update ≤ 300 ms server side).

A synthetic two-group 480×640×63 store with illumination cubes (tests/synthetic_store.py; or
``--store`` and ``--scene/--view``) is served by ``illumix serve`` on 127.0.0.1 in a subprocess. The
benchmark then sends what the page sends (service/web_static/js/main.js): the page load (``/``, its
modules, ``/scenes``, ``/sensors``, ``/illuminants``, ``/health``), the first frame, then updates —
one ``GET /explore/frame`` each, plus ``GET /explore/spectra`` when the sensor or illuminants change
(the page sends both at once). The kinds of update, interleaved over ``--repeats`` rounds, each
round with values not asked before (so a new illuminant or sensor is never a cache hit):

- ``intensity``: an intensity slider (same illuminants: the cached projections are sliced);
- ``illuminant``: another registry illuminant on a group (a new projection of its cubes);
- ``cct``: the colour-temperature slider (``blackbody:K``, new K);
- ``sensor``: another camera (``ILLUMIX_SENSOR_PATH`` = the rawtoaces cameras in ../shared/data);
- ``gt_formula``: the ground-truth switch; ``half_size``: the frame-size switch.

Server side is the ``Server-Timing`` ``total`` of ``/explore/frame`` (request parsed → body encoded,
before sending); ``request`` is the client's wall time of the whole frame read to the last byte.

The research tools (issue 38), client wall time per request: ``pixel_cold`` — ``GET /explore/pixel``
(the hovered pixel's spectra) before any frame decoded the cubes (only the pixel's chunks are read),
``pixel_warm`` — after (sliced from the cached cubes); ``noise_preview`` — the ``GET /sample``
``noise=phone`` raw the page asks; ``gallery_thumbnail`` — one 96-pixel-wide ``GET /sample`` tile
of the dataset gallery (srgb, gain, mixture, mask, meta), 16 of them with random lights.

Usage: python bench/web.py [--repeats N] [--store PATH --scene S --view V]; JSON printed last.
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

from server_lib import free_port, wait_healthy  # bench/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]
CAMERAS = ROOT.parent / "shared" / "data" / "rawtoaces-data" / "data" / "camera"
BUDGET_MS = 300.0
ILLUMINANTS = ["FL1", "FL2", "FL3", "FL4", "FL5", "FL6", "FL7", "FL8", "FL9", "FL10", "FL12", "LED-B1", "LED-B2"]


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def server_ms(r) -> float:
    parts = dict(p.strip().split(";dur=") for p in r.headers["server-timing"].split(","))
    return float(parts["total"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--store", help="a store to serve (default: a synthetic 480x640 one in a temp folder)")
    ap.add_argument("--scene", default="synth")
    ap.add_argument("--view", default="v0")
    args = ap.parse_args()
    import httpx

    with tempfile.TemporaryDirectory() as tmp:
        store = args.store
        if store is None:
            import synthetic_store

            store = str(Path(tmp) / "store")
            log("building a synthetic 480x640x63 store with illumination cubes …")
            synthetic_store.build(store, h=480, w=640, extras=False, illumination=True)
        port = free_port()
        url = f"http://127.0.0.1:{port}"
        env = dict(os.environ, ILLUMIX_SENSOR_PATH=str(CAMERAS)) if CAMERAS.is_dir() else dict(os.environ)
        with open(Path(tmp) / "server.log", "w+b") as slog:
            proc = subprocess.Popen([sys.executable, "-m", "illumix.cli", "serve", "--store", store, "--host",
                                     "127.0.0.1", "--port", str(port), "--cache-mb", "1024"],
                                    cwd=ROOT, env=env, stdout=slog, stderr=subprocess.STDOUT)
            try:
                wait_healthy(url, proc, log=slog)
                with httpx.Client(base_url=url, timeout=60) as client:
                    result = run(client, args)
            finally:
                proc.terminate()
                proc.wait(timeout=30)
    print(json.dumps(result))


def run(client, args) -> dict:
    t = time.perf_counter()
    page = [client.get(p) for p in ("/", "/web/js/main.js", "/web/vendor/uPlot.esm.js", "/scenes", "/sensors",
                                    "/illuminants", "/health")]
    assert all(r.status_code == 200 for r in page), [r.status_code for r in page]
    page_ms = 1e3 * (time.perf_counter() - t)
    sensors = page[4].json()["builtin"]
    cameras = [s for s in sensors if s != "XYZ"] or ["XYZ"]
    view = next(v for s in page[3].json()["scenes"] if s["name"] == args.scene for v in s["views"]
                if v["name"] == args.view)
    w, h = view["width"], view["height"]
    lights = ["A", "D65", "FL11", "D50", "F2"][:len(view["groups"])]
    state = {"scene": args.scene, "view": args.view, "sensor": "XYZ", "illuminants": ",".join(lights),
             "intensities": ",".join("1" * len(lights))}

    def changed(illuminant: str | None = None, intensity: float | None = None) -> dict:
        """The page's state with the first group's illuminant or the last group's intensity changed."""
        if illuminant is not None:
            return {"illuminants": ",".join([illuminant, *lights[1:]])}
        return {"intensities": ",".join(["1"] * (len(lights) - 1) + [f"{intensity:.2f}"])}

    def update(changes: dict, spectra: bool) -> tuple[float, float, float]:
        q = {**state, **changes}
        t0 = time.perf_counter()
        r = client.get("/explore/frame", params=q)
        wall = 1e3 * (time.perf_counter() - t0)
        if r.status_code != 200:
            raise SystemExit(f"/explore/frame {q}: {r.status_code} {r.text[:300]}")
        spec_ms = 0.0
        if spectra:
            t1 = time.perf_counter()
            s = client.get("/explore/spectra", params={"sensor": q["sensor"], "illuminants": q["illuminants"]})
            spec_ms = 1e3 * (time.perf_counter() - t1)
            assert s.status_code == 200, s.text
        return server_ms(r), wall, spec_ms

    tools = {"pixel_cold": [_timed(client, "/explore/pixel", {**state, "x": (97 * i) % w, "y": (61 * i) % h})
                            for i in range(args.repeats)]}
    first = update({}, True)
    log(f"first frame (cubes decoded from the store): server {first[0]:.0f} ms")
    update({}, False)  # the page's second look at the same lights: its projections are kept from here on
    kinds = {
        "intensity": lambda i: (changed(intensity=0.9 - 0.1 * i), False),
        "illuminant": lambda i: (changed(ILLUMINANTS[i % len(ILLUMINANTS)]), True),
        "cct": lambda i: (changed(f"blackbody:{2500 + 137 * i}"), True),
        "sensor": lambda i: ({"sensor": cameras[i % len(cameras)]}, True),
        "gt_formula": lambda i: ({"gt": "formula", **changed(intensity=0.85 - 0.1 * i)}, False),
        "half_size": lambda i: ({"size": f"{w // 2}x{h // 2}", **changed(intensity=0.95 - 0.1 * i)}, False),
    }
    times: dict[str, list[tuple[float, float, float]]] = {k: [] for k in kinds}
    for i in range(args.repeats):
        for name, make in kinds.items():
            changes, spectra = make(i)
            times[name].append(update(changes, spectra))
        log(f"round {i + 1}/{args.repeats}: " + ", ".join(f"{k} {v[-1][0]:.0f}" for k, v in times.items()))
    tools |= tool_times(client, state, w, h, args.repeats)
    log("tools (ms, median): " + ", ".join(f"{k} {statistics.median(v):.0f}" for k, v in tools.items()))
    updates = {}
    for name, rows in times.items():
        srv, wall, spec = zip(*rows)
        updates[name] = {"server_ms_min": round(min(srv), 1), "server_ms_median": round(statistics.median(srv), 1),
                         "server_ms_max": round(max(srv), 1), "request_ms_median": round(statistics.median(wall), 1),
                         "spectra_ms_median": round(statistics.median(spec), 1) if any(spec) else None}
    worst = max(u["server_ms_median"] for u in updates.values())
    return {"frame": f"{w}x{h}", "store": args.store or "synthetic 480x640x63, 2 groups, illumination cubes",
            "repeats": args.repeats, "page_load_ms": round(page_ms, 1), "first_frame_server_ms": round(first[0], 1),
            "updates": updates, "worst_update_server_ms_median": worst,
            "worst_update_server_ms_max": max(u["server_ms_max"] for u in updates.values()),
            "within_budget": worst <= BUDGET_MS, "budget_ms": BUDGET_MS,
            "tools_request_ms_median": {k: round(statistics.median(v), 1) for k, v in tools.items()},
            "load_average": os.getloadavg()[0]}


def _timed(client, path: str, params: dict) -> float:
    """Client wall time (ms) of one GET, which must answer 200."""
    t0 = time.perf_counter()
    r = client.get(path, params=params)
    if r.status_code != 200:
        raise SystemExit(f"{path} {params}: {r.status_code} {r.text[:300]}")
    return 1e3 * (time.perf_counter() - t0)


def tool_times(client, state: dict, w: int, h: int, repeats: int) -> dict[str, list[float]]:
    """The explorer's hover spectrum (cubes cached), noise preview and gallery tiles (module docstring)."""
    import random

    rng = random.Random(0)
    pixel = [_timed(client, "/explore/pixel", {**state, "x": rng.randrange(w), "y": rng.randrange(h)})
             for _ in range(max(10, repeats))]
    noise = [_timed(client, "/sample", {**state, "outputs": "raw,meta", "format": "arrays", "noise": "phone",
                                        "exposure": f"{4 + i}", "seed": "1"}) for i in range(repeats)]
    tile = f"96x{max(1, round(96 * h / w))}"
    pool = ["A", "D65", "FL11", *ILLUMINANTS[:6]]
    gallery = [_timed(client, "/sample", {**state, "illuminants": ",".join(rng.sample(pool, len(state["illuminants"].split(",")))),
                                          "outputs": "srgb,gain,mixture,mask,meta", "format": "arrays", "size": tile,
                                          "seed": str(i)}) for i in range(16)]
    return {"pixel_warm": pixel, "noise_preview": noise, "gallery_thumbnail": gallery}


if __name__ == "__main__":
    main()
