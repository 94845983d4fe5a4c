"""Client tests (issue 6): encoding and error mapping offline, then every client call against a real
``illumix serve`` on 127.0.0.1, retries through a misbehaving TCP proxy, and the PyTorch dataset
through a DataLoader with two workers."""

from __future__ import annotations

import ast
import asyncio
import io
import json
import subprocess
import sys
from pathlib import Path

import illumix_client as ic
import numpy as np
import pytest
from client_server import FlakyProxy, ServerProcess
from illumix_client.draw import IlluminantPool, SpecSampler, ViewInfo, select_views
from illumix_client.errors import error_for
from illumix_client.sample import encode_spec

TOKEN = "t0ken"
FAST = ic.RetryPolicy(attempts=3, backoff=0.02, max_backoff=0.1)
CLIENT_DIR = Path(ic.__file__).resolve().parent
SENSOR_CSV = "wavelength,r,g,b\n" + "\n".join(
    f"{wl},{np.exp(-((wl - 600) / 40) ** 2):.6f},{np.exp(-((wl - 540) / 40) ** 2):.6f},"
    f"{np.exp(-((wl - 460) / 30) ** 2):.6f}" for wl in range(380, 785, 5))
SPD_CSV = "wavelength,value\n" + "\n".join(f"{wl},{1.0 + (wl - 380) / 400:.4f}" for wl in range(380, 785, 5))


