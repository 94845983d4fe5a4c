"""Issue 38, the explorer's research tools in headless Chromium (as tests/test_web.py): zoom and pan
shared by every panel and kept in the page link, the spectrum at the hovered pixel, the camera-noise preview and the dataset
gallery with its statistics — each drawn without a console error. The gallery's screenshot is kept
in ``bench/out/web-explorer-gallery.png`` (git ignores it).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import synthetic_store as synth
from server_testutil import ThreadServer

try:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait
    from test_web import CHROMIUM, DRIVER, browser, open_page, pixels, ready  # noqa: F401
except ImportError:
    CHROMIUM = DRIVER = None

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="no selenium, or no chromium/chromedriver on PATH: "
                                "`bash scripts/install.sh --test` installs them (as root)")
WAIT_S = 20  # each test stays within ~20 s: a wait that long is a failure, not a slow machine
H, W = 60, 80
ARTIFACTS = Path(__file__).resolve().parents[1] / "bench" / "out"


@pytest.fixture(scope="module")
def url(tmp_path_factory):
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    path = tmp_path_factory.mktemp("tools") / "store"
    synth.build(path, h=H, w=W, extras=False, illumination=True)
    with ThreadServer(create_app(CubeStore.open(str(path), mode="a"), cache_mb=64)) as base:
        yield base


def severe(driver) -> list:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def counter(driver, name: str) -> int:
    return int(driver.execute_script(f"return document.body.dataset.{name} || 0"))


def transforms(driver) -> list[str]:
    return driver.execute_script(
        "return Array.from(document.querySelectorAll('.frame canvas'), (c) => c.style.transform)")


def wheel(driver, canvas_id: str, fx: float, fy: float, delta: float) -> None:
    """A wheel event at fraction (fx, fy) of a panel (what a mouse wheel sends)."""
    driver.execute_script("""
        const f = document.getElementById(arguments[0]).closest('.frame'), r = f.getBoundingClientRect();
        f.dispatchEvent(new WheelEvent('wheel', {deltaY: arguments[3], bubbles: true, cancelable: true,
            clientX: r.left + arguments[1] * r.width, clientY: r.top + arguments[2] * r.height}));""",
                          canvas_id, fx, fy, delta)


def image_point(driver, canvas_id: str, fx: float, fy: float) -> list[float]:
    """Where panel fraction (fx, fy) of the canvas lands in the image (0..1), read from the drawn layout."""
    return driver.execute_script("""
        const c = document.getElementById(arguments[0]), f = c.closest('.frame');
        const r = c.getBoundingClientRect(), fr = f.getBoundingClientRect();
        const px = fr.left + arguments[1] * fr.width, py = fr.top + arguments[2] * fr.height;
        return [(px - r.left) / r.width, (py - r.top) / r.height];""", canvas_id, fx, fy)


def test_zoom_pan_and_reset_stay_in_sync(browser, url):
    browser.get_log("browser")
    open_page(browser, url, "?illuminants=A,D65")
    assert set(transforms(browser)) == {""}
    wheel(browser, "c-srgb", 0.3, 0.6, 100)  # out, at no zoom: nothing happens (the page may scroll)
    assert set(transforms(browser)) == {""}
    before = image_point(browser, "c-srgb", 0.3, 0.6)
    for _ in range(4):
        wheel(browser, "c-srgb", 0.3, 0.6, -100)  # four notches in: 1.25^4
    zoom = float(browser.execute_script("return document.body.dataset.zoom"))
    assert zoom == pytest.approx(1.25 ** 4, rel=1e-3)
    after = image_point(browser, "c-srgb", 0.3, 0.6)
    assert after == pytest.approx(before, abs=2e-3)  # the point under the cursor stays put
    shown = transforms(browser)
    assert len(shown) >= 5 and len(set(shown)) == 1 and "scale(2.44" in shown[0]  # every panel alike
    # the raw panel shows the same image point at the same place
    assert image_point(browser, "c-raw", 0.3, 0.6) == pytest.approx(after, abs=2e-3)
    # drag to pan: the image follows the pointer on every panel
    # the panel, not the canvas: a transformed canvas' centre is not where the panel shows it
    frame = browser.find_element(By.CSS_SELECTOR, "figure[data-kind=mixture] .frame")
    ActionChains(browser).move_to_element(frame).click_and_hold().move_by_offset(-30, -20).release().perform()
    panned = transforms(browser)
    assert len(set(panned)) == 1 and panned != shown
    moved = image_point(browser, "c-gain", 0.3, 0.6)
    assert moved[0] > after[0] and moved[1] > after[1]  # dragged left and up: further right and down
    # the hover readout reads the pixel under the pointer through the zoom
    ActionChains(browser).move_to_element(frame).perform()  # the centre of the panel
    u, v = image_point(browser, "c-mixture", 0.5, 0.5)
    WebDriverWait(browser, WAIT_S).until(lambda d: "pixel x" in d.find_element(By.ID, "readout").text)
    assert f"pixel x {int(u * W)}, y {int(v * H)}" in browser.find_element(By.ID, "readout").text
    ActionChains(browser).double_click(frame).perform()
    assert set(transforms(browser)) == {""}
    assert not severe(browser)


def zoom_link(driver) -> dict[str, str]:
    """The link's ``zoom`` and ``at`` (absent at no zoom)."""
    from urllib.parse import parse_qs, urlsplit

    q = parse_qs(urlsplit(driver.current_url).query)
    return {k: q[k][0] for k in ("zoom", "at") if k in q}


