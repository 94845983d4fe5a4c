"""``GET /sample?format=dng|exr``: the DNG read back by libraw (``rawpy``) — digital numbers, levels,
CFA pattern, as-shot white balance against the ground truth computed independently here — and the
OpenEXR read back equal to the npz arrays, bit for bit; the refusals."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

rawpy = pytest.importorskip("rawpy", reason="the export extra installs rawpy (pip install -e '.[export]')")
pytest.importorskip("pidng", reason="the export extra installs pidng")
pytest.importorskip("OpenEXR", reason="the export extra installs OpenEXR")
from server_testutil import synthetic_service_fixtures

from illumix.retarget.grid import DEFAULT_GRID
from illumix.retarget.illuminants import illuminant_spd
from illumix.retarget.sensors import get_sensor

SENSOR = "Nikon 5100 (NPL)"
BLACK, WHITE = 64, 4095  # the DNG's levels without noise= (the export's default sensor levels)


store_path, client = synthetic_service_fixtures("files", illumination=True)


def get(client, **params):
    r = client.get("/sample", params={"scene": "synth", "sensor": SENSOR, "seed": 3, **params})
    assert r.status_code == 200, r.text
    return r


def npz(client, **params) -> tuple[dict[str, np.ndarray], dict]:
    with np.load(io.BytesIO(get(client, format="npz", **params).content)) as z:
        arrays = {k: z[k] for k in z.files if k != "meta"}
        return arrays, json.loads(str(z["meta"])) if "meta" in z.files else None


def open_dng(body: bytes):
    return rawpy.imread(io.BytesIO(body))


def cfa_letters(d) -> str:
    """libraw's 2×2 pattern as letters, row by row (its second green, index 3, read as G)."""
    desc = d.color_desc.decode()
    return "".join(desc[i] for i in d.raw_pattern.ravel()).replace(desc[3], "G")


@pytest.mark.parametrize("bayer", [None, "GBRG"])
def test_dng_single_illuminant(client, bayer):
    """One lit group (view ``solo``): the mosaic is the auto-exposed raw quantised to
    ``round(64 + raw·(4095 − 64))``; libraw's camera white balance is 1 / the illuminant's white point
    seen by the sensor (computed here from the SPD and the curves) to the rationals' 1e-6."""
    q = {"view": "solo", "illuminants": "A", **({"bayer": bayer} if bayer else {})}
    r = get(client, format="dng", outputs="raw", **q)
    assert r.headers["content-type"] == "image/x-adobe-dng"
    assert r.headers["content-disposition"] == 'attachment; filename="synth-solo-3.dng"'
    about = json.loads(r.headers["x-illumix-meta"])
    raw, meta = npz(client, outputs="raw,meta", exposure="auto", **q | {"bayer": bayer or "RGGB"})
    assert about["exposure_gain"] == meta["exposure_gain"]
    dn = np.clip(np.round(BLACK + raw["raw"].astype(np.float64) * (WHITE - BLACK)), 0, WHITE)
    w = get_sensor(SENSOR, DEFAULT_GRID).weights()
    wp = illuminant_spd("A", DEFAULT_GRID) @ w
    with open_dng(r.content) as d:
        np.testing.assert_array_equal(d.raw_image, dn.astype(np.uint16))
        assert list(d.black_level_per_channel) == [BLACK] * 4 and d.white_level == WHITE
        assert cfa_letters(d) == (bayer or "RGGB")
        wb = np.array(d.camera_whitebalance[:3])
        np.testing.assert_allclose(wb / wb[1], wp[1] / wp, rtol=1e-5)
    np.testing.assert_allclose(meta["illuminants"][0]["white_point_rgb"], wp / wp[1], rtol=1e-5)
    # asked without outputs=: a DNG holds the raw
    assert get(client, format="dng", **q).content == r.content


