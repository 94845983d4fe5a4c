"""Numerical stability stress suite (issue 7, item 3): the store codec and the service path.

tests/test_properties.py covers the physics core (compose, ground truth, band scales, resampling)
on in-memory arrays. This file pushes the same kinds of input through the layers around it:

- the store: cubes with per-pixel magnitudes from 1e-30 to 1e30, visible emitters beyond float16's
  65504, shadows below its normal range, zeros and negatives, written with each dtype policy and
  read back whole, cropped and band-subset — finite, within the documented bound, crops exact;
- CCM fits for near-degenerate sensors (collinear, 1e-9-weak or narrow channels) under spiky
  illuminants — a finite, white-preserving, least-squares-optimal matrix or a clear SpectralError;
- the service (FastAPI TestClient over a synthetic store, 8 MB cache so it churns): spiky and
  narrow-band uploaded illuminants, degenerate uploaded sensors, intensities 1e-6 … 1e6, 1×1 to
  at-the-limit crops and resizes, zero-light and all-dark frames, float16 and float32-fallback
  cubes — a 200 whose arrays are finite, in range and equal to an independent float64 computation
  from the cubes as written (before storage), a 422 that says what is wrong, or a 413 for a size
  over the limits. Nothing else.

Seeded (derandomize=True): the same cases run in CI every time.
"""

from __future__ import annotations

import io
import json
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from illumix.retarget.ccm import fit_ccm
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID
from illumix.retarget.illuminants import illuminant_spd
from illumix.retarget.reflectances import get_reflectances
from illumix.retarget.sensors import sensor_from_samples
from illumix.store import CubeMeta, CubeStore, StoreError, ViewMeta
from illumix.store.codec import REL_BOUND_F16

_SCALE = int(os.environ.get("ILLUMIX_HYPOTHESIS_SCALE", "1"))
SETTINGS = dict(derandomize=_SCALE == 1, database=None, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])
N = DEFAULT_GRID.n_bands
WL = DEFAULT_GRID.wavelengths
PALETTE = get_reflectances("ColorChecker N Ohta")[1]
FLAT = [1.0] * N


def _meta(**kw) -> CubeMeta:
    return CubeMeta(grid=DEFAULT_GRID.to_dict(), emission=FLAT, emission_name="flat", **kw)


# ------------------------------------------------------------------------------ store codec


@st.composite
def extreme_cubes(draw) -> np.ndarray:
    """``(h, w, 63)`` float32: pixel magnitude 1e-30…1e30, per-band spread up to 12 decades
    (beyond float16's 29 stops per pixel), zeros, optional negatives and a bright emitter."""
    h, w = draw(st.integers(1, 9)), draw(st.integers(1, 9))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    centre = draw(st.floats(-30, 30))
    spread = draw(st.sampled_from([0.0, 1.0, 4.0, 8.0, 12.0]))
    logv = centre + rng.uniform(-3, 3, (h, w, 1)) + rng.uniform(0, spread, (h, w, N))
    c = 10.0 ** logv
    c *= rng.uniform(0, 1, c.shape) > draw(st.sampled_from([0.0, 0.2, 0.9]))  # zeros
    if draw(st.booleans()):
        c *= np.where(rng.uniform(0, 1, c.shape) < 0.05, -1.0, 1.0)  # denoiser undershoot
    if draw(st.booleans()):
        c[rng.integers(0, h), rng.integers(0, w)] = 10.0 ** draw(st.floats(5, 37))  # visible emitter
    return np.clip(c, -3e38, 3e38).astype(np.float32)


@pytest.fixture(scope="module")
def codec_store(tmp_path_factory):
    return CubeStore.open(str(tmp_path_factory.mktemp("codec") / "st"), mode="a", tile=16)


@settings(max_examples=100 * _SCALE, **SETTINGS)
@given(cube=extreme_cubes(), policy=st.sampled_from(["auto", "auto", "float16", "float32"]),
       data=st.data())
