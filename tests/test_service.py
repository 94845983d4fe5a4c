"""Service tests: every endpoint and error path through FastAPI's TestClient, plus a real uvicorn
server on 127.0.0.1 for restart persistence and concurrency."""

from __future__ import annotations

import io
import json
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

pytest.importorskip("store")
from fastapi.testclient import TestClient  # noqa: E402

import synthetic_store as synth  # noqa: E402
from server_testutil import ThreadServer, synthetic_service_fixtures  # noqa: E402
from illumix.retarget.groundtruth import gain_map, illuminant_weights, mixed_white_point, white_point  # noqa: E402
from illumix.retarget.illuminants import illuminant_spd  # noqa: E402
from illumix.retarget.sensors import get_sensor  # noqa: E402
from illumix.service.app import create_app  # noqa: E402
from illumix.store import CubeStore  # noqa: E402

TOKEN = "s3cret"
SENSOR_CSV = "wavelength,r,g,b\n" + "\n".join(
    f"{wl},{np.exp(-((wl - 600) / 40) ** 2):.6f},{np.exp(-((wl - 540) / 40) ** 2):.6f},"
    f"{np.exp(-((wl - 460) / 30) ** 2):.6f}" for wl in range(380, 785, 5))


store_path, client = synthetic_service_fixtures("svc", TOKEN)


def load(resp) -> dict:
    assert resp.status_code == 200, resp.text
    z = np.load(io.BytesIO(resp.content))
    return {k: z[k] for k in z.files}


def test_health_and_scenes(client):
    assert client.get("/health").json()["status"] == "ok"
    scenes = {s["name"]: s for s in client.get("/scenes").json()["scenes"]}
    assert set(scenes) == {"synth", "thesis"}
    v0 = next(v for v in scenes["synth"]["views"] if v["name"] == "v0")
    assert (v0["width"], v0["height"]) == (synth.W, synth.H)
    assert [g["name"] for g in v0["groups"]] == ["window", "lamp"]
    assert client.get("/docs").status_code == 200


def test_sample_all_outputs_shapes_and_finiteness(client):
    base = {"scene": "synth", "view": "v0", "sensor": "XYZ", "pair": "A,D65"}
    default = load(client.get("/sample", params=base))
    assert {"raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture", "meta"} <= set(default)
    z = load(client.get("/sample", params=base | {"outputs": "raw,gain,ccm,srgb,weights,mask,meta"}))
    h, w = synth.H, synth.W
    assert z["raw"].shape == (h, w, 3) and z["gain"].shape == (h, w, 3)
    assert z["ccm"].shape == (h, w, 3, 3) and z["srgb"].shape == (h, w, 3)
    assert z["weights"].shape == (h, w, 2) and z["mask"].shape == (h, w)
    for k in ("raw", "gain", "ccm", "srgb", "weights"):
        assert np.all(np.isfinite(z[k])), k
    assert not z["mask"][-synth.DARK_ROWS:].any() and z["mask"][:-synth.DARK_ROWS].all()
    meta = json.loads(str(z["meta"]))
    assert meta["scene"] == "synth" and meta["groups"] == ["window", "lamp"]
    assert [i["illuminant"] for i in meta["illuminants"]] == ["A", "D65"]
    assert {"setup", "read", "compose"} <= set(meta["timings_ms"])


def test_gain_map_equals_core_library(client, store_path):
    """The service's gain map vs the core functions on the analytic cubes (no store, no service)."""
    # The store may keep cubes as float16 (its dtype policy): every stored value then carries a
    # relative error <= u (the bound it records). Raw is a positive-weighted band sum, so its
    # relative error is <= u too; weights are ratios of such sums (<= 2u), and the gain map is a
    # ratio of weight-mixed white points (<= 4u).
    meta = CubeStore.open(str(store_path), mode="r").cube_meta("synth", "v0", "window")
    u = max(meta.storage.rel_error_bound, 1e-6)
    z = load(client.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "XYZ",
                                           "pair": "FL11,D65", "intensities": "1,0.5",
                                           "outputs": "gain,weights,raw"}))
    sensor = get_sensor("XYZ")
    refl = synth.reflectance_image()
    fw, fl = synth.falloffs()
    spds = [illuminant_spd("FL11"), illuminant_spd("D65")]
    group_raw = np.stack([(refl * (a * f / np.pi)[..., None] * spd) @ sensor.weights()
                          for a, f, spd in zip((1.0, 0.5), (fw, fl), spds)])
    wps = np.stack([white_point(sensor.weights(), s) for s in spds])
    weights, mask = illuminant_weights(group_raw[..., 1])
    expected = gain_map(mixed_white_point(weights, wps))
    np.testing.assert_allclose(z["raw"], group_raw.sum(0), rtol=u + 1e-6, atol=1e-7)
    np.testing.assert_allclose(z["gain"], expected, rtol=4 * u + 1e-6)
    # Gray surfaces become neutral after the GT gains (independent of the formulae above).
    gray = (z["raw"] * z["gain"])[:-synth.DARK_ROWS, 40:]
    np.testing.assert_allclose(gray / gray[..., 1:2], 1.0, rtol=1e-4)


