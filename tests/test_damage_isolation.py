"""One damaged view never takes down the rest (issue 36): a half-truncated view document or a flipped
chunk byte makes that view's samples a 503 naming the damage, `/scenes` lists it as damaged beside
the healthy views, and everything else is served as before."""

from __future__ import annotations

import pytest
from server_testutil import synthetic_service_fixtures

store_path, client = synthetic_service_fixtures("damage")


def _truncate(path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def _flip(path, n: int = 16) -> None:
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    for i in range(mid, min(mid + n, len(data))):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.fixture
def damage(store_path):
    """Damage files for one test, and restore them after it."""
    saved = {}

    def apply(rel: str, how) -> None:
        p = store_path / rel
        saved[p] = p.read_bytes()
        how(p)

    yield apply
    for p, data in saved.items():
        p.write_bytes(data)


def _views(client) -> dict:
    r = client.get("/scenes")
    assert r.status_code == 200, r.text
    return {f"{s['name']}/{v['name']}": v for s in r.json()["scenes"] for v in s["views"]}


def test_a_half_truncated_view_document_is_listed_as_damaged_and_the_rest_served(client, damage):
    damage("scenes/synth/solo/zarr.json", _truncate)
    views = _views(client)
    assert views["synth/solo"]["damaged"] and "zarr.json" in views["synth/solo"]["damaged"]
    assert views["synth/v0"]["damaged"] is None and views["synth/v0"]["width"] > 0
    assert client.get("/sample", params={"scene": "synth", "view": "v0", "illuminants": "D65,A",
                                         "outputs": "raw"}).status_code == 200
    r = client.get("/sample", params={"scene": "synth", "view": "solo", "illuminants": "D65", "outputs": "raw"})
    assert r.status_code in (404, 503) and "\n" not in r.json()["detail"]
    for seed in range(6):  # a random view is drawn among the healthy ones
        assert client.get("/sample", params={"seed": seed, "illuminants": "D65", "outputs": "raw"}).status_code \
            in (200, 422)  # 422: a two-group lighting drawn for a one-group view is the caller's choice


def test_a_flipped_chunk_byte_is_a_503_for_that_cube_only(client, damage):
    damage("scenes/synth/solo/cubes/lamp/data/c/0/0/0", _flip)
    r = client.get("/sample", params={"scene": "synth", "view": "solo", "illuminants": "D65", "outputs": "raw",
                                      "seed": 91})
    assert r.status_code == 503 and "CRC-32C" in r.json()["detail"] and "synth/solo/lamp" in r.json()["detail"]
    assert client.get("/sample", params={"scene": "synth", "view": "v0", "illuminants": "D65,A",
                                         "outputs": "raw"}).status_code == 200


def test_an_altered_cube_document_is_listed_as_damaged(client, damage):
    def alter(p):
        p.write_text(p.read_text().replace('"emission_name":"flat"', '"emission_name":"flux"', 1))

    damage("scenes/synth/v0/cubes/lamp/zarr.json", alter)
    views = _views(client)
    assert "fails its checksum" in views["synth/v0"]["damaged"]
    assert views["synth/solo"]["damaged"] is None
