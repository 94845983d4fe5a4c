"""The web explorer's endpoints without a browser: ``GET /`` and its static files, ``/explore/frame``
(the single-global-white-point baseline checked against an independent numpy computation) and
``/explore/spectra`` (the Planckian locus checked against Planck's law integrated at 1 nm)."""

from __future__ import annotations

import io
import json
import re

import colour
import numpy as np
import pytest
import synthetic_store as synth
from server_testutil import synthetic_service_fixtures

from illumix.service.arrays_format import MAGIC
from illumix.service.routes.web import STATIC

TOKEN = "explore-token"


store_path, client = synthetic_service_fixtures("explore", TOKEN, illumination=True)


def decode(body: bytes) -> tuple[dict[str, np.ndarray], dict]:
    """The arrays container, read here with numpy alone (the layout in service/arrays_format.py)."""
    assert body[:8] == MAGIC and body[8] == 1
    n = int.from_bytes(body[12:16], "little")
    header = json.loads(body[16:16 + n])
    arrays = {k: np.frombuffer(body, np.dtype(e["dtype"]), int(np.prod(e["shape"])), e["offset"]).reshape(e["shape"])
              for k, e in header["arrays"].items()}
    return arrays, header.get("meta")


def frame(client, **params) -> tuple[dict[str, np.ndarray], dict]:
    r = client.get("/explore/frame", params={"scene": "synth", "view": "v0", **params})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "application/x-illumix-arrays"
    return decode(r.content)


