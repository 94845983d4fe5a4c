"""Physical ground truth through the service (issue 14): gt=physical|formula, the new outputs
(illum, mixture, albedo, normal, depth, reflectance, illumination) and their independent checks.

The synthetic store's illumination cubes are exact (a white Lambertian under each group is
``falloff/π`` in every band), so every physical quantity has a closed form computed here in float64
from the arrays as written — no service code involved.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

import synthetic_store as synth
from illumix.retarget.illuminants import illuminant_spd
from illumix.retarget.sensors import get_sensor
from illumix.service.app import create_app
from illumix.store import CubeStore

V0 = {"scene": "synth", "view": "v0", "sensor": "XYZ"}
PAIR = {"pair": "FL11,D65", "intensities": "1,0.5"}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    path = tmp_path_factory.mktemp("gt") / "store"
    synth.build(path, illumination=True)
    with TestClient(create_app(CubeStore.open(str(path), mode="r"), cache_mb=64)) as c:
        yield c


def get(client, **params) -> dict:
    r = client.get("/sample", params=V0 | PAIR | params)
    assert r.status_code == 200, r.text
    z = np.load(io.BytesIO(r.content))
    out = {k: z[k] for k in z.files}
    if "meta" in out:
        out["meta"] = json.loads(str(out["meta"]))
    return out


def closed_form():
    """Float64 physical ground truth of synth/v0 under PAIR, from the arrays as written."""
    w = get_sensor("XYZ").weights()
    fw, fl = synth.falloffs()
    spds = [illuminant_spd("FL11"), illuminant_spd("D65")]
    u = [a * f[..., None] / np.pi * (spd @ w) for a, f, spd in zip((1.0, 0.5), (fw, fl), spds)]  # (H, W, 3) each
    total = u[0] + u[1]
    lit = total[..., 1] > 0
    share = np.stack([x[..., 1] for x in u], -1) / np.where(lit, total[..., 1], 1)[..., None]
    wp = np.where(lit[..., None], total / np.where(lit, total[..., 1], 1)[..., None], 1.0)
    return wp, share, lit


def test_physical_is_the_default_and_matches_the_closed_form(client):
    z = get(client, outputs="illum,mixture,gain,mask,meta")
    assert z["meta"]["ground_truth"]["method"] == "physical"
    assert "U_k" in z["meta"]["ground_truth"]["equations"]
    wp, share, lit = closed_form()
    ok = z["mask"]
    assert ok.sum() > 0.8 * ok.size and not ok[-synth.DARK_ROWS:].any() and not ok[:2, :2].any()  # dark, emitter
    # float16 storage: relative error <= 2^-11 per value; ratios of positive sums stay within 4·2^-11
    np.testing.assert_allclose(z["illum"][ok], wp[ok], rtol=4 * 2**-11)
    np.testing.assert_allclose(z["mixture"][ok], share[ok], atol=4 * 2**-11)
    np.testing.assert_allclose(z["gain"][ok], (wp.max(-1, keepdims=True) / wp)[ok], rtol=4 * 2**-11)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def test_physical_white_point_ignores_the_surface_colour_the_formula_does_not(client):
    """Same light, different reflectance: on the coloured patches the physical white point is the
    light's (closed form), whatever the patch; the formula's mixes the groups by each patch's own G
    share and misses it — the formula's known error, which the physical ground truth removes."""
    phys = get(client, outputs="illum,mask")
    form = get(client, outputs="illum,mask", gt="formula")
    wp, _, _ = closed_form()
    ok = phys["mask"].copy()
    ok[:, synth.W // 2:] = False  # the ColorChecker half
    err_phys = _angle_deg(phys["illum"][ok], wp[ok])
    err_form = _angle_deg(form["illum"][ok], wp[ok])
    # float16 cubes: each channel within 2^-11 relative, so the angle within √2·2^-11 rad ≈ 0.04°
    assert err_phys.max() < 0.04 and err_form.max() > 0.3, (err_phys.max(), err_form.max())


def test_mixture_is_never_negative_or_nan_and_sums_to_one(client):
    for params in ({}, {"size": "17x13"}, {"crop": "60,40,4,8"}, {"intensities": "0,1"}, {"pair": "A,A"}):
        z = get(client, outputs="mixture,mask,illum,gain", **params)
        m = z["mixture"]
        assert np.isfinite(m).all() and (m >= 0).all()
        np.testing.assert_allclose(m.sum(-1), 1.0, atol=1e-5)
        assert np.isfinite(z["illum"]).all() and np.isfinite(z["gain"]).all() and (z["gain"] >= 1).all()


def test_formula_on_request_and_refusals_without_illumination(client, tmp_path):
    z = get(client, outputs="weights,mixture,meta", gt="formula")
    assert z["meta"]["ground_truth"]["method"] == "formula"
    np.testing.assert_array_equal(z["weights"], z["mixture"])  # the formula's mixture is eq. 3.3's weights
    old = tmp_path / "old"
    synth.build(old, extras=False)  # no illumination cubes
    with TestClient(create_app(CubeStore.open(str(old), mode="r"))) as c:
        r = c.get("/sample", params=V0 | PAIR | {"outputs": "gain,meta"})
        meta = json.loads(str(np.load(io.BytesIO(r.content))["meta"]))
        assert meta["ground_truth"]["method"] == "formula" and "re-render" in meta["ground_truth"]["why"]
        for bad in ({"gt": "physical"}, {"outputs": "reflectance"}, {"outputs": "illumination"}):
            r = c.get("/sample", params=V0 | PAIR | bad)
            assert r.status_code == 422 and "illumination cubes" in r.json()["detail"], r.text


def test_spectral_outputs_are_the_reflectance_and_the_relit_illumination(client):
    z = get(client, outputs="reflectance,illumination,mask", crop="8,4,40,20")
    refl = synth.reflectance_image()[4:24, 8:48]
    ok = z["mask"]
    np.testing.assert_allclose(z["reflectance"][ok], refl[ok], rtol=2 * 2**-11, atol=1e-6)
    fw, fl = synth.falloffs()
    expect = (fw[..., None] * illuminant_spd("FL11") + 0.5 * fl[..., None] * illuminant_spd("D65")) / np.pi
    np.testing.assert_allclose(z["illumination"], expect[4:24, 8:48], rtol=2 * 2**-11, atol=1e-7)
    assert z["reflectance"].shape == (20, 40, 63) and z["illumination"].dtype == np.float32


def test_aov_outputs_and_mask_reasons(client):
    z = get(client, outputs="albedo,normal,depth,mask,meta")
    assert z["albedo"].shape == (synth.H, synth.W, 3) and z["depth"].shape == (synth.H, synth.W)
    np.testing.assert_allclose(z["normal"], np.broadcast_to([0, 0, 1], z["normal"].shape), atol=1e-6)
    reasons = z["meta"]["mask_reasons"]
    assert reasons["pixels"]["emitter"] == 4 and reasons["pixels"]["no_geometry"] == 0
    assert reasons["pixels"]["no_light"] == synth.DARK_ROWS * synth.W
    assert set(reasons["meaning"]) == {"no_geometry", "emitter", "no_light"}
    small = get(client, outputs="albedo,normal,depth,mixture", size="32x24")
    assert small["albedo"].shape == (24, 32, 3) and small["mixture"].shape == (24, 32, 2)
