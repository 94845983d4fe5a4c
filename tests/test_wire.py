"""Transfer less (issue 19): the ``arrays`` container (server encoder ↔ client decoder), ``dtype=float16``
with per-output power-of-two scales, and the CCM map left out of the default outputs (the client
rebuilds it exactly with ``Sample.ccm_map()``)."""

from __future__ import annotations

import asyncio
import io
import json

import illumix_client as ic
import numpy as np
import pytest
import synthetic_store as synth
from fastapi.testclient import TestClient
from illumix_client import arrays_format as dec
from illumix_client.sample import parse_batch, parse_sample
from server_testutil import ThreadServer

from illumix.service import arrays_format as enc
from illumix.service.app import create_app
from illumix.service.encoding import half_precision
from illumix.engine.spec import DEFAULT_OUTPUTS
from illumix.store import CubeStore

V0 = {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "FL11,D65", "intensities": "1,0.5", "seed": 3}
EVERY = "raw,gain,ccm,srgb,weights,mask,illum,mixture,meta"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    path = tmp_path_factory.mktemp("wire") / "store"
    synth.build(path, illumination=True)
    return create_app(CubeStore.open(str(path), mode="r"), cache_mb=64)


@pytest.fixture(scope="module")
def client(app):
    with TestClient(app) as c:
        yield c


def get(client, **params):
    r = client.get("/sample", params=V0 | params)
    assert r.status_code == 200, r.text
    return r


def same_meta(a: dict, b: dict) -> bool:
    """Metadata equal but for the timings."""
    return {k: v for k, v in a.items() if k != "timings_ms"} == {k: v for k, v in b.items() if k != "timings_ms"}


def npz(resp) -> dict:
    with np.load(io.BytesIO(resp.content)) as z:
        return {k: z[k] for k in z.files}


# -- the container ----------------------------------------------------------------------------------
def sample_arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"f32": rng.random((5, 7, 3), dtype=np.float32), "scalar": np.array(2.5), "empty": np.zeros((0, 3), np.float32),
            "mask": rng.random((5, 7)) > 0.5, "half": rng.random(9).astype(np.float16), "i64": np.arange(-3, 4),
            "u8": np.arange(200, 256, dtype=np.uint8).reshape(8, 7), "c64": np.array([1 + 2j], np.complex64),
            "strided": rng.random((6, 4), dtype=np.float32).T,  # non-contiguous: sent in C order
            "big_endian": np.arange(6, dtype=">f8").reshape(2, 3), "empty_last": np.zeros((2, 0), bool)}


def test_container_roundtrip_including_0d_empty_and_bool():
    arrays = sample_arrays()
    body = enc.encode(arrays, {"f32": 0.25}, meta={"scene": "s", "n": [1, 2]})
    raw = body.tobytes()
    assert len(raw) == body.nbytes and raw[:8] == dec.MAGIC and raw[8] == dec.VERSION
    got, header = dec.decode(raw)
    assert list(got) == list(arrays) and header["meta"] == {"scene": "s", "n": [1, 2]}
    assert dec.scales(header) == {"f32": 0.25}
    for k, a in arrays.items():
        assert got[k].shape == a.shape and got[k].dtype == a.dtype.newbyteorder("<"), k
        np.testing.assert_array_equal(got[k], a, err_msg=k)
        assert header["arrays"][k]["offset"] % 64 == 0, k
        assert not got[k].flags.writeable  # views of immutable bytes: read-only, no copy
    assert header["arrays"]["mask"]["dtype"] == "|b1" and got["scalar"].ndim == 0
    w, _ = dec.decode(bytearray(raw))  # over a bytearray (what the client reads into): writable views
    assert w["f32"].flags.writeable and np.shares_memory(w["f32"], w["mask"]) is False
    assert enc.MAGIC == dec.MAGIC and enc.VERSION == dec.VERSION and enc.PREFIX.format == dec.PREFIX.format


def test_encoder_does_not_copy_contiguous_arrays():
    a = np.arange(4096, dtype=np.float32).reshape(64, 64)
    body = enc.encode({"a": a})
    assert any(np.shares_memory(np.frombuffer(c, np.uint8), a) for c in body.chunks)


def test_empty_container_and_memoryview_input():
    body = enc.encode({}).tobytes()
    arrays, header = dec.decode(memoryview(body))
    assert arrays == {} and header == {"arrays": {}}


