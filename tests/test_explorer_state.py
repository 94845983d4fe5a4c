"""Issue 38, the explorer's state (API and headless Chromium, as tests/test_web.py):

- ``GET /illuminants`` lists the built-ins that cannot be used on the grid (the seven ISO 7589 tables
  stop at 690 nm or before) under ``unavailable`` with the reason, not under ``builtin``; the page
  offers them disabled with the reason, and a link naming one is replaced with a notice;
- a failed update (any 4xx/5xx, or no answer) puts the controls, the URL and the downloads back at
  the frame on screen, or marks the images stale when nothing was drawn yet;
- the denoise toggle (``denoise=none`` against the stored copies) and the geometry AOV panel
  (albedo, normal, depth from ``GET /sample``).
"""

from __future__ import annotations

import colour
import httpx
import numpy as np
import pytest
import synthetic_store as synth
from server_testutil import ThreadServer
from test_explore import decode

ISO = sorted(n for n in colour.SDS_ILLUMINANTS if n.startswith("ISO 7589"))
TOKEN = "state-token"


# -- the API -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def url(tmp_path_factory):
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    path = tmp_path_factory.mktemp("state") / "store"
    synth.build(path, h=60, w=80, extras=False, denoised=True)  # denoised implies the illumination cubes and AOVs
    with ThreadServer(create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=64)) as base:
        yield base


def test_illuminants_list_the_unusable_ones_with_the_reason(url):
    body = httpx.get(f"{url}/illuminants").json()
    assert len(ISO) == 7 and sorted(body["unavailable"]) == ISO
    assert all("392.5-707.5 nm" in why and "samples cover" in why for why in body["unavailable"].values())
    assert not set(body["builtin"]) & set(ISO)
    assert set(body["builtin"]) | set(body["unavailable"]) == set(colour.SDS_ILLUMINANTS.keys())
    assert {"A", "D65", "FL11"} <= set(body["builtin"]) and "blackbody" in body["parametric"]
    # the listed ones are usable, the unavailable ones are refused, as the list says
    ok = httpx.get(f"{url}/explore/spectra", params={"sensor": "XYZ", "illuminants": ",".join(body["builtin"][:16])})
    assert ok.status_code == 200, ok.text
    bad = httpx.get(f"{url}/explore/spectra", params={"sensor": "XYZ", "illuminants": ISO[0]})
    assert bad.status_code == 422 and "samples cover" in bad.json()["detail"]


def test_the_illuminant_list_schema_names_unavailable():
    from illumix.service.models import IlluminantList

    schema = IlluminantList.model_json_schema()
    assert "unavailable" in schema["properties"] and "unavailable" not in schema.get("required", [])
    # backwards compatible: an answer without it (an older server) still validates
    assert IlluminantList.model_validate({"builtin": ["A"], "parametric": {}, "uploaded": []}).unavailable == {}


def test_the_frame_takes_denoise_none_and_sample_gives_the_aovs(url):
    q = {"scene": "synth", "view": "v0", "illuminants": "A,D65"}
    stored = httpx.get(f"{url}/explore/frame", params=q)
    raw = httpx.get(f"{url}/explore/frame", params={**q, "denoise": "none"})
    assert stored.status_code == raw.status_code == 200, (stored.text, raw.text)
    (a, ma), (b, mb) = decode(stored.content), decode(raw.content)
    assert ma["denoise"]["method"] != "none" and mb["denoise"]["method"] == "none"
    assert np.abs(a["raw"] - b["raw"]).mean() > 1e-4  # the noisy cubes against their denoised copies
    for name, shape in (("albedo", (60, 80, 3)), ("normal", (60, 80, 3)), ("depth", (60, 80))):
        r = httpx.get(f"{url}/sample", params={"scene": "synth", "view": "v0", "outputs": name, "format": "arrays"})
        assert r.status_code == 200, r.text
        arrays, _ = decode(r.content)
        assert arrays[name].shape == shape


# -- the page ----------------------------------------------------------------------------------------
try:  # the API tests above run without selenium; the page's below are skipped then
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait
    from test_web import (  # noqa: F401
        CHROMIUM,
        DRIVER,
        WAIT_S,
        browser,
        controls,
        open_page,
        pixels,
        ready,
    )
except ImportError:
    CHROMIUM = DRIVER = None

needs_browser = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="no selenium, or no chromium/chromedriver on "
                                   "PATH: `bash scripts/install.sh --test` installs them (as root)")


def text(driver, element_id: str) -> str:
    return driver.execute_script("return document.getElementById(arguments[0]).textContent", element_id)


def failed(driver) -> int:
    return int(driver.execute_script("return document.body.dataset.failed || 0"))


def ill_options(driver) -> list[dict]:
    return driver.execute_script("""return Array.from(document.querySelectorAll('#groups select.ill')[0].options,
        (o) => ({value: o.value, disabled: o.disabled, title: o.title, text: o.text}));""")


@needs_browser
def test_unusable_illuminants_are_offered_disabled_with_the_reason(browser, url):
    open_page(browser, url, "?illuminants=A,D65")
    opts = {o["value"]: o for o in ill_options(browser)}
    for name in ISO:
        assert opts[name]["disabled"] and "samples cover" in opts[name]["title"], opts[name]
        assert "nm only" in opts[name]["text"]
    assert not opts["A"]["disabled"] and not opts["FL11"]["disabled"]
    # a link naming one is replaced, said in the notice, and no 422 is asked for
    browser.get_log("browser")
    open_page(browser, url, f"?illuminants={ISO[0]},D65")
    shown = controls(browser)
    assert shown["ill"][0] == "A" and f"illuminant '{ISO[0][:40]}" in shown["notice"] and "unavailable here" in shown["notice"]
    assert not [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]


