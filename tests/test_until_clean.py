"""Render until clean (issue 39): ``RenderSettings.clean_max_spp`` adds paths to a cube while two
independent halves of it disagree as a noisy cube does (renderer_jobs/clean_check.py)."""

from __future__ import annotations

import numpy as np
import pytest
from illumix.renderer_jobs.clean_check import is_clean, measure
from illumix.renderer_jobs.mitsuba.until_clean import render_until_clean
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.schema import SceneError

H, W, B = 40, 50, 3


def _truth() -> np.ndarray:
    y, x = np.mgrid[0:H, 0:W]
    return np.stack([0.2 + 0.01 * x, 0.3 + 0.005 * y, np.full((H, W), 0.25)], -1)


def _fake(firefly_rate: float):
    """A render_once stand-in: the truth plus noise ~ 1/√spp and fireflies (one path worth 2000× a
    pixel) at ``firefly_rate`` per pixel per path, independent per seed; records the calls."""
    calls = []

    def render_once(s):
        calls.append((s.spp, s.seed))
        rng = np.random.default_rng(s.seed)
        t = _truth()
        cube = t * (1 + rng.normal(0, 0.3 / np.sqrt(s.spp), (H, W, 1)))
        hits = rng.random((H, W)) < firefly_rate * s.spp / 64
        cube[hits] += 2000 * t[hits] / s.spp
        stats = {k: 1.0 for k in ("load_s", "trace_s", "total_s")}
        stats.update({"nonfinite_samples": 0, "paths_per_pixel": s.spp, "samples_per_band": s.spp,
                      "paths_per_pixel_rendered": s.spp, "samples_per_band_rendered": s.spp})
        noise = np.stack([cube.sum(-1), np.full((H, W), 1.0 / s.spp)], -1)
        return cube.astype(np.float32), (2 * cube).astype(np.float32), stats, noise.astype(np.float32)

    return render_once, calls


def test_a_clean_cube_costs_its_spp():
    render, calls = _fake(firefly_rate=0.0)
    cube, illum, stats, noise = render_until_clean(render, RenderSettings(spp=64, clean_max_spp=1024))
    assert [c[0] for c in calls] == [32, 32] and len({c[1] for c in calls}) == 2  # two halves, own seeds
    assert stats["until_clean"]["clean"] and stats["until_clean"]["rounds"] == 2 and stats["paths_per_pixel"] == 64
    np.testing.assert_allclose(cube, _truth(), rtol=0.2)
    np.testing.assert_allclose(illum, 2 * cube, rtol=1e-6)
    np.testing.assert_allclose(noise[..., 1], 1 / 64, rtol=1e-6)  # two halves of variance 1/32, averaged


def test_fireflies_buy_more_paths_up_to_the_cap():
    render, calls = _fake(firefly_rate=0.01)
    _, _, stats, _ = render_until_clean(render, RenderSettings(spp=64, clean_max_spp=1024))
    spps = [c[0] for c in calls]
    assert spps[:2] == [32, 32] and sum(spps) <= 1024 and len(spps) > 2
    assert len({c[1] for c in calls}) == len(calls)  # every round its own paths
    assert stats["paths_per_pixel"] == sum(spps) and stats["until_clean"]["rounds"] == len(spps)
    capped, _ = _fake(firefly_rate=0.01)
    _, _, small, _ = render_until_clean(capped, RenderSettings(spp=64, clean_max_spp=128))
    assert small["paths_per_pixel"] <= 128 and not small["until_clean"]["clean"]


def test_the_rounds_average_to_an_unbiased_cube():
    """Each round is weighted by its samples: a constant scene comes back exactly."""
    def flat(s):
        stats = {k: 0.0 for k in ("load_s", "trace_s", "total_s")}
        stats.update({k: s.spp for k in ("nonfinite_samples", "paths_per_pixel", "samples_per_band",
                                         "paths_per_pixel_rendered", "samples_per_band_rendered")})
        c = np.full((H, W, B), 0.5, np.float32)
        c[0, 0] = 1e3 if s.seed % 2 else 0.5  # one firefly in every other round keeps it "not clean"
        return c, None, stats, None
    cube, illum, _, noise = render_until_clean(flat, RenderSettings(spp=64, clean_max_spp=256))
    assert illum is None and noise is None
    np.testing.assert_allclose(cube[1:, 1:], 0.5)


def test_clean_check_definition():
    t = _truth().sum(-1)
    assert is_clean(measure(t, t))
    b = t.copy()
    b[::4, ::4] *= 10  # 6 % of pixels 10:1 apart
    assert not is_clean(measure(t, b))


@pytest.mark.parametrize("kw, words", [({"clean_max_spp": 32}, "below --spp"),
                                       ({"clean_max_spp": 512, "wavelengths": "stratified"}, "all-bands")])
def test_bad_settings_are_one_line(kw, words):
    with pytest.raises(SceneError, match=words):
        RenderSettings(**kw)


def test_a_real_cube_renders_in_rounds():
    """Through the renderer (a 32×24 demo cube at 16 spp: noisy, so it adds rounds up to the cap)."""
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.scene.demo import demo_room
    scene = demo_room(0, (32, 24))
    r = render_cube(scene, scene.views[0].name, "desk",
                    RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=False))
    uc = r.stats["until_clean"]
    assert uc["rounds"] >= 2 and 16 <= r.stats["paths_per_pixel"] <= 64
    assert np.isfinite(r.cube).all() and r.cube.shape == (24, 32, scene.spectral_grid.n_bands)


def test_the_estimate_says_the_rule_can_add_paths():
    from illumix.renderer_jobs.cost_model import Estimate
    plain = Estimate(cpu_s=10, wall_s=8, workers=1, jobs=2, paths=1e6, kernel_s=3)
    capped = Estimate(cpu_s=10, wall_s=8, workers=1, jobs=2, paths=1e6, kernel_s=3, clean_max_factor=16)
    assert "clean-max-spp" not in plain.line() and "up to 16x the paths" in capped.line()
