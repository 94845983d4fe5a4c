"""Issue 38, ``GET /explore/pixel``: the spectra at one pixel of an explorer frame (API, no browser).

Checked against the synthetic store's closed form (tests/synthetic_store.py: the transport cube of
group g is ``R(x, λ) · f_g(x) / π`` with flat unit emission, its illumination cube ``f_g(x) / π``),
so per group ``radiance = a_g Φ_g(λ) R f_g / π``, ``illumination = a_g Φ_g f_g / π`` and the
reflectance is ``R`` itself; the groups' raw sums to what ``/explore/frame`` composes at that pixel;
only the pixel's chunk is read; bad x/y get a one-line 422.
"""

from __future__ import annotations

import numpy as np
import pytest
import synthetic_store as synth
from fastapi.testclient import TestClient
from test_explore import decode

from illumix.retarget.grid import DEFAULT_GRID

H, W = 60, 80
Q = {"scene": "synth", "view": "v0", "sensor": "XYZ", "illuminants": "A,D65", "intensities": "1,0.5"}


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("pixel") / "store"
    synth.build(path, h=H, w=W, extras=False, illumination=True)
    return path


def _client(path) -> TestClient:
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    return TestClient(create_app(CubeStore.open(str(path), mode="a"), cache_mb=64))


@pytest.fixture(scope="module")
def client(store_path):
    with _client(store_path) as c:
        yield c


def _spd(name: str) -> np.ndarray:
    """The illuminant as the service relights with it (the library's band-averaged, normalised SPD)."""
    from illumix.engine.library import Library

    spd, _ = Library(None).illuminant(name, DEFAULT_GRID)
    return np.asarray(spd, np.float64)


def test_spectra_follow_the_closed_form(client):
    x, y = 5, 7  # a ColorChecker patch (left half), both groups lit
    r = client.get("/explore/pixel", params={**Q, "x": x, "y": y})
    assert r.status_code == 200, r.text
    body = r.json()
    refl = synth.reflectance_image(H, W)[y, x].astype(np.float64)
    falloff = [f[y, x] for f in synth.falloffs(H, W)]
    assert len(body["wavelengths"]) == 63 and body["footprint"] == [x, y, 1, 1] and body["area_weighted"]
    assert [g["group"] for g in body["groups"]] == ["window", "lamp"]
    for g, name, a, f in zip(body["groups"], ("A", "D65"), (1.0, 0.5), falloff):
        assert g["illuminant"] == name and g["intensity"] == a
        np.testing.assert_allclose(g["radiance"], a * _spd(name) * refl * f / np.pi, rtol=2e-3, atol=1e-7)
        np.testing.assert_allclose(g["illumination"], a * _spd(name) * f / np.pi, rtol=2e-3, atol=1e-7)
    np.testing.assert_allclose(body["total"]["reflectance"], refl, rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(body["total"]["radiance"], np.sum([g["radiance"] for g in body["groups"]], 0), rtol=1e-5)
    assert body["valid"] is True and body["sensor"] == "XYZ"


def test_raw_matches_the_frame_the_page_shows(client):
    """Σ_g raw_rgb is the frame's raw at the pixel — at full size and at half size (a 2×2 footprint)."""
    for size, (x, y) in ((None, (30, 20)), ("40x30", (12, 9))):
        q = {**Q, **({"size": size} if size else {})}
        frame = client.get("/explore/frame", params=q)
        assert frame.status_code == 200, frame.text
        arrays, _ = decode(frame.content)
        body = client.get("/explore/pixel", params={**q, "x": x, "y": y}).json()
        np.testing.assert_allclose(body["total"]["raw_rgb"], arrays["raw"][y, x], rtol=2e-3)
        np.testing.assert_allclose(np.sum([g["raw_rgb"] for g in body["groups"]], 0), body["total"]["raw_rgb"], rtol=1e-5)
        if size:
            assert body["footprint"] == [2 * x, 2 * y, 2, 2] and body["area_weighted"]


def test_validity_and_an_unlit_group(client):
    emitter = client.get("/explore/pixel", params={**Q, "x": 0, "y": 0}).json()  # the synthetic emitter's 2×2
    assert emitter["valid"] is False
    off = client.get("/explore/pixel", params={**Q, "intensities": "1,0", "x": 70, "y": 10}).json()
    assert off["groups"][1]["intensity"] == 0 and not any(off["groups"][1]["radiance"])
    dark = client.get("/explore/pixel", params={**Q, "x": 10, "y": H - 1}).json()  # the unlit bottom rows
    assert not any(dark["total"]["radiance"]) and not any(dark["total"]["reflectance"])


@pytest.mark.parametrize("bad, where, words", [
    ({"x": W}, "x", f"x={W} is outside the {W}x{H} frame of synth/v0: give x in 0..{W - 1}"),
    ({"y": H}, "y", f"give y in 0..{H - 1}"),
    ({"x": 20, "y": 15, "size": "20x15"}, "x", "give x in 0..19"),
    ({"x": -1}, "x", "greater than or equal to 0"),
    ({"y": "top"}, "y", "valid integer"),
    ({"exposure": "2"}, "exposure", "do not depend on exposure"),
    ({"noise": "phone"}, "noise", "do not depend on noise"),
])
def test_bad_pixels_are_one_line_422s(client, bad, where, words):
    r = client.get("/explore/pixel", params={**Q, "x": 1, "y": 1, **bad})
    assert r.status_code == 422, r.text
    body = r.json()
    assert words in body["detail"] and "\n" not in body["detail"] and body["loc"][-1] == where, body


def test_missing_pixel_and_unknown_view(client):
    r = client.get("/explore/pixel", params=Q)
    assert r.status_code == 422 and r.json()["loc"][-1] in ("x", "y")
    r = client.get("/explore/pixel", params={**Q, "view": "v1", "x": 0, "y": 0})
    assert r.status_code == 404 and "v0" in r.json()["detail"]  # the close match


def test_only_the_pixels_chunk_is_read(store_path, monkeypatch):
    """A fresh service (nothing cached): the cubes are read with the pixel's crop, never whole."""
    from illumix.store import CubeStore

    crops = []
    real = CubeStore.read_cube

    def spy(self, scene, view, group, crop=None, *a, **k):
        crops.append((group, k.get("kind", "transport"), crop))
        return real(self, scene, view, group, crop, *a, **k)

    monkeypatch.setattr(CubeStore, "read_cube", spy)
    with _client(store_path) as c:
        r = c.get("/explore/pixel", params={**Q, "x": 33, "y": 44})
    assert r.status_code == 200, r.text
    assert sorted(crops) == sorted((g, k, (33, 44, 1, 1)) for g in ("window", "lamp")
                                   for k in ("transport", "illumination")), crops
