"""Cube store: round trips, crops, listing and ordering, names, backends (local dir and fsspec)."""

from __future__ import annotations

import uuid
import warnings

import numpy as np
import pytest
import zarr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs
from store_testutil import H, NB, TILE, W, add_view, cube, meta, new_store

from illumix.store import CubeStore, StoreError, StoreKeyError, ViewMeta
from illumix.store.codec import REL_BOUND_F16


def _aovs(rng: np.random.Generator) -> dict:
    return {"albedo": rng.random((H, W, 3), dtype=np.float32),
            "normal": rng.standard_normal((H, W, 3)).astype(np.float32),
            "depth": rng.random((H, W)).astype(np.float32) * 5,
            "mask": rng.random((H, W)) > 0.3}


def test_round_trip_values_metadata_and_aovs(tmp_path):
    rng = np.random.default_rng(0)
    st = new_store(tmp_path / "st")
    aovs = _aovs(rng)
    vm = st.write_view("kitchen", "v0", ViewMeta(width=W, height=H, origin=(0, 1.5, 3), target=(0, 1, 0),
                                                 up=(0, 1, 0), fov=55, groups=["window", "lamp"],
                                                 scene_hash="abc"), aovs)
    assert vm.aovs == ["albedo", "depth", "mask", "normal"]
    c = cube()
    m = meta(emission_name="flat", renderer={"name": "mitsuba", "version": "3.6", "variant": "scalar_spectral",
                                             "settings": {"max_depth": 8}}, spp=64, seed=7, scene_hash="abc",
             denoiser="none")
    stored = st.write_cube("kitchen", "v0", "window", c, m)
    got = st.read_cube("kitchen", "v0", "window")
    assert got.dtype == np.float32 and got.shape == (H, W, NB)
    # Exponent-scaled float16: |x̂ − x| ≤ 2⁻¹¹|x| (round-to-nearest, 11-bit significand; scales exact).
    assert stored.storage.dtype == "float16"
    assert np.all(np.abs(got - c) <= REL_BOUND_F16 * np.abs(c))
    assert np.any(got != c)  # it really is float16 storage, not a float32 copy
    back = st.cube_meta("kitchen", "v0", "window")
    assert back == stored
    assert (back.spp, back.seed, back.scene_hash, back.renderer.settings) == (64, 7, "abc", {"max_depth": 8})
    assert back.model_extra == {"denoiser": "none"} and back.emission == [1.0] * NB
    assert back.created.endswith("Z") and back.stats.max == c.reshape(-1, NB).max(0).tolist()
    assert st.view_meta("kitchen", "v0") == vm and vm.model_extra == {"scene_hash": "abc"}
    for name, a in aovs.items():
        assert np.array_equal(st.read_aov("kitchen", "v0", name), a.astype(st.read_aov("kitchen", "v0", name).dtype))
    assert st.read_aov("kitchen", "v0", "mask").dtype == np.bool_
    assert np.array_equal(st.read_aov("kitchen", "v0", "depth", crop=(5, 7, 20, 9)), aovs["depth"][7:16, 5:25])
    ro = CubeStore.open(tmp_path / "st", mode="r")
    assert np.array_equal(ro.read_cube("kitchen", "v0", "window"), got)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # zarr warns about any directory that is not a zarr node
        members = dict(zarr.open_group(tmp_path / "st", mode="r").members(max_depth=None))
    assert members["scenes/kitchen/v0/cubes/window/data"].shape == (H, W, NB)
    with pytest.raises(StoreError, match="read-only"):
        ro.write_cube("kitchen", "v0", "lamp", c, m)


@pytest.fixture(scope="module")
def filled(tmp_path_factory):
    st = new_store(tmp_path_factory.mktemp("crop") / "st")
    add_view(st)
    st.write_cube("s", "v", "g", cube(seed=1), meta())
    return st, st.read_cube("s", "v", "g")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=hs.data())
