"""Hardening of the service's input handling (issue 13): each defect found has a regression test here.

Every answer to bad input is a 4xx whose body is the one error shape ``{detail, status, code, loc}``
(``detail`` a sentence that says what to fix); no input may produce a 500 or a non-finite number.
"""

from __future__ import annotations

import errno
import io
import json
import logging

import numpy as np
import pytest
from fastapi.testclient import TestClient

import synthetic_store as synth
from server_testutil import synthetic_service_fixtures
from illumix.service.app import create_app
from illumix.store import CubeStore

TOKEN = "s3cret"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
WL = np.arange(380, 781, 5)
V0 = {"scene": "synth", "view": "v0"}


store_path, client = synthetic_service_fixtures("hard", TOKEN)


def error(r, status: int) -> dict:
    """The error body, checked for the common shape."""
    assert r.status_code == status, (r.status_code, r.text[:400])
    body = r.json()
    assert set(body) == {"detail", "status", "code", "loc"}, body
    assert isinstance(body["detail"], str) and len(body["detail"]) > 10 and "\n" not in body["detail"]
    assert body["status"] == status and isinstance(body["code"], str)
    return body


# -- unknown and malformed parameters --------------------------------------------------------------
def test_unknown_query_parameter_is_422_with_the_close_match(client):
    body = error(client.get("/sample", params=V0 | {"crops": "0,0,4,4"}), 422)
    assert body["code"] == "unknown_parameter" and body["loc"] == ["query", "crops"]
    assert "'crops'" in body["detail"] and "did you mean 'crop'" in body["detail"]


def test_unknown_batch_item_parameter_is_422_with_the_close_match(client):
    body = error(client.post("/batch", json={"samples": [V0 | {"ouputs": "raw"}]}), 422)
    assert body["code"] == "unknown_parameter" and "did you mean 'outputs'" in body["detail"]
    body = error(client.post("/batch", json={"sample": [V0]}), 422)
    assert "did you mean 'samples'" in body["detail"]


@pytest.mark.parametrize("params, needle", [
    ({"seed": "-1"}, "seed"), ({"seed": "1.0"}, "seed"), ({"seed": "true"}, "seed"),  # one shape for both
    ({"pair": "A,D56"}, "did you mean"),                                               # kinds of error
])
def test_one_error_shape_for_validation_and_library_errors(client, params, needle):
    r = client.get("/sample", params=V0 | params)
    body = error(r, 404 if "D56" in str(params) else 422)
    assert needle in body["detail"]


@pytest.mark.parametrize("noise", ["full_well:1e19", "full_well:inf", "full_well:1e308", "read_noise:inf",
                                   "read_noise:nan", "black_level:-inf", "bit_depth:1.5"])
def test_noise_parameters_out_of_range_are_422_not_500(client, noise):
    body = error(client.get("/sample", params=V0 | {"noise": noise, "outputs": "raw,meta"}), 422)
    assert "noise" in body["detail"]


@pytest.mark.parametrize("size", [[0, 0], [-8, 8], [8, 8, 8], "0x0", [8.5, 8], [True, 8]])
def test_batch_sizes_are_validated_like_query_sizes(client, size):
    body = error(client.post("/batch", json={"samples": [V0 | {"size": size, "outputs": "raw"}]}), 422)
    assert "size" in body["detail"] and body["loc"][:2] == ["samples", 0]


def test_batch_items_accept_json_lists_and_query_strings_alike(client):
    a = client.post("/batch", json={"samples": [V0 | {"pair": ["A", "D65"], "crop": [0, 0, 8, 8], "size": [4, 4],
                                                      "outputs": ["raw"], "seed": 3}]})
    b = client.post("/batch", json={"samples": [V0 | {"pair": "A,D65", "crop": "0,0,8,8", "size": "4x4",
                                                      "outputs": "raw", "seed": 3}]})
    assert a.status_code == b.status_code == 200
    za, zb = np.load(io.BytesIO(a.content)), np.load(io.BytesIO(b.content))
    np.testing.assert_array_equal(za["0/raw"], zb["0/raw"])


@pytest.mark.parametrize("params", [{"format": "png", "outputs": "meta"}, {"format": "png", "outputs": "raw,gain"},
                                    {"format": "tiff", "outputs": "ccm"}])
def test_image_formats_need_exactly_one_image_output(client, params):
    assert "exactly one image output" in error(client.get("/sample", params=V0 | params), 422)["detail"]


