"""The OpenAPI description tells the truth (issue 36, item 7).

- Every example in ``app.openapi()`` is accepted: each route's parameter examples, combined as a
  client (or schemathesis) would send them, and its body examples — the model's own and the one
  its properties' examples compose — are sent to the app and answered 2xx.
- The upload ``name`` fields declare the rule the server applies: the schema (checked with a JSON
  Schema validator, as a client would) accepts a name exactly when the server's name checks do.
"""

from __future__ import annotations

import json
from itertools import product

import pytest

pytest.importorskip("fastapi")
from fastapi.testclient import TestClient  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import synthetic_store as synth  # noqa: E402
from conftest import SHARED_DATA  # noqa: E402
from illumix.engine.library import check_upload_name  # noqa: E402
from illumix.retarget import illuminants as ill  # noqa: E402
from illumix.retarget import sensors as sen  # noqa: E402
from illumix.service import models  # noqa: E402
from illumix.service.app import create_app  # noqa: E402
from illumix.store import CubeStore  # noqa: E402

jsonschema_rs = pytest.importorskip("jsonschema_rs", reason="schemathesis brings jsonschema_rs")

TOKEN = "truth-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
#: the routes whose examples the issue found refused, and the uploads: each must have examples
MUST_HAVE_EXAMPLES = {("get", "/sample"), ("post", "/batch"), ("get", "/explore/frame"), ("post", "/sensors"),
                      ("post", "/illuminants")}


CAMERAS = SHARED_DATA / "rawtoaces-data/data/camera"  # POST /sensors/estimate learns its prior from them


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        if CAMERAS.is_dir():
            mp.setenv("ILLUMIX_SENSOR_PATH", str(CAMERAS))
        yield from _client(tmp_path_factory)


def _client(tmp_path_factory):
    path = tmp_path_factory.mktemp("truth") / "store"
    # extras=False: the synthetic "thesis" view's emission is named after no illuminant (cut650), so
    # no request without illuminants= can light it — a quirk of the fixture, not of rendered stores
    synth.build(path, h=24, w=32, extras=False)
    with TestClient(create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=16)) as c:
        yield c


@pytest.fixture(scope="module")
def doc(client):
    return client.app.openapi()


