"""Harder, truer exports: ``--gt physical`` puts illumix's physical ground truth into the very files
LSMI's trainers read (the mixture ``.npy`` + ``Light<i>``); camera noise is on by default (``--noise
none`` turns it off) and the card says so; ``--pairs`` lights a view's groups by their kinds, as
``/sample?pair=`` does. Checked against independent computations: white points from the spectra,
the same frame composed with explicit per-group illuminants, scipy's NNLS."""

from __future__ import annotations

import json

import numpy as np
import pytest
import synthetic_store as syn

cv2 = pytest.importorskip("cv2")
pytest.importorskip("pidng")

SENSOR = "Nikon 5100 (NPL)"
SCENE, VIEW = "tinted", "v0"


def _tint(h: int, w: int, n: int) -> np.ndarray:
    """``(h, w, n)``: 1 on the right half; on the left half a spectral ramp (a reddish wall's bounce
    light), so the window's illumination there is no longer its illuminant's colour."""
    ramp = np.linspace(0.3, 1.7, n, dtype=np.float32)
    t = np.ones((h, w, n), np.float32)
    t[:, : w // 2] = ramp
    return t


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """One view, groups ``lamp`` (declared artificial) then ``window`` (declared daylight) — so the
    order rule and the kind rule disagree — with illumination cubes; the window's light is tinted on
    the left half."""
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.store import CubeMeta, CubeStore, ViewMeta

    path = tmp_path_factory.mktemp("truth") / "store"
    st = CubeStore.open(str(path), mode="a")
    h, w, n = syn.H, syn.W, DEFAULT_GRID.n_bands
    refl = syn.reflectance_image(h, w)
    fw, fl = syn.falloffs(h, w)
    st.write_view(SCENE, VIEW, ViewMeta(width=w, height=h, fov=45.0),
                  {"mask": np.ones((h, w), bool), "emitter": np.zeros((h, w), bool)})
    common = {"grid": DEFAULT_GRID.to_dict(), "renderer": {"name": "synthetic", "version": "1"}, "spp": 0, "seed": 0,
              "scene_hash": "synthetic", "emission": [1.0] * n, "emission_name": "flat"}
    for name, f, kind, tint in (("lamp", fl, "artificial", np.ones((h, w, n), np.float32)),
                                ("window", fw, "daylight", _tint(h, w, n))):
        u = (f / np.float32(np.pi))[..., None] * tint
        st.write_cube(SCENE, VIEW, name, refl * u, CubeMeta(**common, group_kind=kind), illumination=u)
    return str(path)


def _export(store, out, **kw):
    from illumix.dataset_export.run import ExportOptions, export_dataset

    opts = {"store": store, "out": str(out), "sensors": [SENSOR], "seed": 0, "noise": None} | kw
    return export_dataset(ExportOptions(**opts))


def _place(out):
    cam = out / "Nikon-5100-NPL"
    meta = json.loads((cam / "meta.json").read_text())
    (place, entry), = meta.items()
    return cam / place, place, entry


def _tiff(path):
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB).astype(np.float64)


def _white_point(name):
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    wp = illuminant_spd(name, DEFAULT_GRID) @ get_sensor(SENSOR, DEFAULT_GRID).weights()
    return wp / wp[1]


def _sample(store, **params):
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    ctx = make_context(CubeStore.open(store, mode="r"))
    return build_sample(SampleSpec(**({"scene": SCENE, "view": VIEW, "sensor": SENSOR} | params)), ctx)


def test_pairs_follow_the_group_kinds(store, tmp_path):
    """--pairs D65,A: D65 is daylight, so it lights the daylight group (window, the view's *second*
    group) and A the lamp — as /sample?pair= assigns them; in order it would have been the other way."""
    _export(store, tmp_path / "o", pairs="D65,A")
    folder, place, entry = _place(tmp_path / "o")
    assert [e["groups"] for e in entry["Illuminants"]] == [["window"], ["lamp"]]
    assert [e["name"] for e in entry["Illuminants"]] == ["D65", "A"]
    np.testing.assert_allclose(entry["Light1"], _white_point("D65"), rtol=1e-5)
    np.testing.assert_allclose(entry["Light2"], _white_point("A"), rtol=1e-5)
    # the "_1" frame (light 1 alone) is the window under D65 with the lamp off, composed per group here
    man = json.loads((tmp_path / "o" / "manifest.json").read_text())
    one = next(s for s in man["samples"] if s["file"].endswith("_1.tiff"))
    arrays, _ = _sample(store, illuminants=["A", "D65"], intensities=[0.0, 1.0], outputs=["raw"],
                           exposure=one["params"]["exposure"])
    from illumix.retarget.sensor_model import NoiseModel, simulate_raw

    np.testing.assert_array_equal(_tiff(folder / f"{place}_1.tiff"), simulate_raw(arrays["raw"], NoiseModel(), noise=False))
    served = _sample(store, pair=["D65", "A"], intensities=[1.0, 0.0], outputs=["meta"])[1]
    assert served["lighting_rule"]["rule"] == "kind"
    # --illuminants stays explicit: light i on group i
    _export(store, tmp_path / "e", illuminants="D65,A")
    _, _, explicit = _place(tmp_path / "e")
    assert [e["groups"] for e in explicit["Illuminants"]] == [["lamp"], ["window"]]