def test_store_round_trip_of_extreme_cubes_is_finite_bounded_and_crop_exact(codec_store, cube, policy, data):
    h, w, _ = cube.shape
    view = f"v{h}x{w}"
    if "s" not in codec_store.scenes() or view not in codec_store.views("s"):
        codec_store.write_view("s", view, ViewMeta(width=w, height=h, fov=45.0))
    m = codec_store.write_cube("s", view, "g", cube, _meta(), overwrite=True, dtype_policy=policy)
    event(f"{policy} -> {m.storage.dtype}")
    got = codec_store.read_cube("s", view, "g")
    assert got.dtype == np.float32 and got.shape == cube.shape and np.isfinite(got).all()
    assert np.array_equal(got == 0, cube == 0) or m.storage.underflow_values > 0
    assert np.all(np.sign(got) * np.sign(cube) >= 0)  # never a flipped sign
    err = np.abs(got.astype(np.float64) - cube)
    if m.storage.dtype == "float32":
        assert np.array_equal(got, cube)
    elif m.storage.underflow_values == 0:
        assert np.all(err <= REL_BOUND_F16 * np.abs(cube.astype(np.float64)))
    else:  # forced float16: values below its normal range keep an absolute bound of half a float16
        # subnormal step, 2^-25 · 2^(ε − 15) · 2^β, with ε the pixel exponent the codec clamps at -96
        beta = np.ldexp(1.0, np.asarray(m.storage.band_exponent))
        pixmax = (np.abs(cube) / beta).max(axis=-1, keepdims=True)
        eps = np.maximum(np.where(pixmax > 0, np.frexp(pixmax)[1], 0), -96)
        assert np.all(err <= REL_BOUND_F16 * np.abs(cube.astype(np.float64)) + np.ldexp(beta, eps - 40))
    x0, y0 = data.draw(st.integers(0, w - 1)), data.draw(st.integers(0, h - 1))
    cw, ch = data.draw(st.integers(1, w - x0)), data.draw(st.integers(1, h - y0))
    bands = sorted(data.draw(st.sets(st.integers(0, N - 1), min_size=1, max_size=8)))
    crop = codec_store.read_cube("s", view, "g", crop=(x0, y0, cw, ch), bands=bands)
    assert np.array_equal(crop, got[y0:y0 + ch, x0:x0 + cw][..., bands])


def test_store_refuses_values_beyond_float32_and_nan_by_name(codec_store):
    codec_store.write_view("s", "v2x2", ViewMeta(width=2, height=2, fov=45.0))
    for bad in (1e39, np.inf, np.nan):
        c = np.ones((2, 2, N))
        c[1, 0, 5] = bad
        with pytest.raises(StoreError, match="NaN/inf"):
            codec_store.write_cube("s", "v2x2", "bad", c, _meta(), overwrite=True)


# ------------------------------------------------------------------------------- CCM fits


@st.composite
def degenerate_sensors(draw):
    wl = np.arange(380.0, 781.0, 5.0)
    rgb = np.stack([np.exp(-0.5 * ((wl - c) / draw(st.floats(10, 60))) ** 2)
                    for c in (600 + draw(st.floats(-30, 30)), 540, 455 + draw(st.floats(-20, 20)))], axis=-1)
    kind = draw(st.sampled_from(["collinear", "weak", "narrow", "overlap"]))
    i, j = draw(st.sampled_from([(0, 1), (1, 2), (0, 2)]))
    eps = 10.0 ** draw(st.floats(-12, -1))
    if kind == "collinear":  # channel j = channel i up to a tiny perturbation
        rgb[:, j] = rgb[:, i] * (1 + eps * np.sin(wl / 17.0))
    elif kind == "weak":
        rgb[:, j] *= eps
    elif kind == "narrow":  # every channel a few bands wide, dark elsewhere
        rgb = np.where(np.abs(wl[:, None] - np.array([610, 545, 460])) <= 5 + 100 * eps, rgb + 1e-3, 0.0)
    else:  # all three nearly the same broad curve
        rgb = np.exp(-0.5 * ((wl - 550) / 80) ** 2)[:, None] * (1 + eps * np.array([[1.0, 0.0, -1.0]])
                                                                 * np.cos(wl / 23.0)[:, None])
    return kind, sensor_from_samples("degenerate", wl, rgb)


def _unresolvable_energy(raw: np.ndarray, target: np.ndarray) -> float:
    """Target energy that double precision cannot attribute to the fit or to the residual.

    The constrained problem is least squares on ``A = raw · N`` (N spans M·1 = 1's null space). Along
    a left singular vector of A whose singular value is below √ε·‖raw‖ (ε = 2.2e-16), any two
    correct solvers — lstsq on A, or the KKT system, whose normal-equation block squares A's
    condition number — may either fit or leave the target's component, depending on rounding (BLAS
    kernel and operand alignment, hence test order). Their residuals may differ by that energy.
    """
    null = np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, -1.0]])
    a = raw @ null
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    weak = sv < np.sqrt(np.finfo(float).eps) * np.linalg.norm(raw, 2)  # on raw's scale: A's columns cancel
    rhs = target - (raw @ np.full(3, 1.0 / 3.0))[:, None]
    return float(np.sum((u[:, weak].T @ rhs) ** 2))