def test_crop_read_equals_crop_of_full_read(filled, data):
    st, full = filled
    x = data.draw(hs.integers(0, W - 1))
    y = data.draw(hs.integers(0, H - 1))
    w = data.draw(hs.integers(1, W - x))
    h = data.draw(hs.integers(1, H - y))
    assert np.array_equal(st.read_cube("s", "v", "g", crop=(x, y, w, h)), full[y:y + h, x:x + w])


def test_crop_reads_only_the_chunks_it_overlaps(filled, monkeypatch):
    st, full = filled
    st.close()  # fresh array handles: all reads below go through the patched store
    cls = type(st.backend.zstore)  # zarr copies the store object per array: patch the class
    seen: list[str] = []
    orig = cls.get

    async def counting(self, key, *a, **k):
        seen.append(key)
        return await orig(self, key, *a, **k)

    monkeypatch.setattr(cls, "get", counting)
    out = st.read_cube("s", "v", "g", crop=(40, 10, 20, 30))  # x 40-59 -> tile col 1; y 10-39 -> rows 0, 1
    assert np.array_equal(out, full[10:40, 40:60])
    chunks = sorted(k.split("/cubes/g/")[1] for k in seen if "/c/" in k)
    # data tiles are 32 px, exponent tiles 128 px (store.layout.exponent_chunks)
    assert chunks == ["data/c/0/1/0", "data/c/1/1/0", "exponent/c/0/0"]


def test_band_subset_and_bad_crops(filled):
    st, full = filled
    idx = [0, 5, 62]
    assert np.array_equal(st.read_cube("s", "v", "g", crop=(3, 4, 50, 30), bands=idx), full[4:34, 3:53][..., idx])
    for bad in [(0, 0, W + 1, 1), (-1, 0, 2, 2), (0, 0, 0, 5), (70, 40, 20, 20), ("a", 0, 1, 1)]:
        with pytest.raises(StoreError, match="crop"):
            st.read_cube("s", "v", "g", crop=bad)
    with pytest.raises(StoreError, match="bands"):
        st.read_cube("s", "v", "g", bands=[63])


def test_listing_order_empty_groups_and_lookup_errors(tmp_path):
    st = new_store(tmp_path / "st")
    add_view(st, groups=["window", "lamp"])
    c = cube()
    for g in ["zeta", "lamp", "alpha"]:
        st.write_cube("s", "v", g, c, meta())
    st.mark_empty("s", "v", "window", meta(emission_name="D65"))
    # declared order first, then undeclared ones in order of first write (not alphabetical)
    assert st.groups("s", "v") == ["window", "lamp", "zeta", "alpha"]
    assert st.scenes() == ["s"] and st.views("s") == ["v"]
    assert st.is_complete("s", "v", "window") and not st.is_complete("s", "v", "nope")
    z = st.read_cube("s", "v", "window", crop=(1, 2, 3, 4))
    assert z.shape == (4, 3, NB) and not z.any()
    em = st.cube_meta("s", "v", "window")
    assert em.empty and em.storage.dtype == "none" and em.emission_name == "D65"
    with pytest.raises(StoreKeyError, match="did you mean 'lamp'") as ei:
        st.read_cube("s", "v", "lamb")
    assert ei.value.kind == "group" and "zeta" in ei.value.known
    with pytest.raises(StoreKeyError, match="no scene 'x'"):
        st.views("x")
    with pytest.raises(StoreKeyError, match="no view 'w'"):
        st.read_cube("s", "w", "lamp")
    with pytest.raises(StoreError, match="already exists"):
        st.write_cube("s", "v", "lamp", c, meta())
    st.write_cube("s", "v", "lamp", 2 * c, meta(), overwrite=True)
    assert np.allclose(st.read_cube("s", "v", "lamp"), 2 * c, rtol=REL_BOUND_F16, atol=0)
    assert st.groups("s", "v") == ["window", "lamp", "zeta", "alpha"]  # overwrite keeps the place
    st.delete("s", "v", "zeta")
    assert st.groups("s", "v") == ["window", "lamp", "alpha"]


