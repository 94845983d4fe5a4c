"""Any camera without measured curves (issue 35, first route): sensitivities from colour matrices under
a prior of measured cameras, each camera estimated with itself left out of the prior."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_testutil import run_cli
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.grid import DEFAULT_GRID as G
from illumix.sensor_estimate import fit
from illumix.sensor_estimate.prior import learn_prior, load_measured
from test_cli_spectra import assert_one_line_error

CAMERAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "rawtoaces-data" / "data" / "camera"
needs_cameras = pytest.mark.skipif(not CAMERAS.is_dir(), reason="the measured cameras live in ../shared/data")
EVAL = ["A", "D50", "D65", "D75", "FL2", "FL7", "FL11", "LED-B3", "LED-RGB1", "LED-V1", "HP1"]


def wp_error_deg(est: np.ndarray, true: np.ndarray) -> float:
    """Mean white-point angular error (degrees) over the 11 illuminants of issue 35."""
    from illumix.retarget.metrics import angular_error

    lights = np.stack([ill.illuminant_spd(n, G) for n in EVAL])
    return float(angular_error(lights @ est, lights @ true).mean())


def _refl(name: str) -> np.ndarray:
    return fit.reflectance_columns(name, G)


@pytest.fixture(scope="module")
def measured():
    return load_measured([CAMERAS])


@needs_cameras
def test_a_colour_matrix_round_trips_through_the_dng_convention(measured):
    """The matrix of a camera's own curves maps its white to max channel 1, and the estimate's matrix
    reproduces the given one (what the fit was asked)."""
    d65, obs = ill.illuminant_spd("D65", G), fit.xyz_observer(G)
    m = fit.colour_matrix(measured.curves[3], d65, _refl("CIE 2017"), obs)
    white = obs.T @ d65
    assert np.max(m @ (white / white[1])) == pytest.approx(1.0)
    est = fit.estimate(learn_prior(measured.without([measured.names[3]])), [(m, d65)], _refl(fit.FIT_REFLECTANCES), obs)
    m2 = fit.colour_matrix(est.curves, d65, _refl("CIE 2017"), obs)
    assert np.abs(m2 - m).max() < 0.05
    assert est.samples.shape[1:] == est.curves.shape and np.all(est.curves >= 0)


@needs_cameras
def test_held_out_cameras_beat_the_average_camera(measured):
    """Every 7th camera, left out of the prior: from its D65 matrix (made from other reflectances than
    the fit's) the white points land within 3° (the issue's worst-camera goal) and better than the
    prior's mean camera on average (bench/sensors.py measures every camera)."""
    d65, obs = ill.illuminant_spd("D65", G), fit.xyz_observer(G)
    est_err, mean_err = [], []
    for i in range(0, len(measured.names), 7):
        prior = learn_prior(measured.without([measured.names[i]]))
        m = fit.colour_matrix(measured.curves[i], d65, _refl("CIE 2017"), obs)
        est = fit.estimate(prior, [(m, d65)], _refl(fit.FIT_REFLECTANCES), obs)
        est_err.append(wp_error_deg(est.curves, measured.curves[i]))
        mean_err.append(wp_error_deg(prior.mean, measured.curves[i]))
    assert max(est_err) < 3.0 and np.mean(est_err) < 0.5 * np.mean(mean_err), (est_err, mean_err)