def _rounding_slack(raw: np.ndarray, m: np.ndarray, residual: float) -> float:
    """First-order bound on how much rounding in ``raw`` moves a least-squares residual
    (Golub & Van Loan, *Matrix Computations*, §5.3.7): each entry of raw is a 63-term band sum, so
    ``‖δraw‖ ≤ 64 ε ‖raw‖``, and a residual ``r`` of solution ``M`` moves by at most
    ``2‖δraw‖‖M‖√r + (‖δraw‖‖M‖)²`` per output channel. Near-collinear sensors have huge ``‖M‖``."""
    d = 64 * np.finfo(float).eps * np.linalg.norm(raw, 2) * np.linalg.norm(m, 2)
    return 3 * (2 * d * np.sqrt(residual) + d * d)


def _kkt_residual(raw: np.ndarray, target: np.ndarray) -> float:
    """Independent white-preserving least squares (KKT system): min Σ‖M ρ_n − t_n‖², M·1 = 1."""
    a = raw.T @ raw
    kkt = np.block([[a, np.ones((3, 1))], [np.ones((1, 3)), np.zeros((1, 1))]])
    total = 0.0
    for r in range(3):
        sol = np.linalg.lstsq(kkt, np.concatenate([raw.T @ target[:, r], [1.0]]), rcond=None)[0]
        total += float(np.sum((raw @ sol[:3] - target[:, r]) ** 2))
    return total


@settings(max_examples=100 * _SCALE, **SETTINGS)
@given(sensor=degenerate_sensors(), ill=st.sampled_from(["FL11", "LED-RGB1", "FL2", "A", "F2-line"]))
def test_ill_conditioned_ccm_fits_are_optimal_and_white_preserving_or_refused(sensor, ill):
    kind, s = sensor
    spd = np.where(np.abs(WL - 545) <= 2.5, 1e3, 1e-3) if ill == "F2-line" else illuminant_spd(ill)
    try:
        fit = fit_ccm(s.weights(), spd, PALETTE, s.grid)
    except SpectralError as exc:
        event(f"{kind}: refused")
        assert str(exc).strip()
        return
    event(f"{kind}: fitted")
    m = fit.matrix
    assert np.all(np.isfinite(m)) and np.all(np.isfinite(fit.delta_e00))
    np.testing.assert_allclose(m @ np.ones(3), np.ones(3), rtol=0, atol=1e-6 * max(1.0, np.abs(m).max()))
    from illumix.retarget.ccm import target_linear_srgb

    cw = s.weights()
    raw = (PALETTE * spd) @ cw / (spd @ cw)
    target = target_linear_srgb(spd, PALETTE, s.grid)
    ours = float(np.sum((raw @ m.T - target) ** 2))
    slack = _unresolvable_energy(raw, target) + _rounding_slack(raw, m, max(ours, 1e-300))
    event(f"{kind}: slack {'> 1e-9' if slack > 1e-9 else '<= 1e-9'}")
    assert ours <= _kkt_residual(raw, target) * (1 + 1e-6) + 1e-9 + slack  # no worse than the optimum


# ---------------------------------------------------------------------------------- service
# (the service fixture, strategies and checks live in stress_service.py to keep files small)

from stress_service import build_stress_app, check_response, sample_requests  # noqa: E402


@pytest.fixture(scope="module")
def stress_app(tmp_path_factory):
    yield from build_stress_app(tmp_path_factory)


@settings(max_examples=400 * _SCALE, **SETTINGS)
@given(params=sample_requests())
def test_service_answers_finite_correct_samples_or_clear_422(stress_app, params):
    client, ctx = stress_app
    r = client.get("/sample", params=params)
    assert r.status_code in (200, 413, 422), (r.status_code, r.text[:300], params)
    if r.status_code in (413, 422):
        err = r.json()
        assert isinstance(err["detail"], str) and len(err["detail"]) > 10, err
        assert err["status"] == r.status_code and (r.status_code == 422 or err["code"] == "too_large"), err
        event(f"{r.status_code}: {err['detail'].split(':')[0][:40]}")
        return
    event("200")
    z = np.load(io.BytesIO(r.content))
    arrays = {k: z[k] for k in z.files if k != "meta"}
    meta = json.loads(str(z["meta"]), parse_constant=lambda c: pytest.fail(f"meta holds {c}"))
    check_response(ctx, params, arrays, meta)


