"""Denoised copies in the store: written with their cube, read by kind, checked by verify, refused
when inconsistent, and never claimed by metadata copied from another cube."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from illumix.retarget.grid import DEFAULT_GRID
from illumix.store import CubeMeta, CubeStore, StoreError, ViewMeta
from illumix.store.report import verify
from illumix.store.schema import DenoisedInfo
from tests import synthetic_store as synth

H, W, NB = 16, 12, DEFAULT_GRID.n_bands


def _store(tmp_path):
    st = CubeStore.open(str(tmp_path / "st"), mode="a")
    st.write_view("s", "v", ViewMeta(width=W, height=H, fov=45.0))
    return st


def _meta(**kw):
    return CubeMeta(grid=DEFAULT_GRID.to_dict(), spp=1, seed=0, scene_hash="x", **kw)


def test_roundtrip_by_kind(tmp_path):
    st = _store(tmp_path)
    rng = np.random.default_rng(0)
    cube, u, dc, du = (rng.uniform(0.1, 1.0, (H, W, NB)).astype(np.float32) for _ in range(4))
    meta = _meta(denoised=DenoisedInfo(method="dt-guides", params={"sigma_spatial": 4.0}))
    out = st.write_cube("s", "v", "g", cube, meta, illumination=u, denoised={"transport": dc, "illumination": du})
    assert out.denoised.storage.nbytes_stored > 0 and out.denoised.illumination_storage.nbytes_stored > 0
    assert out.storage.nbytes_stored < 2 * cube.nbytes  # the raw cube's own bytes, not the copies'
    for kind, want in (("transport", dc), ("illumination", du)):
        np.testing.assert_allclose(st.read_cube("s", "v", "g", kind=kind, denoised=True), want, rtol=1e-3)
    np.testing.assert_allclose(st.read_cube("s", "v", "g"), cube, rtol=1e-3)  # the raw stays
    np.testing.assert_allclose(st.read_cube("s", "v", "g", crop=(2, 3, 5, 4), denoised=True), dc[3:7, 2:7], rtol=1e-3)
    assert verify(st)["ok"]


def test_refusals(tmp_path):
    st = _store(tmp_path)
    cube = np.ones((H, W, NB), np.float32)
    with pytest.raises(StoreError, match="meta.denoised"):
        st.write_cube("s", "v", "a", cube, _meta(), denoised={"transport": cube})
    with pytest.raises(StoreError, match="needs the illumination cube"):
        st.write_cube("s", "v", "a", cube, _meta(denoised=DenoisedInfo(method="dt-guides")),
                      denoised={"transport": cube, "illumination": cube})
    with pytest.raises(StoreError, match="shape"):
        st.write_cube("s", "v", "a", cube, _meta(denoised=DenoisedInfo(method="dt-guides")),
                      denoised={"transport": cube[:4]})
    assert not st.groups("s", "v")  # nothing half-written
    # metadata naming copies the node does not get must not claim them
    out = st.write_cube("s", "v", "b", cube, _meta(denoised=DenoisedInfo(method="dt-guides")))
    assert out.denoised is None
    with pytest.raises(StoreError, match="no denoised transport copy"):
        st.read_cube("s", "v", "b", denoised=True)


def test_verify_finds_a_corrupt_copy(tmp_path):
    path = tmp_path / "store"
    synth.build(path, extras=False, denoised=True)
    st = CubeStore.open(str(path))
    assert verify(st)["ok"]
    node = path / "scenes" / "synth" / "v0" / "cubes" / "lamp" / "denoised" / "data"
    chunks = [p for p in node.rglob("*") if p.is_file() and p.name != "zarr.json"]
    shutil.rmtree(chunks[0].parent) if chunks[0].parent != node else chunks[0].unlink()
    rep = verify(CubeStore.open(str(path)))
    assert not rep["ok"] and any("denoised" in p["where"] for p in rep["problems"])