def centre_in_link(driver) -> bool:
    """The link's ``at`` is the image point at the panels' centre now (the URL follows a gesture once it rests)."""
    link = zoom_link(driver)
    if "at" not in link:
        return False
    return [float(t) for t in link["at"].split(",")] == pytest.approx(image_point(driver, "c-srgb", 0.5, 0.5), abs=2e-3)


def test_zoom_and_pan_are_kept_in_the_link(browser, url):
    browser.get_log("browser")
    open_page(browser, url, "?illuminants=A,D65")
    assert zoom_link(browser) == {}
    for _ in range(3):
        wheel(browser, "c-srgb", 0.7, 0.3, -100)
    frame = browser.find_element(By.CSS_SELECTOR, "figure[data-kind=mixture] .frame")
    ActionChains(browser).move_to_element(frame).click_and_hold().move_by_offset(25, 15).release().perform()
    WebDriverWait(browser, WAIT_S).until(centre_in_link)
    link = zoom_link(browser)
    assert float(link["zoom"]) == pytest.approx(1.25 ** 3, rel=1e-3)
    zoom = browser.execute_script("return document.body.dataset.zoom")
    points = [image_point(browser, c, fx, fy) for c, fx, fy in (("c-srgb", 0.5, 0.5), ("c-raw", 0.1, 0.9))]
    # the link reopens the same zoom and pan (on every panel), with no notice
    query = browser.current_url.split("?", 1)[1]
    open_page(browser, url, "?" + query)
    assert browser.execute_script("return document.body.dataset.zoom") == zoom
    again = [image_point(browser, c, fx, fy) for c, fx, fy in (("c-srgb", 0.5, 0.5), ("c-raw", 0.1, 0.9))]
    assert again == [pytest.approx(p, abs=2e-3) for p in points]
    assert len(set(transforms(browser))) == 1 and not browser.find_element(By.ID, "notice").is_displayed()
    assert zoom_link(browser) == link  # the reopened page keeps it in its link
    # image fractions, not pixels: the same spot at half the frame size
    open_page(browser, url, f"?{query}&size={W // 2}x{H // 2}")
    assert image_point(browser, "c-srgb", 0.5, 0.5) == pytest.approx(points[0], abs=2e-3)
    # a reset drops both from the link
    frame = browser.find_element(By.CSS_SELECTOR, "figure[data-kind=mixture] .frame")
    ActionChains(browser).double_click(frame).perform()
    WebDriverWait(browser, WAIT_S).until(lambda d: zoom_link(d) == {})
    assert set(transforms(browser)) == {""} and "illuminants=A%2CD65" in browser.current_url
    assert not severe(browser)