# -- the page --------------------------------------------------------------------------------------
def test_root_answers_the_page_and_its_assets(client):
    r = client.get("/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    page = r.text
    assets = re.findall(r'(?:src|href)="(/web/[^"]+)"', page)
    assert "/web/js/main.js" in assets
    modules = sorted(p.relative_to(STATIC).as_posix() for p in (STATIC / "js").glob("*.js"))
    for path in assets + [f"/web/{m}" for m in modules] + ["/web/vendor/uPlot.esm.js"]:
        a = client.get(path)
        assert a.status_code == 200, path
        if path.endswith(".js"):  # a module script must be served with a JavaScript MIME type
            assert a.headers["content-type"].split(";")[0] in ("text/javascript", "application/javascript"), path
    assert client.get("/web/nothing.js").status_code == 404


def test_the_page_names_no_other_host():
    """Everything the page loads comes from the service: no absolute URL in our files outside
    comments (the vendored library's URLs are all in comments; the browser test records the
    requests themselves)."""
    for path in [STATIC / "index.html", STATIC / "explorer.css", *sorted((STATIC / "js").glob("*.js"))]:
        code = re.sub(r"<!--.*?-->|/\*.*?\*/|^\s*//.*$", "", path.read_text(), flags=re.DOTALL | re.MULTILINE)
        assert not re.search(r"https?://|//[a-z0-9.-]+\.[a-z]{2,}/", code), path
    vendor = (STATIC / "vendor" / "uPlot.esm.js").read_text()
    for line in vendor.splitlines():
        if "http" in line:
            assert line.lstrip().startswith(("//", "*")), line


def test_the_page_modules_stay_small():
    """The page's ES modules keep the project's ~400 lines a module (tests/test_import_flow.py checks the Python)."""
    big = [f"{p.name}: {n} lines" for p in sorted((STATIC / "js").glob("*.js")) if (n := p.read_text().count("\n")) > 410]
    assert not big, "split these:\n" + "\n".join(big)


def test_static_files_ship_with_the_package():
    """A non-editable install carries the page: every static file matches the package data globs."""
    import tomllib
    from fnmatch import fnmatch

    conf = tomllib.loads((STATIC.parents[1] / "pyproject.toml").read_text())
    globs = conf["tool"]["setuptools"]["package-data"]["illumix.service"]
    for f in STATIC.rglob("*"):
        if f.is_file():
            rel = f.relative_to(STATIC.parent).as_posix()
            assert any(fnmatch(rel, g) and rel.count("/") == g.count("/") for g in globs), rel


def test_the_page_offers_every_download_the_service_serves(client):
    """Each download link (``forms.js``) names a format ``GET /sample`` serves — npz, PNG, DNG, EXR —
    and is answered with its media type for the page's parameters (the browser test follows the
    links themselves); nothing is marked "not served" any more."""
    page = (STATIC / "index.html").read_text()
    links = dict(re.findall(r'link\("(dl-[a-z]+)", \{ format: "([a-z]+)"', (STATIC / "js" / "forms.js").read_text()))
    assert links == {"dl-npz": "npz", "dl-exr": "exr", "dl-srgb": "png", "dl-raw": "png", "dl-dng": "dng"}
    assert all(f'id="{k}"' in page for k in links) and "not served" not in page
    page_params = {"scene": "synth", "view": "v0", "sensor": "XYZ", "illuminants": "A,D65", "intensities": "1,1"}
    for fmt, outputs, media in (("dng", "raw", "image/x-adobe-dng"),
                                ("exr", "raw,gain,srgb,weights,mask,illum,mixture,meta", "image/x-exr")):
        r = client.get("/sample", params=page_params | {"format": fmt, "outputs": outputs})
        assert r.status_code == 200 and r.headers["content-type"] == media, r.text
        assert r.headers["content-disposition"].endswith(f'.{fmt}"')


# -- /explore/frame --------------------------------------------------------------------------------
def test_frame_holds_what_the_page_draws(client):
    a, meta = frame(client, illuminants="A,D65")
    h, w = synth.H, synth.W
    assert {k: (v.dtype.str, v.shape) for k, v in a.items()} == {
        "raw": ("<f4", (h, w, 3)), "gain": ("<f4", (h, w, 3)), "illum": ("<f4", (h, w, 3)),
        "mixture": ("<f4", (h, w, 2)), "mask": ("|b1", (h, w)), "srgb": ("|u1", (h, w, 3)),
        "baseline": ("|u1", (h, w, 3))}
    for k in ("raw", "gain", "illum", "mixture"):
        assert np.isfinite(a[k]).all()
    b = meta["baseline"]
    assert set(b) == {"white_point_rgb", "ccm", "exposure", "shares", "definition"}
    assert b["white_point_rgb"][1] == pytest.approx(1.0)
    assert sum(b["shares"].values()) == pytest.approx(1.0)
    assert meta["ground_truth"]["method"] == "physical"


def _independent_baseline(client, illuminants: str, intensities: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """The baseline recomputed from ``/sample``'s npz with numpy and colour-science's sRGB encoding:
    m̄_g = mean mixture over valid pixels, W̄ = Σ m̄_g w_g, gain = max W̄ / W̄, CCM̄ = Σ m̄_g CCM_g."""
    r = client.get("/sample", params={"scene": "synth", "view": "v0", "illuminants": illuminants,
                                      "intensities": intensities, "outputs": "raw,mixture,mask,meta"})
    z = np.load(io.BytesIO(r.content))
    meta = json.loads(str(z["meta"]))
    raw, mix, mask = z["raw"].astype(np.float64), z["mixture"].astype(np.float64), z["mask"]
    shares = mix[mask].mean(axis=0)
    wp = shares @ np.array([g["white_point_rgb"] for g in meta["illuminants"]])
    ccm = np.einsum("g,gij->ij", shares, np.array([g["ccm"] for g in meta["illuminants"]]))
    return raw, (wp, ccm), meta


def test_baseline_is_one_white_point_and_one_ccm(client):
    a, meta = frame(client, illuminants="A,D65")
    raw, (wp, ccm), _ = _independent_baseline(client, "A,D65", "1,1")
    b = meta["baseline"]
    # float32 means of float32 shares against float64: 1e-6 relative
    np.testing.assert_allclose(b["white_point_rgb"], wp / wp[1], rtol=1e-6)
    np.testing.assert_allclose(b["ccm"], ccm, rtol=1e-6, atol=1e-8)
    gain = np.max(wp) / wp
    linear = np.einsum("ij,hwj->hwi", ccm, raw * gain) * b["exposure"]
    expected = colour.cctf_encoding(np.clip(linear, 0, 1), function="sRGB") * 255
    # uint8 rounding of float32 vs float64 values: at most one step apart
    assert np.abs(a["baseline"].astype(float) - expected).max() <= 1.0


def test_one_light_baseline_equals_the_pixel_wise_ground_truth(client):
    """With one group lit, one white point is every pixel's white point: the two renderings agree
    (same white point, CCM and exposure; within one uint8 step for float rounding)."""
    a, meta = frame(client, illuminants="FL11,D65", intensities="1,0")
    assert meta["baseline"]["shares"] == {"window": 1.0, "lamp": 0.0}
    assert np.abs(a["baseline"].astype(int) - a["srgb"].astype(int)).max() <= 1


def test_baseline_shows_the_cast_the_ground_truth_removes(client):
    """On the neutral gray half under A + D65 the ground truth is neutral; one white point leaves the
    A side warm and the D65 side cool."""
    a, _ = frame(client, illuminants="A,D65")
    gray = a["mask"].copy()
    gray[:, : synth.W // 2 + 2] = False

    def cast(img: np.ndarray) -> np.ndarray:  # |R − B| of the gray pixels, uint8 steps
        return np.abs(img[..., 0].astype(int) - img[..., 2].astype(int))[gray]

    assert cast(a["srgb"]).max() <= 3  # measured 0
    assert cast(a["baseline"]).max() >= 20  # measured 80


def test_frame_shares_edge_cases():
    from illumix.retarget.errors import SpectralError
    from illumix.retarget.global_wb import frame_shares

    mix = np.zeros((2, 3, 2), np.float32)
    mix[0] = [1, 0]
    mix[1] = [0.25, 0.75]
    np.testing.assert_allclose(frame_shares(mix, np.array([[True] * 3, [False] * 3])), [1, 0])
    np.testing.assert_allclose(frame_shares(mix, np.zeros((2, 3), bool)), [0.625, 0.375])  # no valid pixel: all
    with pytest.raises(SpectralError, match="no positive share"):
        frame_shares(np.zeros((2, 3, 2), np.float32))


@pytest.mark.parametrize("bad, status, code", [
    ({"outputs": "raw"}, 422, "invalid_parameter"),
    ({"format": "npz"}, 422, "invalid_parameter"),
    ({"bayer": "RGGB"}, 422, "invalid_parameter"),
    ({"noise": "phone"}, 422, "invalid_parameter"),  # the baseline would expose digital numbers as radiance
    ({"illuminants": "A,D56"}, 404, "not_found"),
    ({"sceen": "synth"}, 422, "unknown_parameter"),
])
def test_frame_refusals(client, bad, status, code):
    r = client.get("/explore/frame", params={"scene": "synth", "view": "v0", **bad})
    assert r.status_code == status, r.text
    body = r.json()
    assert body["code"] == code and body["status"] == status and "\n" not in body["detail"]
    if "outputs" in bad:
        assert "drop outputs" in body["detail"]


@pytest.mark.parametrize("path, typo, close, listed, not_listed", [
    ("/explore/spectra", "sensr", "sensor", ["sensor", "illuminants"], ["scene", "bayer", "outputs"]),
    ("/explore/frame", "sceen", "scene", ["scene", "view", "illuminants", "exposure"],
     ["outputs", "format", "dtype", "bayer", "noise"]),  # the ones /explore/frame refuses are not offered
    ("/explore/frame", "output", None, ["scene"], ["outputs"]),
    ("/sample", "sceen", "scene", ["scene", "outputs", "format", "bayer"], ["sensr"]),
])
def test_unknown_parameter_lists_the_routes_own(client, path, typo, close, listed, not_listed):
    body = client.get(path, params={typo: "x"}).json()
    assert body["code"] == "unknown_parameter", body
    detail = body["detail"]
    offered = detail.split("Valid parameters: ")[1].rstrip(".").split(", ")
    assert set(listed) <= set(offered) and not set(not_listed) & set(offered), detail
    assert (f"did you mean {close!r}" in detail) if close else "did you mean" not in detail, detail


# -- /explore/spectra ------------------------------------------------------------------------------
def _planck_white_point_xyz(kelvin: float) -> tuple[float, float]:
    """X/Y and Z/Y of a blackbody over the grid's span [392.5, 707.5] nm, from Planck's law (closed
    form) and the CIE 1931 CMFs at 0.5 nm (midpoint rule): independent of the band integration."""
    wl = np.arange(392.75, 707.5, 0.5)
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    lam = wl * 1e-9
    b = 2 * h * c**2 / lam**5 / np.expm1(h * c / (lam * k * kelvin))
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = np.array([np.interp(wl, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)]) @ b
    return xyz[0] / xyz[1], xyz[2] / xyz[1]


def test_planckian_locus_is_plancks_law_seen_by_the_sensor(client):
    s = client.get("/explore/spectra", params={"sensor": "XYZ"}).json()
    locus = {p["kelvin"]: p for p in s["planckian"]}
    assert len(locus) >= 30 and {2000.0, 3000.0, 6500.0, 10000.0} <= set(locus)
    for kelvin in (1500.0, 2000.0, 3000.0, 5000.0, 6500.0, 10000.0, 20000.0):
        rg, bg = _planck_white_point_xyz(kelvin)
        # products of 5 nm band averages vs the 0.5 nm integral differ at second order in the band
        # width: measured ≤ 1.2e-3 relative (B/G at 1500 K, where it is 0.05 and Planck's law is
        # steepest), ≤ 1.2e-4 in R/G; 2e-3 leaves room without hiding a wrong law or constant
        # (c2 off by 0.1 % moves B/G at 1500 K by ~0.4 %)
        assert locus[kelvin]["r_over_g"] == pytest.approx(rg, rel=2e-3), kelvin
        assert locus[kelvin]["b_over_g"] == pytest.approx(bg, rel=2e-3), kelvin
    assert all(4000 <= p["kelvin"] <= 20000 for p in s["daylight"]) and len(s["daylight"]) > 10


def test_spectra_white_points_are_the_samples(client, shared_data):
    """The chromaticity diagram's white points are the ones the samples are balanced with."""
    cam = shared_data / "rawtoaces-data" / "data" / "camera" / "Nikon_D810_380_780_5.json"
    r = client.post("/sensors", data={"name": "cam-explore", "overwrite": "true"},
                    files={"file": (cam.name, cam.read_bytes())}, headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 201, r.text
    s = client.get("/explore/spectra", params={"sensor": "cam-explore", "illuminants": "A,blackbody:3000"}).json()
    _, meta = frame(client, sensor="cam-explore", illuminants="A,blackbody:3000")
    for curve, group in zip(s["illuminants"], meta["illuminants"]):
        np.testing.assert_allclose(curve["white_point_rgb"], group["white_point_rgb"], rtol=1e-9)
        assert max(curve["spd"]) == pytest.approx(1.0)
    bb3000 = next(p for p in s["planckian"] if p["kelvin"] == 3000)
    assert bb3000["r_over_g"] == pytest.approx(s["illuminants"][1]["r_over_g"], rel=1e-9)
    assert np.array(s["sensitivities"]).shape == (len(s["wavelengths"]), 3)


@pytest.mark.parametrize("params, status, code", [
    ({"sensor": "XZY"}, 404, "not_found"),
    ({"illuminants": "A,D56"}, 404, "not_found"),
    ({"illuminants": ",".join(["A"] * 17)}, 422, "invalid_parameter"),
    ({"sensr": "XYZ"}, 422, "unknown_parameter"),
])
def test_spectra_refusals(client, params, status, code):
    r = client.get("/explore/spectra", params=params)
    assert r.status_code == status and r.json()["code"] == code, r.text