def _resolve(doc: dict, schema: dict) -> dict:
    while isinstance(schema, dict) and "$ref" in schema:
        schema = doc["components"]["schemas"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _examples(obj: dict) -> list:
    """The values an OpenAPI object or schema gives as examples (``example``, ``examples`` list or map)."""
    out = [obj["example"]] if "example" in obj else []
    ex = obj.get("examples")
    if isinstance(ex, list):
        out += ex
    elif isinstance(ex, dict):
        out += [e["value"] for e in ex.values() if isinstance(e, dict) and "value" in e]
    return out


def _composed(doc: dict, schema: dict):
    """The value a schema's own or its properties' examples compose (``None``: none)."""
    schema = _resolve(doc, schema)
    if own := _examples(schema):
        return own[0]
    if schema.get("type") == "array" and "items" in schema:
        item = _composed(doc, schema["items"])
        return None if item is None else [item]
    props = {k: _composed(doc, v) for k, v in schema.get("properties", {}).items()}
    props = {k: v for k, v in props.items() if v is not None}
    return props or None


def example_requests(doc: dict) -> list[tuple[str, str, dict]]:
    """``(method, path, request kwargs)`` for every example in the document."""
    requests = []
    for path, ops in doc["paths"].items():
        for method, op in ops.items():
            per_param = {p["name"]: (p["in"], _examples(p) + _examples(p.get("schema", {})))
                         for p in op.get("parameters", [])}
            per_param = {k: v for k, v in per_param.items() if v[1]}
            if any(where == "path" for where, _ in per_param.values()) or "{" in path:
                continue  # no route with a path parameter carries examples (a name would be store-specific)
            n = max((len(v) for _, v in per_param.values()), default=0)
            for i in range(n):  # the i-th example of every parameter, together: one request
                query = {k: v[i % len(v)] for k, (where, v) in per_param.items() if where == "query"}
                requests.append((method, path, {"params": query}))
            for media, content in op.get("requestBody", {}).get("content", {}).items():
                schema = content.get("schema", {})
                bodies = _examples(content) + _examples(_resolve(doc, schema))
                if (whole := _composed(doc, {"properties": _resolve(doc, schema).get("properties", {})})) is not None:
                    bodies.append(whole)
                requests += [(method, path, _body_kwargs(media, body)) for body in bodies]
    return requests


def _body_kwargs(media: str, body) -> dict:
    if media == "application/json":
        return {"json": body}
    assert media == "multipart/form-data", media
    files = {k: (f"example-{k}.csv", v) for k, v in body.items() if k == "file"}
    return {"data": {k: v for k, v in body.items() if k != "file"}, "files": files}


def test_every_example_in_the_schema_is_accepted(client, doc):
    requests = example_requests(doc)
    assert MUST_HAVE_EXAMPLES <= {(m, p) for m, p, _ in requests}, "a route lost its examples"
    for method, path, kwargs in requests:
        if method != "get":  # uploads: a fresh store entry each time, whatever ran before
            for entry in ("sensors", "illuminants"):
                client.delete(f"/{entry}/{kwargs.get('data', {}).get('name', '-')}", headers=AUTH)
        if path == "/sensors/estimate" and not CAMERAS.is_dir():
            continue  # the service needs measured cameras for a prior (its description says so)
        r = client.request(method.upper(), path, headers=AUTH, **kwargs)
        assert 200 <= r.status_code < 300, (method, path, json.dumps(kwargs, default=str)[:300], r.text[:300])


def test_examples_of_the_issue_are_combined_into_valid_requests(doc):
    """The combinations the issue found refused: pair= with illuminants=, outputs on /explore/frame."""
    for path in ("/sample", "/explore/frame"):
        named = {p["name"] for p in doc["paths"][path]["get"]["parameters"] if _examples(p.get("schema", {}))}
        assert not {"pair", "illuminants"} <= named, path
        assert {"crop", "size", "seed"} <= named, path
    frame = {p["name"]: p["schema"] for p in doc["paths"]["/explore/frame"]["get"]["parameters"]}
    for fixed in ("outputs", "format", "dtype", "bayer", "noise"):
        assert frame[fixed].get("not") == {} and "default" not in frame[fixed], fixed  # no value is acceptable


# -- upload names --------------------------------------------------------------------------------------
def _name_schema(doc: dict, path: str) -> dict:
    body = doc["paths"][path]["post"]["requestBody"]["content"]["multipart/form-data"]["schema"]
    return _resolve(doc, body)["properties"]["name"]


def _server_accepts(kind: str, name: str) -> bool:
    """The name checks the upload routes apply (the form field's, then the handler's)."""
    try:
        models._store_name(kind)(name)
        check_upload_name(f"{kind}s", name, sen.builtin_names() if kind == "sensor" else ill.builtin_names())
    except ValueError:
        return False
    return not (kind == "sensor" and name.lower() == "estimate")


NAMES = st.one_of(st.text(st.sampled_from("aZ09_.+-/ :é\n"), max_size=12),
                  st.sampled_from(["zarr.json", "ZARR.JSON", "x.partial", "x.PARTIAL", "estimate", "Estimate",
                                   "XYZ", "D65", "FL3.1", "LED-B1", "a" * 128, "a" * 129, "a.", "a..b", ".a",
                                   "x.partial.y", "partial", "1"]))


@pytest.mark.parametrize("path, kind", [("/sensors", "sensor"), ("/illuminants", "illuminant"),
                                        ("/sensors/estimate", "sensor")])
def test_upload_name_schema_is_the_servers_rule(doc, path, kind):
    schema = _name_schema(doc, path)
    assert schema["minLength"] == 1 and schema["maxLength"] == 128, schema
    valid = jsonschema_rs.validator_for(schema).is_valid

    @given(NAMES)
    @settings(max_examples=300, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def agree(name):
        assert valid(name) == _server_accepts(kind, name), name

    agree()


@pytest.mark.parametrize("kind, name, accepted", [
    *product(["sensors", "illuminants"], ["", "a..b", "zarr.json", "x.partial", "a b", "../x"], [False]),
    ("sensors", "XYZ", False), ("sensors", "ESTIMATE", False), ("illuminants", "D65", False),
    ("sensors", "Cam_1.0+b-", True), ("illuminants", "lamp.v2", True)])
def test_upload_names_over_http_match_the_schema(client, doc, kind, name, accepted):
    valid = jsonschema_rs.validator_for(_name_schema(doc, f"/{kind}")).is_valid
    csv = models.SENSOR_CSV_EXAMPLE if kind == "sensors" else models.ILLUMINANT_CSV_EXAMPLE
    r = client.post(f"/{kind}", data={"name": name, "overwrite": "true"}, files={"file": ("f.csv", csv)},
                    headers=AUTH)
    assert valid(name) == accepted and (r.status_code == 201) == accepted, (name, r.status_code, r.text)
    if not accepted:
        body = r.json()
        assert r.status_code == 422 and "\n" not in body["detail"] and "name" in body["detail"], body


# -- sample parameters: the declared patterns are the validators' rule ---------------------------------
PARAM_TEXT = {
    "size": st.one_of(st.from_regex(r"\A ?[0-9]{1,7} ?[xX] ?[0-9]{1,7} ?\Z"), st.text("0123x ", max_size=8)),
    "crop": st.one_of(st.from_regex(r"\A([0-9]{1,3}, ?){3}[0-9]{1,3}\Z"), st.text("0123, ", max_size=10)),
    "outputs": st.one_of(st.lists(st.sampled_from(["raw", "gain", "meta", "Raw", "x", "", " depth "]), max_size=4)
                         .map(",".join), st.text("rawgin, ", max_size=8)),
    "pair": st.one_of(st.lists(st.sampled_from(["A", "D65", " FL2 ", "", "x y"]), max_size=4).map(",".join),
                      st.text("AD, ", max_size=6)),
    "illuminants": st.one_of(st.lists(st.sampled_from(["A", " D65", "", "x y"]), max_size=3).map(",".join),
                             st.text("A, ", max_size=5)),
    "intensities": st.one_of(st.lists(st.sampled_from(["1", "0.5", ".5", "5.", "1e3", "-0", "+2", "", " 3 ", "x"]),
                                      max_size=3).map(",".join), st.text("01.e, ", max_size=6)),
    "exposure": st.one_of(st.sampled_from(["auto", "AUTO", " adaptive ", "Constant", "0", "0.0", "0e3", ".5", "1e3",
                                           "00.001", "autox", "5.", "1e12"]),
                          st.from_regex(r"\A[0-9.eE+-]{1,6}\Z")),
}


#: the counts the composition checks (pair: two; one per light group for the others, so at least one)
COUNTS = {"pair": lambda n: n == 2, "illuminants": lambda n: n >= 1, "intensities": lambda n: n >= 1}


def _spec_accepts(name: str, value: str) -> bool:
    from pydantic import ValidationError

    from illumix.engine.spec import SampleSpec

    try:
        spec = SampleSpec.model_validate({name: value})
    except ValidationError:
        return False
    return COUNTS.get(name, lambda n: True)(len(getattr(spec, name)))


RANGES = {"exposure": lambda v: float(v) >= 1e12,
          "intensities": lambda v: any(not 0 <= float(x) <= 1e9 for x in v.split(",") if x.strip())}


@pytest.mark.parametrize("name", sorted(PARAM_TEXT))
def test_sample_parameter_patterns_are_the_validators_rule(doc, name):
    """ASCII text (spaces, not other whitespace: Python's and ECMA-262's differ on \\x1c-\\x1f): the schema
    (a client's JSON Schema validator) accepts exactly what /sample's validators do — but the ranges of
    exposure (below 1e12) and intensities (0..1e9), stated in words and left to the validators."""
    param = next(p for p in doc["paths"]["/sample"]["get"]["parameters"] if p["name"] == name)
    valid = jsonschema_rs.validator_for(param["schema"]).is_valid

    @given(PARAM_TEXT[name])
    @settings(max_examples=300, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def agree(value):
        if valid(value) and not _spec_accepts(name, value) and name in RANGES:  # the range is in words
            assert RANGES[name](value), value
            return
        assert valid(value) == _spec_accepts(name, value), value

    agree()


@pytest.mark.parametrize("query", ["pair=", "pair=A", "pair=A,B,C", "illuminants=", "illuminants=%20,",
                                   "intensities=,"])
def test_item_counts_the_patterns_state_are_enforced(client, query):
    r = client.get(f"/sample?scene=synth&view=v0&{query}")
    assert r.status_code == 422 and "\n" not in r.json()["detail"], r.text