def test_a_malformed_zoom_in_the_link_opens_the_default_view(browser, url):
    browser.get_log("browser")
    bad = ["zoom=abc", "zoom=0.5", "zoom=65", "zoom=Infinity", "zoom=2&at=1.5,0.2", "zoom=2&at=0.3",
           "zoom=2&at=x,y", "zoom=2&at=0.1,0.2,0.3"]
    quiet = ["zoom=", "at=0.2,0.2", "zoom=1&at=0.2,0.2"]  # no zoom asked for: nothing to say
    for extra in bad + quiet:
        open_page(browser, url, f"?illuminants=A,D65&{extra}")
        assert set(transforms(browser)) == {""}, extra
        assert browser.execute_script("return document.body.dataset.zoom") == "1.0000", extra
        assert zoom_link(browser) == {}, extra
        notice = browser.find_element(By.ID, "notice-text").get_attribute("textContent")
        assert ("no zoom" in notice) == (extra in bad), (extra, notice)
    assert not severe(browser)


def test_the_hovered_pixel_spectrum_is_plotted(browser, url):
    browser.get_log("browser")
    open_page(browser, url, "?illuminants=A,D65&intensities=1,0.5")
    n = counter(browser, "spectra")
    canvas = browser.find_element(By.ID, "c-srgb")
    ActionChains(browser).move_to_element_with_offset(canvas, -60, -20).perform()
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "spectra") > n)
    chart = browser.find_element(By.ID, "p-pixel")
    assert chart.find_elements(By.CSS_SELECTOR, "canvas")
    legend = chart.text
    assert "window: A" in legend and "lamp: D65" in legend and "sum" in legend
    assert "raw (R, G, B)" in browser.find_element(By.ID, "px-raw").text
    # the chart's axis is wavelength; the other views of the same answer draw without a request
    from illumix.retarget.grid import DEFAULT_GRID

    wl = DEFAULT_GRID.wavelengths
    assert chart.get_attribute("data-bands") == f"63 bands, {wl[0]:g}-{wl[-1]:g} nm"
    m = counter(browser, "spectra")
    for kind, words in (("illumination", "lamp: D65"), ("reflectance", "reflectance")):
        Select(browser.find_element(By.ID, "px-kind")).select_by_value(kind)
        assert words in browser.find_element(By.ID, "p-pixel").text
    assert counter(browser, "spectra") == m
    # new lights: the chart follows them at the same pixel without another hover
    Select(browser.find_element(By.ID, "px-kind")).select_by_value("radiance")
    Select(browser.find_elements(By.CSS_SELECTOR, "#groups select.ill")[0]).select_by_value("FL11")
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "spectra") > m)
    assert "window: FL11" in browser.find_element(By.ID, "p-pixel").text
    assert not severe(browser)


def test_the_noise_preview_toggles_at_the_raw_exposure(browser, url):
    browser.get_log("browser")
    open_page(browser, url, "?illuminants=A,D65")
    panel = browser.find_element(By.ID, "c-noisy")
    assert not panel.is_displayed()
    n = counter(browser, "noisy")
    Select(browser.find_element(By.ID, "noise")).select_by_value("high")
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "noisy") > n)
    assert panel.is_displayed() and "noise=high" in browser.current_url
    legend = browser.find_element(By.ID, "noisy-legend").text
    assert "full well 1000" in legend and "10 bit" in legend and "+0 EV" in legend
    clean, noisy = pixels(browser, "c-raw"), pixels(browser, "c-noisy")
    assert len(clean) == len(noisy) == W * H * 4
    # the same exposure: the mean level agrees, the pixels differ by the grain (high ISO: 1000 e-)
    mean = lambda px: sum(px[i] for i in range(len(px)) if i % 4 != 3) / (len(px) * 3 / 4)
    assert abs(mean(noisy) - mean(clean)) < 6, (mean(noisy), mean(clean))
    assert sum(abs(a - b) for a, b in zip(clean, noisy)) / len(clean) > 2
    # the exposure slider exposes the noisy raw anew; off hides it
    n = counter(browser, "noisy")
    browser.execute_script("const e = document.getElementById('ev'); e.value = '1'; e.dispatchEvent(new Event('input'));")
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "noisy") > n)
    assert "+1 EV" in browser.find_element(By.ID, "noisy-legend").text
    Select(browser.find_element(By.ID, "noise")).select_by_value("")
    assert not panel.is_displayed() and "noise=" not in browser.current_url
    assert not severe(browser)


