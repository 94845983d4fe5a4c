"""``illumix export --format lsmi``: the LSMI release's layout, read back the way LSMI's own
``2_preprocess_data.py`` reads it (plain numpy / cv2 / rawpy, re-stated here, not copied), against
independent computations: the same sample composed again, the sensor's white points from the
spectra, the physical illumination map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from export_testutil import CHART_SCENE, build_export_store, chart_corners

cv2 = pytest.importorskip("cv2")
rawpy = pytest.importorskip("rawpy")

SENSOR = "Nikon 5100 (NPL)"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    from illumix.dataset_export.run import ExportOptions, export_dataset

    root = tmp_path_factory.mktemp("lsmi")
    store = build_export_store(root / "store")
    out = root / "out"
    # noise-free (noise=None, `--noise none`): the checks below compare exact values
    summary = export_dataset(ExportOptions(store=store, out=str(out), sensors=[SENSOR], seed=3, noise=None))
    return store, out, summary


def _read_rgb(path: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB).astype(np.float32)


def test_layout_runs_like_lsmi_preprocess(exported):
    """LSMI's reading steps on every file: template levels, split keys, place folders, tiffs, npy,
    the illumination map Σ mixture·Light, white balance, the chart mask of the training split."""
    _, out, _ = exported
    cam = out / "Nikon-5100-NPL"
    with rawpy.imread(str(out / "Nikon-5100-NPL.dng")) as t:
        black, sat = min(t.black_level_per_channel), t.white_level
    assert (black, sat) == (64, 4095)
    meta = json.loads((cam / "meta.json").read_text())
    split = json.loads((cam / "split.json").read_text())
    assert {k.split("_")[-1] for k in split} == {"train", "val", "test"}
    places = [p for ps in split.values() for p in ps]
    assert sorted(places) == sorted(meta) and len(places) == len(set(places)) == 5
    n_files = charts = 0
    for key, ps in split.items():
        for place in ps:
            assert "_" not in place
            files = [f for f in (cam / place).iterdir() if f.suffix == ".tiff"]
            assert sorted(f.stem.split("_")[1] for f in files) == ["1", "12"]
            for f in files:
                lights = f.stem.split("_")[1]
                img = np.clip(_read_rgb(f) - black, 0, sat - black)
                mix = np.ones_like(img[..., :1]) if len(lights) == 1 else np.load(f.with_suffix(".npy"))
                assert mix.dtype == np.float32 and mix.shape == (*img.shape[:2], len(lights))
                assert np.all(np.isfinite(mix)) and np.all((mix >= 0) | (mix == -1))
                lit = mix[..., 0] != -1
                np.testing.assert_allclose(mix[lit].sum(-1), 1, atol=1e-5)
                chroma = np.array([meta[place][f"Light{c}"] for c in lights])
                illum = np.einsum("hwk,kc->hwc", mix, chroma)
                illum[~lit] = 1
                wb = np.clip(img / illum, 0, sat - black)
                assert np.all(np.isfinite(wb))
                # white-balanced, the right-hand quarter (a flat 50 % gray) is gray: R = G = B
                x0 = img.shape[1] * 3 // 4
                g = wb[:-4, x0:][lit[:-4, x0:]]
                np.testing.assert_allclose(g[:, 0] / g[:, 1], 1, atol=0.02)
                np.testing.assert_allclose(g[:, 2] / g[:, 1], 1, atol=0.02)
                n_files += 1
            if key.split("_")[-1] == "train":
                mask = np.ones(img.shape[:2], np.float32)
                for c in ("mcc1", "mcc2", "mcc3"):
                    pts = (np.float32(meta[place]["MCCCoord"][c]) / 2).astype(int)
                    cv2.drawContours(mask, [pts[:, None, :]], 0, 0, -1)
                if meta[place]["MCCCount"]:  # the chart's own area is masked, within its outline's pixels
                    quad = np.float32(meta[place]["MCCCoord"]["mcc1"]) / 2
                    area, rim = cv2.contourArea(quad), cv2.arcLength(quad[:, None, :], True)
                    assert abs((mask.size - mask.sum()) - area) <= rim + 4, (mask.size - mask.sum(), area, rim)
                    charts += 1
                else:  # absent charts (corners off the image) mask nothing
                    assert mask.sum() == mask.size
    assert n_files == 10 and charts >= 1


def test_frames_are_the_samples_served(exported):
    """The tiff is what /sample answers for the recorded parameters (composed again here), in DN;
    ``_12 − _1`` is light 2 alone (one exposure for the place)."""
    from illumix.retarget.sensor_model import NoiseModel, simulate_raw
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    store, out, _ = exported
    man = json.loads((out / "manifest.json").read_text())
    sample = next(s for s in man["samples"] if s["file"].endswith("room-1-v0_12.tiff"))
    ctx = make_context(CubeStore.open(store, mode="r"))
    arrays, meta = build_sample(SampleSpec(**sample["params"]), ctx)
    dn = simulate_raw(arrays["raw"], NoiseModel(), noise=False)
    tiff = _read_rgb(out / sample["file"])
    np.testing.assert_array_equal(tiff, dn)
    one = _read_rgb(out / sample["file"].replace("_12.", "_1."))
    p2 = dict(sample["params"], intensities=[0.0, 1.0], exposure=repr(meta["exposure_gain"]))
    only2 = simulate_raw(build_sample(SampleSpec(**p2), ctx)[0]["raw"], NoiseModel(), noise=False) - 64
    assert np.abs((tiff - one) - only2).max() <= 1  # two roundings


def test_physical_ground_truth_file(exported):
    """Every frame carries ``<place>_<lights>_gt_illum.npy``: the sample's ``illum`` (the physical
    white point per pixel, G = 1, composed again here from the recorded parameters) where the ground
    truth is defined, -1 elsewhere; LSMI's model Σ mixture·Light differs from it (the bounce light),
    by the angles meta.json records."""
    from illumix.retarget.metrics import angular_error
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    store, out, _ = exported
    man = json.loads((out / "manifest.json").read_text())
    meta = json.loads((out / "Nikon-5100-NPL" / "meta.json").read_text())
    ctx = make_context(CubeStore.open(store, mode="r"))
    assert len(man["samples"]) == 10
    for sample in man["samples"]:
        gt_file = sample["file"].replace(".tiff", "_gt_illum.npy")
        assert gt_file in man["files"]
        gt = np.load(out / gt_file)
        arrays, m = build_sample(SampleSpec(**sample["params"]), ctx)
        lit = arrays["mask"]
        assert gt.dtype == np.float32 and gt.shape == arrays["illum"].shape and m["ground_truth"]["method"] == "physical"
        np.testing.assert_array_equal(gt[lit], arrays["illum"][lit])
        assert np.all(gt[~lit] == -1) and np.all(gt[lit][:, 1] == 1) and np.all(gt[lit] > 0)
        if sample["file"].endswith("_12.tiff"):
            place = sample["file"].split("/")[1]
            mix = np.load(out / sample["file"].replace(".tiff", ".npy"))
            model = np.einsum("hwk,kc->hwc", mix, np.array([meta[place]["Light1"], meta[place]["Light2"]]))
            err = angular_error(model[lit], gt[lit])
            np.testing.assert_allclose([err.mean(), err.max()], [meta[place]["LSMIModelErrorDeg"][k]
                                                                 for k in ("mean", "max")], atol=1e-4)


def test_light_chromaticities_from_the_spectra(exported):
    """Light_i = Σ C(λ) Φ_i(λ) / its green, from the sensor and illuminant spectra directly; names and
    CCTs written (A ≈ 2856 K)."""
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    _, out, _ = exported
    meta = json.loads((out / "Nikon-5100-NPL" / "meta.json").read_text())
    w = get_sensor(SENSOR, DEFAULT_GRID).weights()
    for entry in meta.values():
        for i, ill in enumerate(entry["Illuminants"]):
            rgb = illuminant_spd(ill["name"], DEFAULT_GRID) @ w
            np.testing.assert_allclose(entry[f"Light{i + 1}"], rgb / rgb[1], rtol=1e-6)
            assert isinstance(ill["cct_K"], float) and isinstance(ill["duv"], float)  # numbers, not a nested dict
        assert entry["NumOfLights"] == 2 and entry["GroundTruth"] == "physical"
    ills = json.loads((out / "Nikon-5100-NPL" / "illuminants.json").read_text())
    assert abs(ills["A"]["cct_K"] - 2856) < 15 and len(ills["A"]["spd"]) == DEFAULT_GRID.n_bands


def test_chart_corners_in_meta(exported):
    """The chart view's MCCCoord: its corners at 2× pixel coordinates (within a pixel); the others absent."""
    _, out, _ = exported
    meta = json.loads((out / "Nikon-5100-NPL" / "meta.json").read_text())
    entry = meta[f"{CHART_SCENE.replace('_', '-')}-v0"]
    assert entry["MCCCount"] == 1
    np.testing.assert_allclose(np.array(entry["MCCCoord"]["mcc1"]) / 2, chart_corners(), atol=1.0)
    assert entry["MCCCoord"]["mcc2"] == [[-2.0, -2.0]] * 4
    assert meta["room-1-v0"]["MCCCount"] == 0


def test_card_and_manifest(exported):
    from illumix.dataset_export.journal import verify_manifest

    _, out, summary = exported
    assert verify_manifest(out) == []
    man = json.loads((out / "manifest.json").read_text())
    assert "README.md" in man["files"] and "Nikon-5100-NPL.dng" in man["files"]
    card = (out / "README.md").read_text()
    for text in ("Nikon 5100 (NPL)", "seed: `3`", "physical", "BSD-3-Clause", "| A |"):
        assert text in card
    assert summary["counts"]["places"] == 5
