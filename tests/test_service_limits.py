"""Bounded requests (issue 13): memory priced before work (413 / 503), bodies bounded in size and
time (413 / 408), PNG raw on a fixed scale. Servers bind to 127.0.0.1; every wait is bounded."""

from __future__ import annotations

import io
import itertools
import json
import socket
import struct
import threading
import time
import tracemalloc
import zlib

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

import synthetic_store as synth
from server_testutil import ThreadServer
from illumix.engine.budget import MemoryBudget
from illumix.engine.errors import Busy, TooLarge
from illumix.engine.limits import Limits
from illumix.engine.sampling import build, plan, price
from illumix.engine.spec import SampleSpec
from illumix.service.app import create_app
from illumix.service.encoding import encode_npz
from illumix.store import CubeMeta, CubeStore

H, W = 96, 128


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("limits") / "store"
    synth.build(path, H, W, extras=False)
    return path


def _price_and_peak(ctx, p) -> tuple[int, int]:
    """The plan's price, and the numpy memory its build and encoding allocate at their peak beyond
    what they add to the cube cache (bounded on its own by --cache-mb)."""
    bound = price(p, ctx)
    cached_before = ctx.cache.total_cost
    tracemalloc.start()
    arrays, meta = build(p, ctx)
    body = encode_npz(arrays, meta)
    del arrays, body
    peak = tracemalloc.get_traced_memory()[1] - (ctx.cache.total_cost - cached_before)
    tracemalloc.stop()
    return bound, peak


@pytest.fixture(scope="module")
def store_with_illumination(tmp_path_factory):
    path = tmp_path_factory.mktemp("limits_u") / "store"
    synth.build(path, H, W, extras=False, illumination=True)
    return path


@pytest.mark.parametrize("cache", ["cold", "warm"])
def test_price_bounds_the_physical_ground_truth_and_spectra(store_with_illumination, cache):
    ctx = create_app(CubeStore.open(str(store_with_illumination), mode="r"), cache_mb=64).state.ctx
    for outs, size in itertools.product(["gain", "raw,gain,ccm,srgb,mask,illum,mixture,meta", "reflectance",
                                         "illumination", "reflectance,illumination,raw,mask", "albedo,normal,depth"],
                                        [None, f"{2 * W}x{2 * H}", "16x12"]):
        spec = SampleSpec(scene="synth", view="v0", pair="FL11,D65", outputs=outs, size=size, seed=1)
        p = plan(spec, ctx)
        if cache == "warm":
            build(p, ctx)
            p = plan(spec, ctx)
        else:
            ctx.cache.clear()
        bound, peak = _price_and_peak(ctx, p)
        assert peak <= bound, (outs, size, cache, peak, bound)


@pytest.mark.parametrize("cache", ["none", "cold", "warm"])
def test_price_bounds_what_a_sample_allocates(store_path, cache):
    """The admission price is an upper bound of the numpy memory a sample allocates (tracemalloc
    sees numpy's buffers) beyond what it adds to the cube cache (bounded by --cache-mb on its own),
    over outputs, crops, resizes, noise; without a cache, with a cold one and a warm one."""
    ctx = create_app(CubeStore.open(str(store_path), mode="r"), cache_mb=0 if cache == "none" else 64).state.ctx
    worst = 0.0
    for outs, crop, size, noise in itertools.product(
            ["raw", "gain", "srgb", "ccm,weights,mask", "raw,gain,ccm,srgb,weights,mask,meta"],
            [None, "5,7,60,40", "100,90,1,1"], [None, f"{2 * W}x{2 * H}", "16x12"], [None, "phone"]):
        spec = SampleSpec(scene="synth", view="v0", pair="FL11,D65", outputs=outs, crop=crop, size=size,
                          noise=noise, seed=1)
        p = plan(spec, ctx)
        if cache == "warm":
            build(p, ctx)
        elif cache == "cold":
            ctx.cache.clear()
        bound, peak = _price_and_peak(ctx, p)
        worst = max(worst, peak / bound)
        assert peak <= bound, (outs, crop, size, noise, peak, bound)
    assert worst > 0.3  # a bound, but not a wildly loose one


