"""Evaluation inputs: samples composed from a store (the service's pipeline) and LSMI-layout files
read back as LSMI reads them; on both the ground truth scores 0 (to float32 rounding: the GT gain is
a float32 division, so 1/gain is the GT illuminant to ~1e-7 relative, an angle below 1e-3°)."""

from __future__ import annotations

import numpy as np
import pytest
from evaluate_testutil import BLACK, LIGHTS, WHITE, lsmi_image, make_lsmi, make_store

from illumix.awb_eval.lsmi_input import LsmiCases, is_lsmi, read_levels
from illumix.awb_eval.methods import resolve
from illumix.awb_eval.report import aggregate
from illumix.awb_eval.run import evaluate
from illumix.awb_eval.store_input import StoreCases, parse_pairs
from illumix.retarget.errors import SpectralError, UnknownName

ZERO = 1e-3  # degrees; module docstring


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return str(make_store(tmp_path_factory.mktemp("evalstore") / "s"))


@pytest.fixture(scope="module")
def lsmi(tmp_path_factory):
    return make_lsmi(tmp_path_factory.mktemp("lsmi"))


def test_store_cases_are_the_service_samples(store):
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    src = StoreCases(store, pairs="A,D65;D50", sensor="Nikon 5100 (NPL)")
    assert len(src) == 2 and [j.pair for j in src.jobs] == ["A,D65", "D50"]
    case = next(iter(src))
    arrays, meta = build_sample(SampleSpec(scene="synth", view="v0", pair=["A", "D65"], sensor="Nikon 5100 (NPL)",
                                           seed=0, outputs=["raw", "illum", "mask", "ccm", "meta"], exposure="auto"),
                                make_context(CubeStore.open(store, mode="r")))
    for k in ("illum", "mask", "ccm"):
        np.testing.assert_array_equal(getattr(case, k), arrays[k])
    # the raw a camera records: auto-exposed (the service's AEC) and clipped at the white level
    np.testing.assert_array_equal(case.raw, np.minimum(arrays["raw"], 1))
    assert case.usable is not None and not case.usable[case.raw.max(axis=-1) >= 1].any()
    np.testing.assert_allclose(case.white_points, [g["white_point_rgb"] for g in meta["illuminants"]])
    assert case.mixture.shape == (*case.shape, 2) and not case.mask.all()  # the dark rows are masked


def test_ground_truth_scores_zero_on_a_store(store):
    src = StoreCases(store, pairs="A,D65;FL11,D50;D65")
    res = evaluate(src, resolve(["Ground Truth", "Gray World", "Weighted Average"]))
    summary = aggregate(res, ["Ground Truth", "Gray World", "Weighted Average"])
    gt = summary["methods"]["Ground Truth"]
    assert gt["images"] == 3 and gt["angular_max"] < ZERO and gt["grid_de00_worst25"] == 0.0
    assert summary["methods"]["Gray World"]["angular_mean"] > 1.0  # a mixed light it cannot see
    # one illuminant everywhere: the single weighted white point is the ground truth
    single = next(im for im in res.images if im["pair"] == "D65")["methods"]["Weighted Average"]
    assert single["angular_max"] < ZERO
    assert set(summary["pairs"]) == {"A,D65", "FL11,D50", "D65"}


def test_store_input_errors(store, tmp_path):
    with pytest.raises(UnknownName, match="sensor"):
        StoreCases(store, sensor="Nikon 5101")
    with pytest.raises(UnknownName, match="FL11"):
        StoreCases(store, pairs="A,F11")
    with pytest.raises(SpectralError, match="one or two"):
        parse_pairs("A,D65,D50")
    empty = tmp_path / "empty"
    from illumix.store import CubeStore

    CubeStore.open(str(empty), mode="a")
    with pytest.raises(SpectralError, match="no rendered views"):
        StoreCases(str(empty))


