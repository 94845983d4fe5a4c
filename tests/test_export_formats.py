"""``illumix export --format dng`` (rawpy reads it: levels, CFA, as-shot neutral = the GT white
point, ColorMatrix1 consistent with the sensor's D65 CCM) and ``--format exr`` (exact round trip,
Fichet et al. 2021 channel names), and the chart finder."""

from __future__ import annotations

import json

import numpy as np
import pytest
from export_testutil import build_export_store, chart_albedo, chart_corners

rawpy = pytest.importorskip("rawpy")
pytest.importorskip("pidng")
OpenEXR = pytest.importorskip("OpenEXR")

SENSOR = "Nikon 5100 (NPL)"


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return build_export_store(tmp_path_factory.mktemp("fmt") / "store")


def test_dng_single_illuminant(store, tmp_path):
    """A single-light DNG: the raw values as composed, black/white level, RGGB, and libraw's
    camera white balance = 1 / the ground-truth white point (G = 1) to 1e-5; libraw's camera → sRGB
    matrix from ColorMatrix1 equals illumix's D65 CCM (what ColorMatrix1 was built from)."""
    from illumix.dataset_export.run import ExportOptions, export_dataset
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensor_model import NoiseModel, mosaic, simulate_raw
    from illumix.retarget.sensors import get_sensor
    from illumix.engine.context import make_context
    from illumix.engine.library import Library
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    out = tmp_path / "dng"
    export_dataset(ExportOptions(store=store, out=str(out), format="DNG", sensors=[SENSOR], count=2, seed=1,
                                 size=(32, 24), noise=None))  # noise-free: exact digital numbers below
    man = json.loads((out / "manifest.json").read_text())
    single = next(s for s in man["samples"] if s["file"].endswith("_1.dng"))
    # a pair place (the default A,D65): the one lit illuminant of the pair
    name = single["params"]["pair"][single["params"]["intensities"].index(1.0)]
    w = get_sensor(SENSOR, DEFAULT_GRID).weights()
    wp = illuminant_spd(name, DEFAULT_GRID) @ w
    wp = wp / wp[1]
    st = CubeStore.open(store, mode="r")
    arrays, _ = build_sample(SampleSpec(**single["params"]), make_context(st))
    with rawpy.imread(str(out / single["file"])) as d:
        assert d.raw_image.shape == (24, 32)
        np.testing.assert_array_equal(d.raw_image, simulate_raw(arrays["raw"], NoiseModel(), noise=False))
        assert min(d.black_level_per_channel) == 64 and d.white_level == 4095
        np.testing.assert_array_equal(d.raw_pattern, [[0, 1], [3, 2]])  # R G / G B
        cam_wb = np.array(d.camera_whitebalance[:3])
        np.testing.assert_allclose(cam_wb / cam_wb[1], 1 / wp, rtol=1e-5)
        lib = Library(st)
        sensor, skey = lib.sensor(SENSOR, DEFAULT_GRID)
        ccm, _ = lib.ccm(sensor, skey, *lib.illuminant("D65", DEFAULT_GRID))
        np.testing.assert_allclose(d.color_matrix[:, :3], ccm, atol=2e-4)
    # the Bayer mosaic is the service's own (bayer=RGGB in the recorded parameters)
    assert single["params"]["bayer"] == "RGGB"
    rgb = dict(single["params"], bayer=None)
    np.testing.assert_array_equal(mosaic(build_sample(SampleSpec(**rgb), make_context(st))[0]["raw"], "RGGB"),
                                  arrays["raw"])