@needs_cameras
def test_cli_from_an_exported_dng_recovers_the_camera(tmp_path, capsys, monkeypatch):
    """A DNG written by `illumix export --format dng` with a measured camera → `illumix sensors estimate
    --from-raw` (that camera left out of the prior) → a sensor file the library loads, within 3°."""
    import export_testutil

    name = "Canon_EOS_5D_Mark_II"
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(CAMERAS))
    store = export_testutil.build_export_store(tmp_path / "st")
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "o"), "--format", "dng", "--sensors", name,
                           "--count", "1", "--size", "32x24")
    assert code == 0, err
    dng = next((tmp_path / "o").rglob("*.dng"))
    out = tmp_path / "est.json"
    code, stdout, err = run_cli(capsys, "sensors", "estimate", "--from-raw", str(dng), "--exclude", name,
                                "--prior", str(CAMERAS), "--out", str(out), "--json")
    assert code == 0, err
    assert json.loads(stdout)["excluded"] == [name]
    doc = json.loads(out.read_text())
    assert doc["header"]["illumix_estimate"]["matrices"][0]["calibration_illuminant"] == "D65"
    wl, rgb = sen.read_sensor_file(out)
    est = sen.sensor_from_samples("est", wl, rgb, G)
    true = sen.get_sensor(name)
    assert wp_error_deg(est.sensitivities, true.sensitivities) < 3.0


def test_bad_input_is_one_line(tmp_path, capsys):
    out = str(tmp_path / "x.json")
    for argv, says in ((["--out", out], "give --color-matrix"),
                       (["--out", out, "--color-matrix", "1,2,3"], "nine"),
                       (["--out", out, "--color-matrix", "1,0,0,0,1,0,0,0,1", "--prior", str(tmp_path)],
                        "at least 8 measured cameras"),
                       (["--out", out, "--from-raw", str(tmp_path / "none.dng")], "does not exist"),
                       (["--out", out, "--color-matrix-2", "1,0,0,0,1,0,0,0,1"], "go together")):
        line = assert_one_line_error(*run_cli(capsys, "sensors", "estimate", *argv))
        assert says in line, (argv, line)
    assert not Path(out).exists()


@needs_cameras
def test_unknown_exclusion_names_close_matches(capsys, tmp_path):
    line = assert_one_line_error(*run_cli(capsys, "sensors", "estimate", "--out", str(tmp_path / "x.json"),
                                          "--color-matrix", "0.6,0,-0.07,-0.47,1.15,0.27,-0.13,0.25,0.54",
                                          "--prior", str(CAMERAS), "--exclude", "Canon_EOS_5D_Mark2"))
    assert "Canon_EOS_5D_Mark_II" in line


@needs_cameras
def test_service_estimates_and_serves_the_new_sensor(tmp_path, monkeypatch):
    """POST /sensors/estimate (token-protected): the matrices → a registered sensor /sample serves;
    a DNG upload works the same; refusals are 4xx with one line."""
    from fastapi.testclient import TestClient

    import synthetic_store as synth
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(CAMERAS))
    synth.build(tmp_path / "st")
    app = create_app(CubeStore.open(str(tmp_path / "st"), mode="a"), token="t0k")
    auth = {"Authorization": "Bearer t0k"}
    m = "0.6722,-0.0635,-0.0963,-0.4287,1.2460,0.2028,-0.0908,0.2162,0.5668"
    with TestClient(app) as c:
        assert c.post("/sensors/estimate", data={"name": "est-cam", "color_matrix": m}).status_code == 401
        r = c.post("/sensors/estimate", data={"name": "est-cam", "color_matrix": m}, headers=auth)
        assert r.status_code == 201, r.text
        assert r.json()["prior_cameras"] == 52 and r.json()["matrices"][0]["calibration_illuminant"] == "D65"
        assert "est-cam" in c.get("/sensors").json()["uploaded"]
        s = c.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "est-cam", "pair": "A,D65",
                                    "outputs": "raw"})
        assert s.status_code == 200
        assert c.post("/sensors/estimate", data={"name": "est-cam", "color_matrix": m}, headers=auth).status_code == 409
        bad = c.post("/sensors/estimate", data={"name": "x", "color_matrix": "1,2"}, headers=auth)
        assert bad.status_code == 422 and "nine" in bad.json()["detail"]
        none = c.post("/sensors/estimate", data={"name": "x"}, headers=auth)
        assert none.status_code == 422 and "color_matrix" in none.json()["detail"]
        junk = c.post("/sensors/estimate", data={"name": "y"}, files={"file": ("a.dng", b"not a raw")}, headers=auth)
        assert junk.status_code == 422
        from illumix.imagefiles.dng import dng_bytes

        cm = np.array([float(v) for v in m.split(",")]).reshape(3, 3)
        dng = dng_bytes(np.full((32, 32), 500, np.uint16), black=64, white=4095, pattern="RGGB", matrix=cm,
                        neutral=[1, 1, 1], model="cam")
        r = c.post("/sensors/estimate", data={"name": "from-dng"}, files={"file": ("cam.dng", dng)}, headers=auth)
        assert r.status_code == 201 and np.allclose(r.json()["matrices"][0]["color_matrix"], cm, atol=1e-5)


