"""The web explorer in a real browser: headless Chromium (Debian's ``chromium`` + ``chromium-driver``)
driven by Selenium against the service on 127.0.0.1.

Checks: the page loads with no console error and asks nothing of any host but the service; changing
the illuminant pair changes the displayed images and the URL, and the URL restores the view; an
upload with the token appears in the sensor list; the page opens on a camera, and a link with bad
values (unknown names, numbers out of range) still draws, with a one-line notice naming what was
replaced and no console error; screenshots are saved as artifacts (the test's tmp folder, copied to
``bench/out/web-explorer.png`` and ``web-explorer-bad-link.png``, which git ignores). Skipped, with the reason,
where Chromium, its driver or Selenium is missing (``bash scripts/install.sh --test`` installs them
on Debian as root).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("selenium", reason="the test extra installs selenium (pip install -e '.[test]')")
import synthetic_store as synth
from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select, WebDriverWait
from server_testutil import ThreadServer

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(
    not (CHROMIUM and DRIVER),
    reason="no chromium/chromedriver on PATH: `bash scripts/install.sh --test` installs Debian's chromium and "
           "chromium-driver (as root)")
TOKEN = "web-token"
WAIT_S = 30  # bound of every wait: a page that never becomes ready fails instead of hanging
ARTIFACT = Path(__file__).resolve().parents[1] / "bench" / "out" / "web-explorer.png"


@pytest.fixture(scope="module")
def url(tmp_path_factory):
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    path = tmp_path_factory.mktemp("web") / "store"
    synth.build(path, h=120, w=160, extras=False, illumination=True)
    with ThreadServer(create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=64)) as base:
        yield base


@pytest.fixture(scope="module")
def browser():
    opts = Options()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1500,1400", "--hide-scrollbars"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(options=opts, service=Service(DRIVER))
    driver.set_page_load_timeout(WAIT_S)
    yield driver
    driver.quit()


def ready(driver) -> int:
    """How many frames the page has drawn (``body[data-ready]``, set after each update)."""
    return int(driver.execute_script("return document.body.dataset.ready || 0"))


def open_page(driver, url: str, query: str = "") -> None:
    driver.get(f"{url}/{query}")
    WebDriverWait(driver, WAIT_S).until(lambda d: ready(d) >= 1)


def pixels(driver, canvas: str) -> list[int]:
    return driver.execute_script(
        "const c = document.getElementById(arguments[0]);"
        "return Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height).data);", canvas)


def test_page_loads_without_errors_or_other_hosts(browser, url):
    browser.get_log("browser"), browser.get_log("performance")  # start from empty logs
    open_page(browser, url)
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors
    requested = [m["params"]["request"]["url"] for m in
                 (json.loads(e["message"])["message"] for e in browser.get_log("performance"))
                 if m["method"] == "Network.requestWillBeSent"]
    assert any("/explore/frame" in u for u in requested) and any("/web/vendor/uPlot.esm.js" in u for u in requested)
    others = [u for u in requested if not u.startswith((url + "/", "data:"))]
    assert not others, others
    assert "ground truth" in browser.find_element(By.ID, "status").text
    for legend in ("gain-legend", "mixture-legend"):
        assert browser.find_element(By.ID, legend).text.strip()
    assert browser.find_elements(By.CSS_SELECTOR, "#p-chroma canvas")
    # the downloads are GET /sample with the page's parameters
    import httpx

    for link, kind in (("dl-npz", "application/octet-stream"), ("dl-srgb", "image/png"), ("dl-raw", "image/png"),
                       ("dl-dng", "image/x-adobe-dng"), ("dl-exr", "image/x-exr")):
        href = browser.find_element(By.ID, link).get_attribute("href")
        assert href.startswith(url + "/sample?"), href
        r = httpx.get(href, timeout=WAIT_S)
        assert r.status_code == 200 and r.headers["content-type"] == kind, (link, r.status_code, r.text[:200])


def test_changing_the_illuminants_changes_the_image_and_the_url(browser, url):
    open_page(browser, url, "?illuminants=A,D65")
    before = {c: pixels(browser, c) for c in ("c-raw", "c-baseline")}
    n = ready(browser)
    Select(browser.find_elements(By.CSS_SELECTOR, "#groups select.ill")[0]).select_by_value("FL11")
    WebDriverWait(browser, WAIT_S).until(lambda d: ready(d) > n)
    for canvas, old in before.items():
        new = pixels(browser, canvas)
        diff = sum(abs(a - b) for a, b in zip(old, new)) / len(new)
        assert diff > 2, (canvas, diff)  # A → FL11 on the window group: a visible change, not rounding
    assert "illuminants=FL11%2CD65" in browser.current_url
    open_page(browser, url, "?" + browser.current_url.split("?", 1)[1])  # a shared link restores the view
    assert Select(browser.find_elements(By.CSS_SELECTOR, "#groups select.ill")[0]).first_selected_option \
        .get_attribute("value") == "FL11"


def settle(driver) -> None:
    """Wait until the page drew a frame or gave up with an error (so a broken page fails fast)."""
    WebDriverWait(driver, WAIT_S).until(
        lambda d: ready(d) >= 1 or "error" in d.find_element(By.ID, "status").get_attribute("class"))


def controls(driver) -> dict:
    """What the controls show, read in one script."""
    return driver.execute_script("""
        const v = (sel) => Array.from(document.querySelectorAll(sel), (e) => e.value);
        return {sensor: document.getElementById('sensor').value, ill: v('#groups select.ill'),
                intensity: v('#groups input.int').map(Number), ev: Number(document.getElementById('ev').value),
                notice: document.getElementById('notice').hidden ? '' : document.getElementById('notice-text').textContent};""")


def test_the_default_sensor_is_a_camera(browser, url):
    open_page(browser, url, "?illuminants=A,D65")
    assert controls(browser)["sensor"] == "Nikon 5100 (NPL)"
    assert "sensor=Nikon+5100+%28NPL%29" in browser.current_url
    assert controls(browser)["notice"] == ""  # a good link: no notice


def test_a_bad_link_still_renders_with_a_notice(browser, url, tmp_path):
    """Every URL value is checked against the lists and ranges: a bad one is replaced, the page says
    which in one line, and still draws (no 4xx request, so no console error)."""
    browser.get_log("browser")
    browser.get(f"{url}/?scene=nope&sensor=nope&illuminants=D56,blackbody:99&intensities=foo,1e99&ev=9"
                "&gain=x&gt=y&size=abc&npz=raw,zz")
    settle(browser)
    assert ready(browser) >= 1, browser.find_element(By.ID, "status").text
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors
    shown = controls(browser)
    assert shown["sensor"] == "Nikon 5100 (NPL)" and shown["ill"] == ["A", "blackbody"]
    assert shown["intensity"] == [1, 4] and shown["ev"] == 4
    notice = shown["notice"]
    for part in ("scene 'nope'", "sensor 'nope' unknown", "'D56'", "blackbody:99", "'foo'", "1e99", "ev", "gain", "gt",
                 "size", "'zz'"):
        assert part in notice, (part, notice)
    assert "\n" not in notice.strip()
    assert "sensor=Nikon" in browser.current_url and "blackbody%3A1500" in browser.current_url
    assert max(pixels(browser, "c-srgb")) > 0
    shot = tmp_path / "web-explorer-bad-link.png"
    assert browser.save_screenshot(str(shot))
    ARTIFACT.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shot, ARTIFACT.with_name(shot.name))


def test_the_default_sensor_falls_back_on_installs_without_it(browser, url):
    """js/linkcheck.js run in the page on made-up lists: the first built-in camera, else XYZ."""
    open_page(browser, url)
    got = browser.execute_async_script("""
        const done = arguments[arguments.length - 1];
        import('/web/js/linkcheck.js').then((m) => done([
            m.defaultSensor({builtin: ['XYZ', 'Canon EOS 5DS', 'Nikon 5100 (NPL)'], uploaded: []}),
            m.defaultSensor({builtin: ['XYZ', 'Canon EOS 5DS'], uploaded: ['mine']}),
            m.defaultSensor({builtin: ['XYZ'], uploaded: []})]));""")
    assert got == ["Nikon 5100 (NPL)", "Canon EOS 5DS", "XYZ"]


def test_an_upload_with_the_token_appears_in_the_sensor_list(browser, url, tmp_path):
    import numpy as np

    wl = np.arange(380, 781, 5)
    curves = [np.exp(-0.5 * ((wl - mu) / 30) ** 2) for mu in (600, 540, 460)]
    csv = tmp_path / "browser-cam.csv"
    csv.write_text("wavelength,r,g,b\n" + "".join(f"{w},{r:.5f},{g:.5f},{b:.5f}\n" for w, r, g, b in zip(wl, *curves)))
    open_page(browser, url)
    browser.find_element(By.ID, "token").send_keys(TOKEN)
    form = browser.find_element(By.ID, "up-sensor")
    form.find_element(By.NAME, "name").send_keys("browser-cam")
    form.find_element(By.NAME, "file").send_keys(str(csv))
    n = ready(browser)
    form.find_element(By.TAG_NAME, "button").click()
    # read in one script: the page rebuilds the list, so element handles could go stale between calls
    WebDriverWait(browser, WAIT_S).until(lambda d: "browser-cam" in d.execute_script(
        "return Array.from(document.querySelectorAll('#sensor option'), o => o.value)"))
    assert "uploaded sensor 'browser-cam'" in browser.find_element(By.ID, "upload-status").text
    WebDriverWait(browser, WAIT_S).until(lambda d: ready(d) > n)  # the page switches to the new sensor
    assert "sensor=browser-cam" in browser.current_url


def test_screenshot_artifact(browser, url, tmp_path):
    open_page(browser, url, "?illuminants=A,D65&intensities=1,0.8")
    canvas = browser.find_element(By.ID, "c-srgb")
    ActionChains(browser).move_to_element_with_offset(canvas, 40, 10).perform()
    WebDriverWait(browser, WAIT_S).until(lambda d: "mixture" in d.find_element(By.ID, "readout").text)
    readout = browser.find_element(By.ID, "readout").text
    assert "white point" in readout and "gain" in readout
    shot = tmp_path / "web-explorer.png"
    assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 20_000
    ARTIFACT.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shot, ARTIFACT)
    print(f"web explorer screenshot: {shot} (copied to {ARTIFACT})")


def test_a_dng_upload_estimates_a_sensor(browser, url, tmp_path, monkeypatch):
    """Issue 35: the explorer's DNG form posts to /sensors/estimate; the estimated sensor joins the list."""
    from pathlib import Path

    import numpy as np

    from illumix.imagefiles.dng import dng_bytes

    cameras = Path(__file__).resolve().parents[2] / "shared" / "data" / "rawtoaces-data" / "data" / "camera"
    if not cameras.is_dir():
        pytest.skip("the measured cameras live in ../shared/data")
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(cameras))  # the service runs in this process
    cm = np.array([[0.6722, -0.0635, -0.0963], [-0.4287, 1.2460, 0.2028], [-0.0908, 0.2162, 0.5668]])
    dng = tmp_path / "browser.dng"
    dng.write_bytes(dng_bytes(np.full((32, 32), 500, np.uint16), black=64, white=4095, pattern="RGGB", matrix=cm,
                              neutral=[1, 1, 1], model="cam"))
    open_page(browser, url)
    browser.find_element(By.ID, "token").send_keys(TOKEN)
    form = browser.find_element(By.ID, "up-dng")
    form.find_element(By.NAME, "name").send_keys("browser-dng")
    form.find_element(By.NAME, "file").send_keys(str(dng))
    form.find_element(By.TAG_NAME, "button").click()
    WebDriverWait(browser, WAIT_S).until(lambda d: "browser-dng" in d.execute_script(
        "return Array.from(document.querySelectorAll('#sensor option'), o => o.value)"))
    assert "uploaded sensor 'browser-dng'" in browser.find_element(By.ID, "upload-status").text
