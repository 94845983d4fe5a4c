"""The client's local mode (issue 19): LocalClient and IllumixDataset(store=...) compose in-process
with the service's own code, so their samples equal what the HTTP service answers."""

from __future__ import annotations

import io
import json
from pathlib import Path

import illumix_client as ic
import numpy as np
import pytest
import synthetic_store
from fastapi.testclient import TestClient
from illumix_client.local import LocalClient

from illumix.service.app import create_app
from illumix.store import CubeStore

SPEC = {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65", "crop": "8,4,32,24",
        "intensities": "1,0.5", "seed": 3}


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("local") / "store"
    synthetic_store.build(path, illumination=True)
    return str(path)


@pytest.fixture(scope="module")
def http(store_path):
    with TestClient(create_app(CubeStore.open(store_path, mode="r"), cache_mb=64)) as c:
        yield c


def test_local_samples_equal_the_service(store_path, http):
    with LocalClient(store_path, cache_mb=64) as local:
        assert local.scenes() == http.get("/scenes").json()["scenes"]
        assert local.sensors() == http.get("/sensors").json()
        for outputs in ("raw,gain,mask,meta", "raw,gain,srgb,illum,mixture,weights,meta"):
            spec = SPEC | {"outputs": outputs}
            got = local.sample(**spec)
            z = np.load(io.BytesIO(http.get("/sample", params=spec).content))
            for k in z.files:
                if k == "meta":
                    want = json.loads(str(z["meta"]))
                    want.pop("timings_ms"), got.meta.pop("timings_ms")
                    assert got.meta == want
                else:
                    np.testing.assert_array_equal(getattr(got, k), z[k], err_msg=k)
        batch = local.batch([SPEC | {"seed": s} for s in (1, 2)])
        assert [b.meta["seed"] for b in batch] == [1, 2]


def test_local_errors_are_the_clients_typed_errors(store_path):
    with LocalClient(store_path, cache_mb=64) as local:
        with pytest.raises(ic.NotFoundError, match="did you mean"):
            local.sample(**(SPEC | {"sensor": "XYZZ"}))
        with pytest.raises(ic.InvalidRequestError, match="crop"):
            local.sample(**(SPEC | {"crop": "60,40,32,24"}))
        with pytest.raises(ic.InvalidRequestError):
            local.sample(**(SPEC | {"outputs": "rawr"}))
    with pytest.raises(ic.NotFoundError, match="no illumix store"):
        LocalClient(str(Path(store_path).parent / "nothing-here"))


def test_local_dataset_equals_the_http_dataset(store_path, http, tmp_path):
    torch = pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    from torch.utils.data import DataLoader

    args = dict(scenes=["synth/v0"], illuminants=["A", "D65", "FL11"], sensors=["XYZ"], crop=(16, 16),
                epoch_length=8, batch_size=4, seed=5)
    local = ic.IllumixDataset(store=store_path, cache_mb=64, **args)
    assert local._local.ctx.cache.total_cost > 0  # warmed at construction
    items = {int(b["index"][j]): b["raw"][j] for b in DataLoader(local, batch_size=2, num_workers=2)
             for j in range(len(b["index"]))}
    assert sorted(items) == list(range(8))
    # the same specs through the HTTP path of the same composition code
    for i, raw in items.items():
        spec = local.spec(i)
        z = np.load(io.BytesIO(http.post("/batch", json={"samples": [spec]}).content))
        want = z["0/raw"].transpose(2, 0, 1)
        torch.testing.assert_close(raw, torch.from_numpy(want / want.max()))


def test_the_dataset_passes_dtype_to_every_item_spec(store_path):
    torch = pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    ds = ic.IllumixDataset(store=store_path, warm=False, cache_mb=64, scenes=["synth/v0"], illuminants=["A"],
                           sensors=["XYZ"], crop=(8, 8), epoch_length=2, dtype="float16")
    assert all(ds.spec(i)["dtype"] == "float16" for i in range(2))
    item = next(iter(ds))  # composed locally: float32 arrays whatever the wire dtype
    assert item["raw"].dtype == torch.float32 and item["raw"].shape == (3, 8, 8)


def test_persistent_workers_follow_consecutive_epochs(store_path):
    """set_epoch() in the main process never reaches a persistent worker's copy of the dataset;
    each iteration of that copy is the next epoch, so consecutive set_epoch calls are followed."""
    pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    from torch.utils.data import DataLoader

    ds = ic.IllumixDataset(store=store_path, cache_mb=64, scenes=["synth/v0"], illuminants=["A", "D65", "FL11"],
                           sensors=["XYZ"], crop=(8, 8), epoch_length=8, batch_size=2, seed=4, outputs=("raw",),
                           auto_epoch=True)
    loader = DataLoader(ds, batch_size=4, num_workers=2, persistent_workers=True)
    for epoch in range(3):
        ds.set_epoch(epoch)
        seeds = {int(i): json.loads(m)["seed"] for b in loader for i, m in zip(b["index"], b["meta"])}
        assert seeds == {i: ds.spec(i, epoch)["seed"] for i in range(8)}, epoch
    # without set_epoch, iterating again is the next epoch; set_epoch goes back
    ds.set_epoch(0)
    first = [json.loads(it["meta"])["seed"] for it in ds]
    assert [json.loads(it["meta"])["seed"] for it in ds] == [ds.spec(i, 1)["seed"] for i in range(8)]
    ds.set_epoch(0)
    assert [json.loads(it["meta"])["seed"] for it in ds] == first
    ds.auto_epoch = False  # the default: iterating again repeats the epoch
    assert [json.loads(it["meta"])["seed"] for it in ds] == [json.loads(it["meta"])["seed"] for it in ds]


def test_device_items_without_raw_or_gain(store_path):
    pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    ds = ic.IllumixDataset(store=store_path, device="cpu", cache_mb=64, scenes=["synth/v0"], illuminants=["A", "D65"],
                           sensors=["XYZ"], crop=(8, 8), epoch_length=2, outputs=("weights", "mask"))
    item = next(iter(ds))
    assert item["weights"].shape == (2, 8, 8) and item["mask"].shape == (1, 8, 8)


def test_ccm_map_of_a_device_sample_stays_on_the_device(store_path):
    """``Sample.ccm_map()`` of a local ``device=`` sample (tensors): a tensor on that device, equal
    to the numpy rebuild of the same sample."""
    torch = pytest.importorskip("torch", reason="torch is not installed (pip install torch==2.13.0)")
    spec = {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65", "outputs": ["mixture", "meta"]}
    with LocalClient(store_path, cache_mb=64, device="cpu") as dev, LocalClient(store_path, cache_mb=64) as cpu:
        t, a = dev.sample(**spec).ccm_map(), cpu.sample(**spec).ccm_map()
    assert isinstance(t, torch.Tensor) and t.device.type == "cpu" and t.shape == a.shape
    np.testing.assert_allclose(t.numpy(), a, rtol=1e-5, atol=1e-7)