def test_dng_mixed_light_neutral_is_the_mean_white_point(client):
    """Two lit groups: AsShotNeutral = the mean over valid pixels of Σ_g mixture_g · white_g — with
    ``gt=formula`` the mean of the ``illum`` output — computed here from the npz arrays."""
    q = {"view": "v0", "illuminants": "A,D65", "gt": "formula"}
    r = get(client, format="dng", outputs="raw,meta", **q)
    a, meta = npz(client, outputs="mixture,mask,illum,meta", **q)
    wps = np.array([i["white_point_rgb"] for i in meta["illuminants"]], np.float64)
    valid = a["mask"]
    model = np.einsum("hwk,kc->hwc", a["mixture"].astype(np.float64), wps)[valid].mean(axis=0)
    mean_illum = a["illum"].astype(np.float64)[valid].mean(axis=0)
    np.testing.assert_allclose(mean_illum / mean_illum[1], model / model[1], rtol=1e-5)
    with open_dng(r.content) as d:
        wb = np.array(d.camera_whitebalance[:3])
        np.testing.assert_allclose(wb / wb[1], model[1] / model, rtol=1e-5)
    assert json.loads(r.headers["x-illumix-meta"])["encoding"]["cfa"] == "RGGB"


def test_dng_linear_with_bayer_none(client):
    """``bayer=none``: a LinearRaw DNG (3 samples per pixel, no mosaic) of the RGB raw, which libraw
    opens with the same digital numbers, levels and as-shot neutral as the Bayer one's."""
    q = {"view": "solo", "illuminants": "A"}
    r = get(client, format="dng", bayer="none", **q)
    raw, _ = npz(client, outputs="raw", exposure="auto", **q)
    dn = np.clip(np.round(BLACK + raw["raw"].astype(np.float64) * (WHITE - BLACK)), 0, WHITE).astype(np.uint16)
    assert raw["raw"].ndim == 3 and json.loads(r.headers["x-illumix-meta"])["encoding"]["cfa"] is None
    with open_dng(r.content) as d, open_dng(get(client, format="dng", **q).content) as bayer:
        assert d.raw_type == rawpy.RawType.Stack
        np.testing.assert_array_equal(d.raw_image[..., :3], dn)
        assert list(d.black_level_per_channel) == [BLACK] * 4 and d.white_level == WHITE
        np.testing.assert_allclose(d.camera_whitebalance[:3], bayer.camera_whitebalance[:3], rtol=1e-6)
    assert get(client, format="npz", bayer="NONE", outputs="raw", **q).content == get(
        client, format="npz", outputs="raw", **q).content  # elsewhere none is no mosaic, as omitted


def test_dng_with_noise_holds_the_sensor_models_numbers(client):
    """``noise=``: the noisy digital numbers as ``/sample`` composes them, the model's levels."""
    q = {"view": "v0", "illuminants": "A,D65", "noise": "full_well:5000;black_level:128;bit_depth:14", "bayer": "BGGR"}
    r = get(client, format="dng", **q)
    raw, _ = npz(client, outputs="raw", **q)
    with open_dng(r.content) as d:
        np.testing.assert_array_equal(d.raw_image, raw["raw"].astype(np.uint16))
        assert list(d.black_level_per_channel) == [128] * 4 and d.white_level == 2**14 - 1
        assert cfa_letters(d) == "BGGR"