def _npz(r) -> dict:
    assert r.status_code == 200, r.text
    z = np.load(io.BytesIO(r.content))
    return {k: z[k] for k in z.files}


def test_tiny_and_at_the_limit_crops_and_sizes(stress_app):
    client, _ = stress_app
    base = {"scene": "synth", "view": "v0", "illuminants": "FL11,LED-RGB1", "sensor": "weakblue"}
    one = _npz(client.get("/sample", params=base | {"crop": "63,47,1,1"}))
    assert one["raw"].shape == (1, 1, 3) and one["mask"].shape == (1, 1)
    px = _npz(client.get("/sample", params=base | {"crop": "10,10,1,1", "outputs": "raw,gain"}))
    up = _npz(client.get("/sample", params=base | {"crop": "10,10,1,1", "size": "512x64", "outputs": "raw,gain"}))
    assert up["raw"].shape == (64, 512, 3)  # one pixel blown up: that pixel everywhere (bilinear, ±1 ulp)
    np.testing.assert_allclose(up["raw"], np.broadcast_to(px["raw"], up["raw"].shape), rtol=1e-6)
    np.testing.assert_allclose(up["gain"], np.broadcast_to(px["gain"], up["gain"].shape), rtol=1e-6)
    big = _npz(client.get("/sample", params=base | {"size": "512x64", "outputs": "srgb"}))  # exactly at the limit
    assert big["srgb"].shape == (64, 512, 3) and np.isfinite(big["srgb"]).all()
    for bad, status, needle in (({"size": "513x1"}, 413, "exceeds the limits"),
                                ({"size": "256x129"}, 413, "exceeds the limits"),
                                ({"crop": "1,0,64,48"}, 422, "exceeds the view"), ({"crop": "0,0,0,5"}, 422, "crop"),
                                ({"crop": "0,0,5"}, 422, "crop"), ({"size": "0x5"}, 422, "size")):
        r = client.get("/sample", params=base | bad)
        assert r.status_code == status and needle in r.json()["detail"], (bad, r.text)
    r = client.post("/batch", json={"samples": [base | {"outputs": "raw"}] * 5})  # max_batch is 4
    assert r.status_code == 413 and "split it" in r.json()["detail"]


def test_all_dark_and_half_dark_frames_are_flagged_not_nan(stress_app):
    client, _ = stress_app
    for view, valid in (("dark", False), ("halfdark", True)):
        z = _npz(client.get("/sample", params={"scene": "stress", "view": view, "illuminants": "D65,A",
                                               "outputs": "raw,gain,ccm,srgb,weights,mask"}))
        assert z["mask"].all() == valid and not (z["mask"].any() and not valid)
        for k in ("raw", "gain", "ccm", "srgb", "weights"):
            assert np.isfinite(z[k]).all(), k
        if valid:  # all light comes from group b: its weight is 1 everywhere
            np.testing.assert_array_equal(z["weights"][..., 1], 1.0)


def test_bad_uploads_are_refused_with_a_reason(stress_app):
    client, _ = stress_app
    auth = {"Authorization": "Bearer stress-token"}
    wl = np.arange(380, 781, 5)
    cases = {
        "uvonly": ("wavelength,value\n" + "\n".join(f"{w},{1.0 if w < 390 else 0.0}" for w in wl), "luminance"),
        "negative": ("wavelength,value\n" + "\n".join(f"{w},{-1.0 if w == 500 else 1.0}" for w in wl), "negative"),
        "nanvalue": ("wavelength,value\n" + "\n".join(f"{w},{'nan' if w == 500 else 1.0}" for w in wl), ""),
        "huge": ("wavelength,value\n" + "\n".join(f"{w},1e400" for w in wl), ""),
    }
    for name, (csv, needle) in cases.items():
        r = client.post("/illuminants", data={"name": name}, files={"file": (f"{name}.csv", csv)}, headers=auth)
        assert r.status_code == 422, (name, r.status_code, r.text)
        assert needle in r.json()["detail"] and len(r.json()["detail"]) > 10
    dead = "wavelength,r,g,b\n" + "\n".join(f"{w},1,{0.0},1" for w in wl)
    r = client.post("/sensors", data={"name": "deadgreen"}, files={"file": ("d.csv", dead)}, headers=auth)
    assert r.status_code == 422 and "all zero" in r.json()["detail"]