def test_the_gallery_draws_samples_and_statistics(browser, url, tmp_path):
    browser.get_log("browser")
    open_page(browser, url, "?illuminants=A,D65")
    Select(browser.find_element(By.ID, "gal-count")).select_by_value("12")
    n = counter(browser, "gallery")
    browser.find_element(By.ID, "gal-draw").click()
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "gallery") > n)
    assert "12 of 12 samples composed" in browser.find_element(By.ID, "gal-status").text
    # each thumbnail is the sample's sRGB: bright colours (the patches), not black (alpha left out)
    tiles = browser.execute_script("""return Array.from(document.querySelectorAll('#gal-grid canvas'), (c) =>
        [c.width, c.height, Math.max(...c.getContext('2d').getImageData(0, 0, c.width, c.height).data
                                     .filter((v, i) => i % 4 !== 3))])""")
    assert len(tiles) == 12 and all(t[:2] == [96, 72] and t[2] > 100 for t in tiles), tiles
    for chart in ("gal-xy", "gal-mix", "gal-gain"):
        assert browser.find_elements(By.CSS_SELECTOR, f"#{chart} canvas"), chart
    assert "valid pixels are mixed" in browser.find_element(By.ID, "gal-mix-note").text
    assert "gain R" in browser.find_element(By.ID, "gal-gain-note").text
    gallery = browser.find_element(By.ID, "gallery")
    browser.execute_script("arguments[0].scrollIntoView()", gallery)
    shot = tmp_path / "web-explorer-gallery.png"
    assert gallery.screenshot(str(shot))
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shot, ARTIFACTS / shot.name)  # bench/out/ (git ignores it)
    captions = browser.execute_script("return Array.from(document.querySelectorAll('#gal-grid figcaption'), (f) => f.textContent)")
    # the same seed draws the same set; another seed another one
    browser.find_element(By.ID, "gal-draw").click()
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "gallery") > n + 1)
    assert captions == browser.execute_script(
        "return Array.from(document.querySelectorAll('#gal-grid figcaption'), (f) => f.textContent)")
    assert not severe(browser)


def test_the_gallery_draws_as_the_client_sampler(browser, url):
    """js/gallery.js drawSpec against illumix_client.draw.SpecSampler's rules, on made-up views."""
    open_page(browser, url)
    got = browser.execute_async_script("""
        const done = arguments[arguments.length - 1];
        import('/web/js/gallery.js').then((m) => {
          const views = [{scene: 's', view: 'a', width: 8, height: 6, groups: ['g1', 'g2']},
                         {scene: 's', view: 'b', width: 8, height: 6, groups: ['g1', 'g2', 'g3']}];
          const pool = ['A', 'D65', 'blackbody:2500-7500'];
          const draws = Array.from({length: 2000}, (_, i) => m.drawSpec(m.itemRng(5, i), views, pool, ['XYZ', 'cam']));
          const again = m.drawSpec(m.itemRng(5, 7), views, pool, ['XYZ', 'cam']);
          done({draws, again, other: m.drawSpec(m.itemRng(6, 7), views, pool, ['XYZ', 'cam'])});
        });""")
    draws = got["draws"]
    assert got["again"] == draws[7] and got["other"] != draws[7]
    views = [d["view"] for d in draws]
    assert 900 < views.count("a") < 1100  # uniform over views
    assert 900 < [d["sensor"] for d in draws].count("cam") < 1100
    for d in draws:
        assert len(d["illuminants"]) == len(d["intensities"]) == (2 if d["view"] == "a" else 3)
        assert max(d["intensities"]) == 1 and min(d["intensities"]) >= 0.25 - 1e-9
        for name in d["illuminants"]:
            if name.startswith("blackbody:"):
                k = float(name.split(":")[1])
                assert 2500 <= k <= 7500 and k % 50 == 0
            else:
                assert name in ("A", "D65")
    # distinct where the pool allows: two groups almost never share an illuminant
    same = sum(d["illuminants"][0] == d["illuminants"][1] for d in draws)
    assert same < 20, same