def test_dng_linear(store, tmp_path):
    """``--format dng --bayer none``: LinearRaw DNGs (3 samples per pixel) that libraw opens — the RGB
    digital numbers as composed, the levels, and its camera white balance = 1 / the recorded neutral;
    the camera's template is linear too."""
    from illumix.dataset_export.run import ExportOptions, export_dataset
    from illumix.retarget.sensor_model import NoiseModel, simulate_raw
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    out = tmp_path / "linear"
    s = export_dataset(ExportOptions(store=store, out=str(out), format="dng", bayer=None, count=2, seed=1,
                                     size=(32, 24), noise=None))
    assert s["bayer"] is None and "LinearRaw" in (out / "README.md").read_text()
    man = json.loads((out / "manifest.json").read_text())
    ctx = make_context(CubeStore.open(store, mode="r"))
    for sample in man["samples"]:
        assert "bayer" not in sample["params"]
        arrays, _ = build_sample(SampleSpec(**sample["params"]), ctx)
        with rawpy.imread(str(out / sample["file"])) as d:
            assert d.raw_type == rawpy.RawType.Stack and d.raw_image.shape == (24, 32, 4)
            np.testing.assert_array_equal(d.raw_image[..., :3], simulate_raw(arrays["raw"], NoiseModel(), noise=False))
            assert min(d.black_level_per_channel) == 64 and d.white_level == 4095
            wb = np.array(d.camera_whitebalance[:3])
            np.testing.assert_allclose(wb / wb[1], 1 / np.array(sample["neutral"]), rtol=1e-5)
    with rawpy.imread(str(out / "Nikon-5100-NPL.dng")) as t:
        assert t.raw_type == rawpy.RawType.Stack and min(t.black_level_per_channel) == 64


@pytest.mark.parametrize("dtype", ["float32", "float16"])
def test_exr_round_trip(store, tmp_path, dtype):
    """Every cube and illumination cube read back equal to the store's (float16: to its float16)."""
    import re

    from colour.io.fichet2021 import PATTERN_FICHET2021

    from illumix.dataset_export.run import ExportOptions, export_dataset
    from illumix.imagefiles.spectral_exr import read_spectral_exr
    from illumix.store import CubeStore

    out = tmp_path / dtype
    s = export_dataset(ExportOptions(store=store, out=str(out), format="openexr", exr_dtype=dtype))
    st = CubeStore.open(store, mode="r")
    index = json.loads((out / "cubes.json").read_text())
    assert s["counts"]["spectral EXR files"] == len(index) >= 10
    for rel, e in index.items():
        wl, cube, header = read_spectral_exr(out / rel)
        ref = st.read_cube(e["scene"], e["view"], e["group"], kind=e["kind"])
        np.testing.assert_array_equal(wl, st.cube_meta(e["scene"], e["view"], e["group"]).spectral_grid.wavelengths)
        np.testing.assert_array_equal(cube, ref.astype(dtype))
        assert header["spectralLayoutVersion"] == "1.0"
        # honest units: relative band integrals over bands of illumixBandWidthNm, not W.m^-2.sr^-1
        assert "W.m" not in header["emissiveUnits"] and header["emissiveUnits"].startswith("relative")
        assert float(header["illumixBandWidthNm"]) == 5.0
    with OpenEXR.File(str(out / rel)) as f:
        names = list(f.channels())
    assert "S0.550,0nm" in names
    assert all(re.match(rf"^S0\.{PATTERN_FICHET2021}$", n) for n in names)


def test_exr_half_clips_not_inf(tmp_path):
    from illumix.imagefiles.spectral_exr import read_spectral_exr, write_spectral_exr

    cube = np.full((2, 3, 4), 7e4, np.float32)
    assert write_spectral_exr(tmp_path / "x.exr", cube, [400, 450, 500, 550], dtype="float16") == 24
    _, back, h = read_spectral_exr(tmp_path / "x.exr")
    assert np.all(back == np.float16(65504)) and h["illumixClippedToHalf"] == "24"


def test_chart_finder():
    """Corners of a perspective-warped chart within a pixel, with noise and a same-coloured decoy;
    nothing found where there is no chart."""
    from illumix.dataset_export.chart import chart_albedos, find_chart

    rng = np.random.default_rng(0)
    a = chart_albedo() + rng.normal(0, 0.01, (96, 128, 3)).astype(np.float32)
    a[80:90, 110:120] = chart_albedos(3)[13]  # a wall the colour of patch 14 elsewhere
    np.testing.assert_allclose(find_chart(a), chart_corners(), atol=1.0)
    assert find_chart(np.full((96, 128, 3), 0.5, np.float32)) is None