def _model(folder, place, entry, lights="12"):
    mix = np.load(folder / f"{place}_{lights}.npy").astype(np.float64)
    chroma = np.array([entry[f"Light{c}"] for c in lights])
    return mix, np.einsum("hwk,kc->hwc", mix, chroma)


def _angle(a, b):
    cos = np.sum(a * b, -1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def test_gt_physical_writes_the_physical_ground_truth_into_lsmi_files(store, tmp_path):
    from scipy.optimize import nnls

    s_phys = _export(store, tmp_path / "p", pairs="A,D65", gt="physical")
    s_mix = _export(store, tmp_path / "m", pairs="A,D65")
    fp, place, ep = _place(tmp_path / "p")
    fm, _, em = _place(tmp_path / "m")
    assert (ep["MixtureTarget"], em["MixtureTarget"]) == ("physical", "mixture")
    assert ep["GroundTruth"] == em["GroundTruth"] == "physical"
    assert (s_phys["target"], s_mix["target"]) == ("physical", "mixture")
    mix_p, model_p = _model(fp, place, ep)
    mix_m, model_m = _model(fm, place, em)
    # what the engine serves as the physical ground truth for this frame
    man = json.loads((tmp_path / "p" / "manifest.json").read_text())
    full = next(s for s in man["samples"] if s["file"].endswith("_12.tiff"))
    arrays, _ = _sample(store, **dict(full["params"], outputs=["illum", "mask"]))
    lit, g = arrays["mask"], arrays["illum"].astype(np.float64)
    right = np.zeros_like(lit)
    right[:, syn.W // 2:] = True
    # right half (no tint): the physical white point is a mix of the two lights, held exactly
    np.testing.assert_allclose(model_p[lit & right], g[lit & right], atol=2e-5)
    # left half (tinted bounce light): the mixture target misses it, the physical one is LSMI's closest
    left = lit & ~right
    err_p, err_m = _angle(model_p[left], g[left]), _angle(model_m[left], g[left])
    assert err_m.mean() > 1.0 and err_p.mean() < 0.5 * err_m.mean()
    assert np.all(err_p <= err_m + 1e-3)
    assert np.abs(mix_p - mix_m)[left].max() > 0.05  # the files differ on this mixed-light frame
    # each fitted pixel is scipy's non-negative least squares of the lights' white points to it, summing to 1
    a = np.array([ep["Light1"], ep["Light2"]]).T
    for y, x in ((5, 3), (20, 10), (30, 25), (10, 40)):
        m, _ = nnls(a, g[y, x])
        np.testing.assert_allclose(mix_p[y, x], m / m.sum(), atol=1e-5)
    np.testing.assert_allclose(mix_p[lit].sum(-1), 1, atol=1e-5)
    assert np.all(mix_p[~lit] == -1) and np.all(mix_p[lit] >= 0)
    # the stated residual is the fitted model's, and the card says which target the files hold
    assert ep["LSMIModelErrorDeg"]["mean"] == pytest.approx(_angle(model_p[lit], g[lit]).mean(), abs=2e-3)
    card = (tmp_path / "p" / "README.md").read_text()
    assert "`--gt physical`" in card and "fitted to illumix's physical ground truth" in card


def test_noise_is_on_by_default_and_stated(store, tmp_path, capsys):
    """The CLI's default export carries the phone sensor model's noise (the same frame /sample answers
    with noise=phone and the recorded seed), states it in the card and the DNG template; --noise none
    gives the noise-free frame."""
    from cli_testutil import run_cli

    from illumix.retarget.sensor_model import NoiseModel, simulate_raw

    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "n"), "--pairs", "A,D65")
    assert code == 0, err
    man = json.loads((tmp_path / "n" / "manifest.json").read_text())
    s = next(x for x in man["samples"] if x["file"].endswith("_12.tiff"))
    assert s["params"]["noise"] == "phone"
    noisy = _tiff(tmp_path / "n" / s["file"])
    served, _ = _sample(store, **dict(s["params"], outputs=["raw"]))
    np.testing.assert_array_equal(noisy, served["raw"])
    clean = simulate_raw(_sample(store, **dict(s["params"], outputs=["raw"], noise=None))[0]["raw"], NoiseModel(),
                         noise=False)
    resid = (noisy - clean)[: -syn.DARK_ROWS]
    assert resid.std() > 2 and abs(resid.mean()) < 2  # shot + read noise around the clean signal
    card = (tmp_path / "n" / "README.md").read_text()
    assert "camera noise model `phone`" in card and "full well 6000 e-" in card and "`--noise none`" in card
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "c"), "--pairs", "A,D65", "--noise", "none")
    assert code == 0, err
    np.testing.assert_array_equal(_tiff(tmp_path / "c" / s["file"]), clean)
    assert "**noise-free**" in (tmp_path / "c" / "README.md").read_text()