def test_the_gallery_statistics_against_numpy_and_colour(browser, url):
    """The page's per-sample statistics (js/gallery.js sampleStats) against numpy on the same /sample
    answer, and its CIE xy of illuminants against colour-science's tabulated chromaticities."""
    import colour
    import httpx
    import numpy as np
    from test_explore import decode

    q = {"scene": "synth", "view": "v0", "sensor": "XYZ", "illuminants": "FL11,daylight:5500", "intensities": "1,0.6",
         "outputs": "srgb,gain,mixture,mask,meta", "format": "arrays", "size": "40x30", "seed": "3"}
    open_page(browser, url)
    got = browser.execute_async_script("""
        const done = arguments[arguments.length - 1];
        Promise.all([import('/web/js/gallery.js'), import('/web/js/api.js')]).then(async ([g, api]) => {
          const s = g.sampleStats((await api.getArrays('/sample?' + new URLSearchParams(arguments[0]))).arrays);
          const c = await g.chromaticities(['A', 'D65', 'FL11']);
          done({mixed: s.mixed, n: s.top.length, gainR: s.gainR, gainB: s.gainB, xy: c.xy});
        });""", q)
    arrays, _ = decode(httpx.get(f"{url}/sample", params=q).content)
    valid = arrays["mask"]
    top = arrays["mixture"][valid].max(axis=1)
    assert got["n"] == valid.sum() and got["mixed"] == pytest.approx(np.mean(top < 0.9), abs=1e-9)
    for key, c in (("gainR", 0), ("gainB", 2)):
        vals = np.sort(arrays["gain"][valid][:, c])
        lo, hi = vals[int(0.01 * len(vals))], vals[min(len(vals) - 1, int(0.99 * len(vals)))]
        assert got[key] == pytest.approx([lo, hi], rel=1e-6)
    table = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]
    for name in ("A", "D65", "FL11"):
        # the service's grid averages the SPD over 5 nm bands: within 0.002 of the tabulated value
        assert got["xy"][name] == pytest.approx(list(table[name]), abs=2e-3), name


def test_the_gallery_shows_a_datasets_exact_specs(browser, url):
    """Specs pasted from the Python client's sampler (IllumixDataset.spec draws them so) are shown as given."""
    import json

    import httpx
    import numpy as np
    from illumix_client.draw import IlluminantPool, SpecSampler, views_from_scenes

    views = views_from_scenes(httpx.get(f"{url}/scenes").json()["scenes"])
    sampler = SpecSampler(views, IlluminantPool(["A", "D65", "FL11", "blackbody:2500-7500"]), ["XYZ"])
    specs = [sampler.spec(np.random.default_rng([9, 0, i])) for i in range(3)]
    open_page(browser, url)
    browser.execute_script("document.getElementById('gal-specs').value = arguments[0]", json.dumps(specs))
    n = counter(browser, "gallery")
    browser.find_element(By.ID, "gal-draw").click()
    WebDriverWait(browser, WAIT_S).until(lambda d: counter(d, "gallery") > n)
    assert "3 of 3 samples composed" in browser.find_element(By.ID, "gal-status").text
    captions = browser.execute_script(
        "return Array.from(document.querySelectorAll('#gal-grid figcaption'), (f) => f.textContent)")
    for caption, spec in zip(captions, specs):
        assert " + ".join(spec["illuminants"]) in caption and f"{spec['scene']}/{spec['view']}" in caption
    links = browser.execute_script("return Array.from(document.querySelectorAll('#gal-grid a'), (a) => a.href)")
    # a tile opens that sample in the explorer
    assert f"intensities={'%2C'.join(f'{a:g}' for a in specs[0]['intensities'])}" in links[0], links[0]
    assert not severe(browser)
