"""Issue 36, items 2 and 3: degenerate illuminants and sensors are refused with one clear line (at upload
and again at composition), ``meta`` states each served CCM's real fit error and condition number, and
subnormal or zero intensities behave like tiny ones."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

pytest.importorskip("store")

import synthetic_store as synth  # noqa: E402
from server_testutil import synthetic_service_fixtures  # noqa: E402
from illumix.engine.library import Library  # noqa: E402
from illumix.retarget import conditioning as cond  # noqa: E402
from illumix.retarget import illuminants as ill  # noqa: E402
from illumix.retarget import sensors as sen  # noqa: E402
from illumix.retarget.ccm import fit_ccm, linear_srgb_to_lab, target_linear_srgb  # noqa: E402
from illumix.retarget.grid import DEFAULT_GRID  # noqa: E402
from illumix.retarget.projected import Projected  # noqa: E402
from illumix.retarget.reflectances import DEFAULT_TRAINING_SET, get_reflectances  # noqa: E402
from illumix.retarget.relight import band_scales, raw_weights  # noqa: E402
from illumix.retarget.errors import SpectralError  # noqa: E402

TOKEN = "c0nd"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
V0 = {"scene": "synth", "view": "v0"}
WL = np.arange(380, 781, 1.0)
# Power only in 392-393 nm (the audit's input): |ccm| 1e12 through XYZ, a zero red channel through Nikon.
NARROW_CSV = "wavelength,value\n" + "\n".join(f"{w:g},{1.0 if 392 <= w <= 393 else 0.0}" for w in WL)
CAMERA_DIR = "rawtoaces-data/data/camera"
# Measured cameras for the no-false-refusal sweep: the extremes of the measured range and two ordinary ones.
CAMERAS = ("Canon_PowerShot_S90", "ARRI_D21", "Canon_EOS_5DS", "Fujifilm_X-T3")

store_path, client = synthetic_service_fixtures("cond", TOKEN)


def sensor_csv(blue_scale: float = 1.0) -> str:
    """A three-Gaussian sensor (R 600, G 540, B 460 nm) with its blue curve scaled by ``blue_scale``."""
    return "wavelength,r,g,b\n" + "\n".join(
        f"{w},{np.exp(-((w - 600) / 40) ** 2):.6g},{np.exp(-((w - 540) / 40) ** 2):.6g},"
        f"{blue_scale * np.exp(-((w - 460) / 30) ** 2):.6g}" for w in range(380, 785, 5))


def load(resp) -> dict:
    assert resp.status_code == 200, resp.text
    z = np.load(io.BytesIO(resp.content))
    return {k: z[k] for k in z.files}


def refusal(resp, *needles: str) -> str:
    """The detail of a 422, checked to be one line holding every needle."""
    assert resp.status_code == 422, resp.text
    detail = resp.json()["detail"]
    assert "\n" not in detail and all(n in detail for n in needles), detail
    return detail


# -- item 3: subnormal and zero intensities ---------------------------------------------------------
@pytest.mark.parametrize("intensities", ["1e-320,1e-320", "5e-324,0", "0,1e-320"])
def test_subnormal_intensities_give_a_dark_frame(client, intensities):
    params = V0 | {"pair": "FL2,FL7", "intensities": intensities, "outputs": "raw,gain,meta"}
    for _ in range(2):  # the second request reads the cached projection (where the audit's 422 came from)
        z = load(client.get("/sample", params=params))
        assert not np.any(z["raw"]) and np.all(np.isfinite(z["gain"]))
    meta = json.loads(str(z["meta"]))
    assert [i["intensity"] for i in meta["illuminants"]] == [float(x) for x in intensities.split(",")]


def test_subnormal_intensity_adds_what_zero_adds(client):
    base = V0 | {"pair": "FL2,FL7", "outputs": "raw"}
    off = load(client.get("/sample", params=base | {"intensities": "0,1"}))["raw"]
    for _ in range(2):
        tiny = load(client.get("/sample", params=base | {"intensities": "1e-320,1"}))["raw"]
        np.testing.assert_array_equal(tiny, off)


def test_projected_vanishing_weights_are_dark_and_other_weights_still_refused():
    """Weights as the engine computes them (``a · Φ̄/Ē · C Δλ``) against a projection cached at a = 1."""
    rng = np.random.default_rng(0)
    phi, emi = rng.uniform(0.2, 1.5, (1, 63)), rng.uniform(0.5, 2.0, (1, 63))
    c = sen.get_sensor("XYZ", DEFAULT_GRID).weights()

    def weights(a: float) -> np.ndarray:
        return raw_weights(band_scales(phi, emi, np.array([a])), c)[0]

    p = Projected(rng.uniform(0, 1, (4, 5, 3)).astype(np.float32), weights(1.0), 63)
    for a in (1e-320, 5e-324, 1e-310, 0.0):
        assert not np.any(p.project(weights(a)))
    np.testing.assert_allclose(p.project(weights(1e-30)), p.raw * np.float32(1e-30), rtol=1e-6)
    with pytest.raises(SpectralError, match="cache key"):
        p.project(weights(1.0)[::-1].copy())  # another sensor or illuminant: still a bug, still refused


def test_subnormal_intensity_is_relit_like_a_tiny_one():
    """A band the cube cannot relight is refused for 5e-324 as for 1e-3 (0.3 · 5e-324 underflows to 0)."""
    phi, emi = np.full((1, 4), 0.3), np.array([[1.0, 1.0, 1.0, 0.0]])
    for a in (1e-3, 5e-324):
        with pytest.raises(SpectralError, match="zero emission"):
            band_scales(phi, emi, np.array([a]))


# -- item 2: degenerate inputs refused at upload ----------------------------------------------------
def test_narrow_band_illuminant_upload_refused(client):
    r = client.post("/illuminants", data={"name": "narrow"}, files={"file": ("n.csv", NARROW_CSV)}, headers=AUTH)
    refusal(r, "illuminant 'narrow'", "through sensor", "condition number", "limit", "broadband SPD")
    assert "narrow" not in client.get("/illuminants").json()["uploaded"]


def test_near_zero_blue_sensor_upload_refused(client):
    r = client.post("/sensors", data={"name": "blindblue"}, files={"file": ("b.csv", sensor_csv(1e-12))},
                    headers=AUTH)
    refusal(r, "sensor 'blindblue'", "blue channel", "white-balance gain", "blue column")
    assert "blindblue" not in client.get("/sensors").json()["uploaded"]
    # the same curves at full blue are a fine camera: no false refusal
    ok = client.post("/sensors", data={"name": "fullblue"}, files={"file": ("f.csv", sensor_csv())}, headers=AUTH)
    assert ok.status_code == 201, ok.text


# -- item 2: the same inputs refused at composition, when they arrive another way -------------------
def test_stored_narrow_illuminant_refused_at_composition(client, store_path):
    from illumix.store import CubeStore

    # stored before these bounds existed (or written around the upload route)
    CubeStore.open(str(store_path), mode="a").registry("illuminants").put("oldnarrow", NARROW_CSV.encode(), "csv")
    for outputs in ("raw", "raw,ccm,meta"):  # refused whatever the outputs
        r = client.get("/sample", params=V0 | {"sensor": "XYZ", "illuminants": "oldnarrow,D65", "outputs": outputs})
        refusal(r, "illuminant 'oldnarrow' through sensor 'XYZ'", "condition number", "broadband illuminant")
    # a group it does not light does not refuse a raw-only request (its CCM is not served)
    r = client.get("/sample", params=V0 | {"sensor": "XYZ", "illuminants": "oldnarrow,D65", "intensities": "0,1",
                                           "outputs": "raw"})
    assert r.status_code == 200, r.text


def test_sensor_file_with_near_zero_blue_refused_at_composition(client, tmp_path, monkeypatch):
    (tmp_path / "blind_blue.csv").write_text(sensor_csv(1e-12))
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(tmp_path))
    r = client.get("/sample", params=V0 | {"sensor": "blind_blue", "pair": "A,D65", "outputs": "raw"})
    refusal(r, "through sensor 'blind_blue'", "blue channel", "limit 1e-06")


def test_library_refuses_degenerate_pairs_for_every_caller(monkeypatch):
    """:meth:`Library.ccm` is what export and DNG encoding ask too: none of them gets a degenerate CCM."""
    grid = DEFAULT_GRID
    lib = Library(store=None)
    xyz, skey = sen.get_sensor("XYZ", grid), "builtin:XYZ"
    narrow = ill.spd_from_samples(WL, (WL >= 392) & (WL <= 393), grid)
    with pytest.raises(SpectralError, match=r"illuminant 'narrow' through sensor 'XYZ'.*condition number"):
        lib.ccm(xyz, skey, narrow, "upload:narrow:0123abcd")
    nikon = sen.get_sensor("Nikon 5100 (NPL)", grid)  # no red response at all at 395 nm
    with pytest.raises(SpectralError, match=r"'violet' through sensor 'Nikon 5100 \(NPL\)'.*red channel is 0 of"):
        lib.ccm(nikon, "builtin:nikon", narrow, "upload:v:1", "violet")


# -- meta: the real fit error and condition number --------------------------------------------------
def test_meta_states_real_fit_error_and_condition(client):
    import colour

    z = load(client.get("/sample", params=V0 | {"sensor": "XYZ", "pair": "A,FL11", "outputs": "ccm,meta"}))
    meta = json.loads(str(z["meta"]))
    assert meta["conditioning_limits"] == {"max_white_balance_gain": cond.MAX_WHITE_GAIN,
                                           "max_ccm_condition_number": cond.MAX_CCM_CONDITION}
    grid = DEFAULT_GRID
    _, refl = get_reflectances(DEFAULT_TRAINING_SET, grid)
    w = sen.get_sensor("XYZ", grid).weights()
    for entry in meta["illuminants"]:
        m = np.asarray(entry["ccm"])
        assert entry["ccm_condition_number"] == pytest.approx(np.linalg.cond(m), rel=1e-6)
        assert 1 <= entry["ccm_condition_number"] <= cond.MAX_CCM_CONDITION
        # recomputed here from the served matrix, independently of the fit
        spd = ill.illuminant_spd(entry["illuminant"], grid)
        raw = (refl * spd) @ w / (spd @ w)
        de = colour.delta_E(linear_srgb_to_lab(raw @ m.T), linear_srgb_to_lab(target_linear_srgb(spd, refl, grid)),
                            method="CIE 2000")
        assert entry["ccm_fit_delta_e00_mean"] == pytest.approx(de.mean(), abs=1e-4)
        assert entry["ccm_fit_delta_e00_max"] == pytest.approx(de.max(), abs=1e-4)
        wp = spd @ w
        assert entry["white_balance_gain"] == pytest.approx(wp.max() / wp.min(), rel=1e-9)


def test_fit_error_is_that_of_the_served_matrix():
    """The audit's case: a |ccm| ~1e12 fit claimed 0.007 ΔE00; as served (float32) it is ~100."""
    grid = DEFAULT_GRID
    _, refl = get_reflectances(DEFAULT_TRAINING_SET, grid)
    narrow = ill.spd_from_samples(WL, (WL >= 392) & (WL <= 393), grid)
    fit = fit_ccm(sen.get_sensor("XYZ", grid).weights(), narrow, refl, grid)
    assert fit.condition > 1e10 and fit.delta_e00_mean > 10