def test_a_view_that_cannot_be_composed_is_skipped_not_the_end_of_the_run(tmp_path):
    """--gt physical on a store where only synth/v0 has illumination cubes: the other views are
    skipped with the service's reason, synth/v0 is scored."""
    import synthetic_store

    path = tmp_path / "s"
    synthetic_store.build(path, illumination=True)
    src = StoreCases(str(path), pairs="A,D65;D65", gt="physical")
    assert len(src) > 2
    res = evaluate(src, resolve(["Ground Truth"]))
    assert sorted(im["name"] for im in res.images) == ["synth/v0 A,D65", "synth/v0 D65"]
    assert len(res.skipped) == len(src) - 2
    assert all("illumination cubes" in s["why"] for s in res.skipped)
    with pytest.raises(SpectralError, match="size"):  # the run's own options still fail at once
        StoreCases(str(path), size="12")


def test_lsmi_files_read_back_as_lsmi_reads_them(lsmi):
    assert is_lsmi(lsmi) and is_lsmi(lsmi / "cam")
    src = LsmiCases(lsmi)
    assert [i.name for i in src.items] == ["p0_1", "p0_12", "p1_12", "p1_123"]
    assert (src.levels.black, src.levels.white) == (BLACK, WHITE)
    # the sRGB matrix as the colour matrix (written as rationals n/1e6: the inverse is the identity to 1e-4)
    np.testing.assert_allclose(src.ccm, np.eye(3), atol=1e-4)
    cases = {c.name: c for c in src}
    _, mix, _raw = lsmi_image("123", np.random.default_rng(0))
    c = cases["p1_123"]
    assert c.mixture.shape == (*c.shape, 3) and not c.mask[-3:].any() and c.mask[:-3].all()
    # the GT map is LSMI's mix_chroma: Σ_i mix_i · Light_i
    chroma = np.array([LIGHTS[f"Light{i}"] for i in "123"])
    np.testing.assert_allclose(c.illum[:-3], (mix @ chroma)[:-3], rtol=1e-6)
    # raw = tiff - black, exactly (the texture is random per file: compare the lit structure)
    assert c.raw.dtype == np.float32 and float(c.raw[-3:].max()) == 0.0 and c.raw.max() <= WHITE - BLACK
    single = cases["p0_1"]  # one light: no .npy, the mixture is ones everywhere (LSMI), so every pixel is scored
    assert single.mixture.shape[-1] == 1 and single.mask.all()