@needs_browser
def test_a_failed_update_puts_the_controls_back(browser, url):
    """An illuminant deleted by someone else after the page listed it: the frame answers 404; the
    select, URL and downloads go back to what the images show, the list drops the deleted name."""
    wl = np.arange(380, 781, 5)
    csv = "wavelength,value\n" + "".join(f"{w},{1 + (w - 380) / 400:.4f}\n" for w in wl)
    auth = {"Authorization": f"Bearer {TOKEN}"}
    r = httpx.post(f"{url}/illuminants", data={"name": "gone-lamp"}, files={"file": ("g.csv", csv)}, headers=auth)
    assert r.status_code == 201, r.text
    open_page(browser, url, "?illuminants=A,D65")
    assert "gone-lamp" in [o["value"] for o in ill_options(browser)]
    before, link = pixels(browser, "c-srgb"), browser.current_url
    npz = browser.find_element(By.ID, "dl-npz").get_attribute("href")
    assert httpx.delete(f"{url}/illuminants/gone-lamp", headers=auth).status_code == 200
    n = failed(browser)
    Select(browser.find_elements(By.CSS_SELECTOR, "#groups select.ill")[0]).select_by_value("gone-lamp")
    WebDriverWait(browser, WAIT_S).until(lambda d: failed(d) > n)
    status = browser.find_element(By.ID, "status")
    assert "error" in status.get_attribute("class") and "gone-lamp" in status.text and "back at the frame" in status.text
    assert controls(browser)["ill"] == ["A", "D65"]
    assert browser.current_url == link and browser.find_element(By.ID, "dl-npz").get_attribute("href") == npz
    assert pixels(browser, "c-srgb") == before
    assert "gone-lamp" not in [o["value"] for o in ill_options(browser)]
    assert "stale" not in browser.find_element(By.ID, "views").get_attribute("class")
    # the page still works: the next change draws
    n = ready(browser)
    Select(browser.find_elements(By.CSS_SELECTOR, "#groups select.ill")[0]).select_by_value("FL11")
    WebDriverWait(browser, WAIT_S).until(lambda d: ready(d) > n)
    assert "illuminants=FL11%2CD65" in browser.current_url


@needs_browser
def test_a_first_frame_that_fails_marks_the_images_stale(browser, url):
    browser.execute_cdp_cmd("Network.enable", {})
    browser.execute_cdp_cmd("Network.setBlockedURLs", {"urls": ["*/explore/frame*"]})
    try:
        browser.get(f"{url}/?illuminants=A,D65")
        WebDriverWait(browser, WAIT_S).until(lambda d: failed(d) >= 1)
        assert "stale" in browser.find_element(By.ID, "views").get_attribute("class")
        assert "nothing drawn yet" in browser.find_element(By.ID, "status").text
    finally:
        browser.execute_cdp_cmd("Network.setBlockedURLs", {"urls": []})
    n = ready(browser)
    Select(browser.find_element(By.ID, "gt")).select_by_value("formula")
    WebDriverWait(browser, WAIT_S).until(lambda d: ready(d) > n)
    assert "stale" not in browser.find_element(By.ID, "views").get_attribute("class")


@needs_browser
def test_the_denoise_toggle_shows_the_cubes_as_rendered(browser, url):
    open_page(browser, url, "?illuminants=A,D65")
    assert "denoise: none" not in browser.find_element(By.ID, "status").text
    assert "stored copies" in browser.find_element(By.ID, "denoise-note").text
    before = pixels(browser, "c-raw")
    n = ready(browser)
    Select(browser.find_element(By.ID, "denoise")).select_by_value("none")
    WebDriverWait(browser, WAIT_S).until(lambda d: ready(d) > n)
    assert "denoise=none" in browser.current_url and "denoise: none" in browser.find_element(By.ID, "status").text
    after = pixels(browser, "c-raw")
    assert sum(abs(a - b) for a, b in zip(before, after)) / len(after) > 0.5  # the noise is back
    assert "denoise=none" in browser.find_element(By.ID, "dl-npz").get_attribute("href")
    open_page(browser, url, "?" + browser.current_url.split("?", 1)[1])  # the link keeps it
    assert Select(browser.find_element(By.ID, "denoise")).first_selected_option.get_attribute("value") == "none"


@needs_browser
def test_the_geometry_panel_shows_albedo_normal_and_depth(browser, url):
    open_page(browser, url, "?illuminants=A,D65")
    assert not browser.find_element(By.ID, "c-aov").is_displayed()
    seen = {}
    for name in ("albedo", "normal", "depth"):
        Select(browser.find_element(By.ID, "aov")).select_by_value(name)
        WebDriverWait(browser, WAIT_S).until(
            lambda d, name=name: f"{name}:" in text(d, "aov-legend"))
        assert f"aov={name}" in browser.current_url
        px = pixels(browser, "c-aov")
        assert len(px) == 60 * 80 * 4
        seen[name] = px
    # normals (0, 0, 1) everywhere → (128, 128, 255)
    assert seen["normal"][:3] == [128, 128, 255]
    assert seen["albedo"] != seen["normal"]
    open_page(browser, url, "?" + browser.current_url.split("?", 1)[1])
    WebDriverWait(browser, WAIT_S).until(lambda d: "depth:" in text(d, "aov-legend"))
    assert browser.find_element(By.ID, "c-aov").is_displayed()