@pytest.mark.parametrize("cut", [0, 5, 15, 17, 100, -1])
def test_truncated_body_is_a_clear_error(cut):
    body = enc.encode(sample_arrays(), meta={"x": 1}).tobytes()
    with pytest.raises(ic.IllumixError) as e:
        dec.decode(body[:cut] if cut >= 0 else body[:-3])
    assert "not a valid illumix arrays body" in str(e.value) and "\n" not in str(e.value)
    assert "truncated" in str(e.value) or "header" in str(e.value)


def test_bad_magic_version_and_header_are_clear_errors():
    body = bytearray(enc.encode({"a": np.ones(3)}).tobytes())
    for mutate, needle in ((lambda b: b.__setitem__(slice(0, 8), b"PK\x03\x04\0\0\0\0"), "magic"),
                           (lambda b: b.__setitem__(8, 9), "version 9"),
                           (lambda b: b.__setitem__(16, ord("[")), "unreadable header")):
        bad = bytearray(body)
        mutate(bad)
        with pytest.raises(ic.IllumixError, match=needle):
            dec.decode(bytes(bad))
    lying = json.loads(bytes(body[16:16 + int.from_bytes(body[12:16], "little")]))
    lying["arrays"]["a"]["nbytes"] = 16  # 3 float64 are 24 bytes
    text = json.dumps(lying).encode()
    forged = enc.PREFIX.pack(enc.MAGIC, enc.VERSION, len(text)) + text + bytes(200)
    with pytest.raises(ic.IllumixError, match="is not nbytes"):
        dec.decode(forged)
    wrapping = json.loads(text)  # 2**32 × 2**32 wraps to 0 in int64: must not pass for nbytes 0
    for shape in ([2**32, 2**32], [0, 2**70]):  # the second: 0 elements, a side numpy cannot hold
        wrapping["arrays"]["a"].update(shape=shape, nbytes=0)
        text = json.dumps(wrapping).encode()
        with pytest.raises(ic.IllumixError, match="is not nbytes"):
            dec.decode(enc.PREFIX.pack(enc.MAGIC, enc.VERSION, len(text)) + text + bytes(200))


# -- the service ------------------------------------------------------------------------------------
def test_arrays_equal_npz_values_for_every_output(client):
    a = get(client, outputs=EVERY, format="arrays")
    assert a.headers["content-type"] == "application/x-illumix-arrays"
    assert int(a.headers["content-length"]) == len(a.content)
    n = npz(get(client, outputs=EVERY))
    got, header = dec.decode(a.content)
    assert set(got) == set(n) - {"meta"} and same_meta(header["meta"], json.loads(str(n["meta"])))
    for k, v in got.items():
        assert v.dtype == n[k].dtype and v.shape == n[k].shape, k
        np.testing.assert_array_equal(v, n[k], err_msg=k)
    s = parse_sample(a.content)
    np.testing.assert_array_equal(s.ccm, n["ccm"])
    assert s.meta["scene"] == "synth" and s.scales == {}


def test_default_outputs_are_the_users_four_and_the_rest_of_the_ground_truth(client):
    """Issue 34: raw, gain map, CCM map and sRGB by default (the CCM map had been dropped)."""
    assert {"raw", "gain", "ccm", "srgb", "mixture", "meta"} <= set(DEFAULT_OUTPUTS)
    got, header = dec.decode(get(client, format="arrays").content)
    assert {"raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture"} <= set(got)
    assert "meta" in header