@needs_cameras
def test_sensor_random_draws_a_plausible_camera_per_seed(tmp_path, monkeypatch):
    """sensor=random: each seed a camera from the prior (recorded in meta as random:<seed>), the same
    camera for the same seed; the draws' white points under A and D65 lie among the measured ones'."""
    import synthetic_store as synth
    from illumix.engine.context import make_context
    from illumix.engine.sampling import build_sample
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(CAMERAS))
    synth.build(tmp_path / "st")
    ctx = make_context(CubeStore.open(str(tmp_path / "st"), mode="r"), cache_mb=16)
    metas, raws = [], []
    for seed in (1, 2, 1):
        arrays, meta = build_sample(SampleSpec(scene="synth", view="v0", sensor="random", seed=seed,
                                               pair="A,D65", outputs="raw,meta"), ctx)
        metas.append(meta["sensor"]["name"])
        raws.append(arrays["raw"])
    assert metas == ["random:1", "random:2", "random:1"]
    np.testing.assert_array_equal(raws[0], raws[2])
    assert not np.array_equal(raws[0], raws[1])
    measured = load_measured([CAMERAS])
    lights = np.stack([ill.illuminant_spd(n, G) for n in ("A", "D65")])
    rg = lambda c: (c.T @ lights.T)[0] / (c.T @ lights.T)[1]  # noqa: E731 - R/G under A and D65
    lo, hi = np.min([rg(c) for c in measured.curves], 0), np.max([rg(c) for c in measured.curves], 0)
    s, _ = ctx.library.sensor("random:5", G)
    assert np.all(rg(s.sensitivities) >= 0.8 * lo) and np.all(rg(s.sensitivities) <= 1.2 * hi)
    with pytest.raises(Exception, match="whole number"):
        ctx.library.sensor("random:x", G)


@needs_cameras
def test_noise_camera_is_the_dngs_own_sensor_model(tmp_path, capsys, monkeypatch):
    """A DNG exported with --noise phone states its NoiseProfile and levels; the sensor estimated from
    it carries them, and noise=camera serves raws with that very model (full well 6000 e-, read noise
    2.5 e-, black 64, white 4095) and that camera's mosaic (GRBG here), unless bayer= says otherwise."""
    import export_testutil
    from illumix.engine.context import make_context
    from illumix.engine.plan import plan
    from illumix.engine.spec import SampleSpec
    from illumix.store import CubeStore

    name = "Canon_EOS_5D_Mark_II"
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(CAMERAS))
    store = export_testutil.build_export_store(tmp_path / "st")
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "o"), "--format", "dng", "--sensors", name,
                           "--count", "1", "--size", "32x24", "--noise", "phone", "--bayer", "GRBG")
    assert code == 0, err
    dng = next(p for p in (tmp_path / "o").rglob("*.dng") if p.parent != tmp_path / "o")
    code, _, err = run_cli(capsys, "sensors", "estimate", "--from-raw", str(dng), "--exclude", name,
                           "--prior", str(CAMERAS), "--out", str(tmp_path / "est.json"))
    assert code == 0, err
    st = CubeStore.open(store, mode="a")
    st.registry("sensors").put("est", (tmp_path / "est.json").read_bytes(), "json")
    ctx = make_context(st, cache_mb=16)
    view = st.views(st.scenes()[0])[0]
    p = plan(SampleSpec(scene=st.scenes()[0], view=view, sensor="est", noise="camera", illuminants="D65,D65"), ctx)
    assert (p.noise.full_well, p.noise.read_noise, p.noise.black_level, p.noise.white) == pytest.approx(
        (6000, 2.5, 64, 4095))
    assert p.bayer == "GRBG"
    assert plan(SampleSpec(scene=st.scenes()[0], view=view, sensor="est", noise="camera", illuminants="D65,D65",
                           bayer="RGGB"), ctx).bayer == "RGGB"
    assert plan(SampleSpec(scene=st.scenes()[0], view=view, sensor="est", noise="phone", illuminants="D65,D65"),
                ctx).bayer is None
    with pytest.raises(Exception, match="states no camera noise model"):
        plan(SampleSpec(scene=st.scenes()[0], view=view, sensor="XYZ", noise="camera", illuminants="D65,D65"), ctx)