def test_crop_and_size(client):
    full = load(client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                              "outputs": "raw,gain"}))
    crop = load(client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                              "crop": "8,4,32,24", "outputs": "raw,gain"}))
    np.testing.assert_allclose(crop["raw"], full["raw"][4:28, 8:40], rtol=1e-6)
    np.testing.assert_allclose(crop["gain"], full["gain"][4:28, 8:40], rtol=1e-6)
    small = load(client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                               "size": "32x24", "outputs": "raw"}))
    assert small["raw"].shape == (24, 32, 3)
    # Area resampling by 2 is the mean of 2×2 blocks (linear, so raw stays consistent with GT).
    blocks = full["raw"].reshape(24, 2, 32, 2, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(small["raw"], blocks, rtol=1e-5)


def test_random_view_reproducible_with_seed(client):
    a = load(client.get("/sample", params={"scene": "synth", "seed": 7, "outputs": "raw,meta"}))
    b = load(client.get("/sample", params={"scene": "synth", "seed": 7, "outputs": "raw,meta"}))
    assert json.loads(str(a["meta"]))["view"] == json.loads(str(b["meta"]))["view"]
    np.testing.assert_array_equal(a["raw"], b["raw"])


def test_png_and_tiff(client):
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                      "outputs": "srgb", "format": "png"})
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content[:8] == b"\x89PNG\r\n\x1a\n"
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                      "outputs": "gain", "format": "png"})
    import cv2

    img = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_UNCHANGED)
    assert img.dtype == np.uint16 and img.shape == (synth.H, synth.W, 3)
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                      "outputs": "raw", "format": "tiff"})
    import tifffile

    assert tifffile.imread(io.BytesIO(r.content)).dtype == np.float32
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65", "format": "png"})
    assert r.status_code == 422 and "exactly one image output" in r.json()["detail"]


def test_noise_and_bayer(client):
    z = load(client.get("/sample", params={"scene": "synth", "view": "v0", "pair": "A,D65",
                                           "noise": "phone", "bayer": "RGGB", "seed": 3,
                                           "outputs": "raw,gain,meta"}))
    assert z["raw"].shape == (synth.H, synth.W)
    assert z["raw"].max() <= 4095 and z["raw"].min() >= 0
    assert np.all(z["raw"] == np.round(z["raw"]))
    assert json.loads(str(z["meta"]))["exposure_gain"] > 0


@pytest.mark.parametrize("params, status, needle", [
    ({"scene": "synt"}, 404, "did you mean 'synth'"),
    ({"scene": "synth", "view": "v00"}, 404, "did you mean 'v0'"),
    ({"sensor": "XZY", "scene": "synth", "view": "v0"}, 404, "did you mean 'XYZ'"),
    ({"scene": "synth", "view": "v0", "pair": "A,D56"}, 404, "did you mean"),
    ({"scene": "synth", "view": "solo", "pair": "A,D65"}, 422, "two light groups"),
    ({"scene": "synth", "view": "v0", "pair": "A"}, 422, "exactly two"),
    ({"scene": "synth", "view": "v0", "illuminants": "A"}, 422, "one entry per light group"),
    ({"scene": "synth", "view": "v0", "crop": "0,0,999,10"}, 422, "exceeds"),
    ({"scene": "synth", "view": "v0", "crop": "a,b"}, 422, "crop"),
    ({"scene": "synth", "view": "v0", "size": "99999x2"}, 413, "limits"),
    ({"scene": "synth", "view": "v0", "size": "big"}, 422, "WxH"),
    ({"scene": "synth", "view": "v0", "outputs": "raw,foo"}, 422, "unknown"),
    ({"scene": "synth", "view": "v0", "format": "jpg"}, 422, "format"),
    ({"scene": "synth", "view": "v0", "intensities": "1,x"}, 422, "numbers"),
    ({"scene": "synth", "view": "v0", "intensities": "-1,1"}, 422, "intensities"),
    ({"scene": "synth", "view": "v0", "exposure": "-2"}, 422, "exposure"),
    ({"scene": "synth", "view": "v0", "noise": "loud"}, 422, "preset"),
    ({"scene": "synth", "view": "v0", "bayer": "RGBG"}, 422, "bayer"),
    ({"scene": "synth", "view": "v0", "pair": "A,blackbody:10"}, 422, "outside"),
    ({"scene": "thesis", "view": "v0", "illuminants": "D65"}, 422, "zero emission"),
    ({"scene": "thesis", "view": "v0"}, 404, "unknown illuminant 'cut650'"),
])
def test_bad_requests(client, params, status, needle):
    r = client.get("/sample", params=params)
    assert r.status_code == status, r.text
    assert needle in r.json()["detail"]