def test_float16_scales_and_error_bound(client):
    ref = npz(get(client, outputs=EVERY))
    r = get(client, outputs=EVERY, format="arrays", dtype="float16")
    stored, header = dec.decode(r.content)
    scales = dec.scales(header)
    assert header["meta"]["encoding"]["scales"] == scales and header["meta"]["encoding"]["dtype"] == "float16"
    assert set(scales) == set(stored) - {"mask"} and stored["mask"].dtype == bool
    for k, scale in scales.items():
        assert stored[k].dtype == np.float16, k
        assert np.log2(scale) == round(np.log2(scale)), (k, scale)  # a power of two
        peak = float(np.abs(stored[k].astype(np.float32)).max())
        assert peak == 0 or 2**14 <= peak <= 2**15, (k, peak)  # the maximum in [0.5, 1) x 2^15
    s = parse_sample(r.content)
    assert s.raw.dtype == np.float32 and s.scales == {}
    # The scale is a power of two, so scaling is exact both ways; the maximum is stored in
    # [2^14, 2^15), so a value >= 2^-14 of it is stored >= 1, well above float16's smallest normal
    # number (2^-14): only rounding to float16's 11 significant bits remains, at most half an ulp,
    # i.e. 2^-11 relative.
    for k in ("raw", "gain", "srgb", "illum", "mixture", "ccm"):
        big = np.abs(ref[k]) >= 2**-14 * np.abs(ref[k]).max()
        err = np.abs(getattr(s, k) - ref[k])[big] / np.abs(ref[k])[big]
        assert err.max() <= 2**-11, (k, err.max())
    kept = parse_sample(r.content, keep_float16=True)
    assert kept.raw.dtype == np.float16 and kept.scales == scales
    np.testing.assert_array_equal(kept.raw.astype(np.float32) * np.float32(kept.scales["raw"]), s.raw)
    np.testing.assert_array_equal(kept.ccm_map(), s.ccm)  # the served ccm, scaled back
    light = parse_sample(get(client, outputs="mixture,meta", format="arrays", dtype="float16").content, keep_float16=True)
    # from the float16 mixture (each share within 2^-11 relative): within 2^-11 Σ_g |CCM_g| of the float32 map
    bound = 2**-11 * np.abs([i["ccm"] for i in light.meta["illuminants"]]).sum(0)
    assert (np.abs(light.ccm_map() - ref["ccm"]) <= bound + 1e-7).all()


def test_float16_npz_carries_its_scales_with_or_without_meta(client):
    z = npz(get(client, outputs="raw,gain,mask", dtype="float16"))
    assert z["raw"].dtype == np.float16 and z["mask"].dtype == bool and "meta" not in z
    scales = json.loads(str(z["scales"]))
    assert set(scales) == {"raw", "gain"}
    ref = npz(get(client, outputs="raw,gain"))
    s = parse_sample(get(client, outputs="raw,gain,mask", dtype="float16").content)
    np.testing.assert_allclose(s.raw, ref["raw"], rtol=2**-11, atol=2**-14 * float(ref["raw"].max()))


@pytest.mark.parametrize("gain_peak, raw_peak", [(1e6, 1e30), (1.0, 1e-30), (0.0, 3.0)])
def test_float16_never_overflows_or_underflows_to_nan(gain_peak, raw_peak):
    rng = np.random.default_rng(1)
    raw = (rng.random((16, 16, 3)) * raw_peak).astype(np.float32)
    gain = (1 + rng.random((16, 16, 3)) * (gain_peak - 1) if gain_peak else np.zeros((16, 16, 3))).astype(np.float32)
    half, scales = half_precision({"raw": raw, "gain": gain, "mask": raw[..., 0] > 0})
    assert half["mask"].dtype == bool and all(np.isfinite(half[k]).all() for k in ("raw", "gain"))
    got = parse_sample(enc.encode(half, scales).tobytes())
    for ref, out in ((raw, got.raw), (gain, got.gain)):
        assert out.dtype == np.float32 and np.isfinite(out).all()
        big = np.abs(ref) >= 2**-14 * np.abs(ref).max() if ref.any() else np.zeros(ref.shape, bool)
        assert (np.abs(out - ref)[big] <= 2**-11 * np.abs(ref)[big]).all()
        np.testing.assert_array_equal(out[ref == 0], 0)


def test_float16_of_a_huge_sample_is_finite(client):
    r = get(client, outputs="raw,gain,meta", format="arrays", dtype="float16", intensities="1e9,1e9",
            exposure="1e11")
    s = parse_sample(r.content)
    assert np.isfinite(s.raw).all() and np.isfinite(s.gain).all() and s.raw.max() > 1e15


@pytest.mark.parametrize("fmt", ["png", "tiff"])
def test_float16_with_an_image_format_is_422(client, fmt):
    r = client.get("/sample", params=V0 | {"outputs": "raw", "format": fmt, "dtype": "float16"})
    assert r.status_code == 422 and "dtype=float16 is for format=npz or arrays" in r.json()["detail"]
    assert client.get("/sample", params=V0 | {"dtype": "float64"}).status_code == 422
    r = client.post("/batch", json={"samples": [V0 | {"outputs": "raw", "format": fmt}]})
    assert r.status_code == 422