@needs_cameras
def test_cli_from_a_chart_photo(tmp_path, capsys, measured):
    """A linear camera-RGB photo of a ColorChecker (its patches the camera's responses to a real chart's
    measured reflectances, BabelColor's, under A) with its corners → within 3° of the camera."""
    import cv2
    import tifffile

    i = 11
    spd = ill.illuminant_spd("A", G)
    resp = (measured.curves[i].T @ (spd[:, None] * _refl("BabelColor Average"))).T
    resp = resp / resp.max() * 0.7
    cell = 20
    chart = np.zeros((4 * cell, 6 * cell, 3), np.float32)
    for k, v in enumerate(resp):
        r, c = divmod(k, 6)
        chart[r * cell + 2:(r + 1) * cell - 2, c * cell + 2:(c + 1) * cell - 2] = v
    corners = np.float32([[30, 20], [170, 30], [160, 120], [25, 105]])
    hom = cv2.getPerspectiveTransform(np.float32([[0, 0], [6 * cell, 0], [6 * cell, 4 * cell], [0, 4 * cell]]), corners)
    photo = cv2.warpPerspective(chart, hom, (200, 140), flags=cv2.INTER_NEAREST)
    tifffile.imwrite(tmp_path / "chart.tif", (photo * 65535).astype(np.uint16))
    out = tmp_path / "est.json"
    code, stdout, err = run_cli(capsys, "sensors", "estimate", "--chart-photo", str(tmp_path / "chart.tif"),
                                "--illuminant", "A", "--corners", ",".join(f"{v:g}" for v in corners.ravel()),
                                "--exclude", measured.names[i], "--prior", str(CAMERAS), "--out", str(out), "--json")
    assert code == 0, err
    assert json.loads(stdout)["chart_photo"] is True
    wl, rgb = sen.read_sensor_file(out)
    assert wp_error_deg(sen.sensor_from_samples("e", wl, rgb, G).sensitivities, measured.curves[i]) < 3.0
    line = assert_one_line_error(*run_cli(capsys, "sensors", "estimate", "--chart-photo", str(tmp_path / "chart.tif"),
                                          "--out", str(out)))
    assert "--illuminant" in line