def test_unexpected_errors_are_500_in_the_common_shape(store_path, monkeypatch):
    import illumix.service.routes.samples as routes

    def boom(*a, **k):
        raise RuntimeError("synthetic bug")

    monkeypatch.setattr(routes, "build", boom)
    with TestClient(create_app(CubeStore.open(str(store_path), mode="r")), raise_server_exceptions=False) as c:
        body = error(c.get("/sample", params=V0 | {"outputs": "raw"}), 500)
        assert body["code"] == "internal" and "RuntimeError" in body["detail"]
        assert c.get("/health").json()["memory"]["inflight_bytes"] == 0  # the reservation came back


def test_405_names_the_allowed_methods(client):
    r = client.put("/sample")
    body = error(r, 405)
    assert r.headers["allow"] == "GET" and "allowed: GET" in body["detail"]
    r = client.put("/sensors")
    assert r.status_code == 405 and r.headers["allow"] == "GET, POST"


def test_unknown_path_is_404_in_the_common_shape(client):
    assert "see /docs" in error(client.get("/smaple"), 404)["detail"]


# -- uploads ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("doc", [
    '{"spectral_data": {"index": "RGB", "data": {"main": {"380": [1, 2, 3]}}}}',
    '{"header": 5, "spectral_data": {"data": {"main": {"380": [1, 2, 3]}}}}',
    "[" * 100_000,
    '{"spectral_data": {"data": {"main": {"380": true}}}}',
    '{"spectral_data": {"data": {"main": {"380": [1, 2, {}]}}}}',
    "{" + '"a":' * 50_000,
])
def test_malformed_sensor_json_is_422_not_500(client, doc):
    r = client.post("/sensors", data={"name": "badjson"}, files={"file": ("s.json", doc)}, headers=AUTH)
    error(r, 422)


@pytest.mark.parametrize("kind", ["sensors", "illuminants"])
def test_csv_with_a_bare_carriage_return_in_a_field_is_422(client, kind):
    r = client.post(f"/{kind}", data={"name": "crfield"}, files={"file": ("x.csv", "380,1\r2\n")}, headers=AUTH)
    error(r, 422)


@pytest.mark.parametrize("value", ["1e-320", "1e308", "5e-324"])
def test_extreme_but_valid_illuminant_scales_work_and_can_be_deleted(client, value):
    name = f"scale{value.replace('-', 'm').replace('.', '')}"
    csv = "\n".join(f"{w},{value}" for w in WL)
    r = client.post("/illuminants", data={"name": name}, files={"file": (f"{name}.csv", csv)}, headers=AUTH)
    assert r.status_code == 201, r.text
    r = client.get("/sample", params=V0 | {"illuminants": f"{name},A", "outputs": "raw,gain,meta"})
    assert r.status_code == 200, r.text
    z = np.load(io.BytesIO(r.content))
    assert np.isfinite(z["raw"]).all() and np.isfinite(z["gain"]).all()
    # a flat SPD at any scale is the equal-energy illuminant: the same sample as E
    e = np.load(io.BytesIO(client.get("/sample", params=V0 | {"illuminants": "E,A", "outputs": "raw"}).content))
    np.testing.assert_allclose(z["raw"], e["raw"], rtol=1e-5)
    assert client.delete(f"/illuminants/{name}", headers=AUTH).json() == {"deleted": name}
    error(client.get("/sample", params=V0 | {"illuminants": f"{name},A"}), 404)
    error(client.delete(f"/illuminants/{name}", headers=AUTH), 404)
    assert error(client.delete("/illuminants/D65", headers=AUTH), 403)["code"] == "forbidden"


@pytest.mark.parametrize("header", ["Bearer café", "Bearer \u00ff\u00fe", "s3cret", "Basic s3cret", "Bearer"])
def test_bad_authorization_headers_are_401_not_500(client, header):
    r = client.post("/sensors", data={"name": "authx"}, files={"file": ("s.csv", "1,1,1,1")},
                    headers={"Authorization": header.encode("latin-1")})
    body = error(r, 401)
    assert "Bearer <token>" in body["detail"] and r.headers["www-authenticate"].startswith("Bearer")


def test_upload_on_a_full_disk_is_507_and_writes_nothing(client, store_path, monkeypatch):
    from illumix.store.backend import Backend

    def full(self, key, data, exclusive=False):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Backend, "write_bytes", full)
    csv = "\n".join(f"{w},1" for w in WL)
    body = error(client.post("/illuminants", data={"name": "nospace"}, files={"file": ("n.csv", csv)},
                             headers=AUTH), 507)
    assert "No space left" in body["detail"] and "nothing was written" in body["detail"]
    monkeypatch.undo()
    assert "nospace" not in client.get("/illuminants").json()["uploaded"]
    assert not list(store_path.glob("_registry/illuminants/nospace*"))


