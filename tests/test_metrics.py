"""``GET /metrics`` (Prometheus text) and ``serve --warm``'s :func:`engine.warm.warm_cache`.

/metrics must count requests by route template (unknown paths as ``other``), time them, and show
the cube cache's hits and misses exactly as ``/health`` does. Warming must fill the cache with
exactly the entries a default ``/sample`` of each view reads (compared with the keys a cold service
caches after serving those samples), so the first samples are all hits, and must stop — never
evict, never raise — when the cache is too small.
"""

from __future__ import annotations

import pytest
import synthetic_store as synth
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from illumix.service.app import create_app
from illumix.engine.warm import warm_cache
from illumix.store import CubeStore


def scrape(client) -> dict[tuple, float]:
    """``{(sample name, sorted labels…): value}`` of one /metrics answer."""
    r = client.get("/metrics")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/plain; version=0.0.4")
    return {(s.name, *sorted(s.labels.items())): s.value
            for fam in text_string_to_metric_families(r.text) for s in fam.samples}


def requests_of(m: dict, route: str, method: str = "GET", status: str = "200") -> float:
    return m.get(("illumix_requests_total", ("method", method), ("route", route), ("status", status)), 0.0)


def durations_of(m: dict, route: str) -> float:
    return m.get(("illumix_request_duration_seconds_count", ("route", route)), 0.0)


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """Store paths by variant: plain (no AOVs, no illumination), illumination, denoised. Each holds the
    illuminant ``cut650`` (dark above 630 nm: no power where the ``thesis`` view was rendered dark),
    so every view's default sample works."""
    root = tmp_path_factory.mktemp("metrics")
    csv = "wavelength,value\n" + "\n".join(f"{wl},{1.0 if wl <= 630 else 0.0}" for wl in range(380, 785, 5))
    out = {}
    for name, kw in (("plain", {}), ("illumination", {"illumination": True}), ("denoised", {"denoised": True})):
        synth.build(root / name, **kw)
        out[name] = str(root / name)
        r = client_for(out[name]).post("/illuminants", data={"name": "cut650"}, files={"file": ("cut.csv", csv)},
                                       headers={"Authorization": "Bearer t"})
        assert r.status_code in (200, 201), r.text
    return out


def client_for(path: str, cache_mb: int = 64) -> TestClient:
    return TestClient(create_app(CubeStore.open(path, mode="a"), token="t", cache_mb=cache_mb))


def test_metrics_is_prometheus_text_with_the_cache_counters(stores):
    c = client_for(stores["plain"])
    r = c.get("/metrics")
    assert "illumix_cache_hits_total" in r.text and "illumix_cache_misses_total" in r.text
    m = scrape(c)
    assert m[("illumix_process_resident_memory_bytes",)] > 10 * 2**20
    assert m[("illumix_cache_max_bytes",)] == 64 * 2**20 and m[("illumix_inflight_bytes",)] == 0
    assert m[("illumix_projection_hits_total",)] == 0 and m[("illumix_projection_bytes",)] == 0
    assert m[("illumix_refused_busy_total",)] == 0 and m[("illumix_cache_evicted_in_use_bytes",)] == 0
    assert "/metrics" in c.get("/openapi.json").json()["paths"]


def test_a_sample_is_counted_and_timed_and_cache_figures_match_health(stores):
    c = client_for(stores["plain"])
    before = scrape(c)
    q = {"scene": "synth", "view": "v0", "crop": "0,0,16,16", "outputs": "raw,gain"}
    assert c.get("/sample", params=q).status_code == 200
    assert c.get("/sample", params=q).status_code == 200
    after = scrape(c)
    assert requests_of(after, "/sample") - requests_of(before, "/sample") == 2
    assert durations_of(after, "/sample") - durations_of(before, "/sample") == 2
    hits, misses = after[("illumix_cache_hits_total",)], after[("illumix_cache_misses_total",)]
    assert misses >= 1 and hits >= 1
    cache = c.get("/health").json()["cache"]
    assert (cache["hits"], cache["misses"], cache["bytes"]) == (hits, misses, after[("illumix_cache_bytes",)])
    assert requests_of(after, "/metrics") >= 1  # the first scrape is counted by the second


def test_unknown_paths_and_methods_do_not_grow_the_labels(stores):
    c = client_for(stores["plain"])
    for path in ("/nope", "/sample/extra", "/a/b/c"):
        assert c.get(path).status_code == 404
    assert c.delete("/sample").status_code == 405
    assert c.request("BREW", "/health").status_code == 405
    m = scrape(c)
    assert requests_of(m, "other", status="404") == 3
    assert requests_of(m, "/sample", "DELETE", "405") == 1 and requests_of(m, "/health", "other", "405") == 1
    routes = {dict(k[1:]).get("route") for k in m if k[0] == "illumix_requests_total"}
    assert routes == {"other", "/sample", "/health"}
    assert c.get("/sensors/XYZ").status_code == 200  # a path parameter: counted under its template
    assert requests_of(scrape(c), "/sensors/{name}") == 1


def _default_samples(c: TestClient) -> None:
    """A default /sample (small crop) of every view; the crop does not change what is read."""
    for scene in c.get("/scenes").json()["scenes"]:
        for view in scene["views"]:
            r = c.get("/sample", params={"scene": scene["name"], "view": view["name"], "crop": "0,0,8,8",
                                         "outputs": "raw,gain,meta"})
            assert r.status_code == 200, r.text


@pytest.mark.parametrize("variant", ["plain", "illumination", "denoised"])
def test_warm_cache_holds_exactly_what_the_default_samples_read(stores, variant):
    cold = client_for(stores[variant])
    _default_samples(cold)
    read = set(cold.app.state.ctx.cache._items)  # the keys (LRUCache lists none publicly)

    warm = client_for(stores[variant])
    lines: list[str] = []
    counts = warm_cache(warm.app.state.ctx, log=lines.append)
    cache = warm.app.state.ctx.cache
    assert set(cache._items) == read
    assert counts["skipped"] == 0 and counts["bytes"] == cache.total_cost
    assert counts["cubes"] + counts["aovs"] == len(read) == len(lines) - 1
    assert (cache.hits, cache.misses) == (0, 0)  # warming is not traffic
    kinds = {k[3] for k in read if k[2] != "aov"}
    denoise = {k[4] for k in read if k[2] != "aov"}
    assert kinds == ({"transport", "illumination"} if variant != "plain" else {"transport"})
    assert denoise == ({"none", synth_default_denoise()} if variant == "denoised" else {"none"})
    _default_samples(warm)
    assert cache.misses == 0 and cache.hits > 0


def synth_default_denoise() -> str:
    from illumix.retarget.denoise import DEFAULT_METHOD

    return DEFAULT_METHOD


def test_warm_cache_stops_when_the_cache_is_full(stores):
    cube = synth.H * synth.W * 63 * 4
    for cache_mb, cubes in ((0, 0), (1, 2**20 // cube)):
        c = client_for(stores["illumination"], cache_mb=cache_mb)
        lines: list[str] = []
        counts = warm_cache(c.app.state.ctx, log=lines.append)
        cache = c.app.state.ctx.cache
        assert counts["cubes"] == cubes and counts["skipped"] > 0
        assert any("cache full" in line for line in lines)
        assert cache.total_cost == counts["bytes"] <= cache.max_cost and len(cache) == counts["cubes"] + counts["aovs"]
        _default_samples(c)  # the service still answers