def test_batch_in_arrays_format_equals_npz(client):
    items = [V0 | {"outputs": "raw,gain,meta"}, V0 | {"crop": "0,0,16,8", "outputs": "gain,mask"},
             V0 | {"outputs": "raw,mask,meta", "dtype": "float16"}]
    a = client.post("/batch", json={"samples": [it | {"format": "arrays"} for it in items]})
    assert a.status_code == 200 and a.headers["content-type"] == "application/x-illumix-arrays"
    arrays, header = dec.decode(a.content)
    assert [sorted(it) for it in header["items"]] == [["meta"], [], ["meta"]]
    assert set(dec.scales(header)) == {"2/raw"} and arrays["2/raw"].dtype == np.float16
    n = client.post("/batch", json={"samples": items})
    assert n.status_code == 200 and "2/scales" in npz(n)
    for x, y, it in zip(parse_batch(a.content, 3), parse_batch(n.content, 3), items):
        for k in ("raw", "gain", "mask"):
            if k in it["outputs"]:
                np.testing.assert_array_equal(getattr(x, k), getattr(y, k), err_msg=k)
        assert same_meta(x.meta, y.meta)
    assert parse_batch(a.content, 3)[2].raw.dtype == np.float32
    mixed = client.post("/batch", json={"samples": [items[0] | {"format": "arrays"}, items[1]]})
    assert mixed.status_code == 422 and "same format" in mixed.json()["detail"]


# -- the CCM map, rebuilt ---------------------------------------------------------------------------
@pytest.mark.parametrize("gt", ["physical", "formula"])
@pytest.mark.parametrize("extra", [{}, {"crop": "4,2,40,30", "size": "20x15"}])
def test_ccm_map_rebuilds_the_served_ccm(client, gt, extra):
    ref = npz(get(client, outputs="ccm", gt=gt, **extra))["ccm"]
    s = parse_sample(get(client, outputs="mixture,meta", gt=gt, format="arrays", **extra).content)
    assert s.meta["ground_truth"]["method"] == gt and s.ccm is None
    got = s.ccm_map()
    assert got.dtype == np.float32 and got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-7)
    if gt == "formula":  # the formula's mixture is eq. 3.3's weights: they serve too
        w = parse_sample(get(client, outputs="weights,meta", gt=gt, format="arrays", **extra).content)
        np.testing.assert_allclose(w.ccm_map(), ref, rtol=1e-6, atol=1e-7)


def test_ccm_map_says_what_it_needs(client):
    with pytest.raises(ValueError, match="'meta'"):
        parse_sample(get(client, outputs="mixture", format="arrays").content).ccm_map()
    with pytest.raises(ValueError, match="'mixture'"):
        parse_sample(get(client, outputs="weights,meta", format="arrays").content).ccm_map()  # physical


# -- the client over HTTP ---------------------------------------------------------------------------
def test_client_defaults_to_arrays_and_can_ask_npz(app):
    with ThreadServer(app) as url:
        with ic.Client(url) as c, ic.Client(url, wire_format="npz") as z, ic.Client(url, keep_float16=True) as k:
            a, b = c.sample(**_spec(), outputs=EVERY), z.sample(**_spec(), outputs=EVERY)
            for name, v in a.arrays().items():
                np.testing.assert_array_equal(v, getattr(b, name), err_msg=name)
                assert v.flags.writeable, name
            assert same_meta(a.meta, b.meta)
            h = c.sample(**_spec(), outputs="raw,meta", dtype="float16")
            assert h.raw.dtype == np.float32 and h.meta["encoding"]["dtype"] == "float16"
            kept = k.batch([_spec() | {"outputs": "raw", "dtype": "float16"}])[0]
            assert kept.raw.dtype == np.float16 and set(kept.scales) == {"raw"}
            np.testing.assert_array_equal(kept.raw.astype(np.float32) * np.float32(kept.scales["raw"]), h.raw)
            got = c.batch([_spec(), _spec() | {"outputs": ["raw"]}])
            np.testing.assert_array_equal(got[1].raw, a.raw)
        with pytest.raises(ValueError, match="wire_format"):
            ic.Client(url, wire_format="zip")

        async def main():
            async with ic.AsyncClient(url) as ac:
                return await ac.sample(**_spec(), outputs="raw,mixture,meta")

        s = asyncio.run(main())
        np.testing.assert_array_equal(s.raw, a.raw)
        np.testing.assert_allclose(s.ccm_map(), a.ccm, rtol=1e-6, atol=1e-7)


def _spec() -> dict:
    return {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": ("FL11", "D65"), "intensities": (1, 0.5),
            "seed": 3}