def test_one_upload_limit_for_store_and_service(client):
    from illumix.engine.limits import Limits
    from illumix.store.registry import DEFAULT_MAX_BYTES

    assert Limits().max_upload_bytes == DEFAULT_MAX_BYTES
    big = b"380,1\n" + b"#" * DEFAULT_MAX_BYTES
    assert error(client.post("/illuminants", data={"name": "big"}, files={"file": ("b.csv", big)},
                             headers=AUTH), 413)["code"] == "too_large"


def test_sensor_list_shows_only_usable_builtins_and_says_why_not(client):
    body = client.get("/sensors").json()
    assert "Sigma SDMerill (NPL)" not in body["builtin"] and "XYZ" in body["builtin"]
    assert "400-680 nm" in body["unavailable"]["Sigma SDMerill (NPL)"]
    for name in body["builtin"][:3]:
        assert client.get("/sample", params=V0 | {"sensor": name, "outputs": "raw", "crop": "0,0,4,4"}).status_code == 200


# -- no non-finite number reaches a response -------------------------------------------------------
def test_meta_never_holds_infinity(client):
    error(client.get("/sample", params=V0 | {"noise": "read_noise:inf", "outputs": "raw,meta"}), 422)
    r = client.get("/sample", params=V0 | {"noise": "phone", "outputs": "raw,meta", "exposure": "1e11"})
    meta = json.loads(str(np.load(io.BytesIO(r.content))["meta"]),
                      parse_constant=lambda c: pytest.fail(f"meta holds {c}"))
    assert np.isfinite(meta["exposure_gain"])


def test_empty_token_disables_auth_with_a_warning(store_path, caplog):
    with caplog.at_level(logging.WARNING, logger="illumix.service"):
        app = create_app(CubeStore.open(str(store_path), mode="r"), token="")
    assert any("open to anyone" in r.message for r in caplog.records)
    with TestClient(app) as c:
        assert c.get("/health").json()["auth"] is False


# -- a damaged view is reported, never silently re-shaped ------------------------------------------
def test_corrupt_cube_metadata_makes_the_view_503_not_a_different_view(tmp_path):
    path = tmp_path / "store"
    synth.build(path, extras=False)
    (path / "scenes/synth/v0/cubes/window/zarr.json").write_text("{ not json")
    with TestClient(create_app(CubeStore.open(str(path), mode="r"))) as c:
        body = error(c.get("/sample", params=V0 | {"pair": "A,D65"}), 503)
        assert "damaged" in body["detail"] and "illumix store verify" in body["detail"]
        # the listing marks the view damaged rather than failing as a whole (issue 36)
        views = {v["name"]: v for s in c.get("/scenes").json()["scenes"] for v in s["views"]}
        assert "damaged" in views["v0"]["damaged"] and views["v0"]["groups"] == []


# -- the OpenAPI document says what is accepted and returned ---------------------------------------
def test_openapi_documents_every_answer(client):
    doc = client.get("/openapi.json").json()
    paths = doc["paths"]
    schemas = doc["components"]["schemas"]
    assert set(schemas["ErrorBody"]["properties"]) == {"detail", "status", "code", "loc"}
    assert schemas["ErrorBody"]["properties"]["detail"]["type"] == "string"
    for path, ops in paths.items():
        for method, op in ops.items():
            responses = op["responses"]
            ok = responses[next(c for c in responses if c.startswith("2"))]
            assert ok["content"], (method, path)
            for status, r in responses.items():
                if status.startswith(("4", "5")):
                    ref = r["content"]["application/json"]["schema"]["$ref"]
                    assert ref.endswith("/ErrorBody"), (method, path, status)
            if "application/json" in ok["content"]:  # every JSON endpoint has a response model
                assert "$ref" in ok["content"]["application/json"]["schema"], (method, path)
    sample = paths["/sample"]["get"]
    assert {"404", "413", "422", "503"} <= set(sample["responses"])
    assert {"application/octet-stream", "application/x-illumix-arrays", "image/png",
            "image/tiff"} <= set(sample["responses"]["200"]["content"])
    assert [p["name"] for p in sample["parameters"]] == ["scene", "view", "seed", "sensor", "pair", "illuminants",
                                                         "intensities", "crop", "size", "outputs", "gt", "denoise", "format",
                                                         "dtype", "exposure", "noise", "bayer"]
    batch = paths["/batch"]["post"]
    assert batch["requestBody"]["content"]["application/json"]["schema"]["$ref"].endswith("/BatchRequest")
    assert "application/octet-stream" in batch["responses"]["200"]["content"]
    for path, method, codes in (("/sensors", "post", {"401", "409", "413", "422", "507"}),
                                ("/sensors/{name}", "delete", {"401", "403", "404"}),
                                ("/illuminants/{name}", "delete", {"401", "403", "404"})):
        assert codes <= set(paths[path][method]["responses"]), (path, method)
    assert "Allow" in paths["/sample"]["get"]["responses"]["405"]["headers"]