@pytest.mark.parametrize("name", ["../evil", "a/b", "a\\b", "", ".hidden", "x" * 129, "sp ace", "zarr.json", 7])
def test_unsafe_names_refused_and_nothing_written(tmp_path, name):
    st = new_store(tmp_path / "st")
    add_view(st)
    with pytest.raises(StoreError):
        st.write_cube("s", "v", name, cube(), meta())
    with pytest.raises(StoreError):
        st.write_view(name, "v", ViewMeta(width=W, height=H))
    assert st.groups("s", "v", include_incomplete=True) == [] and st.scenes() == ["s"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["st"]


def test_bad_cubes_refused_and_invisible(tmp_path):
    st = new_store(tmp_path / "st")
    add_view(st)
    c = cube()
    bad = c.copy()
    bad[3, 4, 5] = np.nan
    cases = [(c[:-1], "shape"), (bad, "x=4, y=3, band 5"), (c.astype(np.int32), "floating"),
             (np.full((H, W, NB), 1e39), "NaN/inf")]
    for arr, msg in cases:
        with pytest.raises(StoreError, match=msg):
            st.write_cube("s", "v", "g", arr, meta())
    with pytest.raises(StoreError, match="view 'nov'"):
        st.write_cube("s", "nov", "g", c, meta())
    assert st.groups("s", "v", include_incomplete=True) == [] and st.pending_writes() == []
    st.write_cube("s", "v", "g", c, meta())
    with pytest.raises(StoreError, match="has cubes"):
        st.write_view("s", "v", ViewMeta(width=W + 1, height=H))


def test_open_errors(tmp_path):
    with pytest.raises(StoreError, match="no illumix store"):
        CubeStore.open(tmp_path / "missing", mode="r")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "file.txt").write_text("x")
    with pytest.raises(StoreError, match="not empty"):
        CubeStore.open(tmp_path / "junk")
    with pytest.raises(StoreError, match="not a directory"):
        CubeStore.open(tmp_path / "junk" / "file.txt")
    with pytest.raises(StoreError, match="mode"):
        CubeStore.open(tmp_path / "x", mode="w")
    with pytest.raises(StoreError, match="codec"):
        CubeStore.open(tmp_path / "x", codec="gzip9")


def test_fsspec_url_backend_with_completion_marker():
    url = f"memory://illumix-test-{uuid.uuid4().hex}"
    st = CubeStore.open(url, tile=TILE)
    assert not st.backend.atomic_rename
    add_view(st)
    c = cube()

    def boom(done, total):
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError):
        st.write_cube("s", "v", "g", c, meta(), progress=boom)
    # the interrupted in-place write is marked incomplete: invisible to readers
    assert st.groups("s", "v") == [] and st.groups("s", "v", include_incomplete=True) == ["g"]
    with pytest.raises(StoreKeyError, match="incomplete"):
        st.read_cube("s", "v", "g")
    st.write_cube("s", "v", "g", c, meta())  # rerun completes it
    ro = CubeStore.open(url, mode="r")
    assert ro.groups("s", "v") == ["g"]
    full = ro.read_cube("s", "v", "g")
    assert np.all(np.abs(full - c) <= REL_BOUND_F16 * np.abs(c))
    assert np.array_equal(ro.read_cube("s", "v", "g", crop=(7, 3, 40, 30)), full[3:33, 7:47])
    from illumix.store.report import verify

    assert verify(ro)["ok"]


def test_cleanup_removes_stale_staging(tmp_path, monkeypatch):
    st = new_store(tmp_path / "st")
    add_view(st)
    monkeypatch.setattr(st.backend, "discard", lambda key: None)  # as if the writer died uncleanly

    def boom(done, total):
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError):
        st.write_cube("s", "v", "g", cube(), meta(), progress=boom)
    monkeypatch.undo()
    assert len(st.pending_writes()) == 1 and st.groups("s", "v", include_incomplete=True) == ["g"]
    assert st.cleanup(older_than_s=3600) == 0
    assert st.cleanup(older_than_s=0) == 1
    assert st.pending_writes() == [] and st.groups("s", "v", include_incomplete=True) == []
