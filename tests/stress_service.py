"""The service half of tests/test_stress.py: a stress store, request strategy, independent checks.

Store (besides tests/synthetic_store.py's ``synth/v0``): scene ``stress``, every view with groups
``a`` and ``b`` (flat emission):

- ``ext`` 24×32: ``a`` = ColorChecker × a per-pixel light level 1e-7…1 with a visible emitter of
  1e6 (beyond float16's 65504) and a zero-light block; ``b`` = spectra with 1000× lines in three
  bands × light 1e-3…1e2;
- ``dot`` 1×1 (1e-6 and 1e6 lights), ``wide`` 1×300, ``dark`` 8×8 (no light at all), ``halfdark``
  8×12 (group ``a`` dark);
- ``forced16`` / ``fallback32`` 12×16: one pixel spans 1e10 between bands (beyond float16's 29
  stops), stored with the forced float16 policy (underflow: absolute bound) and with ``auto``
  (exact float32 fallback).

Uploads: illuminants ``spike`` (a 1 nm line 1e12 above its floor), ``led450`` (narrow, exact zeros
elsewhere), ``twoline``; sensors ``degen`` (G = R up to 1e-9), ``weakblue`` (B × 1e-5),
``narrowcam`` (each channel ~20 nm wide, zero elsewhere). ``spike`` and ``degen`` are beyond the
bounds of :mod:`retarget.conditioning`: their uploads are refused, so they are written straight into
the registry (as if stored before the bounds) and every sample using them must be a clear 422.
"""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient
from hypothesis import event
from hypothesis import strategies as st

import synthetic_store as synth
from illumix.retarget.grid import DEFAULT_GRID
from illumix.service.app import create_app
from illumix.engine.limits import Limits
from illumix.store import CubeMeta, CubeStore, ViewMeta

TOKEN = "stress-token"
N = DEFAULT_GRID.n_bands
LIMITS = Limits(max_side=512, max_pixels=512 * 64, max_batch=4)
VIEWS = {("synth", "v0"): (synth.W, synth.H), ("stress", "ext"): (32, 24), ("stress", "dot"): (1, 1),
         ("stress", "wide"): (300, 1), ("stress", "dark"): (8, 8), ("stress", "halfdark"): (12, 8),
         ("stress", "forced16"): (16, 12), ("stress", "fallback32"): (16, 12)}
GROUPS = {"synth": ("window", "lamp"), "stress": ("a", "b")}
ILLUMINANTS = ["D65", "A", "FL11", "FL2", "LED-RGB1", "LED-V1", "spike", "led450", "twoline",
               "blackbody:1000", "daylight:25000", "E"]
SENSORS = ["XYZ", "Nikon 5100 (NPL)", "degen", "weakblue", "narrowcam"]
DEGENERATE = {"spike", "degen"}  # refused at upload and at composition (module docstring)
OUTPUTS = ["raw", "gain", "ccm", "srgb", "weights", "mask"]


def _csv(wl, cols) -> str:
    rows = [",".join([f"{w:g}"] + [f"{v:.9g}" for v in np.atleast_1d(c)]) for w, c in zip(wl, cols)]
    return "wavelength," + ("value" if np.ndim(cols[0]) == 0 else "r,g,b") + "\n" + "\n".join(rows)


def _uploads() -> tuple[dict[str, str], dict[str, str]]:
    wl = np.arange(380.0, 781.0, 1.0)
    ills = {"spike": _csv(wl, np.where(wl == 552, 1e6, 1e-6)),
            "led450": _csv(wl, np.where(abs(wl - 450) <= 15, np.exp(-0.5 * ((wl - 450) / 6) ** 2), 0.0)),
            "twoline": _csv(wl, np.where((abs(wl - 435) <= 2) | (abs(wl - 546) <= 2), 1.0, 0.0))}
    w5 = np.arange(380.0, 781.0, 5.0)
    g = np.stack([np.exp(-0.5 * ((w5 - c) / 35) ** 2) for c in (600, 540, 455)], axis=-1)
    degen = g.copy()
    degen[:, 1] = degen[:, 0] * (1 + 1e-9 * np.sin(w5 / 13))
    weak = g * [1, 1, 1e-5]  # white-balance gains ~1e5: near retarget.conditioning's bound, still served
    narrow = np.where(np.abs(w5[:, None] - np.array([610, 545, 460])) <= 10, g + 1e-3, 0.0)
    sens = {"degen": _csv(w5, degen), "weakblue": _csv(w5, weak), "narrowcam": _csv(w5, narrow)}
    return ills, sens