def test_oversized_request_and_batch_are_413_with_a_hint(store_path):
    limits = Limits(max_request_mb=24, inflight_mb=24)
    with TestClient(create_app(CubeStore.open(str(store_path), mode="r"), limits=limits)) as c:
        r = c.get("/sample", params={"scene": "synth", "view": "v0", "size": "2048x2048"})
        body = r.json()
        assert r.status_code == 413 and body["code"] == "too_large"
        assert "24 MiB per request" in body["detail"] and "smaller crop= or size=" in body["detail"]
        ok = c.get("/sample", params={"scene": "synth", "view": "v0", "outputs": "raw"})
        assert ok.status_code == 200
        r = c.post("/batch", json={"samples": [{"scene": "synth", "view": "v0", "size": "512x512"}] * 8})
        assert r.status_code == 413 and "batch of 8" in r.json()["detail"]
        assert c.get("/health").json()["memory"]["inflight_bytes"] == 0  # every reservation released


def test_memory_budget_queues_then_refuses_busy_with_retry_after():
    """The engine's budget raises its own errors (Busy, TooLarge); the service answers them 503 with
    Retry-After and 413 (test_busy_and_too_large_map_to_503_and_413)."""
    budget = MemoryBudget(capacity=100, timeout=0.3)
    first = budget.acquire(80, "a")
    t = time.monotonic()
    with pytest.raises(Busy) as exc:
        budget.acquire(30, "b")
    assert exc.value.retry_after == 1
    assert 0.25 <= time.monotonic() - t < 5
    threading.Timer(0.1, first.release).start()
    second = budget.acquire(30, "c")  # waits for the first to finish, then runs
    assert budget.used == 30
    second.release()
    second.release()  # idempotent
    assert budget.used == 0 and budget.peak == 80 and budget.refused_busy == 1
    with pytest.raises(TooLarge, match="working memory"):
        budget.acquire(101, "d")


def test_busy_and_too_large_map_to_503_and_413():
    """The service maps the engine's errors to status codes, in the common error shape."""
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from illumix.service import errors

    app = FastAPI()
    errors.install(app)

    @app.get("/busy")
    def busy():
        raise Busy("the service is busy", retry_after=3)

    @app.get("/large")
    def large():
        raise TooLarge("output 9999x9999 exceeds the limits")

    with TestClient(app) as c:
        r = c.get("/busy")
        assert r.status_code == 503 and r.headers["Retry-After"] == "3" and r.json()["code"] == "busy"
        r = c.get("/large")
        assert r.status_code == 413 and r.json()["code"] == "too_large" and "exceeds" in r.json()["detail"]


# -- request bodies bounded in size and time (real sockets) ----------------------------------------
def _raw_http(port: int, head: bytes, body: bytes = b"", wait: float = 10.0) -> tuple[bytes, float]:
    t = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=wait) as s:
        s.sendall(head + body)
        data = b""
        while b"\r\n\r\n" not in data or len(data) < data.find(b"\r\n\r\n") + 4 + _length(data):
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    return data, time.monotonic() - t


def _length(data: bytes) -> int:
    for line in data.split(b"\r\n"):
        if line.lower().startswith(b"content-length:"):
            return int(line.split(b":")[1])
    return 0