def _chart_image(resp: np.ndarray, corners, size=(800, 600), seed=0) -> np.ndarray:
    """A linear photo of a ColorChecker (patches ``resp`` (24, 3), black gaps and border) warped onto
    ``corners`` on a grey background, with 1 % Gaussian noise."""
    import cv2

    cell, gap, border = 100, 8, 10
    chart = np.full((4 * cell + 2 * border, 6 * cell + 2 * border, 3), 0.03, np.float32)
    for k, v in enumerate(resp):
        r, c = divmod(k, 6)
        y, x = border + r * cell, border + c * cell
        chart[y + gap:y + cell - gap, x + gap:x + cell - gap] = v
    h, w = chart.shape[:2]
    hom = cv2.getPerspectiveTransform(np.float32([[0, 0], [w, 0], [w, h], [0, h]]), np.float32(corners))
    warped = cv2.warpPerspective(chart, hom, size, flags=cv2.INTER_LINEAR, borderValue=(-1, -1, -1))
    img = np.where(warped >= 0, warped, np.float32(0.15))
    return img + np.random.default_rng(seed).normal(0, 0.01, img.shape).astype(np.float32)


def _rotated(cx, cy, w, h, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]) @ [[c, s], [-s, c]] + [cx, cy]


@needs_cameras
def test_cli_finds_the_chart_itself_in_several_photos(tmp_path, capsys, measured):
    """No --corners: colour-checker-detection finds the chart (turned 0.3 rad, or upside down) and the
    patch means agree with the chart's within 1 % of white; two photos (A and D65) give an estimate
    within 3° of the camera; a chart seen too obliquely for the detector is refused in one line."""
    pytest.importorskip("colour_checker_detection")
    from illumix.sensor_estimate.chart import find_patches

    i = 11
    paths = []
    for light, angle in (("A", 0.3), ("D65", np.pi)):
        resp = (measured.curves[i].T @ (ill.illuminant_spd(light, G)[:, None] * _refl("BabelColor Average"))).T
        resp = resp / resp.max() * 0.7
        img = _chart_image(resp, _rotated(400, 300, 500, 340, angle))
        np.testing.assert_allclose(find_patches(img.astype(np.float64) * 4000) / 4000, resp, atol=0.007)
        paths.append(tmp_path / f"{light}.npy")
        np.save(paths[-1], img)
    out = tmp_path / "est.json"
    code, stdout, err = run_cli(capsys, "sensors", "estimate", "--chart-photo", str(paths[0]), "--illuminant", "A",
                                "--chart-photo", str(paths[1]), "--illuminant", "D65", "--exclude", measured.names[i],
                                "--prior", str(CAMERAS), "--out", str(out), "--json")
    assert code == 0, err
    assert json.loads(stdout)["chart_photos"] == 2
    wl, rgb = sen.read_sensor_file(out)
    assert wp_error_deg(sen.sensor_from_samples("e", wl, rgb, G).sensitivities, measured.curves[i]) < 3.0
    np.save(tmp_path / "oblique.npy", _chart_image(resp, [[150, 120], [640, 150], [620, 470], [170, 440]]))
    line = assert_one_line_error(*run_cli(capsys, "sensors", "estimate", "--chart-photo", str(tmp_path / "oblique.npy"),
                                          "--illuminant", "D65", "--prior", str(CAMERAS), "--out", str(out)))
    assert "oblique.npy" in line and "--corners" in line



@needs_cameras
def test_the_estimate_ignores_a_matrix_scale_and_refuses_a_negative_white(measured):
    """A matrix is rescaled to the DNG convention first: 1e-300 or 1e300 × it gives the same curves (no
    overflow, no NaN); one mapping the white to no positive channel is refused in one line."""
    from illumix.retarget.errors import SpectralError

    d65, obs = ill.illuminant_spd("D65", G), fit.xyz_observer(G)
    prior, refl = learn_prior(measured), _refl(fit.FIT_REFLECTANCES)
    m = fit.colour_matrix(measured.curves[3], d65, _refl("CIE 2017"), obs)
    ref = fit.estimate(prior, [(m, d65)], refl, obs).curves
    for scale in (1e-300, 1e300):
        np.testing.assert_allclose(fit.estimate(prior, [(m * scale, d65)], refl, obs).curves, ref, rtol=1e-9, atol=1e-12)
    with pytest.raises(SpectralError, match="no positive camera channel"):
        fit.estimate(prior, [(-m, d65)], refl, obs)