def test_relight_allowed_where_emission_covers(client):
    csv = "wavelength,value\n" + "\n".join(f"{wl},{1.0 if wl <= 640 else 0.0}" for wl in range(380, 785, 5))
    r = client.post("/illuminants", data={"name": "cut640"}, files={"file": ("c.csv", csv)},
                    headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 201, r.text
    z = load(client.get("/sample", params={"scene": "thesis", "view": "v0", "illuminants": "cut640",
                                           "outputs": "raw"}))
    assert np.all(np.isfinite(z["raw"]))


def test_batch(client):
    body = {"samples": [{"scene": "synth", "view": "v0", "pair": "A,D65", "outputs": "raw,meta"},
                        {"scene": "synth", "view": "v0", "pair": "D65,A", "crop": [0, 0, 16, 16]}]}
    z = load(client.post("/batch", json=body))
    assert z["0/raw"].shape == (synth.H, synth.W, 3) and z["1/gain"].shape == (16, 16, 3)
    assert json.loads(str(z["0/meta"]))["illuminants"][0]["illuminant"] == "A"
    assert client.post("/batch", json={"samples": []}).status_code == 422
    assert client.post("/batch", json={"samples": [{"scene": "nope"}]}).status_code == 404
    typo = client.post("/batch", json={"samples": [{"scene": "synth", "crops": "0,0,8,8"}]})
    assert typo.status_code == 422 and "crops" in typo.json()["detail"]
    png = client.post("/batch", json={"samples": [{"scene": "synth", "format": "png"}]})
    assert png.status_code == 422


def test_sensor_upload_token_and_delete(client):
    before = set(client.get("/sensors").json()["uploaded"])  # the module's store is shared by other tests
    files = {"file": ("cam.csv", SENSOR_CSV)}
    assert client.post("/sensors", data={"name": "mycam"}, files=files).status_code == 401
    assert client.post("/sensors", data={"name": "mycam"}, files=files,
                       headers={"Authorization": "Bearer wrong"}).status_code == 401
    auth = {"Authorization": f"Bearer {TOKEN}"}
    assert client.post("/sensors", data={"name": "mycam"}, files=files, headers=auth).status_code == 201
    assert client.post("/sensors", data={"name": "mycam"}, files=files, headers=auth).status_code == 409
    assert "mycam" in client.get("/sensors").json()["uploaded"]
    detail = client.get("/sensors/mycam").json()
    assert len(detail["sensitivities"]) == 63
    z = load(client.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "mycam", "pair": "A,D65"}))
    assert np.all(np.isfinite(z["gain"]))
    # Bad uploads leave nothing behind.
    for name, payload in (("../evil", SENSOR_CSV), ("neg", "wavelength,r,g,b\n400,-1,1,1\n700,1,1,1"),
                          ("XYZ", SENSOR_CSV), ("short", "wavelength,r,g,b\n500,1,1,1\n600,1,1,1")):
        r = client.post("/sensors", data={"name": name}, files={"file": ("c.csv", payload)}, headers=auth)
        assert r.status_code in (409, 422), (name, r.text)
    assert set(client.get("/sensors").json()["uploaded"]) == before | {"mycam"}
    big = "x" * (3 * 2**20)
    assert client.post("/sensors", data={"name": "big"}, files={"file": ("b.csv", big)},
                       headers=auth).status_code == 413
    assert client.delete("/sensors/XYZ", headers=auth).status_code == 403
    assert client.delete("/sensors/mycam").status_code == 401
    assert client.delete("/sensors/nope", headers=auth).status_code == 404


def test_empty_token_means_no_token_not_an_empty_password(store_path):
    """An empty token (e.g. ILLUMIX_TOKEN= in an env file) means no token, consistently: writes
    are open, as documented for a service started without one — not a secret equal to ''."""
    app = create_app(CubeStore.open(str(store_path), mode="a"), token="")
    with TestClient(app) as c:
        csv = "wavelength,value\n380,1\n780,1\n"
        r = c.post("/illuminants", data={"name": "flatE"}, files={"file": ("e.csv", csv)})
        assert r.status_code == 201, r.text