def test_huge_declared_body_is_413_at_once_and_slow_body_408(store_path):
    app = create_app(CubeStore.open(str(store_path), mode="a"), token="t",
                     limits=Limits(body_timeout_s=1.0, body_total_s=2.5))
    with ThreadServer(app) as url:
        port = int(url.rsplit(":", 1)[1])
        head = (b"POST /illuminants HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer t\r\n"
                b"Content-Type: multipart/form-data; boundary=b\r\nContent-Length: 2000000000\r\n\r\n")
        data, dt = _raw_http(port, head)
        assert data.startswith(b"HTTP/1.1 413") and b"too_large" in data and dt < 5
        head = (b"POST /batch HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                b"Content-Length: 100\r\n\r\n")
        data, dt = _raw_http(port, head, b'{"samples": [')  # then nothing more
        assert data.startswith(b"HTTP/1.1 408") and b"stopped arriving" in data and dt < 8
        # a trickle (one byte every 0.5 s, never a 1 s pause) is cut at the total deadline
        t = time.monotonic()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
            sock.sendall(head)
            reply = b""
            while time.monotonic() - t < 8 and (b"\r\n\r\n" not in reply
                                                 or len(reply) < reply.find(b"\r\n\r\n") + 4 + _length(reply)):
                if not reply:
                    sock.sendall(b" ")
                sock.settimeout(0.5)
                try:
                    reply += sock.recv(65536)
                except TimeoutError:
                    pass
        assert reply.startswith(b"HTTP/1.1 408") and b"not arrived whole" in reply, reply[:200]
        assert time.monotonic() - t < 6
        data, _ = _raw_http(port, b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n")  # still serving
        assert data.startswith(b"HTTP/1.1 200")


# -- PNG raw on a fixed scale ----------------------------------------------------------------------
def _png_text(png: bytes) -> dict:
    pos, out = 8, {}
    while pos < len(png):
        n, kind = struct.unpack(">I4s", png[pos:pos + 8])
        data = png[pos + 8:pos + 8 + n]
        assert struct.unpack(">I", png[pos + 8 + n:pos + 12 + n])[0] == zlib.crc32(kind + data)
        if kind == b"tEXt":
            key, _, text = data.partition(b"\0")
            out[key.decode()] = json.loads(text)
        pos += 12 + n
    return out


def test_png_raw_keeps_midtones_with_a_lamp_in_view(tmp_path):
    path = tmp_path / "lamp"
    synth.build(path, extras=False)
    st = CubeStore.open(str(path), mode="a")
    cube = st.read_cube("synth", "v0", "window")
    cube[10:12, 10:12] *= 5000.0  # a lamp: a few pixels thousands of times brighter than the room
    meta = st.cube_meta("synth", "v0", "window").model_dump(include={"grid", "emission", "emission_name"})
    st.write_cube("synth", "v0", "window", cube, CubeMeta(**meta), overwrite=True)
    with TestClient(create_app(st)) as c:
        p = {"scene": "synth", "view": "v0", "pair": "A,D65"}
        r = c.get("/sample", params=p | {"outputs": "raw", "format": "png"})
        assert r.status_code == 200, r.text
        text = _png_text(r.content)["illumix"]
        assert text["scale"] == 65535.0 and text["black_level"] == 0.0 and text["white_level"] == 65535.0
        assert r.headers["x-illumix-scale"] == "65535.0"
        png = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_UNCHANGED)[..., ::-1]
        z = np.load(io.BytesIO(c.get("/sample", params=p | {"outputs": "raw,mask,meta"}).content))
        valid = z["mask"]
        assert np.mean(png[valid].max(axis=-1) == 0) < 0.01  # the peak-scaled PNG crushed 80 % to 0
        assert (png[10:12, 10:12] == 65535).any()  # the lamp clips, as a camera's highlights would
        gain = text["exposure_gain"]
        expected = np.clip(z["raw"] * gain, 0, 1) * 65535
        np.testing.assert_allclose(png[valid], expected[valid], atol=0.51 + 1e-6 * 65535)


@pytest.mark.parametrize("h, w, crop", [(480, 640, None), (600, 800, "0,0,256,256")])
def test_default_outputs_pass_the_default_limits(tmp_path, h, w, crop):
    """Issue 34: with the CCM map back among the defaults, a 480x640 frame and a 256² crop are still
    within one request's working memory (the estimate made before any work)."""
    from illumix.engine.context import make_context

    synth.build(tmp_path / "big", h=h, w=w)
    ctx = make_context(CubeStore.open(str(tmp_path / "big"), mode="r"))  # the service's default cache
    spec = SampleSpec(scene="synth", view="v0", sensor="XYZ", pair="A,D65", crop=crop)
    assert "ccm" in spec.outputs
    p = plan(spec, ctx)
    assert price(p, ctx) <= Limits().max_request_mb * 2**20
    arrays, _ = build(p, ctx)
    assert arrays["ccm"].shape == ((256, 256) if crop else (h, w)) + (3, 3)