def _stress_cubes(rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    from illumix.retarget.reflectances import get_reflectances

    cc = get_reflectances("ColorChecker N Ohta")[1].astype(np.float32)

    def refl(h, w):
        return cc[rng.integers(0, 24, (h, w))]

    out = {}
    a = refl(24, 32) * (10.0 ** rng.uniform(-7, 0, (24, 32, 1))).astype(np.float32)
    a[2, 3] = 1e6
    a[10:14, 10:14] = 0.0
    lines = np.ones(N, np.float32)
    lines[[8, 30, 50]] = 1e3
    b = refl(24, 32) * lines * (10.0 ** rng.uniform(-3, 2, (24, 32, 1))).astype(np.float32)
    b[10:14, 10:14] = 0.0
    out["ext"] = (a, b)
    out["dot"] = (refl(1, 1) * np.float32(1e-6), np.full((1, 1, N), 1e6, np.float32))
    out["wide"] = (refl(1, 300) * np.linspace(0, 2, 300, dtype=np.float32)[None, :, None],
                   refl(1, 300) * np.linspace(2, 0, 300, dtype=np.float32)[None, :, None])
    out["dark"] = (np.zeros((8, 8, N), np.float32), np.zeros((8, 8, N), np.float32))
    out["halfdark"] = (np.zeros((8, 12, N), np.float32), refl(8, 12))
    wide_range = refl(12, 16)
    wide_range[5, 5, :20] *= np.float32(1e-10)  # one pixel spans 1e10 between its bands
    out["forced16"] = (wide_range, refl(12, 16))
    out["fallback32"] = (wide_range.copy(), refl(12, 16))
    return out


def build_stress_app(tmp_path_factory):
    """Generator for the module fixture: yields ``(TestClient, app.state)``."""
    path = tmp_path_factory.mktemp("stress") / "store"
    synth.build(path)
    st_ = CubeStore.open(str(path), mode="a", tile=16)
    meta = dict(grid=DEFAULT_GRID.to_dict(), emission=[1.0] * N, emission_name="flat")
    originals = {}
    rf = synth.reflectance_image()
    for g, f in zip(GROUPS["synth"], synth.falloffs()):
        originals[("synth", "v0", g)] = rf * (f / np.float32(np.pi))[..., None]
    for view, cubes in _stress_cubes(np.random.default_rng(7)).items():
        w, h = VIEWS[("stress", view)]
        st_.write_view("stress", view, ViewMeta(width=w, height=h, fov=45.0))
        for g, c in zip(GROUPS["stress"], cubes):
            policy = "float16" if view == "forced16" else None
            m = st_.write_cube("stress", view, g, c, CubeMeta(**meta), dtype_policy=policy)
            originals[("stress", view, g)] = c
            if view == "forced16" and g == "a":
                assert m.storage.dtype == "float16" and m.storage.underflow_values > 0
            if view == "fallback32" and g == "a":
                assert m.storage.dtype == "float32"
    app = create_app(st_, token=TOKEN, cache_mb=1, limits=LIMITS)  # 1 MiB: the cache churns
    client = TestClient(app)
    auth = {"Authorization": f"Bearer {TOKEN}"}
    ills, sens = _uploads()
    for kind, uploads in (("illuminants", ills), ("sensors", sens)):
        for name, csv in uploads.items():
            r = client.post(f"/{kind}", data={"name": name}, files={"file": (f"{name}.csv", csv)}, headers=auth)
            assert r.status_code == (422 if name in DEGENERATE else 201), r.text
            if name in DEGENERATE:
                st_.registry(kind).put(name, csv.encode(), "csv")
    app.state.originals = originals
    with client:
        yield client, app.state


# ------------------------------------------------------------------------------ requests

_log_int = st.floats(-6, 6).map(lambda e: f"{10.0 ** e:.6g}")
_bad_int = st.sampled_from(["-1", "nan", "inf", "1e10", "x"])


@st.composite
def sample_requests(draw) -> dict:
    (scene, view), (w, h) = draw(st.sampled_from(sorted(VIEWS.items())))
    p = {"scene": scene, "view": view, "seed": 1,
         "illuminants": ",".join(draw(st.sampled_from(ILLUMINANTS)) for _ in range(2)),
         "sensor": draw(st.sampled_from(SENSORS))}
    ints = [draw(st.one_of(st.just("0"), _log_int, _log_int, _log_int)) for _ in range(2)]
    if draw(st.integers(0, 9)) == 0:
        ints[draw(st.integers(0, 1))] = draw(_bad_int)
    if draw(st.booleans()):
        p["intensities"] = ",".join(ints)
    crop = draw(st.sampled_from(["none", "none", "inside", "pixel", "beyond"]))
    if crop == "inside":
        x, y = draw(st.integers(0, w - 1)), draw(st.integers(0, h - 1))
        p["crop"] = f"{x},{y},{draw(st.integers(1, w - x))},{draw(st.integers(1, h - y))}"
    elif crop == "pixel":
        p["crop"] = f"{draw(st.integers(0, w - 1))},{draw(st.integers(0, h - 1))},1,1"
    elif crop == "beyond":
        p["crop"] = f"{draw(st.integers(0, w))},0,{w + 1},{h}"
    size = draw(st.sampled_from(["none", "none", "none", "1x1", "small", "512x64", "513x1", "300x200"]))
    if size == "small":
        p["size"] = f"{draw(st.integers(1, 64))}x{draw(st.integers(1, 64))}"
    elif size != "none":
        p["size"] = size
    ex = draw(st.sampled_from(["none", "none", "none", "auto", "adaptive", "1e-6", "1e6", "1e13", "0"]))
    if ex != "none":
        p["exposure"] = ex
    outs = draw(st.sets(st.sampled_from(OUTPUTS), min_size=1))
    p["outputs"] = ",".join(sorted(outs) + ["meta"])
    return p


# -------------------------------------------------------------------------------- checks


def _independent(state, scene, view, names, intens, sensor_name, window):
    """Per-group raw ``(G, h, w, 3)`` float64 from the cubes as written (before storage)."""
    lib = state.ctx.library
    sensor, _ = lib.sensor(sensor_name, DEFAULT_GRID)
    sw = sensor.weights()
    x, y, w, h = window
    out, spds = [], []
    for g, name, a in zip(GROUPS[scene], names, intens):
        spd, _ = lib.illuminant(name, DEFAULT_GRID)
        spds.append(spd)
        if view == "forced16":  # underflowed values keep an absolute bound only: use the decoded cube
            cube = state.ctx.store.read_cube(scene, view, g)
        else:
            cube = state.originals[(scene, view, g)]
        t = np.asarray(cube, np.float64)[y:y + h, x:x + w]
        out.append(a * np.einsum("hwb,bk->hwk", t, spd[:, None] * sw))
    return np.stack(out), np.stack(spds), sw


def check_response(state, p: dict, arrays: dict, meta: dict) -> None:
    scene, view = p["scene"], p["view"]
    fw, fh = VIEWS[(scene, view)]
    x, y, w, h = map(int, p["crop"].split(",")) if "crop" in p else (0, 0, fw, fh)
    ow, oh = map(int, p["size"].lower().split("x")) if "size" in p else (w, h)
    assert meta["crop"] == [x, y, w, h] and meta["size"] == [ow, oh]
    for k, v in arrays.items():
        assert v.shape[:2] == (oh, ow), (k, v.shape)
        assert v.dtype == (bool if k == "mask" else np.float32), (k, v.dtype)
        assert np.all(np.isfinite(v)), f"{k} has NaN/inf"
    if "gain" in arrays:
        assert arrays["gain"].min() >= 1.0 - 1e-6
    if "srgb" in arrays:
        assert arrays["srgb"].min() >= 0.0 and arrays["srgb"].max() <= 1.0
    if "weights" in arrays:
        wts = arrays["weights"]
        assert wts.min() >= 0 and wts.max() <= 1 + 1e-6
        np.testing.assert_allclose(wts.sum(axis=-1), 1.0, atol=1e-4)
    if (ow, oh) != (w, h):
        return  # resized: finiteness and ranges above; resize linearity is tested in test_physics
    names = p["illuminants"].split(",")
    intens = [float(v) for v in p["intensities"].split(",")] if "intensities" in p else [1.0, 1.0]
    grp, spds, sw = _independent(state, scene, view, names, intens, p["sensor"], (x, y, w, h))
    total = np.clip(grp[..., 1], 0, None).sum(axis=0)
    rel = 2.0**-11 + 2e-5  # store float16 bound + float32 accumulation
    if "raw" in arrays and "exposure" not in p:
        ref = grp.sum(axis=0)
        event("raw checked against float64")
        worst = np.max(np.abs(arrays["raw"] - ref) / np.maximum(np.abs(ref), 1e-300))
        assert np.all(np.abs(arrays["raw"] - ref) <= rel * np.abs(ref) + 1e-30), \
            f"raw differs from the float64 composition: max rel {worst:.3g}"
    if "mask" in arrays:
        assert not arrays["mask"][total == 0].any(), "a pixel without light is marked valid"
        if total.max() > 0:
            assert arrays["mask"][total >= 1e-5 * total.max()].all()
    if "gain" in arrays and total.max() > 0:
        sure = total >= 1e-5 * total.max()
        omega = np.clip(grp[..., 1], 0, None)[:, sure] / total[sure]
        lit = np.array(intens) > 0
        wp = np.ones((2, 3))
        wp[lit] = (spds[lit] @ sw) / (spds[lit] @ sw)[:, 1:2]
        white = omega.T @ wp
        gain = white.max(axis=-1, keepdims=True) / white
        np.testing.assert_allclose(arrays["gain"][sure], gain, rtol=4e-3)
        event("gain checked against float64")