def test_real_server_restart_keeps_uploads_and_parallel_equals_sequential(store_path):
    import httpx

    auth = {"Authorization": f"Bearer {TOKEN}"}
    with ThreadServer(create_app(CubeStore.open(str(store_path), mode="a"), token=TOKEN)) as url:
        r = httpx.post(f"{url}/sensors", data={"name": "persist"}, files={"file": ("p.csv", SENSOR_CSV)},
                       headers=auth, timeout=30)
        assert r.status_code == 201, r.text
    with ThreadServer(create_app(CubeStore.open(str(store_path), mode="a"), token=TOKEN)) as url:
        assert "persist" in httpx.get(f"{url}/sensors", timeout=30).json()["uploaded"]
        params = [{"scene": "synth", "view": "v0", "sensor": "persist" if i % 2 else "XYZ",
                   "pair": ("A,D65", "FL2,LED-B1", "D50,HP1", "blackbody:3000,daylight:6000")[i % 4],
                   "seed": i, "crop": f"{i},{i},32,32"} for i in range(16)]
        with httpx.Client(timeout=60) as c:
            sequential = [c.get(f"{url}/sample", params=p).content for p in params]
            with ThreadPoolExecutor(16) as pool:
                parallel = list(pool.map(lambda p: c.get(f"{url}/sample", params=p).content, params))
        assert all(len(s) > 1000 for s in sequential)
        # Bytes differ only in the meta's timings: compare arrays and meta minus timings.
        for s, p in zip(sequential, parallel):
            zs, zp = np.load(io.BytesIO(s)), np.load(io.BytesIO(p))
            for k in zs.files:
                if k == "meta":
                    ms, mp = json.loads(str(zs[k])), json.loads(str(zp[k]))
                    ms.pop("timings_ms"), mp.pop("timings_ms")
                    assert ms == mp
                else:
                    np.testing.assert_array_equal(zs[k], zp[k])


def test_group_recorded_empty_composes_as_no_light(tmp_path):
    """A light group the renderer recorded as empty for a view (dark: ``CubeStore.mark_empty``) is
    served like a group that is lit nowhere: 200, finite outputs, raw equals the lit group's alone,
    and the gain map is that group's white-point gain everywhere it lights (the core library's)."""
    from illumix.store import CubeMeta, ViewMeta
    from illumix.retarget.grid import DEFAULT_GRID

    path = tmp_path / "store"
    synth.build(path, extras=False)
    st = CubeStore.open(str(path), mode="a")
    refl = synth.reflectance_image()
    fw, _ = synth.falloffs()
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"}, spp=0, seed=0,
                  scene_hash="synthetic", emission=[1.0] * DEFAULT_GRID.n_bands, emission_name="flat")
    st.write_view("synth", "dark", ViewMeta(width=synth.W, height=synth.H, fov=45.0))
    st.write_cube("synth", "dark", "window", refl * (fw / np.float32(np.pi))[..., None], CubeMeta(**common))
    st.mark_empty("synth", "dark", "lamp", CubeMeta(**common))
    app = create_app(CubeStore.open(str(path), mode="r"), token=TOKEN, cache_mb=16)
    with TestClient(app) as c:
        z = load(c.get("/sample", params={"scene": "synth", "view": "dark", "sensor": "XYZ", "pair": "A,D65",
                                          "outputs": "raw,gain,weights,mask,srgb"}))
    for k in ("raw", "gain", "weights", "srgb"):
        assert np.all(np.isfinite(z[k])), k
    sensor = get_sensor("XYZ")
    lit = (refl * (fw / np.pi)[..., None] * illuminant_spd("A")) @ sensor.weights()
    u = max(st.cube_meta("synth", "dark", "window").storage.rel_error_bound, 1e-6)
    np.testing.assert_allclose(z["raw"], lit, rtol=u + 1e-6, atol=1e-7)
    m = z["mask"]
    assert m[:-synth.DARK_ROWS].all() and not m[-synth.DARK_ROWS:].any()
    np.testing.assert_allclose(z["weights"][m], [[1.0, 0.0]] * int(m.sum()), atol=1e-6)
    wp = white_point(sensor.weights(), illuminant_spd("A"))
    expected = gain_map(wp[None, None, :] * np.ones((synth.H, synth.W, 1)))
    np.testing.assert_allclose(z["gain"][m], expected[m], rtol=4 * u + 1e-6)
