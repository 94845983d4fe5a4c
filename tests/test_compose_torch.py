"""The torch composition (retarget.compose_torch, the local mode's device= path) against the numpy
composition the service serves, on the CPU: the same equations in float32, so they agree to float32
rounding of differently ordered sums (rtol 1e-5; gains within 1e-4 relative)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
import synthetic_store
from illumix_client.errors import InvalidRequestError
from illumix_client.local import LocalClient

SPEC = {"scene": "synth", "view": "v0", "sensor": "Nikon 5100 (NPL)", "pair": "FL11,D65", "crop": "4,2,40,40",
        "intensities": "1,0.4", "seed": 1}


@pytest.fixture(scope="module")
def clients(tmp_path_factory):
    path = tmp_path_factory.mktemp("torch") / "store"
    synthetic_store.build(path, illumination=True)
    with LocalClient(str(path), cache_mb=64) as cpu, LocalClient(str(path), cache_mb=64, device="cpu") as dev:
        yield cpu, dev


@pytest.mark.parametrize("gt", ["physical", "formula"])
def test_torch_equals_numpy(clients, gt):
    cpu, dev = clients
    outputs = "raw,gain,mask,weights,illum,mixture"
    for spec in (SPEC, SPEC | {"crop": "0,0,64,48", "pair": "A,D65", "intensities": "0,1"}):
        a = cpu.sample(**(spec | {"gt": gt, "outputs": outputs}))
        b = dev.sample(**(spec | {"gt": gt, "outputs": outputs}))
        np.testing.assert_array_equal(b.mask.numpy(), a.mask)
        for k in ("raw", "weights", "illum", "mixture"):
            np.testing.assert_allclose(getattr(b, k).numpy(), getattr(a, k), rtol=1e-5, atol=1e-7, err_msg=k)
        np.testing.assert_allclose(b.gain.numpy(), a.gain, rtol=1e-4, err_msg="gain")


def test_torch_refuses_what_it_does_not_compose(clients):
    _, dev = clients
    for extra in ({"outputs": "raw,srgb"}, {"size": "8x8"}, {"noise": "phone"}):
        with pytest.raises(InvalidRequestError, match="CPU path"):
            dev.sample(**(SPEC | extra))


def test_torch_dataset_items(clients, tmp_path):
    cpu, _ = clients
    import illumix_client as ic

    ds = ic.IllumixDataset(store=cpu.url, device="cpu", cache_mb=64, scenes=["synth/v0"], illuminants=["A", "D65"],
                           sensors=["XYZ"], crop=(16, 16), epoch_length=4, batch_size=2, seed=2)
    ref = ic.IllumixDataset(store=cpu.url, cache_mb=64, scenes=["synth/v0"], illuminants=["A", "D65"],
                            sensors=["XYZ"], crop=(16, 16), epoch_length=4, batch_size=2, seed=2)
    for a, b in zip(ds, ref):
        assert a["raw"].shape == (3, 16, 16) and a["mask"].shape == (1, 16, 16)
        torch.testing.assert_close(a["raw"], b["raw"], rtol=1e-5, atol=1e-7)
        torch.testing.assert_close(a["gain"], b["gain"], rtol=1e-4, atol=1e-6)


def test_the_service_composes_eligible_requests_on_its_device(tmp_path):
    """``illumix serve --device``: eligible requests go to torch (meta["device"]), with the same
    arrays and the same metadata as the CPU path; the rest are composed on the CPU."""
    import io
    import json

    from fastapi.testclient import TestClient

    from illumix.service.app import create_app
    from illumix.store import CubeStore

    synthetic_store.build(tmp_path / "s", illumination=True)
    st = CubeStore.open(str(tmp_path / "s"), mode="r")
    with TestClient(create_app(st, cache_mb=64, device="cpu")) as dev, TestClient(create_app(st, cache_mb=64)) as cpu:
        params = SPEC | {"outputs": "raw,gain,mask,mixture,meta"}
        a, b = (np.load(io.BytesIO(c.get("/sample", params=params).content)) for c in (cpu, dev))
        ma, mb = json.loads(str(a["meta"])), json.loads(str(b["meta"]))
        assert mb.pop("device") == "cpu" and "device" not in ma
        ma.pop("timings_ms"), mb.pop("timings_ms")
        assert ma == mb
        for k, rtol in (("raw", 1e-5), ("gain", 1e-4), ("mixture", 1e-5)):  # as test_torch_equals_numpy
            np.testing.assert_allclose(b[k], a[k], rtol=rtol, atol=1e-7, err_msg=k)
        np.testing.assert_array_equal(b["mask"], a["mask"])
        srgb = np.load(io.BytesIO(dev.get("/sample", params=SPEC | {"outputs": "srgb,meta"}).content))
        assert "device" not in json.loads(str(srgb["meta"]))  # composed on the CPU
        # a PNG of raw is auto-exposed: composed on the CPU, the same image either way
        png = {"outputs": "raw", "format": "png"}
        assert dev.get("/sample", params=SPEC | png).content == cpu.get("/sample", params=SPEC | png).content
        # so is a DNG, a linear one too (bayer=none): the same auto exposure, the same digital numbers
        dng = {"outputs": "raw", "format": "dng", "bayer": "none"}
        assert dev.get("/sample", params=SPEC | dng).content == cpu.get("/sample", params=SPEC | dng).content


def test_a_device_torch_cannot_compute_on_is_refused_at_start(tmp_path):
    """``meta`` is a device torch knows but computes nothing on: refused when the app is made (the
    CLI prints it as one line), not a 500 on every request."""
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    synthetic_store.build(tmp_path / "s", extras=False)
    with pytest.raises(RuntimeError, match="cannot compute"):
        create_app(CubeStore.open(str(tmp_path / "s"), mode="r"), cache_mb=64, device="meta")