# -- no false refusals --------------------------------------------------------------------------------
def _tabulated_builtins(grid) -> tuple[list[str], np.ndarray]:
    names, spds = [], []
    for n in ill.builtin_names():
        try:
            spds.append(ill.illuminant_spd(n, grid))
            names.append(n)
        except SpectralError:  # ISO 7589 tables stop short of the grid: unusable, not degenerate
            continue
    return names, np.stack(spds)


def test_builtin_illuminants_times_measured_cameras_are_never_refused(client, shared_data, monkeypatch):
    grid = DEFAULT_GRID
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(shared_data / CAMERA_DIR))
    names, spds = _tabulated_builtins(grid)
    assert len(names) >= 50
    lib = Library(store=None)
    for cam in ("XYZ", "Nikon 5100 (NPL)", *CAMERAS):
        s = sen.get_sensor(cam, grid)
        _, gains = cond.white_gains(s.weights(), spds)  # all illuminants at once
        assert gains.max() < cond.MAX_WHITE_GAIN / 1e4, (cam, names[int(np.argmax(gains))])
        conds = [lib.ccm(s, f"t:{cam}", spd, f"builtin:{n}")[1].condition for n, spd in zip(names, spds)]
        assert max(conds) < cond.MAX_CCM_CONDITION / 1e3, (cam, names[int(np.argmax(conds))])
    for cam, pair in zip(CAMERAS, ("HP1,FL3.4", "A,LED-V1", "FL12,D75", "LED-RGB1,HP5")):
        z = load(client.get("/sample", params=V0 | {"sensor": cam, "pair": pair, "outputs": "raw,ccm,meta"}))
        assert np.all(np.isfinite(z["ccm"])) and np.any(z["raw"])


def test_parametric_range_ends_are_not_refused():
    """``blackbody:500`` is the documented lower end: the bounds keep ≥ 10× margin over it."""
    grid = DEFAULT_GRID
    _, refl = get_reflectances(DEFAULT_TRAINING_SET, grid)
    for s in ("XYZ", "Nikon 5100 (NPL)"):
        w = sen.get_sensor(s, grid).weights()
        for n in ("blackbody:500", "blackbody:50000", "daylight:4000", "daylight:24000"):
            spd = ill.illuminant_spd(n, grid)
            _, gain = cond.white_gains(w, spd)
            assert gain[0] < cond.MAX_WHITE_GAIN / 10
            assert fit_ccm(w, spd, refl, grid).condition < cond.MAX_CCM_CONDITION / 10