def test_lsmi_raw_is_the_tiff_minus_black(tmp_path):
    root = make_lsmi(tmp_path)
    import cv2

    tiff = cv2.cvtColor(cv2.imread(str(root / "cam/p0/p0_12.tiff"), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    case = LsmiCases(root, pairs="12", split="train").load(LsmiCases(root, pairs="12", split="train").items[0])
    np.testing.assert_array_equal(case.raw, np.clip(tiff.astype(np.float32) - BLACK, 0, WHITE - BLACK))


def test_ground_truth_scores_zero_on_lsmi(lsmi):
    src = LsmiCases(lsmi, split="test")
    res = evaluate(src, resolve(["GT", "GW", "WA", "Patch GE1"]))
    s = aggregate(res, ["Ground Truth", "Gray World", "Weighted Average", "Patch Gray Edge"])
    assert s["methods"]["Ground Truth"]["angular_max"] < ZERO
    assert s["methods"]["Ground Truth"]["grid_de00_worst25"] == 0.0
    assert s["methods"]["Gray World"]["angular_mean"] > 0.5
    assert set(s["pairs"]) == {"12", "123"}


def test_lsmi_levels_and_errors(lsmi, tmp_path):
    levels = read_levels(lsmi / "cam.dng")  # libraw cannot open this tag-only file: the tags are read
    assert (levels.black, levels.white) == (BLACK, WHITE) and levels.cam_xyz.shape == (3, 3)
    assert levels.source == "cam.dng (DNG tags)"
    bare = make_lsmi(tmp_path / "bare", dng=False)
    with pytest.raises(SpectralError, match="--black-level"):
        LsmiCases(bare)
    src = LsmiCases(bare, black_level=BLACK, white_level=WHITE)
    assert src.levels.source == "given"
    np.testing.assert_array_equal(src.ccm, np.eye(3))  # no colour matrix: identity
    with pytest.raises(SpectralError, match="is not above the black level"):  # given levels are checked too
        LsmiCases(bare, black_level=64, white_level=10)
    with pytest.raises(SpectralError, match="must be finite"):  # inf would switch the saturation mask off
        LsmiCases(bare, black_level=64, white_level=float("inf"))
    with pytest.raises(UnknownName, match="did you mean 'cam'"):
        LsmiCases(lsmi, camera="cma")
    with pytest.raises(SpectralError, match="no split 'dev'"):
        LsmiCases(lsmi, split="dev")
    with pytest.raises(SpectralError, match="no <place>_<lights>.tiff"):
        LsmiCases(lsmi, pairs="13")


def test_lsmi_prefers_the_physical_gt_file(tmp_path):
    """Where ``<place>_<lights>_gt_illum.npy`` exists (``illumix export`` writes it) its per-pixel
    white point is the ground truth, -1 marking undefined pixels; elsewhere LSMI's model. The
    results say which."""
    root = make_lsmi(tmp_path)
    assert LsmiCases(root).describe()["gt"].startswith("LSMI model")
    tint = np.array([1.08, 1.0, 0.93], np.float32)
    _, mix, _ = lsmi_image("12", np.random.default_rng(1))
    chroma = np.array([LIGHTS["Light1"], LIGHTS["Light2"]], np.float32)
    gt = (mix @ chroma) * tint
    gt /= gt[..., 1:2]
    gt[-3:] = -1
    gt[0, 0] = -1  # undefined where the mixture is not: not scored
    np.save(root / "cam/p1/p1_12_gt_illum.npy", gt.astype(np.float32))
    src = LsmiCases(root)
    assert "1 of 4" in src.describe()["gt"] and "_gt_illum.npy" in src.describe()["gt"]
    case = next(c for c in src if c.name == "p1_12")
    np.testing.assert_array_equal(case.illum[case.mask], gt[case.mask])
    assert not case.mask[0, 0] and not case.mask[-3:].any() and case.mask[1:-3].all()
    res = evaluate(iter([case]), resolve(["GT"]))
    assert res.images[0]["methods"]["Ground Truth"]["angular_max"] < ZERO
    (root / "cam/p1/p1_12_gt_illum.npy").write_bytes(b"not npy")
    with pytest.raises(SpectralError, match="p1_12_gt_illum.npy"):
        LsmiCases(root).load(next(i for i in LsmiCases(root).items if i.name == "p1_12"))


def test_lsmi_reads_dng_exports(tmp_path):
    """An export with DNG raws evaluates like one with TIFFs: a Bayer DNG becomes the half-size RGB
    LSMI's ``0_cvt2tiff.py`` makes with ``dcraw -h -D`` (R, ⌊(G₁ + G₂)/2⌋, B per 2×2 block; black level
    kept), computed here from the TIFF export of the same frames, with the mixture and ground truth
    averaged over each block; a LinearRaw DNG is the TIFF itself. The ground truth scores 0 on both."""
    pytest.importorskip("rawpy")
    pytest.importorskip("pidng")
    import cv2
    from export_testutil import build_export_store

    from illumix.dataset_export.run import ExportOptions, export_dataset

    store = build_export_store(tmp_path / "store")
    opts = dict(store=store, count=1, seed=2, size=(32, 24))
    outs = {}
    for fmt, bayer in (("lsmi", "RGGB"), ("dng", "RGGB"), ("dng", None)):
        outs[fmt, bayer] = tmp_path / f"{fmt}-{bayer}"
        export_dataset(ExportOptions(out=str(outs[fmt, bayer]), format=fmt, bayer=bayer, **opts))
    tiffs = {c.name: c for c in LsmiCases(outs["lsmi", "RGGB"])}
    bayer_src, linear_src = LsmiCases(outs["dng", "RGGB"]), LsmiCases(outs["dng", None])
    assert "dcraw -h" in bayer_src.describe()["raw"] and "_gt_illum" in bayer_src.describe()["gt"]
    for case in linear_src:
        ref = tiffs[case.name]
        for k in ("raw", "illum", "mask", "mixture"):
            np.testing.assert_array_equal(getattr(case, k), getattr(ref, k), err_msg=k)
    for item in bayer_src.items:
        case = bayer_src.load(item)
        tiff_path = next(i.raw for i in LsmiCases(outs["lsmi", "RGGB"]).items if i.name == item.name)
        t = cv2.cvtColor(cv2.imread(str(tiff_path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB).astype(np.int64)
        half = np.stack([t[0::2, 0::2, 0], (t[0::2, 1::2, 1] + t[1::2, 0::2, 1]) // 2, t[1::2, 1::2, 2]], axis=-1)
        black = bayer_src.levels.black
        np.testing.assert_array_equal(case.raw, np.clip(half - black, 0, bayer_src.levels.white - black))
        ref = tiffs[item.name]
        blocks = ref.mask.reshape(12, 2, 16, 2).all(axis=(1, 3))
        np.testing.assert_array_equal(case.mask, blocks)
        mean_illum = ref.illum.reshape(12, 2, 16, 2, 3).mean(axis=(1, 3))
        np.testing.assert_allclose(case.illum[blocks], mean_illum[blocks], rtol=1e-6)
    res = evaluate(bayer_src, resolve(["GT"]))
    assert len(res.images) == 2 and all(im["methods"]["Ground Truth"]["angular_max"] < ZERO for im in res.images)


def test_damaged_lsmi_files_are_one_line_errors(tmp_path):
    """A Light that is not three numbers, a mixture .npy that is not an array: SpectralErrors
    (one line from the CLI), not tracebacks."""
    import io
    import json

    root = make_lsmi(tmp_path / "d")
    src = LsmiCases(root, pairs="12", split="train")
    item = src.items[0]
    npy = item.raw.with_suffix(".npy")
    good = npy.read_bytes()
    np.save(npy, np.array([{"x": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(SpectralError, match="not a readable .npy"):
        src.load(item)
    shape = np.load(io.BytesIO(good)).shape
    np.save(npy, np.full(shape, "abc"))  # an array of the right shape, of strings
    with pytest.raises(SpectralError, match="expected numbers"):
        src.load(item)
    npy.write_bytes(good)
    meta = root / "cam" / "meta.json"
    doc = json.loads(meta.read_text())
    for bad in (["a", 1, 1], "123"):  # a string is not three values, though it has three characters
        doc[item.place]["Light1"] = bad
        meta.write_text(json.dumps(doc))
        with pytest.raises(SpectralError, match="must be 3 positive"):
            LsmiCases(root, pairs="12", split="train").load(item)


def test_sensor_random_draws_a_camera_per_image(store, monkeypatch):
    """``--sensor random``: each image its own camera from the prior (``random:<seed + k>``), recorded
    per image, and the summary states how widely the white points spread."""
    from pathlib import Path

    cameras = Path(__file__).resolve().parents[2] / "shared/data/rawtoaces-data/data/camera"
    if not cameras.is_dir():
        pytest.skip("the measured cameras live in ../shared/data")
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(cameras))
    src = StoreCases(store, pairs="A;D65;FL11", sensor="Random", seed=5)
    assert [j.sensor for j in src.jobs] == ["random:5", "random:6", "random:7"]
    res = evaluate(src, resolve(["Gray World"]))
    assert [im["sensor"] for im in res.images] == ["random:5", "random:6", "random:7"]
    span = aggregate(res, ["Gray World"])["white_points"]
    assert span["sensors"] == 3 and span["r_over_g"][0] < span["r_over_g"][1]