def test_exr_round_trip_equals_the_npz(client, tmp_path):
    """Every output read back from the EXR (with the reader of :mod:`imagefiles.layered_exr` and
    with OpenEXR alone) equals the npz's array bit for bit; the spectra are Fichet et al.'s channels."""
    import OpenEXR

    from illumix.imagefiles.layered_exr import read_layered_exr
    from illumix.imagefiles.spectral_exr import read_spectral_exr

    outputs = "raw,gain,ccm,srgb,weights,mask,illum,mixture,reflectance,illumination,meta"
    q = {"view": "v0", "illuminants": "FL11,D50", "crop": "8,4,40,32"}
    r = get(client, format="exr", outputs=outputs, **q)
    assert r.headers["content-type"] == "image/x-exr"
    ref, meta = npz(client, outputs=outputs, **q)
    back, header = read_layered_exr(r.content)
    assert set(back) == set(ref)
    for k, a in ref.items():
        assert back[k].dtype == a.dtype and back[k].shape == a.shape, k
        np.testing.assert_array_equal(back[k], a, err_msg=k)
    sent = json.loads(header["illumixMeta"])
    for k in ("scene", "view", "seed", "illuminants", "exposure_gain", "ground_truth", "size"):
        assert sent[k] == meta[k], k
    assert header["spectralLayoutVersion"] == "1.0"
    assert header["emissiveUnits"].startswith("relative") and float(header["illumixBandWidthNm"]) == 5.0
    path = tmp_path / "sample.exr"
    path.write_bytes(r.content)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {n: c.pixels for n, c in f.channels().items()}
    np.testing.assert_array_equal(ch["raw.R"], ref["raw"][..., 0])
    np.testing.assert_array_equal(ch["ccm.GB"], ref["ccm"][..., 1, 2])
    np.testing.assert_array_equal(ch["mixture.lamp"], ref["mixture"][..., 1])
    np.testing.assert_array_equal(ch["mask"], ref["mask"].astype(np.float32))
    assert "S0.550,0nm" in ch and "T.550,0nm" in ch
    wl, cube, _ = read_spectral_exr(path, "T")
    np.testing.assert_array_equal(wl, DEFAULT_GRID.wavelengths)
    np.testing.assert_array_equal(cube, ref["reflectance"])


def test_exr_of_a_bayer_raw_without_meta(client):
    r = get(client, format="exr", outputs="raw", bayer="RGGB", view="v0")
    from illumix.imagefiles.layered_exr import read_layered_exr

    back, header = read_layered_exr(r.content)
    ref, _ = npz(client, outputs="raw", bayer="RGGB", view="v0")
    np.testing.assert_array_equal(back["raw"], ref["raw"])
    assert "illumixMeta" not in header and json.loads(header["illumixLayers"])["raw"]["channels"] == ["raw"]


@pytest.mark.parametrize("params, status, words", [
    ({"format": "dng", "outputs": "gain"}, 422, "exactly one image output, one of raw"),
    ({"format": "dng", "outputs": "raw,mask"}, 422, "exactly one image output"),
    ({"format": "dng", "outputs": "raw", "dtype": "float16"}, 422, "dtype=float16 is for format=npz or arrays"),
    ({"format": "exr", "dtype": "float16"}, 422, "format=exr is float32"),
    ({"format": "exr", "outputs": "meta"}, 422, "format=exr writes array outputs"),
    ({"format": "dng", "size": "21x40"}, 422, "at least 22x22 pixels"),
    ({"format": "dng", "noise": "black_level:64.5"}, 422, "whole black and white levels"),
    ({"format": "dgn"}, 422, "format"),
])
def test_refusals_are_one_line(client, params, status, words):
    r = client.get("/sample", params={"scene": "synth", "view": "v0", **params})
    body = r.json()
    assert r.status_code == status and words in body["detail"], body
    assert "\n" not in body["detail"] and body["status"] == status


@pytest.mark.parametrize("fmt, module", [("dng", "pidng"), ("exr", "OpenEXR")])
def test_without_the_export_extra_a_501_names_the_install(client, monkeypatch, fmt, module):
    import importlib.util

    from illumix.service import file_downloads

    real = importlib.util.find_spec
    monkeypatch.setattr(file_downloads.importlib.util, "find_spec", lambda name, *a: None if name == module
                        else real(name, *a))
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "format": fmt, "outputs": "raw"})
    body = r.json()
    assert r.status_code == 501 and body["code"] == "not_installed", body
    assert "pip install 'illumix[export]'" in body["detail"] and module in body["detail"]