# -- offline: packaging, encoding, errors, drawing ---------------------------------------------------
def test_client_imports_no_server_code_and_no_torch():
    banned = ("retarget", "store", "service", "illumix", "renderer_jobs")
    for path in CLIENT_DIR.glob("*.py"):
        if path.name == "local.py":
            continue  # the local mode is the optional extra that brings the physics core
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not [n for n in names if n.split(".")[0] in banned], (path.name, names)
    code = ("import sys\nfor m in %r: sys.modules[m] = None\n"
            "import illumix_client as ic\nc = ic.Client('http://127.0.0.1:9')\nc.close()\n"
            "assert 'torch' not in sys.modules, 'torch imported eagerly'\nprint('ok')" % (banned,))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd="/")
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_distribution_installed():
    """``bash scripts/install.sh`` installs the client as its own distribution from clients/python."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        assert version("illumix-client") == ic.__version__
    except PackageNotFoundError:
        pytest.fail("illumix-client is not installed; run `bash scripts/install.sh --test`")
    assert CLIENT_DIR == Path(__file__).resolve().parents[1] / "clients" / "python" / "illumix_client"


def test_encode_spec_wire_forms():
    enc = encode_spec({"scene": "s", "seed": np.int64(3), "pair": ("A", "D65"), "intensities": [1, 0.5],
                       "crop": (1, 2, 30, 40), "size": (16, 8), "outputs": ["raw", "meta"], "exposure": 2.0,
                       "noise": {"full_well": 8000, "bit_depth": 12}, "view": None})
    assert enc == {"scene": "s", "seed": 3, "pair": "A,D65", "intensities": "1,0.5", "crop": "1,2,30,40",
                   "size": "16x8", "outputs": "raw,meta", "exposure": "2.0",
                   "noise": "full_well:8000;bit_depth:12"}
    with pytest.raises(TypeError, match="unknown sample parameter"):
        encode_spec({"scenes": "x"})
    with pytest.raises(ValueError, match="image"):
        encode_spec({"format": "png"})
    with pytest.raises(TypeError):
        encode_spec({"seed": True})


@pytest.mark.parametrize("status, cls", [(400, ic.InvalidRequestError), (401, ic.AuthError),
                                         (403, ic.ForbiddenError), (404, ic.NotFoundError),
                                         (409, ic.ConflictError), (413, ic.RequestTooLargeError),
                                         (422, ic.InvalidRequestError), (500, ic.ServerError),
                                         (503, ic.ServerError), (418, ic.IllumixError)])
def test_error_for_status(status, cls):
    err = error_for(status, b'{"detail": "what to fix"}')
    assert type(err) is cls and err.status == status and err.detail == "what to fix"
    assert "what to fix" in str(err) and str(status) in str(err)
    listed = error_for(422, json.dumps({"detail": [{"loc": ["body", "samples"], "msg": "Field required"}]}).encode())
    assert listed.detail == "samples: Field required"
    assert error_for(502, b"<html>bad gateway</html>").detail == "<html>bad gateway</html>"


def test_retry_policy_backoff_is_exponential_and_capped():
    p = ic.RetryPolicy(attempts=6, backoff=0.1, max_backoff=0.5, jitter=0.0)
    assert [p.delay(k) for k in range(1, 6)] == pytest.approx([0.1, 0.2, 0.4, 0.5, 0.5])
    assert p.delay(1, retry_after="0.3") == pytest.approx(0.3) and p.delay(1, "99") == pytest.approx(0.5)
    with pytest.raises(ValueError):
        ic.RetryPolicy(attempts=0)


def test_illuminant_pool_and_spec_sampler():
    pool = IlluminantPool({"window": "daylight:5000-9000", "*": ["A", "blackbody:2500-3000"]}, cct_step=50)
    rng = np.random.default_rng(0)
    for _ in range(200):
        w, lamp = pool.draw(rng, ["window", "lamp"])
        k = float(w.split(":")[1])
        assert w.startswith("daylight:") and 5000 <= k <= 9000 and k % 50 == 0
        assert lamp == "A" or (lamp.startswith("blackbody:") and 2500 <= float(lamp[10:]) <= 3000)
    with pytest.raises(ValueError):
        IlluminantPool({"window": "A"}).draw(rng, ["lamp"])
    views = [ViewInfo("s", "v0", 64, 48, ("window", "lamp")), ViewInfo("s", "tiny", 8, 8, ("lamp",)),
             ViewInfo("t", "v0", 64, 48, ("booth",))]
    assert [v.key for v in select_views(views, ["s"], crop=(16, 16))] == ["s/v0"]
    assert [v.key for v in select_views(views, "*/v0", min_groups=1)] == ["s/v0", "t/v0"]
    sampler = SpecSampler(views[:1], pool, ["XYZ", "CIE 1931"], crop=(16, 12), intensity_range=(0.5, 1.0))
    a, b = sampler.spec(np.random.default_rng([1, 0, 5])), sampler.spec(np.random.default_rng([1, 0, 5]))
    assert a == b and a["outputs"][-1] == "meta" and max(a["intensities"]) == 1.0
    assert min(a["intensities"]) >= 0.5 and len(a["illuminants"]) == 2
    x, y, w, h = a["crop"]
    assert (w, h) == (16, 12) and 0 <= x <= 64 - 16 and 0 <= y <= 48 - 12
    assert sampler.spec(np.random.default_rng([1, 0, 6])) != a


# -- against a real server ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def server(tmp_path_factory):
    import synthetic_store

    root = tmp_path_factory.mktemp("client")
    synthetic_store.build(root / "store")
    srv = ServerProcess(root / "store", TOKEN, root / "server.log")
    try:
        srv.wait_ready()
        yield srv
    finally:
        srv.stop()


@pytest.fixture()
def client(server):
    with ic.Client(server.url, token=TOKEN, retry=FAST) as c:
        yield c


def test_reads(client):
    assert client.health()["status"] == "ok"
    scenes = {s["name"]: s for s in client.scenes()}
    assert set(scenes) == {"synth", "thesis"}
    v0 = next(v for v in scenes["synth"]["views"] if v["name"] == "v0")
    assert (v0["width"], v0["height"], [g["name"] for g in v0["groups"]]) == (64, 48, ["window", "lamp"])
    sensors = client.sensors()
    assert "XYZ" in sensors["builtin"]
    xyz = client.sensor("XYZ")
    assert xyz["sensitivities"].shape == (xyz["wavelengths"].size, 3) and xyz["wavelengths"].size == 63
    ill = client.illuminants()
    assert {"A", "D65", "FL11"} <= set(ill["builtin"]) and "blackbody" in ill["parametric"]


def test_sample_arrays_meta_and_subsets(client, server):
    s = client.sample("synth", "v0", seed=7, sensor="XYZ", pair=("A", "D65"), intensities=(1, 0.5))
    assert s.raw.shape == (48, 64, 3) and s.raw.dtype == np.float32 and s.gain.shape == (48, 64, 3)
    assert s.ccm.shape == (48, 64, 3, 3) and s.srgb.shape == (48, 64, 3) and s.weights.shape == (48, 64, 2)
    lean = client.sample("synth", "v0", seed=7, sensor="XYZ", pair=("A", "D65"), intensities=(1, 0.5),
                         outputs=["mixture", "meta"])  # without the CCM map: rebuilt from mixture + meta
    assert lean.ccm is None
    np.testing.assert_allclose(lean.ccm_map(), s.ccm, rtol=1e-5, atol=1e-6)
    assert s.raw.flags.writeable  # views of the client's own buffer, as npz arrays were
    assert s.mask.dtype == bool and not s.mask[-4:].any() and s.mask[:-4].all()
    assert (s.scene, s.view, s.seed) == ("synth", "v0", 7)
    assert [i["illuminant"] for i in s.meta["illuminants"]] == ["A", "D65"]
    assert [i["intensity"] for i in s.meta["illuminants"]] == [1.0, 0.5]
    import httpx  # the same request by hand: the client decodes exactly what the service sent

    raw = httpx.get(server.url + "/sample", params={"scene": "synth", "view": "v0", "seed": 7, "sensor": "XYZ",
                                                    "pair": "A,D65", "intensities": "1,0.5"}).content
    with np.load(io.BytesIO(raw)) as z:  # the service's default npz; the client asked for arrays
        for k in ic.OUTPUTS:  # the default outputs are sent; the others (AOVs, spectra) are None
            if k in z.files:
                np.testing.assert_array_equal(getattr(s, k), z[k])
            else:
                assert getattr(s, k) is None, k
        assert {"raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture"} <= set(z.files)
    sub = client.sample("synth", "solo", illuminants=["D65"], crop=(8, 4, 16, 12), size=(8, 6),
                        outputs=["gain", "mask"])
    assert sub.gain.shape == (6, 8, 3) and sub.mask.shape == (6, 8)
    assert sub.raw is None and sub.ccm is None and sub.meta == {} and set(sub.arrays()) == {"gain", "mask"}


def test_batch_matches_single_samples(client):
    specs = [dict(scene="synth", view="v0", seed=i, pair=["FL11", "A"], crop=[i, 0, 20, 20]) for i in range(3)]
    specs.append(dict(scene="synth", view="solo", seed=9, illuminants="daylight:5000", outputs=("raw", "meta"),
                      noise="phone", exposure="auto"))
    got = client.batch(specs)
    assert len(got) == 4 and [g.meta["crop"][0] for g in got[:3]] == [0, 1, 2]
    for spec, g in zip(specs, got):
        one = client.sample(**spec)
        np.testing.assert_array_equal(g.raw, one.raw)
        assert g.meta["seed"] == spec["seed"]
    assert got[3].gain is None and got[3].meta["noise"]["bit_depth"] == 12
    with pytest.raises(ValueError):
        client.batch([])


def test_image_formats(client):
    png = client.image("srgb", "png", scene="synth", view="v0", pair="A,D65", seed=1)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    tif = client.image("gain", "tiff", scene="synth", view="v0", pair="A,D65", seed=1)
    assert tif[:4] in (b"II*\x00", b"MM\x00*")
    with pytest.raises(ValueError):
        client.image("srgb", "jpg")


def test_error_mapping_from_the_service(client):
    with pytest.raises(ic.NotFoundError) as e:
        client.sample("synht", "v0")
    assert e.value.status == 404 and "synth" in e.value.detail
    with pytest.raises(ic.NotFoundError, match="IMX"):
        client.sample("synth", "v0", sensor="IMX999")
    with pytest.raises(ic.InvalidRequestError) as e:
        client.sample("synth", "solo", pair="A,D65")
    assert e.value.status == 422 and "one entry" in e.value.detail
    with pytest.raises(ic.InvalidRequestError, match="exceeds"):
        client.sample("synth", "v0", crop=(60, 0, 16, 16))
    with pytest.raises(ic.InvalidRequestError):  # relighting a cube rendered dark above 650 nm by D65
        client.sample("thesis", "v0", illuminants=["D65"])
    with pytest.raises(ic.InvalidRequestError, match="crop"):
        client.batch([{"scene": "synth", "crop": "1,2"}])


def test_uploads_deletes_and_auth(client, server, tmp_path):
    csv = tmp_path / "cam.csv"
    csv.write_text(SENSOR_CSV)
    with ic.Client(server.url, retry=FAST) as anon:
        with pytest.raises(ic.AuthError) as e:
            anon.upload_sensor("cam1", csv)
        assert e.value.status == 401 and "token" in e.value.detail
        with pytest.raises(ic.AuthError):
            anon.delete_sensor("cam1")
    assert client.upload_sensor("cam1", csv) == {"name": "cam1", "format": "csv", "bytes": len(SENSOR_CSV)}
    assert "cam1" in client.sensors()["uploaded"]
    assert client.sample("synth", "v0", sensor="cam1", pair="A,D65", outputs="raw").raw.shape == (48, 64, 3)
    with pytest.raises(ic.ConflictError) as e:
        client.upload_sensor("cam1", csv)
    assert e.value.status == 409 and "overwrite" in e.value.detail
    assert client.upload_sensor("cam1", SENSOR_CSV.encode(), overwrite=True)["name"] == "cam1"
    with pytest.raises(ic.ForbiddenError) as e:
        client.delete_sensor("XYZ")
    assert e.value.status == 403 and isinstance(e.value, ic.AuthError)
    assert client.delete_sensor("cam1") == {"deleted": "cam1"}
    assert client.upload_illuminant("flat1", b"wavelength,value\n380,1\n780,1\n")["name"] == "flat1"
    assert client.delete_illuminant("flat1") == {"deleted": "flat1"}
    with pytest.raises(ic.ForbiddenError):
        client.delete_illuminant("D65")
    with pytest.raises(ic.NotFoundError):
        client.delete_sensor("cam1")
    with pytest.raises(ic.InvalidRequestError):
        client.upload_sensor("bad", b"wavelength,r,g,b\n400,1,2\n")
    with pytest.raises(ic.RequestTooLargeError) as e:
        client.upload_sensor("huge", b"0" * (2 * 2**20 + 10))
    assert e.value.status == 413
    spd = tmp_path / "warm.csv"
    spd.write_text(SPD_CSV)
    assert client.upload_illuminant("warm", spd)["name"] == "warm"
    assert "warm" in client.illuminants()["uploaded"]
    assert client.sample("synth", "v0", pair="warm,D65", outputs="meta").meta["illuminants"][0]["illuminant"] == "warm"
    with pytest.raises(ic.ConflictError):
        client.upload_illuminant("warm", spd)


# -- retries over real sockets --------------------------------------------------------------------
def test_retry_on_dropped_connections_and_5xx(server):
    with FlakyProxy(server.port, lambda n: "drop" if n < 2 else "proxy").start() as px:
        with ic.Client(px.url, retry=FAST) as c:
            assert c.sample("synth", "v0", seed=1, outputs="mask").mask.shape == (48, 64)
        assert px.connections == 3 and len(px.requests) == 2 and px.requests[0].startswith("GET /sample")
    with FlakyProxy(server.port, lambda n: 503 if n < 2 else "proxy").start() as px:
        with ic.Client(px.url, retry=FAST) as c:
            assert c.batch([{"scene": "synth", "outputs": "mask"}])[0].mask.shape == (48, 64)
        assert px.connections == 3
    with FlakyProxy(server.port, lambda n: "drop").start() as px:
        with ic.Client(px.url, retry=FAST) as c, pytest.raises(ic.ConnectionFailed, match="3 tries"):
            c.health()
        assert px.connections == 3  # bounded: attempts=3
    with FlakyProxy(server.port, lambda n: 500).start() as px:
        with ic.Client(px.url, retry=FAST) as c, pytest.raises(ic.ServerError) as e:
            c.scenes()
        assert px.connections == 3 and e.value.status == 500 and "canned 500" in e.value.detail


def test_no_retry_on_4xx_or_on_writes_that_may_have_landed(server):
    with FlakyProxy(server.port, lambda n: 404).start() as px:
        with ic.Client(px.url, retry=FAST) as c, pytest.raises(ic.NotFoundError, match="canned 404"):
            c.sample("synth")
        assert px.connections == 1
    with FlakyProxy(server.port, lambda n: "drop" if n == 0 else "proxy").start() as px:
        with ic.Client(px.url, token=TOKEN, retry=FAST) as c, pytest.raises(ic.ConnectionFailed, match="1 try"):
            c.upload_illuminant("dropped", SPD_CSV.encode())
        assert px.connections == 1
    with FlakyProxy(server.port, lambda n: 503 if n == 0 else "proxy").start() as px:
        with ic.Client(px.url, token=TOKEN, retry=FAST) as c:  # 503: not processed, safe to resend
            assert c.upload_illuminant("resent", SPD_CSV.encode())["name"] == "resent"
        assert px.connections == 2


def test_async_client_twin_and_retry_on_late_listener(server):
    async def main():
        async with ic.AsyncClient(server.url, token=TOKEN, retry=FAST) as c:
            assert (await c.health())["status"] == "ok"
            assert {s["name"] for s in await c.scenes()} == {"synth", "thesis"}
            assert "XYZ" in (await c.sensors())["builtin"] and "A" in (await c.illuminants())["builtin"]
            assert (await c.sensor("XYZ"))["sensitivities"].shape[1] == 3
            s, b = await asyncio.gather(c.sample("synth", "v0", seed=3, pair="A,D65"),
                                        c.batch([{"scene": "synth", "view": "v0", "seed": 3, "pair": "A,D65"}]))
            np.testing.assert_array_equal(s.gain, b[0].gain)
            assert (await c.image("mask", "png", scene="synth", view="v0"))[:4] == b"\x89PNG"
            with pytest.raises(ic.NotFoundError):
                await c.sample("nope")
            await c.upload_sensor("acam", SENSOR_CSV.encode())
            with pytest.raises(ic.ConflictError):
                await c.upload_sensor("acam", SENSOR_CSV.encode())
            await c.upload_illuminant("aspd", SPD_CSV.encode())
            assert (await c.delete_sensor("acam")) == {"deleted": "acam"}
        slow = ic.RetryPolicy(attempts=6, backoff=0.1, max_backoff=0.4)
        with FlakyProxy(server.port, lambda n: "proxy").start(delay=0.3) as px:  # refuses for 0.3 s
            async with ic.AsyncClient(px.url, retry=slow) as c:
                assert (await c.health())["status"] == "ok"

    asyncio.run(main())


# -- PyTorch dataset ------------------------------------------------------------------------------
def _dataset(server, **kw):
    torch = pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    args = dict(scenes=["synth"], illuminants=["A", "D65", "FL11", "blackbody:2500-7500"],
                sensors=["XYZ", "Nikon 5100 (NPL)"], crop=(16, 16), epoch_length=24,
                batch_size=4, seed=5, retry=FAST)
    args.update(kw)
    return torch, ic.IllumixDataset(server.url, **args)


def test_dataloader_two_workers_distinct_valid_reproducible(server):
    torch, ds = _dataset(server)
    from torch.utils.data import DataLoader

    items = {}
    for batch in DataLoader(ds, batch_size=6, num_workers=2):
        assert batch["raw"].shape == (6, 3, 16, 16) and batch["raw"].dtype == torch.float32
        assert batch["gain"].shape == (6, 3, 16, 16) and batch["mask"].shape == (6, 1, 16, 16)
        assert batch["mask"].dtype == torch.bool
        for j, i in enumerate(batch["index"].tolist()):
            assert i not in items, f"index {i} produced twice"
            items[i] = {k: batch[k][j] for k in ("raw", "gain", "mask")} | {"meta": json.loads(batch["meta"][j])}
    assert sorted(items) == list(range(24)) and len(ds) == 24
    keys = {(m["meta"]["view"], tuple(m["meta"]["crop"]), m["meta"]["seed"]) for m in items.values()}
    assert len(keys) == 24, "two items share view, crop and seed"
    for it in items.values():
        raw, gain = it["raw"], it["gain"]
        assert torch.isfinite(raw).all() and torch.isfinite(gain).all()
        assert float(raw.max()) == pytest.approx(1.0) and float(raw.min()) >= 0  # raw_norm="max"
        assert (gain[:, it["mask"][0]] >= 1 - 1e-4).all()
        assert it["meta"]["scene"] == "synth" and len(it["meta"]["illuminants"]) == len(it["meta"]["groups"])
    # the same seed and epoch give the same items without workers; another epoch gives new ones
    _, again = _dataset(server, epoch_length=6, prefetch=0)
    for it in again:
        torch.testing.assert_close(it["raw"], items[it["index"]]["raw"])
        assert json.loads(it["meta"])["crop"] == items[it["index"]]["meta"]["crop"]
    again.set_epoch(1)
    assert [json.loads(it["meta"])["seed"] for it in again] != [items[i]["meta"]["seed"] for i in range(6)]


def test_dataset_sharding_options_and_validation(server):
    torch, r0 = _dataset(server, rank=0, world_size=2, epoch_length=10)
    _, r1 = _dataset(server, rank=1, world_size=2, epoch_length=10)
    a = [c for w in range(2) for c in r0.worker_chunks(w, 2)]
    b = [c for w in range(2) for c in r1.worker_chunks(w, 2)]
    flat_a, flat_b = sum(a, []), sum(b, [])
    assert sorted(flat_a + flat_b) == list(range(10)) and not set(flat_a) & set(flat_b) and len(r0) == 5
    _, ds = _dataset(server, illuminants={"window": "daylight:5000-6000", "*": ["A"]}, noise="phone",
                     raw_norm="exposure", outputs=("raw", "srgb", "ccm", "weights", "mask"), epoch_length=3,
                     scenes="synth/v0", size=(8, 8))
    for it in ds:
        meta = json.loads(it["meta"])
        assert it["raw"].shape == (3, 8, 8) and it["srgb"].shape == (3, 8, 8)
        assert it["ccm"].shape == (3, 3, 8, 8) and it["weights"].shape == (2, 8, 8) and "gain" not in it
        assert -0.1 < float(it["raw"].min()) and float(it["raw"].max()) <= 1.0 + 1e-6
        assert meta["illuminants"][0]["illuminant"].startswith("daylight:") and meta["noise"]["bit_depth"] == 12
    with pytest.raises(ValueError, match="unknown sensor"):
        _dataset(server, sensors=["NoSuchCam"])
    with pytest.raises(ValueError, match="outside"):
        _dataset(server, illuminants=["daylight:1000-5000"])
    with pytest.raises(ValueError, match="no views"):
        _dataset(server, crop=(500, 500))


def test_new_ground_truth_outputs_through_client_and_dataset(client, server):
    s = client.sample("synth", "v0", seed=3, sensor="XYZ", pair=("A", "D65"), outputs=["illum", "mixture", "meta"],
                      gt="formula")
    assert s.illum.shape == (48, 64, 3) and s.mixture.shape == (48, 64, 2) and s.raw is None
    assert s.meta["ground_truth"]["method"] == "formula"
    np.testing.assert_allclose(s.mixture.sum(-1), 1.0, atol=1e-5)
    torch, ds = _dataset(server, epoch_length=4, prefetch=0, outputs=("raw", "illum", "mixture", "mask"),
                         gt="formula", scenes=["synth/v0"])
    for it in ds:
        assert it["illum"].shape == (3, 16, 16) and it["mixture"].shape == (2, 16, 16)
        assert torch.isfinite(it["illum"]).all() and (it["mixture"] >= 0).all()
